#!/usr/bin/env bash
# Validation against real crowds: fundamental diagram (ring corridor) and bottleneck flow J(b)
# for each model given (default: the built-in default and the shipped learned model), against
# ../shared/data/reference. Writes benchmarks/validation/results.md and its pictures (or into the
# folder VALIDATION_OUT names).
# Usage: [VALIDATION_OUT=DIR] benchmarks/validation/run.sh [BUILD_DIR] [MODEL ...]
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${1:-build}
shift || true
models=("$@")
[ ${#models[@]} -gt 0 ] || models=(default scenarios/models/learned_juelich.json scenarios/models/v1.json)
ref=../shared/data/reference
[ -d "$ref" ] || { echo "skipped: $ref is absent"; exit 0; }
v="$build/benchmarks/validate"
work="$build/validation"
mkdir -p "$work"
here=${VALIDATION_OUT:-benchmarks/validation}
mkdir -p "$here"
out=$here/results.md
real=../shared/data/real
# A crowd squeezing through a door is chaotic: a change of 1e-7 in one parameter moves a
# CrowdQueue replay's flow by 10%. Every bottleneck flow is the mean of 5 runs (the waiting crowd
# placed with seeds 1-5), every replay the mean of 10 (the exact replay and 9 with entry points
# jittered by 2 cm); the tables give the spread.
bottleneck_repeats=5
replay_repeats=10
# Whole-run replays: the venue, the recording and the passage line through its bottleneck.
replays=("scenarios/bottleneck_ao.json $real/fzj_hermes_2009_bottleneck_ao/traj_AO_300.txt -0.6,0,2.4,0"
         "scenarios/bottleneck.json $real/fzj_crowdqueue_2018_bottleneck/030_c_56_h0.txt -0.25,-0.6,0.25,-0.6"
         "scenarios/bottleneck.json $real/fzj_crowdqueue_2018_bottleneck/040_c_56_h-.txt -0.25,-0.6,0.25,-0.6")
# The Juelich corridor fundamental diagram from the Hermes uo runs: classic density and speed in
# a 4 m box spanning the corridor (x in [0, width], y in [-2, 2]; width from the run name
# uo-<entrance>-<corridor>-<exit> in cm), one sample a second.
echo "run,t,rho,speed" > "$work/uo_samples.csv"
for f in "$real"/fzj_hermes_2009_corridor_uo/uo-*.txt; do
  run=$(basename "$f" .txt)
  width=$(echo "$run" | cut -d- -f3 | sed 's/^0*//')
  "$v" measure --trajectories "$f" --box "0,-2,$(awk "BEGIN{print $width/100}"),2" | tail -n +2 | sed "s/^/$run,/" >> "$work/uo_samples.csv"
done
# Bottleneck widths of issue 10, each with the density in front of it that the reference reports
# (the Hermes wide bottlenecks, with a crowd as large as theirs: AO_300 has 348 people), else a
# waiting crowd at 3.5 /m^2 filling a 6 m deep room.
widths=(0.4 0.8 1.0 1.2 1.8 2.4 3.0 5.0)
fronts=()
people=()
for b in "${widths[@]}"; do
  d=$(awk -F, -v b="$b" '!/^#/ && $1 + 0 == b + 0 && $3 != "" {d = $3} END {print d}' "$ref/bottleneck_flow.csv")
  fronts+=("${d:-3.5}")
  people+=("$([ -n "$d" ] && echo 350 || echo 0)")
done
for m in "${models[@]}"; do
  name=$(basename "$m" .json)
  "$v" fd --model "$m" --threads 2 > "$work/fd_$name.csv"
  "$v" bottleneck --model "$m" --threads 2 --widths "$(IFS=,; echo "${widths[*]}")" --density "$(IFS=,; echo "${fronts[*]}")" \
      --people "$(IFS=,; echo "${people[*]}")" --repeats "$bottleneck_repeats" \
      > "$work/bottleneck_$name.csv"
  echo "run,people,placed,passages_recorded,passages_simulated,J_recorded,J_simulated,ratio,duration,wall_seconds,J_sd,ratio_min,ratio_max,repeats" \
      > "$work/replay_$name.csv"
  for r in "${replays[@]}"; do
    read -r scen traj line <<< "$r"
    run=$(basename "$traj" .txt)
    "$v" replay --model "$m" --scenario "$scen" --trajectories "$traj" --line "$line" --threads 2 --repeats "$replay_repeats" \
        --curve "$work/nt_${name}_$run.csv" | tail -1 | sed "s/^/$run,/" >> "$work/replay_$name.csv"
  done
done
/usr/bin/python3 - "$ref" "$work" "$out" "$(git rev-parse --short HEAD)" "$bottleneck_repeats" "$replay_repeats" "${models[@]}" <<'PY'
import csv, math, os, sys
ref, work, out, commit, bottleneck_repeats, replay_repeats, models = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4], sys.argv[5], sys.argv[6], sys.argv[7:]
def rows(path):
    with open(path) as f:
        return list(csv.DictReader(l for l in f if not l.startswith("#")))
weid = lambda rho: 1.34 * (1 - math.exp(-1.913 * (1 / rho - 1 / 5.4)))
jue_ref = {float(r["rho"]): float(r["juelich_corridor_v"]) for r in rows(os.path.join(ref, "fundamental_diagram.csv")) if r["juelich_corridor_v"]}
# The Juelich corridor speeds computed here from the uo runs: medians per bin rho +- 0.25.
samples = [(float(r["rho"]), float(r["speed"])) for r in rows(os.path.join(work, "uo_samples.csv"))]
jue, jue_n = {}, {}
for c in [0.5 * k for k in range(1, 13)]:
    vs = sorted(v for rho, v in samples if abs(rho - c) <= 0.25)
    if len(vs) >= 10:
        jue[c] = vs[len(vs) // 2] if len(vs) % 2 else 0.5 * (vs[len(vs) // 2 - 1] + vs[len(vs) // 2])
        jue_n[c] = len(vs)
def band(rho):
    lo = hi = weid(rho)
    near = [v for k, v in jue.items() if abs(k - rho) <= 0.25]
    for v in near:
        lo, hi = min(lo, v), max(hi, v)
    return lo - max(0.25 * lo, 0.15), hi + max(0.25 * hi, 0.15)
names = [os.path.basename(m).replace(".json", "") for m in models]
def results(kind):  # (model name, row) of every model's <kind>_<name>.csv
    for name in names:
        for r in rows(os.path.join(work, "%s_%s.csv" % (kind, name))):
            yield name, r
refJ = {}
for r in rows(os.path.join(ref, "bottleneck_flow.csv")):
    refJ.setdefault(float(r["b_m"]), []).append(float(r["J_per_s"]))
L = ["# Validation against real crowds", "",
     "Produced by `benchmarks/validation/run.sh` at commit %s on a 2-core Debian 12 machine." % commit, "",
     "## Juelich corridor fundamental diagram, computed from the Hermes uo runs", "",
     "Classic density and speed in a 4 m box spanning the corridor, one sample a second, medians per",
     "bin rho +- 0.25 (bins with at least 10 samples), beside the values in the reference file.", "",
     "| rho | samples | median speed m/s (computed) | reference file |", "|---:|---:|---:|---:|"]
for c in sorted(jue):
    L.append("| %.1f | %d | %.2f | %s |" % (c, jue_n[c], jue[c], "%.2f" % jue_ref[c] if c in jue_ref else "-"))
L += ["", "## Fundamental diagram (ring corridor 2.5 m wide, inner radius 6 m, desired speed 1.34 m/s)", "",
     "Mean speed along the corridor over 30 s after 20 s of warm-up; rho = people / corridor area.",
     "Acceptance band (issue 10): between Weidmann and the Juelich corridor value computed above, widened by 25% or",
     "0.15 m/s; below 0.3 m/s from 5 /m^2. Peak: most people in any 1 m x 1 m box.", "",
     "| model | rho target | rho | speed m/s | Weidmann | Juelich | band | in band | peak /m^2 |",
     "|---|---:|---:|---:|---:|---:|---|---|---:|"]
for name, r in results("fd"):
    rho, v = float(r["rho"]), float(r["speed_mean"])
    if rho >= 4.75:
        ok, b = v < 0.3, "< 0.30"
    else:
        lo, hi = band(rho)
        ok, b = lo <= v <= hi, "%.2f-%.2f" % (lo, hi)
    j = [val for k, val in jue.items() if abs(k - rho) <= 0.25]
    L.append("| %s | %s | %.2f | %.3f | %.2f | %s | %s | %s | %s |" % (name, r["rho_target"], rho, v, weid(rho),
             "%.2f" % j[0] if j else "-", b, "yes" if ok else "**no**", r["peak_per_m2"]))
L += ["", "## Bottleneck flow J(b) from a waiting crowd", "",
      "Room 6 m deep, opening of width b in a 0.4 m wall (two rectangular obstacles, so the opening is b",
      "exactly); the crowd waits at the density in front that the reference reports for that width",
      "(Hermes wide bottlenecks; then as many people as the Hermes runs had, 350, the room deepened to",
      "hold them: a 6 m deep crowd drains before a 5 m wide door's flow settles), else at 3.5 /m^2.",
      "J over the passages from the 20th to the 80th percentile, the mean of %s runs with the crowd placed" % bottleneck_repeats,
      "with seeds 1, 2, ... (J sd and range: their spread). Acceptance: the mean within 20% of the measured",
      "value (mean where several).", "",
      "| model | b m | density /m^2 | agents | J /s | J sd | J range | measured | ratio | within 20% | peak /m^2 |",
      "|---|---:|---:|---:|---:|---:|---|---:|---:|---|---:|"]
for name, r in results("bottleneck"):
    b, J = float(r["b"]), float(r["J"])
    meas = refJ.get(b)
    mv = sum(meas) / len(meas) if meas else None
    L.append("| %s | %.1f | %s | %s | %.2f | %.2f | %.2f-%.2f | %s | %s | %s | %s |" % (name, b, r["density"], r["agents"], J,
             float(r["J_sd"]), float(r["J_min"]), float(r["J_max"]), "%.2f" % mv if mv else "-",
             "%.2f" % (J / mv) if mv else "-", ("yes" if abs(J / mv - 1) <= 0.2 else "**no**") if mv else "-", r["peak_per_m2"]))
L += ["", "## Whole-run replays", "",
      "Every recorded person enters where and when the recording first shows them (velocity from their",
      "first 0.5 s; desired speed and goal of the scenario's first group: 1.34 m/s, Weidmann's mean free",
      "speed, since nobody walks freely before these bottlenecks); passages through the line across the",
      "bottleneck; flow over the middle 60%% of passages. Each replay is run %s times: exactly, and with" % replay_repeats,
      "every entry point moved by a Gaussian 2 cm (a tracker's error) with seeds 2, 3, ...; J simulated and",
      "ratio are the means, the range the least and largest ratio. Acceptance: the mean within 15% of the",
      "recording. N(t) curves (the simulated one the mean over the runs): `$BUILD/validation/nt_<model>_<run>.csv`.", "",
      "| model | run | people | passages rec / sim | J recorded | J simulated | J sd | ratio | ratio range | within 15% |",
      "|---|---|---:|---|---:|---:|---:|---:|---|---|"]
for name, r in results("replay"):
    L.append("| %s | %s | %s | %s / %s | %s | %s | %s | %s | %s-%s | %s |" % (name, r["run"], r["people"], r["passages_recorded"],
             r["passages_simulated"], r["J_recorded"], r["J_simulated"], r["J_sd"], r["ratio"], r["ratio_min"], r["ratio_max"],
             "yes" if abs(float(r["ratio"]) - 1) <= 0.15 else "**no**"))
# Reference curves for the pictures: Weidmann and the acceptance band on a fine grid, the Juelich medians.
with open(os.path.join(work, "fd_reference.csv"), "w") as f:
    f.write("rho,weidmann,band_lo,band_hi\n")
    for k in range(10, 461):
        rho = k / 100
        lo, hi = band(rho)
        f.write("%.2f,%.4f,%.4f,%.4f\n" % (rho, weid(rho), max(lo, 0), hi))
with open(os.path.join(work, "fd_juelich.csv"), "w") as f:
    f.write("rho,speed\n" + "".join("%.2f,%.4f\n" % (c, jue[c]) for c in sorted(jue)))
L += ["", "## Pictures", "", "`fd.png` (fundamental diagram), `bottleneck.png` (J(b)) and `nt_<run>.png` (N(t) of each replay),",
      "beside this file.", ""]
open(out, "w").write("\n".join(L) + "\n")
PY
# A picture per check (validate chart), beside results.md.
colours=(1f77b4 ff7f0e 2ca02c 9467bd 8c564b)
fd_series=(--series "acceptance band|$work/fd_reference.csv|rho|band_lo|band|bbbbbb|band_hi"
           --series "Weidmann 1993|$work/fd_reference.csv|rho|weidmann|line|d62728"
           --series "Juelich corridor (Hermes uo runs, computed)|$work/fd_juelich.csv|rho|speed|points|000000")
bn_series=(--series "measured (Kretz, Seyfried, Mueller, Hermes)|$ref/bottleneck_flow.csv|b_m|J_per_s|points|000000")
for i in "${!models[@]}"; do
  name=$(basename "${models[$i]}" .json)
  fd_series+=(--series "$name|$work/fd_$name.csv|rho|speed_mean|linepoints|${colours[$i]}")
  bn_series+=(--series "$name|$work/bottleneck_$name.csv|b|J|linepoints|${colours[$i]}")
done
"$v" chart --out "$here/fd.png" --title "Fundamental diagram: ring corridor 2.5 m wide, desired speed 1.34 m/s" \
    --x "density (persons/m^2)" --y "mean speed (m/s)" "${fd_series[@]}"
"$v" chart --out "$here/bottleneck.png" --title "Bottleneck flow from a waiting crowd" \
    --x "bottleneck width b (m)" --y "flow J (persons/s)" "${bn_series[@]}"
for r in "${replays[@]}"; do
  read -r scen traj line <<< "$r"
  run=$(basename "$traj" .txt)
  first=$(basename "${models[0]}" .json)
  nt_series=(--series "recorded|$work/nt_${first}_$run.csv|t|recorded|line|000000")
  for i in "${!models[@]}"; do
    name=$(basename "${models[$i]}" .json)
    nt_series+=(--series "$name|$work/nt_${name}_$run.csv|t|simulated|line|${colours[$i]}")
  done
  "$v" chart --out "$here/nt_$run.png" --title "Whole-run replay of $run: passages N(t) through the bottleneck" \
      --x "time (s)" --y "passages N(t)" "${nt_series[@]}"
done
cat "$out"
