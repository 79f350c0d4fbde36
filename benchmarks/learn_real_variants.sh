#!/usr/bin/env bash
# Variants of the learning protocol of benchmarks/learn_real.sh, each held to both of issue 10's
# yardsticks: held-out prediction (ADE at 4 s on the five runs of learning_real.md, against the
# untrained default and constant velocity) and the validation against real crowds
# (benchmarks/validation/run.sh: fundamental diagram, J(b), whole-run replays).
# Each variant trains the crowd material only, from the default (or from the default with the
# variant's start parameters changed), on the training runs of
# learn_real.sh. Writes benchmarks/results/learning_real_variants.md; models, predictions and
# validation tables under $BUILD_DIR/variants/<name>/. With NAMEs, only those variants run and the
# table goes to $BUILD_DIR/variants/results.md instead (the recorded one keeps every variant).
# Usage: benchmarks/learn_real_variants.sh [BUILD_DIR] [NAME ...]   (default: every variant)
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
shift || true
data=../shared/data/real
[ -d "$data" ] || { echo "skipped: $data is absent"; exit 0; }
cli="$build/cli/crowdmpm"
corr=$data/fzj_hermes_2009_corridor_uo
bott=$data/fzj_crowdqueue_2018_bottleneck
# name | venue of uo-300-300-160 (training) and of uo-180-180-070 (held out) | train options | what it is
#   [| start: the built-in default with these parameters changed, name=value,... (default: unchanged)]
variants=(
  "shipped|corridor_300 corridor|--window 16 --stride 4 --iterations 200|the shipped protocol (learn_real.sh): the two runs' exit constrictions not modelled"
  "venues|corridor_300_exit_160 corridor_exit_070|--window 16 --stride 4 --iterations 200|the shipped protocol in the runs' venues as built (exit posts modelled)"
  "venues_area1|corridor_300_exit_160 corridor_exit_070|--window 16 --stride 4 --iterations 200 --area-weight 1|as venues, plus the area loss (density and flow in the measurement areas), weight 1"
  "venues_area4|corridor_300_exit_160 corridor_exit_070|--window 16 --stride 4 --iterations 200 --area-weight 4|as venues, plus the area loss, weight 4"
  "venues_w8|corridor_300_exit_160 corridor_exit_070|--window 8 --stride 2 --iterations 200|as venues, 8 s windows every 2 s"
  "venues_w4|corridor_300_exit_160 corridor_exit_070|--window 4 --stride 2 --iterations 200|as venues, 4 s windows every 2 s"
  "venues_area1_gap|corridor_300_exit_160 corridor_exit_070|--window 16 --stride 4 --iterations 200 --area-weight 1|as venues_area1, starting from a headway gap of 0.1 m (learned)|headway_gap=0.1"
  "venues_area1_gap_t06|corridor_300_exit_160 corridor_exit_070|--window 16 --stride 4 --iterations 200 --area-weight 1|as venues_area1_gap, starting from a time gap of 0.6 s|headway_gap=0.1,time_gap=0.6"
  "venues_w8_gap|corridor_300_exit_160 corridor_exit_070|--window 8 --stride 2 --iterations 200|as venues_w8, starting from a headway gap of 0.1 m (learned)|headway_gap=0.1"
  "venues_w8_area1_gap|corridor_300_exit_160 corridor_exit_070|--window 8 --stride 2 --iterations 200 --area-weight 1|as venues_w8_gap, plus the area loss, weight 1|headway_gap=0.1"
  "venues_w8_gap_ds|corridor_300_exit_160 corridor_exit_070|--window 8 --stride 2 --iterations 200|as venues_w8_gap, with the material's density-speed law from Weidmann's values (learned)|headway_gap=0.1,density_speed_gamma=1.913,density_speed_max=5.4"
  "venues_w8_area4_gap_ds|corridor_300_exit_160 corridor_exit_070|--window 8 --stride 2 --iterations 200 --area-weight 4|as venues_w8_gap_ds, plus the area loss, weight 4|headway_gap=0.1,density_speed_gamma=1.913,density_speed_max=5.4"
  "venues_w8_area4_gap_ds_sc|corridor_300_exit_160 corridor_exit_070|--window 8 --stride 2 --iterations 200 --area-weight 4 --desired-speed scenario|as venues_w8_area4_gap_ds, the recorded people walking at their scenario's desired speed (times v0_scale) instead of their own free speed|headway_gap=0.1,density_speed_gamma=1.913,density_speed_max=5.4"
  "venues_w8_area4_gap_ds_open|corridor_300_exit_160 corridor_exit_070|--window 8 --stride 2 --iterations 200 --area-weight 4|as venues_w8_area4_gap_ds, with the law's opening discount from 0.1 m/s (learned)|headway_gap=0.1,density_speed_gamma=1.913,density_speed_max=5.4,density_opening_speed=0.1"
  "venues_w8_area4_gap_ds_r2|corridor_300_exit_160 corridor_exit_070|--window 8 --stride 2 --iterations 200 --area-weight 4|as venues_w8_area4_gap_ds_open from 0.03 m/s, the law reading the density 2 m ahead (focus 1) instead of 1 m|headway_gap=0.1,density_speed_gamma=1.913,density_speed_max=5.4,density_opening_speed=0.03,density_speed_reach=2"
  "venues_w8_area4_gap_ds_r3|corridor_300_exit_160 corridor_exit_070|--window 8 --stride 2 --iterations 200 --area-weight 4|as venues_w8_area4_gap_ds_r2 with a reach of 3 m|headway_gap=0.1,density_speed_gamma=1.913,density_speed_max=5.4,density_opening_speed=0.03,density_speed_reach=3"
  "venues_w8_area4_gap_ds_r3f4|corridor_300_exit_160 corridor_exit_070|--window 8 --stride 2 --iterations 200 --area-weight 4|as venues_w8_area4_gap_ds_open from 0.03 m/s, the law reading the density 3 m ahead with focus 4 (a cone of about 50 degrees) instead of 1 m with focus 1|headway_gap=0.1,density_speed_gamma=1.913,density_speed_max=5.4,density_opening_speed=0.03,density_speed_reach=3,density_speed_focus=4"
  "venues_w8_area4_gap_ds_r2f4|corridor_300_exit_160 corridor_exit_070|--window 8 --stride 2 --iterations 200 --area-weight 4|as venues_w8_area4_gap_ds_r3f4 with a reach of 2 m|headway_gap=0.1,density_speed_gamma=1.913,density_speed_max=5.4,density_opening_speed=0.03,density_speed_reach=2,density_speed_focus=4"
  "venues_w8_area4_gap_ds_r2_floor|corridor_300_exit_160 corridor_exit_070|--window 8 --stride 2 --iterations 200 --area-weight 4|as venues_w8_area4_gap_ds_r2, with the law's floor from 0.3 (learned): people in a dense crowd still want to move at that share of their free speed|headway_gap=0.1,density_speed_gamma=1.913,density_speed_max=5.4,density_opening_speed=0.03,density_speed_reach=2,density_speed_floor=0.3"
  "venues_w8_area4_gap_ds_r3_floor|corridor_300_exit_160 corridor_exit_070|--window 8 --stride 2 --iterations 200 --area-weight 4|as venues_w8_area4_gap_ds_r2_floor with a reach of 3 m|headway_gap=0.1,density_speed_gamma=1.913,density_speed_max=5.4,density_opening_speed=0.03,density_speed_reach=3,density_speed_floor=0.3"
  "venues_w8_area4_gap_ds_r15_floor|corridor_300_exit_160 corridor_exit_070|--window 8 --stride 2 --iterations 200 --area-weight 4|as venues_w8_area4_gap_ds_r2_floor with a reach of 1.5 m|headway_gap=0.1,density_speed_gamma=1.913,density_speed_max=5.4,density_opening_speed=0.03,density_speed_reach=1.5,density_speed_floor=0.3"
  "venues_w8_area4_gap_ds_r15f2_floor|corridor_300_exit_160 corridor_exit_070|--window 8 --stride 2 --iterations 200 --area-weight 4|as venues_w8_area4_gap_ds_r15_floor with focus 2 (the people beside weigh a quarter of those straight ahead)|headway_gap=0.1,density_speed_gamma=1.913,density_speed_max=5.4,density_opening_speed=0.03,density_speed_reach=1.5,density_speed_focus=2,density_speed_floor=0.3"
  "venues_w8_area4_gap_ds_r15f8_u03_floor|corridor_300_exit_160 corridor_exit_070|--window 8 --stride 2 --iterations 200 --area-weight 4|as venues_w8_area4_gap_ds_r15f2_floor with focus 8 (the people beside hardly count) and the opening speed from 0.3 m/s (people walking away count more)|headway_gap=0.1,density_speed_gamma=1.913,density_speed_max=5.4,density_opening_speed=0.3,density_speed_reach=1.5,density_speed_focus=8,density_speed_floor=0.3"
  "venues_w8_area4_gap_ds_r15f8_u03_maxfloor|corridor_300_exit_160 corridor_exit_070|--window 8 --stride 2 --iterations 200 --area-weight 4|as venues_w8_area4_gap_ds_r15f8_u03_floor with the floor as a smooth max(f, phi) (Weidmann's law where it asks for more than the floor: density_speed_floor_max 1), from 0.45|headway_gap=0.1,density_speed_gamma=1.913,density_speed_max=5.4,density_opening_speed=0.3,density_speed_reach=1.5,density_speed_focus=8,density_speed_floor=0.45,density_speed_floor_max=1"
  "venues_w8_area4_gap_ds_r15f8_u03_halfmax|corridor_300_exit_160 corridor_exit_070|--window 8 --stride 2 --iterations 200 --area-weight 4|as venues_w8_area4_gap_ds_r15f8_u03_floor with the floor half added, half a smooth max (density_speed_floor_max 0.5), from 0.4|headway_gap=0.1,density_speed_gamma=1.913,density_speed_max=5.4,density_opening_speed=0.3,density_speed_reach=1.5,density_speed_focus=8,density_speed_floor=0.4,density_speed_floor_max=0.5"
  "venues_w8_area4_ds_r15f8_u03_floor_t08|corridor_300_exit_160 corridor_exit_070|--window 8 --stride 2 --iterations 200 --area-weight 4 --params E,gamma,tension_scale,tau,v0_scale,comfort_distance,alignment_time,density_speed_gamma,density_speed_max,density_opening_speed,density_speed_floor|as venues_w8_area4_gap_ds_r15f8_u03_floor with the default's headway held (time gap 0.8 s, no standstill gap; not learned): 8 s windows do not see the queues that set the time gap, the law is learned on top|density_speed_gamma=1.913,density_speed_max=5.4,density_opening_speed=0.3,density_speed_reach=1.5,density_speed_focus=8,density_speed_floor=0.3"
  "venues_w8_area4_gap_ds_r15f8_u03_floor_t08|corridor_300_exit_160 corridor_exit_070|--window 8 --stride 2 --iterations 200 --area-weight 4 --params E,gamma,tension_scale,tau,v0_scale,comfort_distance,alignment_time,density_speed_gamma,density_speed_max,density_opening_speed,density_speed_floor,headway_gap|as venues_w8_area4_ds_r15f8_u03_floor_t08 with the standstill gap learned from 0.1 m (the time gap still held at 0.8 s)|headway_gap=0.1,density_speed_gamma=1.913,density_speed_max=5.4,density_opening_speed=0.3,density_speed_reach=1.5,density_speed_focus=8,density_speed_floor=0.3"
  "venues_w8_area4_gap_ds_r15f8_u03_floor_hw06|corridor_300_exit_160 corridor_exit_070|--window 8 --stride 2 --iterations 200 --area-weight 4|as venues_w8_area4_gap_ds_r15f8_u03_floor with a headway lane of 0.6 (r_p + r_q) instead of 0.5: in a staggered dense crowd more of the people ahead count for the headway, in single file the same|headway_gap=0.1,density_speed_gamma=1.913,density_speed_max=5.4,density_opening_speed=0.3,density_speed_reach=1.5,density_speed_focus=8,density_speed_floor=0.3,headway_width=0.6"
  "venues_w8_area4_gap015_ds_r15f8_u03_floor|corridor_300_exit_160 corridor_exit_070|--window 8 --stride 2 --iterations 200 --area-weight 4 --params E,gamma,tension_scale,tau,v0_scale,comfort_distance,alignment_time,time_gap,density_speed_gamma,density_speed_max,density_opening_speed,density_speed_floor|as venues_w8_area4_gap_ds_r15f8_u03_floor with the standstill gap held at 0.15 m (not learned; the time gap learned): in a uniform dense crowd the headway speed is (gap - s0)/T, so a larger s0 slows 2-3 persons/m2 more than the sparse corridors|headway_gap=0.15,density_speed_gamma=1.913,density_speed_max=5.4,density_opening_speed=0.3,density_speed_reach=1.5,density_speed_focus=8,density_speed_floor=0.3"
  "venues_w8_area8_gap_ds_r15f8_u03_floor|corridor_300_exit_160 corridor_exit_070|--window 8 --stride 2 --iterations 200 --area-weight 8|as venues_w8_area4_gap_ds_r15f8_u03_floor with the area loss at weight 8 (density and flow in the measurement areas weigh twice as much)|headway_gap=0.1,density_speed_gamma=1.913,density_speed_max=5.4,density_opening_speed=0.3,density_speed_reach=1.5,density_speed_focus=8,density_speed_floor=0.3"
  "venues_area4_gap_ds_r15f8_u03_floor|corridor_300_exit_160 corridor_exit_070|--window 16 --stride 4 --iterations 200 --area-weight 4|as venues_w8_area4_gap_ds_r15f8_u03_floor with 16 s windows every 4 s (the shipped protocol's)|headway_gap=0.1,density_speed_gamma=1.913,density_speed_max=5.4,density_opening_speed=0.3,density_speed_reach=1.5,density_speed_focus=8,density_speed_floor=0.3"
  "venues_w8_area4_gap_ds_r2f4_floor|corridor_300_exit_160 corridor_exit_070|--window 8 --stride 2 --iterations 200 --area-weight 4|as venues_w8_area4_gap_ds_r2f4, with the law's floor from 0.3 (learned)|headway_gap=0.1,density_speed_gamma=1.913,density_speed_max=5.4,density_opening_speed=0.03,density_speed_reach=2,density_speed_focus=4,density_speed_floor=0.3"
  "venues_area1_gap_ds|corridor_300_exit_160 corridor_exit_070|--window 16 --stride 4 --iterations 200 --area-weight 1|as venues_area1_gap, with the material's density-speed law from Weidmann's values (learned)|headway_gap=0.1,density_speed_gamma=1.913,density_speed_max=5.4"
)
wanted=("$@")
out=benchmarks/results/learning_real_variants.md
[ ${#wanted[@]} -eq 0 ] || out="$build/variants/results.md"
for w in "${wanted[@]}"; do
  printf '%s\n' "${variants[@]}" | cut -d'|' -f1 | grep -qx "$w" || { echo "no variant named '$w'" >&2; exit 2; }
done
summary="$build/variants/summary.tsv"
mkdir -p "$build/variants"
: > "$summary"
for v in "${variants[@]}"; do
  IFS='|' read -r name venues opts what changes <<< "$v"
  if [ ${#wanted[@]} -gt 0 ] && [[ ! " ${wanted[*]} " == *" $name "* ]]; then continue; fi
  read -r c300 c070 <<< "$venues"
  dir="$build/variants/$name"
  mkdir -p "$dir"
  start_model=(--material crowd)
  if [ -n "${changes:-}" ]; then
    /usr/bin/python3 - engine/sim/default_model.json "$changes" "$dir/start.json" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
for kv in sys.argv[2].split(","):
    k, v = kv.split("=")
    m["parameters"][k] = float(v)
m["name"] = "start"
m["description"] = "the built-in default with " + sys.argv[2]
json.dump(m, open(sys.argv[3], "w"), indent=1)
PY
    start_model=(--model "$dir/start.json")
  fi
  start=$(date +%s)
  # shellcheck disable=SC2086
  "$cli" train --scenario scenarios/corridor.json --trajectories "$corr/uo-050-180-180.txt" "$corr/uo-100-180-180.txt" "$corr/uo-180-180-180.txt" \
      --scenario "scenarios/$c300.json" --trajectories "$corr/uo-300-300-160.txt" \
      --scenario scenarios/bottleneck.json --trajectories "$bott/030_c_56_h0.txt" \
      "${start_model[@]}" --desired-speed free $opts --threads 2 --quiet --out "$dir/$name.json" > "$dir/train.log"
  seconds=$(( $(date +%s) - start ))
  ade=()
  for spec in "$corr/uo-145-180-180.txt corridor" "$corr/uo-180-180-070.txt $c070" "$corr/uo-240-240-240.txt corridor_240" \
              "$bott/040_c_56_h-.txt bottleneck" "$data/fzj_hermes_2009_bottleneck_ao/traj_AO_300.txt bottleneck_ao"; do
    read -r traj scen <<< "$spec"
    run=$(basename "$traj" .txt)
    "$cli" predict --scenario "scenarios/$scen.json" --trajectories "$traj" --observe 4 --horizon 4 --threads 2 --desired-speed free \
        --model "$dir/$name.json" --out "$dir/$run" > /dev/null
    ade+=("$(/usr/bin/python3 -c '
import json, sys
j = json.load(open(sys.argv[1]))
a = {m["method"]: [h["ade_m"] for h in m["horizons"] if h["horizon_s"] == 4][0] for m in j["methods"]}
print("%s:%s:%.3f/%.3f/%.3f" % (sys.argv[2], sys.argv[3], a["constant velocity"], a["untrained default (crowd)"], [v for k, v in a.items() if k.startswith("learned")][0]))
' "$dir/$run/prediction.json" "$run" "$scen")")
  done
  VALIDATION_OUT="$dir/validation" bash benchmarks/validation/run.sh "$build" "$dir/$name.json" > "$dir/validation.log"
  printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$name" "$what" "$opts${changes:+, start $changes}" "$seconds" "$(grep '^validation' "$dir/train.log")" "${ade[*]}" \
      "$dir/validation/results.md" >> "$summary"
done
/usr/bin/python3 - "$summary" "$out" "$(git rev-parse --short HEAD)" <<'PY'
import re, sys
summary, out, commit = sys.argv[1:]
rows = [l.rstrip("\n").split("\t") for l in open(summary) if l.strip()]
L = ["# Learning from real recordings: protocol variants", "",
     "Produced by `benchmarks/learn_real_variants.sh` at commit %s on a 2-core Debian 12 machine." % commit, "",
     "Each variant trains the crowd material from the default (or, where its options say \"start\", the default with those parameters) on the training runs of `benchmarks/learn_real.sh`",
     "(uo-050/100/180-180-180, uo-300-300-160, CrowdQueue 030) with each person's free speed as desired speed, and is",
     "held to issue 10's two yardsticks: ADE at 4 s on the five held-out runs (the recorded state every 4 s after the",
     "first 4 s, rolled forward 4 s: constant velocity / untrained default / the variant, metres; the variant in bold",
     "where it beats the default) and the validation against real crowds (`benchmarks/validation/run.sh` on the",
     "variant: fundamental diagram densities in band of 12, J(b) widths within 20% of 8, replays within 15% of 3;",
     "CrowdQueue 030, one of the three replays, is a training run of every variant).",
     "uo-180-180-070 is predicted in the venue the variant's training used for the constricted runs: `corridor`",
     "(no exit constriction) for `shipped`, `corridor_exit_070` (its 0.7 m exit) for the others. \"val\": the validation",
     "loss before and after training, m² (with the area loss it includes W times the area term: not comparable across rows).", ""]
L += ["| variant | options | training | uo-145 | uo-180-070 | uo-240 | CQ040 | AO_300 | beats default | FD | J(b) | replays |",
      "|---|---|---|---|---|---|---|---|---|---|---|---|"]
notes = []
for name, what, opts, seconds, val, ade, results in rows:
    cells, wins = [], 0
    for a in ade.split():
        run, scen, nums = a.split(":")
        cv, d, l = (float(x) for x in nums.split("/"))
        wins += l < d
        cells.append("%.3f / %.3f / %s" % (cv, d, ("**%.3f**" if l < d else "%.3f") % l))
    text = open(results).read()
    sections = re.split(r"\n## ", text)
    def count(head):
        sec = [s for s in sections if s.startswith(head)][0]
        r = [l for l in sec.splitlines() if l.startswith("| %s |" % name)]
        return "%d/%d" % (sum("| yes |" in l for l in r), len(r))
    loss = re.search(r"loss (\S+) -> (\S+)", val)
    L.append("| %s | `%s` | %s s, val %s -> %s | %s | %d/5 | %s | %s | %s |" % (
        name, opts, seconds, loss.group(1) if loss else "?", loss.group(2) if loss else "?", " | ".join(cells), wins,
        count("Fundamental diagram (ring"), count("Bottleneck flow"), count("Whole-run replays")))
    fails = [l for l in text.splitlines() if l.startswith("| %s |" % name) and "**no**" in l]
    notes.append("- **%s**: %s.%s" % (name, what, (" Out of acceptance: " + "; ".join(
        " ".join(c.strip() for c in f.strip("|").split("|")[1:8]) for f in fails)) if fails else " Every validation check holds."))
L += ["", "Validation rows out of acceptance (model, then the row's first columns as in the validation tables):", ""] + notes
open(out, "w").write("\n".join(L) + "\n")
print("\n".join(L))
PY
