#!/usr/bin/env bash
# The command-line tool as a user runs it: help, simulate, validate, errors and exit codes, and
# train -> validate -> predict on trajectories the tool itself wrote (no ../shared/data needed).
# Usage: cli_test.sh CROWDMPM SOURCE_DIR WORK_DIR
set -uo pipefail
cli=$1
src=$2
work=$3
rm -rf "$work"
mkdir -p "$work"
failures=0
check() {  # check NAME EXPECTED_STATUS COMMAND... : runs it, keeps stdout+stderr in $out
  local name=$1 want=$2
  shift 2
  out=$("$@" 2>&1)
  local got=$?
  if [ "$got" != "$want" ]; then
    echo "FAIL $name: exit status $got, expected $want"
    echo "$out" | head -20
    failures=$((failures + 1))
  else
    echo "ok   $name"
  fi
}
contains() {  # contains NAME TEXT : $out must contain TEXT
  if ! grep -qF -- "$2" <<< "$out"; then
    echo "FAIL $1: output lacks '$2'"
    echo "$out" | head -20
    failures=$((failures + 1))
  fi
}

check "help" 0 "$cli" help
contains "help lists train" "train --scenario"
for c in simulate validate predict train diagnose analyze report; do
  check "help $c" 0 "$cli" "$c" --help
  contains "help $c" "usage: crowdmpm $c"
done
check "no command" 2 "$cli"
check "unknown command" 2 "$cli" frobnicate
contains "unknown command" "unknown command 'frobnicate'"
check "unknown option" 2 "$cli" simulate "$src/scenarios/drill.json" --out "$work/x" --bogus
contains "unknown option" "unknown option '--bogus'"
check "bad threads" 2 "$cli" simulate "$src/scenarios/drill.json" --out "$work/x" --threads 0
check "bad scenario" 1 "$cli" validate "$src/tests/bad/scenario_negative_density.json"
contains "bad scenario names the path" "density"
check "missing file" 1 "$cli" validate "$work/does_not_exist.json"

# Simulate a bottleneck for 12 s: every output is written.
check "simulate" 0 "$cli" simulate "$src/scenarios/bottleneck.json" --out "$work/sim" --duration 12 --quiet
contains "simulate summary" "12.0 s simulated"
for f in trajectories.txt metrics.json density.npy velocity.npy pressure.npy fields.json pressure_mean.png \
         density_mean.png final.png particles.mp4; do
  [ -s "$work/sim/$f" ] || { echo "FAIL simulate: $f missing or empty"; failures=$((failures + 1)); }
done

# Train on the trajectories just written, then load and use the model.
check "train" 0 "$cli" train --scenario "$src/scenarios/bottleneck.json" --trajectories "$work/sim/trajectories.txt" \
  --window 1 --iterations 3 --eval-every 1 --out "$work/model.json"
contains "train reports" "validation trajectory loss"
check "validate learned model" 0 "$cli" validate "$src/scenarios/bottleneck.json" --model "$work/model.json"
check "validate a model file" 1 "$cli" validate "$work/model.json"
contains "validate a model file" 'format: must be "crowdmpm-scenario", got "crowdmpm-model": a model file'
check "train grid velocity loss" 0 "$cli" train --scenario "$src/scenarios/bottleneck.json" \
  --trajectories "$work/sim/trajectories.txt" --window 1 --iterations 2 --loss grid_velocity --quiet --out "$work/gv.json"
check "train social force" 0 "$cli" train --scenario "$src/scenarios/bottleneck.json" \
  --trajectories "$work/sim/trajectories.txt" --window 1 --iterations 1 --material social_force --quiet --out "$work/sf.json"
# A venue force term marked "learn" is fitted alone (--params none --no-network) and written
# back into a scenario that simulate runs.
sed '$ s/}$/, "forces": [{"type": "drift", "acceleration": [0.2, 0], "learn": ["acceleration"]}]}/' \
  "$src/scenarios/bottleneck.json" > "$work/bottleneck_drift.json"
