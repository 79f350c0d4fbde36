#!/usr/bin/env bash
# Learning from real recordings (../shared/data/real), measured on runs never seen in training.
# Trains three models on the same windows of the same training runs -- the crowd material, the
# fluid material and the social force model -- then predicts 4 s ahead on held-out runs with
# constant velocity, the untrained default crowd model and the three fitted models.
# Writes benchmarks/results/learning_real.md and the models to $BUILD_DIR/learn/.
# Usage: benchmarks/learn_real.sh [BUILD_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
data=../shared/data/real
[ -d "$data" ] || { echo "skipped: $data is absent"; exit 0; }
cli="$build/cli/crowdmpm"
models="$build/learn"
mkdir -p "$models"
corr=$data/fzj_hermes_2009_corridor_uo
bott=$data/fzj_crowdqueue_2018_bottleneck
# Model version 2's protocol (issue 10): windows long enough to see queues form (16 s, every 4 s),
# each person's free speed as their desired speed (the 90th percentile of their walking speed along
# their track so far, not the already slowed speed at the window's start; predictions use it too),
# and dense runs in the
# training set (uo-180-180-180, uo-300-300-160) beside the sparse ones.
train_set=(--scenario scenarios/corridor.json --trajectories "$corr/uo-050-180-180.txt" "$corr/uo-100-180-180.txt" "$corr/uo-180-180-180.txt"
           --scenario scenarios/corridor_300.json --trajectories "$corr/uo-300-300-160.txt"
           --scenario scenarios/bottleneck.json --trajectories "$bott/030_c_56_h0.txt")
protocol=(--desired-speed free --window 16 --stride 4 --iterations 200)
declare -A seconds
for kind in crowd fluid social_force; do
  start=$(date +%s)
  "$cli" train "${train_set[@]}" --material "$kind" "${protocol[@]}" --threads 2 --quiet \
      --out "$models/$kind.json" | tee "$models/$kind.log"
  seconds[$kind]=$(( $(date +%s) - start ))
done
out=benchmarks/results/learning_real.md
{
  echo "# Learning from real recordings: held-out prediction"
  echo
  echo "Produced by \`benchmarks/learn_real.sh\` at commit $(git rev-parse --short HEAD) on a 2-core Debian 12 machine."
  echo
  echo "Training (each model from the built-in defaults of its kind, the same windows: 16 s every 4 s, each"
  echo "person's free speed (90th percentile of their walking speed along their track so far) as desired speed, the"
  echo "last quarter of every run held out for validation and early stopping, Adam, 200 iterations at most):"
  echo "Hermes corridor runs uo-050-180-180, uo-100-180-180, uo-180-180-180 (scenarios/corridor.json) and"
  echo "uo-300-300-160 (scenarios/corridor_300.json), and the CrowdQueue run 030_c_56_h0 (scenarios/bottleneck.json)."
  echo
  for kind in crowd fluid social_force; do
    echo "- $kind (${seconds[$kind]} s): $(grep '^validation' "$models/$kind.log")"
  done
  echo
  echo "Evaluation on runs never seen in training (AO_300 and the 2.4 m corridor are also venues never"
  echo "seen; scenarios/corridor.json has no exit constriction, so uo-180-180-070's 0.7 m exit is not modelled): the recorded"
  echo "state every 4 s after the first 4 s, rolled forward 4 s; desired speed = each person's free speed"
  echo "so far (as in training) times the model's v0_scale. ADE/FDE in metres; gridV = RMS error of"
  echo "the grid velocity field (m/s, 0.5 m cells) at 4 s."
  echo
  echo "| recording | scenario | method | windows | ADE@1s | FDE@1s | ADE@4s | FDE@4s | gridV@4s |"
  echo "|---|---|---|---:|---:|---:|---:|---:|---:|"
} > "$out"
run() {
  local traj=$1 scen=$2 dir
  dir="$build/learn/$(basename "$traj" .txt)"
  "$cli" predict --scenario "scenarios/$scen.json" --trajectories "$traj" --observe 4 --horizon 4 --threads 2 --desired-speed free \
      --model "$models/crowd.json" --model "$models/fluid.json" --model "$models/social_force.json" --out "$dir" > /dev/null
  /usr/bin/python3 benchmarks/prediction_rows.py "$dir/prediction.json" "$(basename "$traj")" "$scen" >> "$out"
}
run "$corr/uo-145-180-180.txt" corridor
run "$corr/uo-180-180-070.txt" corridor
run "$corr/uo-240-240-240.txt" corridor_240
run "$bott/040_c_56_h-.txt" bottleneck
run "$data/fzj_hermes_2009_bottleneck_ao/traj_AO_300.txt" bottleneck_ao
cat "$out"
