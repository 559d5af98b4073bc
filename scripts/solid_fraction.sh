#!/usr/bin/env bash
# Depth error against the ground truth of what the onboard renderer returns, by solid
# fraction (`DepthRenderer::solid_fraction`; `rnerf eval --depth-only --solid-fraction F`)
# and, when COARSE is set, by coarse start (`DepthRenderer::coarse_start`; `--coarse-start
# N|off`): one JSON per model and setting, then a table (the frames' crop MAE and RMSE, object
# MAE, near-crop RMSE, crop-without-object MAE, hole rate; "–" where a split has no object masks).
# usage: scripts/solid_fraction.sh OUT_DIR [MODEL:DATA_DIR ...]
#   (no MODEL:DATA_DIR pairs: only the table of the JSONs already in OUT_DIR)
#   FRACTIONS  space-separated (default "0 0.25 0.5 0.75 1")
#   COARSE     space-separated coarse starts, e.g. "off 1 2 4" (default: the flag left out,
#              every ray from the box; the JSONs then carry no _c suffix)
set -euo pipefail
out=$1; shift
bin=${RNERF_BIN:-./target/release/rnerf}
mkdir -p "$out"
for pair in "$@"; do
  model=${pair%%:*} data=${pair#*:}
  name=$(basename "$model" .safetensors)
  for f in ${FRACTIONS:-0 0.25 0.5 0.75 1}; do
    for c in ${COARSE:--}; do
      if [ "$c" = - ]; then start=() suffix=; else start=(--coarse-start "$c") suffix=_c$c; fi
      RNERF_CPU_LEVEL=${RNERF_CPU_LEVEL:-avx2} $bin eval --model "$model" --data "$data" --json \
        --depth-only --solid-fraction "$f" "${start[@]}" > "$out/${name}_f$f$suffix.json" 2>/dev/null
    done
  done
done
python3 - "$out" <<'PY'
import json, sys, glob, os
rows = []
for p in sorted(glob.glob(os.path.join(sys.argv[1], "*_f*.json"))):
    d = json.load(open(p)); r = d["regions"]
    name, f = os.path.basename(p)[:-5].rsplit("_f", 1)
    f, c = (f.split("_c") + ["off"])[:2]
    get = lambda region, k: (r.get(region) or {}).get(k)
    rows.append((name, float(f), c, d["mae"], d["rmse"], get("object", "mae"), get("near_crop", "rmse"),
                 get("crop_without_object", "mae"), d["hole_rate"]))
print("| model | solid fraction | coarse start | crop MAE | crop RMSE | object MAE | near-crop RMSE | crop w/o object MAE | hole rate |")
print("|---|---|---|---|---|---|---|---|---|")
cell = lambda x: "–" if x is None else f"{x:.4f}"
for n, f, s, m, e, a, b, c, h in sorted(rows, key=lambda r: (r[0], r[1], r[2] != "off", r[2].zfill(3))):
    print(f"| {n} | {f:g} | {s} | {cell(m)} | {cell(e)} | {cell(a)} | {cell(b)} | {cell(c)} | {100*h:.2f}% |")
PY