sed -i "s|\"model\": \"models/|\"model\": \"$src/scenarios/models/|" "$work/bottleneck_drift.json"
check "train force term" 0 "$cli" train --scenario "$work/bottleneck_drift.json" --trajectories "$work/sim/trajectories.txt" \
  --window 1 --iterations 3 --eval-every 1 --params none --no-network --out "$work/drift.json"
contains "train force term reports the term" "forces[0].acceleration.x"
contains "train force term writes the scenario" "drift.bottleneck_drift.json"
check "simulate fitted scenario" 0 "$cli" simulate "$work/drift.bottleneck_drift.json" --out "$work/fitted" --duration 1 --quiet
# A snapshot saved at 2 s and resumed (on another thread count) continues exactly: the frames
# after 2 s are the uninterrupted run's, byte for byte.
check "simulate save snapshot" 0 "$cli" simulate "$src/scenarios/drill.json" --out "$work/full" --duration 4 \
  --save-snapshot "$work/d2.snap" --snapshot-at 2 --quiet
check "simulate resume" 0 "$cli" simulate --resume "$work/d2.snap" --out "$work/resumed" --threads 2 --quiet
if diff <(grep -v '^#' "$work/full/trajectories.txt" | awk '$2 >= 20') <(grep -v '^#' "$work/resumed/trajectories.txt") >/dev/null; then
  echo "ok   resumed frames equal the uninterrupted run's"
else
  echo "FAIL resumed frames differ from the uninterrupted run's"
  failures=$((failures + 1))
fi
check "resume a file that is no snapshot" 1 "$cli" simulate --resume "$src/scenarios/drill.json" --out "$work/bad"
contains "resume a file that is no snapshot" "not a CrowdMPM snapshot"
head -c 5000 "$work/d2.snap" > "$work/cut.snap"
check "resume a truncated snapshot" 1 "$cli" simulate --resume "$work/cut.snap" --out "$work/bad"
contains "resume a truncated snapshot" "truncated snapshot"
# Bounded, confined input (issue 13): a model named outside the scenario's folder, a device, a
# file above the limit.
sed 's|"model": "default"|"model": "/dev/zero"|' "$src/scenarios/bottleneck.json" > "$work/dev_zero.json"
check "model outside the folder" 1 "$cli" validate "$work/dev_zero.json"
contains "model outside the folder" "lies outside the folder"
check "model device" 1 "$cli" validate "$work/dev_zero.json" --allow-outside-paths
contains "model device" "/dev/zero: is not a regular file"
check "input limit" 1 "$cli" validate "$src/scenarios/bottleneck.json" --max-input-mb 0.001
contains "input limit" "above the input limit of"
check "train nothing to learn" 1 "$cli" train --scenario "$src/scenarios/bottleneck.json" --trajectories "$work/sim/trajectories.txt" \
  --params none --no-network --out "$work/none.json"
contains "train nothing to learn" "nothing to learn"
check "predict" 0 "$cli" predict --trajectories "$work/sim/trajectories.txt" --scenario "$src/scenarios/bottleneck.json" \
  --observe 2 --horizon 2 --model "$work/model.json" --model "$work/sf.json" --out "$work/pred"
contains "predict table" "constant velocity"
contains "predict table" "untrained default"
[ -s "$work/pred/prediction.json" ] && [ -s "$work/pred/prediction.png" ] ||
  { echo "FAIL predict: prediction.json or prediction.png missing"; failures=$((failures + 1)); }

# Errors of train and predict.
check "train without --out" 2 "$cli" train --scenario "$src/scenarios/bottleneck.json" --trajectories "$work/sim/trajectories.txt"
check "train trajectories first" 2 "$cli" train --trajectories "$work/sim/trajectories.txt" --out "$work/m.json"
check "train unknown parameter" 1 "$cli" train --scenario "$src/scenarios/bottleneck.json" \
  --trajectories "$work/sim/trajectories.txt" --params E,nonsense --out "$work/m.json"
