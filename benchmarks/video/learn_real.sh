#!/usr/bin/env bash
# Learning from real dense-crowd video (issue 12, acceptance 3): for every clip given (default:
# every .mov in ../shared/data/real/videos/ucf_crowd_segmentation), a model is trained from the
# untrained default on the optical flow of the first 60% of the clip and predicts the rest from
# its first held-out field. Err_vel (mean squared grid velocity error, m2/s2, on observed nodes
# away from the view's border) at seven horizons spread over the held-out part, for persistence
# of the last observed field, constant velocity of the particles, the untrained default and the
# learned model. The same settings for every clip (none is tuned to a file): the clips have no
# calibration, so a top-view scale of 0.05 m per pixel (a 480-pixel frame spans 24 m), particles
# sampled at 2 persons/m2, clips of 1.2 s every 0.2 s (the shortest clip, 144 frames, leaves
# 3.4 s for training), 120 Adam iterations at most, eight clips a step (fewer where the training part has fewer).
# Usage: benchmarks/video/learn_real.sh [BUILD_DIR] [OUT_DIR] [VIDEO...]
set -euo pipefail
build=${1:-build}
out=${2:-$(mktemp -d)}
shift $(( $# < 2 ? $# : 2 ))
repo=$(cd "$(dirname "$0")/../.." && pwd)
videos=("$@")
if [ ${#videos[@]} -eq 0 ]; then
  dir="$repo/../shared/data/real/videos/ucf_crowd_segmentation"
  if [ ! -d "$dir" ]; then echo "skipped: $dir is absent (no real video to learn from)"; exit 0; fi
  videos=("$dir"/*.mov)
fi
cli="$build/cli/crowdmpm"
for v in "${videos[@]}"; do
  name=$(basename "${v%.*}")
  mkdir -p "$out/$name"
  common=(--video "$v" --scale 0.05 --density 2 --threads 2 --quiet)
  "$cli" train "${common[@]}" --clip-length 1.2 --stride 0.2 --iterations 120 --batch 8 --out "$out/$name/learned.json" | tail -1
  "$cli" predict "${common[@]}" --model "$out/$name/learned.json" --out "$out/$name" > /dev/null
  /usr/bin/python3 - "$out/$name/prediction.json" "$name" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
hs = d["methods"][0]["horizons"]
end = d.get("end", d["fields"])
cut = f" (field {end} is a camera glitch: a jump or a cut)" if end < d["fields"] else ""
print(f"\n{sys.argv[2]}: {d['fields'] + 1} frames at {d['fps']:g} fps; held out: fields {d['start']} to {end - 1}{cut}")
print("\n| method | " + " | ".join(f"{h['seconds']:.2f} s" for h in hs) + " |")
print("|---|" + "---|" * len(hs))
best = [min(m["horizons"][k]["err_vel"] for m in d["methods"]) for k in range(len(hs))]
for m in d["methods"]:
    cells = [(f"**{h['err_vel']:.3f}**" if h["err_vel"] == best[k] else f"{h['err_vel']:.3f}") for k, h in enumerate(m["horizons"])]
    print(f"| {m['method']} | " + " | ".join(cells) + " |")
PY
done
echo "outputs in $out"
