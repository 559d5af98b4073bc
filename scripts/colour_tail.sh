#!/usr/bin/env bash
# The colour tail's cost and gain: `rnerf eval --json` (colour + threshold depth) of each
# MODEL:SCENE at each setting of SETTINGS (default "default off": the default colour tail and
# `--colour-tail off`; a number R is `--colour-tail R`), one after the other, for ROUNDS rounds
# at each CPU level of LEVELS. Writes OUT/MODEL_SETTING_LEVEL_ROUND.json and one line per run to
# OUT/colour_tail.log: level, round, model, setting, wall seconds, PSNR, crop MAE. Run it alone,
# in its own autogroup (BENCHMARKS.md): only the ratios within a round are comparable.
# usage: LEVELS="avx2 avx512" ROUNDS=2 [SETTINGS="off 0.2 0.4"] scripts/colour_tail.sh RNERF DEV_DIR OUT MODEL.safetensors:SCENE [...]
set -euo pipefail
rnerf=$1 dev=$2 out=$3
shift 3
mkdir -p "$out"
for level in ${LEVELS:-avx2}; do
  for round in $(seq 1 "${ROUNDS:-2}"); do
    for spec in "$@"; do
      model=${spec%%:*} scene=${spec#*:}
      name=$(basename "$model" .safetensors)
      for setting in ${SETTINGS:-default off}; do
        flags=()
        [ "$setting" != default ] && flags=(--colour-tail "$setting")
        json=$out/${name}_${setting}_${level}_$round.json
        /usr/bin/time -f "%e" -o "$out/time.txt" env RNERF_CPU_LEVEL="$level" \
          "$rnerf" eval --model "$model" --data "$dev/$scene" --json "${flags[@]}" > "$json" 2> /dev/null
        fig=$(python3 -c "import json, sys; d = json.load(open(sys.argv[1])); print(d['psnr'], d['mae'])" "$json")
        echo "$level $round $name $setting $(cat "$out/time.txt") s psnr $fig" >> "$out/colour_tail.log"
      done
    done
  done
done
rm -f "$out/time.txt"