contains "train unknown parameter" "unknown material parameter \"nonsense\""
check "train window too long" 1 "$cli" train --scenario "$src/scenarios/bottleneck.json" \
  --trajectories "$work/sim/trajectories.txt" --window 100 --out "$work/m.json"
check "train unwritable output" 1 "$cli" train --scenario "$src/scenarios/bottleneck.json" \
  --trajectories "$work/sim/trajectories.txt" --out "$work/no/such/dir/m.json"
contains "train unwritable output" "does not exist"
printf '# framerate: 10\n1 0 0.5 nan\n' > "$work/nan.txt"
check "train non-finite trajectory" 1 "$cli" train --scenario "$src/scenarios/bottleneck.json" --trajectories "$work/nan.txt" --out "$work/m.json"
check "predict horizon too long" 2 "$cli" predict --scenario "$src/scenarios/bottleneck.json" \
  --trajectories "$work/sim/trajectories.txt" --observe 10 --horizon 10
check "predict bad model" 1 "$cli" predict --scenario "$src/scenarios/bottleneck.json" \
  --trajectories "$work/sim/trajectories.txt" --model "$src/tests/bad/model_negative_E.json"

# Video: film a crowd, extract its flow, learn from it and predict it (a few iterations: the
# commands and their files, not the numbers; tests/test_vision.cpp and benchmarks/video/ check those).
check "render-video" 0 "$cli" render-video "$src/scenarios/video_exit.json" --out "$work/video" --duration 5 --settle 1 --size 320x240
contains "render-video" "51 frames of 320 x 240"
check "flow" 0 "$cli" flow "$work/video/video.avi" --out "$work/flow" --calibration "$work/video/calibration.json" \
  --scenario "$src/scenarios/video_exit.json"
for f in fields.npy fields.npy.json field_mean.png field_middle.png frame_flow.png flow.json; do
  [ -s "$work/flow/$f" ] || { echo "FAIL flow: $f missing"; failures=$((failures + 1)); }
done
check "flow needs calibration or scale" 1 "$cli" flow "$work/video/video.avi" --out "$work/flow2"
contains "flow needs calibration or scale" "needs a calibration file"
check "flow junk video" 1 "$cli" flow "$src/tests/bad/model_negative_E.json" --out "$work/flow2" --scale 0.05
contains "flow junk video" "OpenCV cannot decode it as a video"
check "flow roi outside" 1 "$cli" flow "$work/video/video.avi" --out "$work/flow2" --scale 0.05 --roi 0,0,400,0,0,100
contains "flow roi outside" "lies outside the 320 x 240 frame"
printf '{"format": "crowdmpm-calibration", "version": 1, "image_points": [[0, 0], [1, 0], [2, 0]], "world_points": [[0, 0], [1, 0], [2, 0]]}' > "$work/cal3.json"
check "flow three-point calibration" 1 "$cli" flow "$work/video/video.avi" --out "$work/flow2" --calibration "$work/cal3.json"
contains "flow three-point calibration" "at least 4 image <-> world point pairs"
video=(--video "$work/video/video.avi" --calibration "$work/video/calibration.json" --scenario "$src/scenarios/video_exit.json" --density 4)
check "train --video" 0 "$cli" train "${video[@]}" --clip-length 0.6 --stride 0.2 --iterations 2 --batch 1 --out "$work/video_model.json" --quiet
contains "train --video" "validation grid velocity loss"
check "predict --video" 0 "$cli" predict "${video[@]}" --model "$work/video_model.json" --out "$work/video_pred"
contains "predict --video" "constant velocity"
contains "predict --video" "learned crowd"
[ -s "$work/video_pred/prediction.png" ] || { echo "FAIL predict --video: prediction.png missing"; failures=$((failures + 1)); }
check "train --video too short" 1 "$cli" train "${video[@]}" --clip-length 30 --out "$work/video_model.json" --quiet
contains "train --video too short" "windows of 30 s"

