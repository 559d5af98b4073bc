#!/usr/bin/env bash
# The frozen tail's coarse part (`--frozen-coarse T,N`) against it off, on the dev scenes: for
# each SCENE:COARSE[:SEED] (COARSE = T,N or off; SEED default 0), trains the default residual
# model over BG_MODEL (`rnerf train --background BG_MODEL --background-data DEV/background`),
# scores it (`rnerf eval --json --depth-only`), and keeps in OUT the eval JSON and the training
# log's last lines (samples kept / evaluated per ray at step 1000, training seconds). Then
# `scripts/frozen_coarse_table.py OUT` prints the table. Training seconds of one run are noisy:
# compare times only from alternated runs taken alone, in their own autogroup (BENCHMARKS.md).
# usage: scripts/frozen_coarse.sh RNERF DEV_DIR BG_MODEL OUT SCENE:COARSE[:SEED]...
#   RNERF_CPU_LEVEL=avx2 to measure the level robots have
set -euo pipefail
rnerf=$1 dev=$2 bg=$3 out=$4
shift 4
mkdir -p "$out"
model=$(mktemp -d)
for spec in "$@"; do
  IFS=: read -r scene coarse seed <<< "$spec"
  seed=${seed:-0}
  name=${scene}_c${coarse/,/x}_s$seed
  "$rnerf" train --data "$dev/$scene" --background "$bg" --background-data "$dev/background" --seed "$seed" \
    --frozen-coarse "$coarse" --out "$model/m.safetensors" 2>&1 | tr '\r' '\n' | grep -E '^train 1000/|wrote' > "$out/$name.train.txt"
  "$rnerf" eval --model "$model/m.safetensors" --data "$dev/$scene" --json --depth-only > "$out/$name.eval.json"
  echo "$name: $(tail -1 "$out/$name.train.txt")"
done
rm -rf "$model"
