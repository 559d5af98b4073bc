#!/usr/bin/env bash
# The scene phase from the command line under a wall-time budget: `rnerf train --budget S`
# (loading and the background prior included) on each dev scene, each model scored by
# `rnerf eval --depth-only` (object MAE, near-crop RMSE), beside Dex-NeRF's finished models.
#
#   [SEEDS="0 1 2"] [RAYS="capture 512"] [VIEWS=25] scripts/train_budget.sh RNERF DEV BG_MODEL OUT "BUDGETS" [DEX_DIR]
#
# RNERF: the rnerf binary; DEV: the dev set (its background/ and scenes); BG_MODEL: the trained
# background; OUT: where models, evaluations and table.md go; BUDGETS: seconds, space separated
# ("15 30"); DEX_DIR: holds dex_SCENE.safetensors (Dex-NeRF's finished seed-0 models), scored
# alongside. SEEDS: the training seeds (default 0); RAYS: rays per step, "capture" for the
# command line's own count (default); VIEWS: train on that many evenly spaced scene views
# (`--scene-views`; default all). Runs at $RNERF_CPU_LEVEL (set it, e.g. avx2), one job at a
# time. table.md: per budget and rays, each seed's three-scene means and their mean.
set -euo pipefail
RNERF=$1 DEV=$2 BG=$3 OUT=$4 BUDGETS=$5 DEX=${6:-}
SCENES=${SCENES:-glass_up bottle wine_flat}
SEEDS=${SEEDS:-0}
RAYS=${RAYS:-capture}
VIEWS=${VIEWS:-}
mkdir -p "$OUT"
row() { # model scene label seed
  "$RNERF" eval --model "$1" --data "$DEV/$2" --json --depth-only > "$OUT/$3_$2_s$4.json" 2> /dev/null
  python3 - "$OUT/$3_$2_s$4.json" "$1" "$3" "$2" "$4" >> "$OUT/rows.tsv" <<'PY'
import json, sys, struct
d = json.load(open(sys.argv[1]))["regions"]
raw = open(sys.argv[2], "rb").read()
n = struct.unpack("<Q", raw[:8])[0]
meta = json.loads(raw[8:8 + n]).get("__metadata__", {})
steps = meta.get("train_stopped", "after step %s of %s" % (meta["train_steps"], meta["train_steps"])).split()[2]
print("\t".join([sys.argv[3], sys.argv[5], sys.argv[4], steps, meta["train_rays_per_step"],
                 "%.4f" % d["object"]["mae"], "%.4f" % d["near_crop"]["rmse"]]))
PY
}
: > "$OUT/rows.tsv"
for b in $BUDGETS; do
  for r in $RAYS; do
    for seed in $SEEDS; do
      for s in $SCENES; do
        m="$OUT/res_${s}_b${b}_r${r}_s$seed.safetensors"
        opts=(); [ "$r" = capture ] || opts=(--rays "$r")
        [ -z "$VIEWS" ] || opts+=(--scene-views "$VIEWS")
        "$RNERF" train --data "$DEV/$s" --background "$BG" --background-data "$DEV/background" --seed "$seed" \
          --budget "$b" "${opts[@]}" --out "$m" 2> "$OUT/train_${s}_b${b}_r${r}_s$seed.log"
        row "$m" "$s" "b${b}_r$r" "$seed"
      done
    done
  done
done
if [ -n "$DEX" ]; then
  for s in $SCENES; do row "$DEX/dex_$s.safetensors" "$s" dex 0; done
fi
python3 - "$OUT" <<'PY'
import sys, collections
out = sys.argv[1]
rows = [l.rstrip("\n").split("\t") for l in open(out + "/rows.tsv")]
runs = collections.OrderedDict()
for label, seed, scene, steps, rays, mae, rmse in rows:
    runs.setdefault(label, collections.OrderedDict()).setdefault(seed, []).append((scene, int(steps), rays, float(mae), float(rmse)))
def mean(v):
    return sum(v) / len(v)
dex = runs.get("dex", {}).get("0")
dm = (mean([r[3] for r in dex]), mean([r[4] for r in dex])) if dex else None
lines = ["| budget, rays | seed: steps (per scene), mean object MAE / near-crop RMSE (m) | over the seeds | / Dex-NeRF's seed-0 final |",
         "|---|---|---|---|"]
for label, seeds in runs.items():
    cells, means = [], []
    for seed, rs in seeds.items():
        m = (mean([r[3] for r in rs]), mean([r[4] for r in rs]))
        means.append(m)
        cells.append(f"{seed}: {', '.join(str(r[1]) for r in rs)}, {m[0]:.4f} / {m[1]:.4f}")
    all_m = (mean([m[0] for m in means]), mean([m[1] for m in means]))
    rays = "/".join(sorted({r[2] for rs in seeds.values() for r in rs}))
    name = "Dex-NeRF, finished" if label == "dex" else f"{label.split('_')[0][1:]} s, {rays}"
    ratio = f"{all_m[0] / dm[0]:.2f}x / {all_m[1] / dm[1]:.2f}x" if dm else "-"
    lines.append(f"| {name} | {'; '.join(cells)} | {all_m[0]:.4f} / {all_m[1]:.4f} | {ratio} |")
open(out + "/table.md", "w").write("\n".join(lines) + "\n")
print("\n".join(lines))
PY