# diagnose: on the bottleneck run the tool wrote above (a scenario and its own recording), then
# the errors a user meets.
check "diagnose" 0 "$cli" diagnose --scenario "$src/scenarios/bottleneck.json" --observed "$work/sim/trajectories.txt" \
  --out "$work/diag" --iterations 3 --candidates drift,slow_zone --options '{"null_replicates": 2, "max_terms": 1, "window": 2}' --quiet
for f in report.json summary.txt residual_before.png residual_after.png scenario.json model.json; do
  [ -s "$work/diag/$f" ] || { echo "FAIL diagnose: $f missing"; failures=$((failures + 1)); }
done
contains "diagnose" "wrote $work/diag/report.json"
check "diagnose without --observed" 2 "$cli" diagnose --scenario "$src/scenarios/bottleneck.json" --out "$work/diag2"
contains "diagnose without --observed" "diagnose needs --scenario and a recording: --observed TRAJECTORIES or --video V"
check "diagnose unknown candidate" 1 "$cli" diagnose --scenario "$src/scenarios/bottleneck.json" --observed "$work/sim/trajectories.txt" \
  --out "$work/diag2" --candidates ghost
contains "diagnose unknown candidate" 'options.candidates[0]: unknown candidate "ghost"'
# An output that cannot be written is refused before the work (a file stands where the folder goes).
check "diagnose output folder in the way" 1 "$cli" diagnose --scenario "$src/scenarios/bottleneck.json" \
  --observed "$work/sim/trajectories.txt" --out "$work/sim/trajectories.txt"
contains "diagnose output folder in the way" "cannot use as the output folder: a file of that name is in the way"
check "predict output under a file" 1 "$cli" predict --trajectories "$work/sim/trajectories.txt" --scenario "$src/scenarios/bottleneck.json" \
  --observe 2 --horizon 2 --out "$work/sim/trajectories.txt/pred"
contains "predict output under a file" "cannot create the output folder"
check "train model file is a folder" 1 "$cli" train --scenario "$src/scenarios/bottleneck.json" --trajectories "$work/sim/trajectories.txt" \
  --out "$work"
contains "train model file is a folder" "cannot write the model file: it is a folder"
check "diagnose --video without calibration" 2 "$cli" diagnose --scenario "$src/scenarios/bottleneck.json" --video "$work/sim/particles.mp4" \
  --out "$work/diag2"
contains "diagnose --video without calibration" "diagnose --video needs --calibration CAL or --scale S"
# The rendered 5 s video goes through detection and tracking, then is too short to split.
check "diagnose --video too short" 1 "$cli" diagnose --scenario "$src/scenarios/video_exit.json" --video "$work/video/video.avi" \
  --calibration "$work/video/calibration.json" --out "$work/diag2" --threads 1
contains "diagnose --video too short" "tracks, 4.9 s at 10 fps"
contains "diagnose --video too short" "video.avi: too short to diagnose"
check "diagnose bad options" 2 "$cli" diagnose --scenario "$src/scenarios/bottleneck.json" --observed "$work/sim/trajectories.txt" \
  --out "$work/diag2" --options '{"cell": '
contains "diagnose bad options" "--options must be a JSON object"
# Whole-number options refuse a fraction instead of truncating it.
check "predict ensemble not whole" 2 "$cli" predict --video "$work/none.mov" --ensemble 2.5
contains "predict ensemble not whole" "--ensemble must be 1..64 rollouts (a whole number), got '2.5'"
check "predict frames not whole" 2 "$cli" predict --video "$work/none.mov" --frames 10.5
contains "predict frames not whole" "--frames must be a number of frames >= 2 (a whole number), got '10.5'"
check "predict horizons in range" 2 "$cli" predict --video "$work/none.mov" --horizons 0
contains "predict horizons in range" "--horizons must be 1..100, got '0'"
check "diagnose option out of range" 1 "$cli" diagnose --scenario "$src/scenarios/bottleneck.json" --observed "$work/sim/trajectories.txt" \
  --out "$work/diag2" --options '{"cell": -1}'
contains "diagnose option out of range" "options.cell"

