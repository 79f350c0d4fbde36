#!/bin/sh
# The C# package as hosts consume it, outside the build tree and with no LD_LIBRARY_PATH:
#  1. nuget install from a local feed holding only CrowdMPM.<version>.nupkg; a program compiled
#     against lib/net45/CrowdMPM.dll, with runtimes/<rid>/native/* copied beside it (what a
#     .NET build does with a package's native assets);
#  2. the Unity-style folder Assets/Plugins/CrowdMPM/{CrowdMPM.dll, x86_64/*.so}, with the
#     plugin folder on the native search path as Unity puts it.
# Both must step the drill to the committed hash.
# usage: nuget_test.sh NUGET MCS MONO FEED UNITY_DIR WORK_DIR DRILL STEPS HASH
set -eu
NUGET=$1 MCS=$2 MONO=$3 FEED=$4 UNITY=$5 WORK=$6 DRILL=$7 STEPS=$8 HASH=$9
HERE=$(cd "$(dirname "$0")" && pwd)
rm -rf "$WORK"
mkdir -p "$WORK/app" "$WORK/unity_app" "$WORK/home"
check() {
  echo "$1: $2"
  case "$2" in *"hash $HASH"*) ;; *) echo "$1: expected hash $HASH"; exit 1 ;; esac
}
HOME="$WORK/home" "$NUGET" install CrowdMPM -Source "$FEED" -OutputDirectory "$WORK/packages" -NonInteractive -Verbosity quiet
set -- "$WORK"/packages/CrowdMPM.*/lib/net45/CrowdMPM.dll
[ -f "$1" ] || { echo "nuget install gave no lib/net45/CrowdMPM.dll"; exit 1; }
pkg=$(dirname "$(dirname "$(dirname "$1")")")
cp "$1" "$pkg"/runtimes/*/native/* "$WORK/app/"
# The native module finds libcrowdmpm.so.1 beside itself and nowhere else (no build-tree path).
runpath=$(readelf -d "$WORK/app/libcrowdmpm_csharp.so" | sed -n 's/.*R\(UN\)\{0,1\}PATH.*\[\(.*\)\]/\2/p')
[ "$runpath" = '$ORIGIN' ] || { echo "libcrowdmpm_csharp.so has RUNPATH '$runpath', expected \$ORIGIN"; exit 1; }
cp "$DRILL" "$WORK/app/drill.json"
cd "$WORK/app"
"$MCS" -nologo -r:CrowdMPM.dll -out:Consumer.exe "$HERE/Consumer.cs"
check "nupkg" "$(env -u LD_LIBRARY_PATH -u MONO_PATH "$MONO" Consumer.exe drill.json "$STEPS")"

cd "$WORK/unity_app"
"$MCS" -nologo -r:"$UNITY/Assets/Plugins/CrowdMPM/CrowdMPM.dll" -out:Consumer.exe "$HERE/Consumer.cs"
check "unity layout" "$(env MONO_PATH="$UNITY/Assets/Plugins/CrowdMPM" LD_LIBRARY_PATH="$UNITY/Assets/Plugins/CrowdMPM/x86_64" "$MONO" Consumer.exe "$DRILL" "$STEPS")"
