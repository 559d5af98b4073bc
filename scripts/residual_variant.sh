#!/usr/bin/env bash
# One setting of the default residual method on the dev scenes: for each SCENE:SEED, trains
# the default residual model over BG_MODEL with the extra FLAGS (`rnerf train --background
# BG_MODEL --background-data DEV/background --seed SEED FLAGS`), scores it (`rnerf eval --json
# --depth-only`), and keeps in OUT the eval JSON (OUT/SCENE_NAME_sSEED.eval.json) and the
# training log's last lines (samples kept / evaluated per ray at the last step, training
# seconds). NAME labels the setting ("default" for no flags); `scripts/variant_table.py OUT`
# prints the table. BG_MODEL `-` trains Dex-NeRF instead (a plain NeRF of the scene, `rnerf
# train --data DEV/SCENE --seed SEED FLAGS`, no background), in the same layout. Training
# seconds of one run are noisy: compare times only from alternated runs taken alone, in their
# own autogroup (BENCHMARKS.md).
# usage: scripts/residual_variant.sh RNERF DEV_DIR BG_MODEL OUT NAME SCENE:SEED[,SCENE:SEED...] [FLAGS...]
#   RNERF_CPU_LEVEL=avx2 to measure the level robots have
set -euo pipefail
rnerf=$1 dev=$2 bg=$3 out=$4 name=$5 runs=$6
shift 6
mkdir -p "$out"
background=(--background "$bg" --background-data "$dev/background")
[ "$bg" = - ] && background=()
model=$(mktemp -d)
trap 'rm -rf "$model"' EXIT
for spec in ${runs//,/ }; do
  IFS=: read -r scene seed <<< "$spec"
  run=${scene}_${name}_s$seed
  "$rnerf" train --data "$dev/$scene" "${background[@]}" --seed "$seed" \
    "$@" --out "$model/m.safetensors" 2>&1 | tr '\r' '\n' | grep -E '^train [0-9]+/[0-9]+ |wrote' | tail -2 > "$out/$run.train.txt"
  "$rnerf" eval --model "$model/m.safetensors" --data "$dev/$scene" --json --depth-only > "$out/$run.eval.json" 2> /dev/null
  echo "$run: $(tail -1 "$out/$run.train.txt")"
done
