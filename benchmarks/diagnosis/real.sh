#!/usr/bin/env bash
# Diagnosis of real recordings (docs/diagnosis.md): the Hermes corridor run uo-180-180-070 (an
# exit constriction of 0.70 m that scenarios/corridor.json lacks), the CrowdQueue run 030 against
# the bottleneck without its gate (real/bottleneck_no_gate.json), the control uo-180-180-180
# (no constriction) against corridor.json, and the Hermes bottleneck AO_300 against its room
# without the bottleneck's walls (real/bottleneck_ao_no_walls.json; about 30 min alone). Skips
# without ../shared/data.
# Usage: benchmarks/diagnosis/real.sh [BUILD_DIR] [crowdmpm diagnose options, e.g. --options JSON]
# (benchmarks/results/diagnosis_real.md; its older sections: --options '{"density_law": false}')
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${1:-build}
shift || true
real=../shared/data/real
[ -d "$real" ] || { echo "skipped: $real is absent"; exit 0; }
cli="$build/cli/crowdmpm"
work="$build/diagnosis_real"
mkdir -p "$work"
runs=("scenarios/corridor.json $real/fzj_hermes_2009_corridor_uo/uo-180-180-070.txt uo-180-180-070"
      "benchmarks/diagnosis/real/bottleneck_no_gate.json $real/fzj_crowdqueue_2018_bottleneck/030_c_56_h0.txt crowdqueue_030_no_gate"
      "scenarios/corridor.json $real/fzj_hermes_2009_corridor_uo/uo-180-180-180.txt uo-180-180-180"
      "benchmarks/diagnosis/real/bottleneck_ao_no_walls.json $real/fzj_hermes_2009_bottleneck_ao/traj_AO_300.txt ao_300_no_walls")
for r in "${runs[@]}"; do
  read -r scenario recording name <<< "$r"
  start=$(date +%s)
  "$cli" diagnose --scenario "$scenario" --observed "$recording" --out "$work/$name" --threads 2 --quiet "$@" > "$work/$name.log"
  echo "$name ($(( $(date +%s) - start )) s): $(head -1 "$work/$name/summary.txt")"
done
