#!/usr/bin/env bash
# Baseline prediction errors on the real Julich recordings (../shared/data/real): constant
# velocity and the default (untrained) crowd model, 4 s horizon, windows every 4 s after 4 s.
# Writes benchmarks/results/prediction_baselines.md. Usage: benchmarks/predict_real.sh [BUILD_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
data=../shared/data/real
[ -d "$data" ] || { echo "skipped: $data is absent"; exit 0; }
out=benchmarks/results/prediction_baselines.md
{
  echo "# Prediction baselines on real recordings"
  echo
  echo "Produced by \`benchmarks/predict_real.sh\` at commit $(git rev-parse --short HEAD) (observe 4 s, horizon 4 s, stride 4 s, 2 threads)."
  echo "ADE/FDE in metres at 1 s and 4 s; the crowd model is the built-in default, not learned."
  echo
  echo "| recording | scenario | method | windows | ADE@1s | FDE@1s | ADE@4s | FDE@4s |"
  echo "|---|---|---|---:|---:|---:|---:|---:|"
} > "$out"
run() {
  local traj=$1 scen=$2
  "$build"/cli/crowdmpm predict --scenario "scenarios/$scen.json" --trajectories "$data/$traj" \
      --observe 4 --horizon 4 --threads 2 --out "$build/predict/$(basename "$traj" .txt)" > /dev/null
  /usr/bin/python3 - "$build/predict/$(basename "$traj" .txt)/prediction.json" "$traj" "$scen" >> "$out" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
for m in j["methods"]:
    h = {e["horizon_s"]: e for e in m["horizons"]}
    f = lambda v: "%.3f" % v if v is not None else "-"
    print("| %s | %s | %s | %d | %s | %s | %s | %s |" % (sys.argv[2].split("/")[-1], sys.argv[3], m["method"], m["windows"],
          f(h[1]["ade_m"]), f(h[1]["fde_m"]), f(h[4]["ade_m"]), f(h[4]["fde_m"])))
PY
}
for r in uo-050-180-180 uo-100-180-180 uo-145-180-180 uo-180-180-180; do run fzj_hermes_2009_corridor_uo/$r.txt corridor; done
run fzj_crowdqueue_2018_bottleneck/030_c_56_h0.txt bottleneck
run fzj_crowdqueue_2018_bottleneck/040_c_56_h-.txt bottleneck
run fzj_hermes_2009_bottleneck_ao/traj_AO_300.txt bottleneck_ao
cat "$out"
