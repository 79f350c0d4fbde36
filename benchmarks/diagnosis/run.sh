#!/usr/bin/env bash
# The diagnosis suite (benchmarks/diagnosis/README.md): every case of suite.json at every noise
# level (or the one given), diagnosed as `crowdmpm diagnose` does; the table goes to
# benchmarks/results/diagnosis.md with the command that made it.
# Usage: benchmarks/diagnosis/run.sh [BUILD_DIR] [--noise SD] [--only SCENE:EFFECT]
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${1:-build}
shift || true
work="$build/diagnosis_suite"
rm -rf "$work"
start=$(date +%s)
"$build/benchmarks/diagnosis_suite" benchmarks/diagnosis/suite.json --out "$work" --threads 2 "$@" | tee "$work.log"
end=$(date +%s)
out=benchmarks/results/diagnosis.md
{
  echo "# Diagnosis suite"
  echo
  echo "Command: \`benchmarks/diagnosis/run.sh $build $*\` at commit $(git rev-parse --short HEAD), $(date -u +%Y-%m-%d),"
  echo "$(nproc) cores, $((end - start)) s in all. Recordings: the social-force model kind with the effect of each"
  echo "row concealed from the scenario handed to the diagnosis (benchmarks/diagnosis/README.md); errors are"
  echo "RMS position errors (m) over 3 s held-out rollouts, of the people passing the found term's region and of"
  echo "everyone."
  echo
  cat "$work/table.md"
} > "$out"
echo "wrote $out"
