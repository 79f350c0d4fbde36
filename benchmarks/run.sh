#!/usr/bin/env bash
# Runs the standard throughput set and writes benchmarks/results/<machine>.csv (one row per run,
# with the commit and peak memory). Usage: benchmarks/run.sh [BUILD_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
bench=$build/benchmarks/bench_step
out=benchmarks/results/$(uname -s | tr 'A-Z' 'a-z')-$(uname -m)-$(nproc)core.csv
commit=$(git rev-parse --short HEAD 2>/dev/null || echo unknown)
echo "commit,machine,compiler,flags,scene,agents,density,threads,steps,seconds,agent_steps_per_s,agents_in_contact,max_rss_kib" > "$out"
run() {
  local tmp; tmp=$(mktemp)
  /usr/bin/time -f "%M" -o "$tmp" "$bench" "$@" | sed "s/^/$commit,/" | tr -d '\n' >> "$out"
  echo ",$(cat "$tmp")" >> "$out"
  rm -f "$tmp"
}
for rep in 1 2 3; do
  run --agents 10000 --threads 1 --steps 300
  run --agents 10000 --threads 2 --steps 300
  run --agents 100000 --threads 1 --steps 40
  run --agents 100000 --threads 2 --steps 40
done
run --agents 1000000 --threads 2 --steps 10 --warmup 5
run --agents 10000 --spacing 0.6 --threads 2 --steps 300
run --scenario scenarios/drill.json --threads 2 --steps 1000 --warmup 0
cat "$out"
