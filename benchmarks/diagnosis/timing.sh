#!/usr/bin/env bash
# Wall-clock time (and peak memory, where /usr/bin/time exists) of one diagnosis of a 40 s,
# 200-person recording on 2 threads, as a user runs it: `crowdmpm diagnose`. The recording is the
# diagnosis suite's corridor (200 people walking in over 40 s, made by the social-force model
# kind) with its concealed obstacle, at 0.05 m tracking noise: a case that fits candidates, not a
# control that stops after the localisation. Recorded in benchmarks/results/diagnosis_timing.md.
# Usage: benchmarks/diagnosis/timing.sh [BUILD_DIR]
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${1:-build}
work="$build/diagnosis_timing"
rm -rf "$work"
mkdir -p "$work"
# The recording (and the suite's own diagnosis of it, not timed here).
"$build/benchmarks/diagnosis_suite" benchmarks/diagnosis/suite.json --out "$work/suite" --threads 2 --noise 0.05 \
  --only corridor:obstacle > "$work/suite.log"
case_dir="$work/suite/corridor_obstacle_0.05"
people=$(awk '!/^#/ && NF >= 4 {print $1}' "$case_dir/observed.txt" | sort -u | wc -l)
seconds_recorded=$(awk '/^# framerate:/ {fps = $3} !/^#/ && NF >= 4 {if (n++ == 0 || $2 < lo) lo = $2; if ($2 > hi) hi = $2}
  END {printf "%.1f", (hi - lo) / fps}' "$case_dir/observed.txt")
cmd=(build/cli/crowdmpm diagnose --scenario "$case_dir/belief.json" --observed "$case_dir/observed.txt" --out "$work/diag" --threads 2)
cmd[0]="$build/cli/crowdmpm"
start=$(date +%s.%N)
if [ -x /usr/bin/time ]; then
  /usr/bin/time -f "%M" -o "$work/rss_kb" "${cmd[@]}" > "$work/diagnose.log" 2>&1
else
  "${cmd[@]}" > "$work/diagnose.log" 2>&1
fi
end=$(date +%s.%N)
seconds=$(awk -v a="$start" -v b="$end" 'BEGIN {printf "%.0f", b - a}')
memory="not measured (/usr/bin/time missing)"
[ -f "$work/rss_kb" ] && memory="$(( $(tail -1 "$work/rss_kb") / 1024 )) MiB peak resident"
verdict=$(head -1 "$work/diag/summary.txt" | tr '|' '/')
out=benchmarks/results/diagnosis_timing.md
{
  echo "# Diagnosis wall-clock time"
  echo
  echo "Command: \`benchmarks/diagnosis/timing.sh $build\` at commit $(git rev-parse --short HEAD), $(date -u +%Y-%m-%d), $(nproc) cores."
  echo
  echo "Timed: \`crowdmpm diagnose --scenario belief.json --observed observed.txt --out DIR --threads 2\` on the"
  echo "diagnosis suite's corridor with its concealed obstacle at 0.05 m noise: $people people over $seconds_recorded s."
  echo
  echo "| recording | threads | wall-clock (s) | memory | summary.txt, first line |"
  echo "|---|---|---|---|---|"
  echo "| $people people, $seconds_recorded s | 2 | $seconds | $memory | $verdict |"
  echo
  echo "Target (issue 11): under 10 minutes (600 s)."
} > "$out"
cat "$out"
