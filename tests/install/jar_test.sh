#!/bin/sh
# crowdmpm.jar as a Java user gets it: copied alone into an empty folder, and a program run with
# only that jar on the class path (no java.library.path, no LD_LIBRARY_PATH). The jar loads its
# own native libraries; the program must step the drill to the committed hash.
# usage: jar_test.sh JAVA JAR WORK_DIR DRILL STEPS HASH
set -eu
JAVA=$1 JAR=$2 WORK=$3 DRILL=$4 STEPS=$5 HASH=$6
HERE=$(cd "$(dirname "$0")" && pwd)
rm -rf "$WORK"
mkdir -p "$WORK"
cp "$JAR" "$WORK/crowdmpm.jar"
cp "$HERE/Consumer.java" "$DRILL" "$WORK/"
cd "$WORK"
out=$(env -u LD_LIBRARY_PATH "$JAVA" -cp crowdmpm.jar Consumer.java "$(basename "$DRILL")" "$STEPS")
echo "$out"
case "$out" in
  *"hash $HASH"*) ;;
  *) echo "expected hash $HASH"; exit 1 ;;
esac
