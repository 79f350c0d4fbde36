#!/usr/bin/env bash
# Diagnosis from rendered video (benchmarks/diagnosis/README.md, "From video"): the suite's
# corridor and room with a concealed obstacle or drift, and their controls, each filmed by the
# synthetic renderer and diagnosed from the video's optical flow (`diagnosis_suite --video`).
# The table goes to benchmarks/results/diagnosis_video.md with the command that made it.
# Usage: benchmarks/diagnosis/video.sh [BUILD_DIR] [--only SCENE:EFFECT[,...]] [--options JSON]
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${1:-build}
shift || true
cases="corridor:none,corridor:obstacle,corridor:drift,room:none,room:obstacle,room:drift"
args=()
while [ $# -gt 0 ]; do
  case "$1" in
    --only) cases=$2; shift 2 ;;
    *) args+=("$1"); shift ;;
  esac
done
work="$build/diagnosis_video"
rm -rf "$work"
start=$(date +%s)
"$build/benchmarks/diagnosis_suite" benchmarks/diagnosis/suite.json --out "$work" --threads 2 --video --only "$cases" "${args[@]}" | tee "$work.log"
end=$(date +%s)
out=benchmarks/results/diagnosis_video.md
{
  echo "# Diagnosis from rendered video"
  echo
  echo "Command: \`benchmarks/diagnosis/video.sh $build --only $cases ${args[*]}\` at commit $(git rev-parse --short HEAD),"
  echo "$(date -u +%Y-%m-%d), $(nproc) cores, $((end - start)) s in all. Each case is the suite's (suite.json): the"
  echo "social-force model kind runs the scene with the effect concealed, the synthetic renderer films it"
  echo "(suite.json \"video\": 40 pixels per metre, 20 degrees tilt, 10 fps, textured heads, sensor noise,"
  echo "blur, Motion JPEG), and the diagnosis gets the scene without the effect and the video with its"
  echo "calibration. The tracks the video gives (detected and followed, docs/diagnosis.md \"From video\") are scored against"
  echo "what was filmed in the last three columns. Errors: RMS position errors (m) of those tracks over 3 s"
  echo "held-out rollouts."
  echo
  cat "$work/table.md"
} > "$out"
echo "wrote $out"
