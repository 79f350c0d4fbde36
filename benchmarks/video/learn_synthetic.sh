#!/usr/bin/env bash
# Learning the crowd material from a rendered video (issue 12, acceptance 2). The crowd of
# scenarios/video_exit.json is simulated with a material the learner does not start from (the
# shipped learned_juelich model), filmed through a tilted camera (render-video: textured heads,
# noise, blur, Motion JPEG), and turned into ground velocity fields by optical flow. A model
# trained from the untrained default on the flow of the first 60% of the video predicts the
# rest from its first field. Err_vel (m2/s2) at seven horizons for persistence, constant
# velocity, the untrained default, the trained model and the true material.
# Usage: benchmarks/video/learn_synthetic.sh [BUILD_DIR] [OUT_DIR]
set -euo pipefail
build=${1:-build}
out=${2:-$(mktemp -d)}
repo=$(cd "$(dirname "$0")/../.." && pwd)
cli="$build/cli/crowdmpm"
scene="$repo/scenarios/video_exit.json"
truth="$repo/scenarios/models/learned_juelich.json"
mkdir -p "$out"
"$cli" render-video "$scene" --out "$out/render" --duration 20 --settle 2 --model "$truth" --threads 2
common=(--video "$out/render/video.avi" --calibration "$out/render/calibration.json" --scenario "$scene" --density 4 --threads 2 --quiet)
"$cli" train "${common[@]}" --out "$out/learned.json" --iterations 40 --batch 2 --no-network | tail -1
"$cli" predict "${common[@]}" --model "$out/learned.json" --model "$truth" --out "$out/prediction"
python3 - "$out/prediction/prediction.json" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
hs = d["methods"][0]["horizons"]
print("\n| method | " + " | ".join(f"{h['seconds']:.1f} s" for h in hs) + " | mean |")
print("|---|" + "---|" * (len(hs) + 1))
for m in d["methods"]:
    e = [h["err_vel"] for h in m["horizons"]]
    print(f"| {m['method']} | " + " | ".join(f"{x:.4f}" for x in e) + f" | {sum(e) / len(e):.4f} |")
PY
echo "outputs in $out"
