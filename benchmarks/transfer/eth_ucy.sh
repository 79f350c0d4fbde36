#!/usr/bin/env bash
# Transfer to open spaces at low density: the ETH/UCY recordings students001 and zara01
# (../shared/data/real/eth_ucy, rows every 0.4 s) predicted 4 s ahead from the recorded state
# every 4 s after the first 3.2 s, in a venue without walls or goals (open_square.json: each
# person walks on in the direction they were moving), by constant velocity, the untrained
# default crowd model and the shipped learned model, with each person's desired speed their
# speed over the last second (observed) or their free speed so far (free).
# Writes benchmarks/results/transfer_eth_ucy.md.
# Usage: benchmarks/transfer/eth_ucy.sh [BUILD_DIR]
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${1:-build}
data=../shared/data/real/eth_ucy
[ -d "$data" ] || { echo "skipped: $data is absent"; exit 0; }
cli="$build/cli/crowdmpm"
work="$build/transfer"
mkdir -p "$work"
out=benchmarks/results/transfer_eth_ucy.md
{
  echo "# Transfer: open spaces at low density (ETH/UCY)"
  echo
  echo "Produced by \`benchmarks/transfer/eth_ucy.sh\` at commit $(git rev-parse --short HEAD) on a 2-core Debian 12 machine."
  echo
  echo "UCY students001 and zara01 (outdoor, at most 3-4.5 persons/m² locally, rows every 0.4 s: positions between"
  echo "them interpolated linearly), the recorded state every 4 s after the first 3.2 s rolled 4 s forward in"
  echo "\`benchmarks/transfer/open_square.json\` (no walls, no goals: behaviour \`heading\`). Not the published"
  echo "ETH/UCY protocol (every 20-row sequence, 4.8 s ahead, leave-one-scene-out), so not comparable with its"
  echo "tables. ADE/FDE in metres; gridV: RMS error of the grid velocity field (m/s, 0.5 m cells) at 4 s."
  echo
  echo "| recording | desired speed | method | windows | ADE@1s | FDE@1s | ADE@4s | FDE@4s | gridV@4s |"
  echo "|---|---|---|---:|---:|---:|---:|---:|---:|"
} > "$out"
for run in students001 crowds_zara01; do
  for speed in observed free; do
    dir="$work/${run}_$speed"
    "$cli" predict --scenario benchmarks/transfer/open_square.json --trajectories "$data/$run.txt" --observe 3.2 --horizon 4 \
        --threads 2 --desired-speed "$speed" --model scenarios/models/learned_juelich.json --out "$dir" > "$dir.log"
    /usr/bin/python3 benchmarks/prediction_rows.py "$dir/prediction.json" "$run" "$speed" >> "$out"
  done
done
cat "$out"
