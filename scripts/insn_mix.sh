#!/usr/bin/env bash
# Executed instructions per training sample, stage by stage, at each CPU level: x86_64's
# scalar and avx2 levels under qemu-x86_64 (-cpu max: AVX2, FMA, F16C, no AVX-512), aarch64's
# scalar and neon levels under qemu-aarch64 (-cpu cortex-a53: base ARMv8 NEON). Each stage of
# examples/insn_mix.rs runs in its own process under qemu with one instruction per translation
# block and every executed block logged; a stage's count is the difference from the stage
# before it, divided by the samples (Adam's by the parameters it updates). Needs the aarch64
# cross tools of DEVELOPERS.md.
#
# usage: scripts/insn_mix.sh [N]     (N samples, default 1024)
set -euo pipefail
N=${1:-1024}
export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc
cargo build -q --release --example insn_mix
cargo build -q --release --example insn_mix --target aarch64-unknown-linux-gnu
X86=target/release/examples/insn_mix
ARM=target/aarch64-unknown-linux-gnu/release/examples/insn_mix
STAGES=(setup density colour backward finish adam)
count() { # qemu-command level stage
  local runner=$1 level=$2 stage=$3
  RNERF_CPU_LEVEL=$level RAYON_NUM_THREADS=1 $runner -singlestep -d exec,nochain -D /dev/stdout \
    "${@:4}" "$stage" "$N" 2>/dev/null | grep -c '^Trace' || true
}
printf '| stage |'
COLS=("x86_64 scalar" "x86_64 avx2" "aarch64 scalar" "aarch64 neon")
for c in "${COLS[@]}"; do printf ' %s |' "$c"; done
printf '\n|---|---|---|---|---|\n'
declare -A TOTAL
for col in 0 1 2 3; do
  case $col in
    0) run=(qemu-x86_64-static -cpu max); level=scalar; bin=$X86 ;;
    1) run=(qemu-x86_64-static -cpu max); level=avx2; bin=$X86 ;;
    2) run=(qemu-aarch64-static -cpu cortex-a53 -L /usr/aarch64-linux-gnu); level=scalar; bin=$ARM ;;
    3) run=(qemu-aarch64-static -cpu cortex-a53 -L /usr/aarch64-linux-gnu); level=neon; bin=$ARM ;;
  esac
  for s in "${STAGES[@]}"; do
    TOTAL[$col,$s]=$(count "${run[*]}" "$level" "$s" "$bin")
  done
done
PARAMS=$("$X86" setup "$N" 2>&1 >/dev/null | sed -n 's/.*params \([0-9]*\).*/\1/p')
prev=setup
for s in "${STAGES[@]:1}"; do
  printf '| %s |' "$s"
  for col in 0 1 2 3; do
    d=$(( TOTAL[$col,$s] - TOTAL[$col,$prev] ))
    if [ "$s" = adam ]; then
      awk -v d="$d" -v p="$PARAMS" 'BEGIN { printf " %.2f per parameter |", d / p }'
    else
      awk -v d="$d" -v n="$N" 'BEGIN { printf " %.0f |", d / n }'
    fi
  done
  printf '\n'
  prev=$s
done
