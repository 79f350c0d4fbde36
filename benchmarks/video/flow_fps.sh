#!/usr/bin/env bash
# Frames per second of `crowdmpm flow` (video decoding, optical flow, rectification and splatting
# onto the grid, pictures and NumPy output) on Debian's 768x576 pedestrian video vtest.avi
# (package opencv-doc), for each flow method. Usage: benchmarks/video/flow_fps.sh [BUILD_DIR]
set -euo pipefail
build=${1:-build}
video=/usr/share/doc/opencv-doc/examples/data/vtest.avi
if [ ! -f "$video" ]; then echo "skipped: $video is absent (install opencv-doc)"; exit 0; fi
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
echo "| method | frames | frames/s | moving nodes per frame | mean speed (m/s) |"
echo "|---|---|---|---|---|"
for m in "dis --dis-preset 0:DIS ultrafast" "dis --dis-preset 1:DIS fast" "dis --dis-preset 2:DIS medium (default)" "farneback:Farneback"; do
  args=${m%%:*}; label=${m#*:}
  "$build/cli/crowdmpm" flow "$video" --out "$out/run" --scale 0.02 --method $args --quiet >/dev/null
  python3 - "$out/run/flow.json" "$label" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
print(f"| {sys.argv[2]} | {d['fields'] + 1} | {d['frames_per_second_processed']:.1f} | {d['moving_nodes_per_frame']:.0f} | {d['mean_speed']:.3f} |")
PY
done
