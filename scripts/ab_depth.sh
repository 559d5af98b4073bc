#!/usr/bin/env bash
# Threshold-depth views of two builds alternated: `examples/depth_rounds` of build A, then of
# build B, ROUNDS times, on each MODEL (its DATA_DIR's first three test views and a 640×480
# one, 7 frames each, rounds of 2 samples), then per build and model the median over the rounds
# of each view's median frame time (ms) and the rounds' range. Run it alone on the host, in its
# own autogroup (BENCHMARKS.md).
# usage: scripts/ab_depth.sh A_DEPTH_ROUNDS B_DEPTH_ROUNDS ROUNDS DATA_DIR MODEL [MODEL ...]
#   (A_/B_DEPTH_ROUNDS: target/release/examples/depth_rounds of each build, copied aside)
set -euo pipefail
a=$1 b=$2 rounds=$3 data=$4; shift 4
log=$(mktemp)
for _ in $(seq "$rounds"); do
  for build in A B; do
    bin=$a; [ "$build" = B ] && bin=$b
    for model in "$@"; do
      echo "$build $model $(RNERF_CPU_LEVEL=${RNERF_CPU_LEVEL:-avx2} "$bin" "$model" "$data" 2 7 2>&1 | tail -1)" >> "$log"
    done
  done
done
python3 - "$log" <<'PY'
import re, statistics, sys
runs = {}
for line in open(sys.argv[1]):
    build, model = line.split()[:2]
    runs.setdefault((build, model), []).append([float(x) for x in re.findall(r"median ([0-9.]+)", line)])
print("| build | model | view 0 | view 1 | view 2 | 640×480 |")
print("|---|---|---|---|---|---|")
for (build, model), rs in sorted(runs.items(), key=lambda kv: (kv[0][1], kv[0][0])):
    cells = [f"{statistics.median(v):.1f} [{min(v):.1f}–{max(v):.1f}]" for v in zip(*rs)]
    print(f"| {build} | {model} | " + " | ".join(cells) + " |")
PY
rm -f "$log"