# --threads defaults to the machine's cores; the output does not depend on it.
check "simulate default threads" 0 "$cli" simulate "$src/scenarios/drill.json" --out "$work/thr_default" --duration 3 --quiet
check "simulate 1 thread" 0 "$cli" simulate "$src/scenarios/drill.json" --out "$work/thr_one" --duration 3 --quiet --threads 1
cmp -s "$work/thr_default/trajectories.txt" "$work/thr_one/trajectories.txt" ||
  { echo "FAIL simulate: trajectories differ between the default thread count and --threads 1"; failures=$((failures + 1)); }
for f in peak.png final.png; do
  [ -s "$work/thr_default/$f" ] || { echo "FAIL simulate: $f missing"; failures=$((failures + 1)); }
done

# report: errors (the page itself is tested in a browser: tests/report/).
check "report no folder" 1 "$cli" report "$work/nowhere"
contains "report no folder" "not a folder"
mkdir -p "$work/empty_run"
check "report no metrics" 1 "$cli" report "$work/empty_run"
contains "report no metrics" "no metrics.json (run crowdmpm simulate"

# analyze: the simulated run's JuPedSim SQLite file with the scenario's measurement areas, the
# reference AO_300 recording with its spec (when ../shared/data is there), and bad input.
[ -s "$work/sim/trajectories.sqlite" ] || { echo "FAIL simulate: trajectories.sqlite missing"; failures=$((failures + 1)); }
check "analyze sqlite" 0 "$cli" analyze "$work/sim/trajectories.sqlite" --scenario "$src/scenarios/bottleneck.json" --out "$work/an"
for f in summary.json crowd_pressure.csv crowd_pressure.png; do
  [ -s "$work/an/$f" ] || { echo "FAIL analyze: $f missing"; failures=$((failures + 1)); }
done
contains "analyze sqlite" "wrote $work/an/summary.json"
ao="$src/../shared/data/reference/jpsreport_bottleneck_AO_300/traj.txt"
if [ -f "$ao" ]; then
  check "analyze AO_300" 0 "$cli" analyze "$ao" --spec "$src/tests/data/ao300_measurement.json" --out "$work/ao"
  contains "analyze AO_300" "line line4: 348 crossings"
  for f in area_bottleneck.csv fd_bottleneck.csv nt_line2.csv nt_line4.csv; do
    [ -s "$work/ao/$f" ] || { echo "FAIL analyze AO_300: $f missing"; failures=$((failures + 1)); }
  done
  # The JPSreport project itself (ini.xml, geo.xml) gives the same measurements.
  check "analyze JPSreport project" 0 "$cli" analyze "$(dirname "$ao")" --out "$work/ao_ini"
  cmp -s "$work/ao_ini/area_area1.csv" "$work/ao/area_bottleneck.csv" ||
    { echo "FAIL analyze JPSreport project: area_area1.csv differs from the spec's area_bottleneck.csv"; failures=$((failures + 1)); }
else
  echo "SKIP analyze AO_300: ../shared/data is absent"
fi
check "analyze without spec" 2 "$cli" analyze "$work/sim/trajectories.txt" --out "$work/an2"
contains "analyze without spec" "analyze needs --spec FILE or --scenario S"
printf '{"areas": [{"id": "a b", "rect": [0, 0, 1, 1]}]}' > "$work/bad_spec.json"
check "analyze bad area id" 1 "$cli" analyze "$work/sim/trajectories.txt" --spec "$work/bad_spec.json" --out "$work/an2"
contains "analyze bad area id" 'areas[0]: id "a b" must be'
printf '{"areas": [{"id": "bow", "polygon": [[0, 0], [1, 1], [1, 0], [0, 1]]}]}' > "$work/bad_spec.json"
check "analyze self-intersecting area" 1 "$cli" analyze "$work/sim/trajectories.txt" --spec "$work/bad_spec.json" --out "$work/an2"
contains "analyze self-intersecting area" "areas[0]"

if [ "$failures" -ne 0 ]; then
  echo "$failures CLI check(s) failed"
  exit 1
fi
echo "all CLI checks passed"
