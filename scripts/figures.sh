#!/usr/bin/env bash
# BENCHMARKS.md's "Current figures" on the host at hand: every figure at the host's best CPU
# level and at `avx2` (the level robots have), each command in its own high-priority autogroup
# so other processes do not take a core. Prints the Markdown table and keeps the raw outputs.
#
# usage: scripts/figures.sh [OUT_DIR]
#   OUT_DIR  raw outputs (default: figures-<date>-<commit>)
# environment:
#   DEV=../shared/data/dev   also time the dev background (train 1000 steps + eval) and a
#                            residual scene (glass_up, 100 views) over it   (~12 min per level)
#   PEER=../shared/bench/torch_ngp_cpu.py PYTHON=.venv-torch/bin/python
#                            also run the PyTorch peer (eager and torch.compile) for the
#                            training-step ratios (scripts/peer_bench.sh does this alone)
#   LEVELS="amx avx2"        the levels to measure (default: the host's best, then avx2)
#   REPS=5                   `rnerf bench` repetitions
set -euo pipefail
cd "$(dirname "$0")/.."
commit=$(git rev-parse --short HEAD)$(git diff --quiet HEAD -- src Cargo.toml || echo "+dirty")
date=$(date -u +%F)
out=${1:-figures-$date-$commit}
mkdir -p "$out"
cargo build --release --quiet
bin=$PWD/target/release/rnerf
host=$(grep -m1 'model name' /proc/cpuinfo 2>/dev/null | sed 's/.*: //' || uname -m)
best=$("$bin" bench --json --reps 1 --log2t 12 2>/dev/null | python3 -c 'import json,sys; print(json.load(sys.stdin)["cpu_level"])')
levels=${LEVELS:-$best avx2}
[ "$best" = avx2 ] && levels=${LEVELS:-avx2}
case "$(uname -m)" in aarch64) levels=${LEVELS:-neon} ;; esac

# Runs CMD at LEVEL in its own autogroup at nice -10 (falls back to a plain run where the
# autogroup is not writable), with /usr/bin/time -v into LOG.time.
prio() {
  local level=$1 log=$2; shift 2
  setsid bash -c 'echo -10 > /proc/self/autogroup 2>/dev/null; exec "$@"' _ \
    env RNERF_CPU_LEVEL="$level" /usr/bin/time -v -o "$log.time" "$@" > "$log" 2> "$log.err"
}

for level in $levels; do
  echo "figures.sh: $level: rnerf bench" >&2
  prio "$level" "$out/bench_$level.json" "$bin" bench --json --reps "${REPS:-5}"
  echo "figures.sh: $level: rnerf demo" >&2
  rm -rf "$out/demo_$level"
  prio "$level" "$out/demo_$level.log" "$bin" demo --out "$out/demo_$level"
  if [ -n "${DEV:-}" ]; then
    echo "figures.sh: $level: dev background and glass_up" >&2
    prio "$level" "$out/bg_$level.log" "$bin" train --data "$DEV/background" --out "$out/bg_$level.safetensors"
    prio "$level" "$out/bg_eval_$level.json" "$bin" eval --model "$out/bg_$level.safetensors" --data "$DEV/background" --json
    prio "$level" "$out/res_$level.log" "$bin" train --data "$DEV/glass_up" --background "$out/bg_$level.safetensors" \
      --background-data "$DEV/background" --out "$out/res_$level.safetensors"
    prio "$level" "$out/res_eval_$level.json" "$bin" eval --model "$out/res_$level.safetensors" --data "$DEV/glass_up" --json
    prio "$level" "$out/bench_models_$level.json" "$bin" bench --json --reps "${REPS:-5}" \
      --model "$out/bg_$level.safetensors" --model "$out/res_$level.safetensors" --data "$DEV/glass_up"
  fi
done
if [ -n "${PEER:-}" ]; then
  echo "figures.sh: the PyTorch peer" >&2
  for mode in eager compile; do
    flag=; [ $mode = compile ] && flag=--compile
    setsid bash -c 'echo -10 > /proc/self/autogroup 2>/dev/null; exec "$@"' _ \
      "${PYTHON:-python3}" "$PEER" train --rays 4096 --samples 32 --log2t 17 --steps 10 $flag > "$out/peer_$mode.log"
  done
fi
python3 scripts/figures_table.py "$out" "$host" "$date" "$commit" $levels | tee "$out/table.md"
