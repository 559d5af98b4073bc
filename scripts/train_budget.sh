#!/usr/bin/env bash
# The scene phase from the command line under a wall-time budget: `rnerf train --budget S`
# (loading and the background prior included) on each dev scene, each model scored by
# `rnerf eval --depth-only` (object MAE, near-crop RMSE), beside Dex-NeRF's finished models.
#
#   scripts/train_budget.sh RNERF DEV BG_MODEL OUT "BUDGETS" [DEX_DIR]
#
# RNERF: the rnerf binary; DEV: the dev set (its background/ and scenes); BG_MODEL: the trained
# background; OUT: where models, evaluations and table.md go; BUDGETS: seconds, space separated
# ("15 30"); DEX_DIR: holds dex_SCENE.safetensors (Dex-NeRF's finished seed-0 models), scored
# alongside. Runs at $RNERF_CPU_LEVEL (set it, e.g. avx2), seed 0, one job at a time.
set -euo pipefail
RNERF=$1 DEV=$2 BG=$3 OUT=$4 BUDGETS=$5 DEX=${6:-}
SCENES=${SCENES:-glass_up bottle wine_flat}
mkdir -p "$OUT"
row() { # model scene label
  "$RNERF" eval --model "$1" --data "$DEV/$2" --json --depth-only > "$OUT/$3_$2.json" 2> /dev/null
  python3 - "$OUT/$3_$2.json" "$1" "$3" "$2" >> "$OUT/rows.tsv" <<'PY'
import json, sys, struct
d = json.load(open(sys.argv[1]))["regions"]
raw = open(sys.argv[2], "rb").read()
n = struct.unpack("<Q", raw[:8])[0]
meta = json.loads(raw[8:8 + n]).get("__metadata__", {})
stopped = meta.get("train_stopped", "finished")
print("\t".join([sys.argv[3], sys.argv[4], stopped, meta.get("train_seconds", "?"),
                 "%.4f" % d["object"]["mae"], "%.4f" % d["near_crop"]["rmse"]]))
PY
}
: > "$OUT/rows.tsv"
for b in $BUDGETS; do
  for s in $SCENES; do
    m="$OUT/res_${s}_$b.safetensors"
    /usr/bin/time -f "%e" -o "$OUT/wall_${s}_$b.txt" "$RNERF" train --data "$DEV/$s" --background "$BG" \
      --background-data "$DEV/background" --seed 0 --budget "$b" --out "$m" 2> "$OUT/train_${s}_$b.log"
    row "$m" "$s" "budget_$b"
  done
done
if [ -n "$DEX" ]; then
  for s in $SCENES; do row "$DEX/dex_$s.safetensors" "$s" dex; done
fi
python3 - "$OUT" $BUDGETS <<'PY'
import sys, collections
out = sys.argv[1]
rows = [l.rstrip("\n").split("\t") for l in open(out + "/rows.tsv")]
by = collections.OrderedDict()
for label, scene, stopped, secs, mae, rmse in rows:
    by.setdefault(label, []).append((scene, stopped, secs, float(mae), float(rmse)))
dex = by.get("dex")
dm = (sum(r[3] for r in dex) / len(dex), sum(r[4] for r in dex) / len(dex)) if dex else None
lines = ["| run | scene: stopped, training s, object MAE / near-crop RMSE (m) | mean | / Dex-NeRF's |", "|---|---|---|---|"]
for label, rs in by.items():
    mae = sum(r[3] for r in rs) / len(rs); rmse = sum(r[4] for r in rs) / len(rs)
    wall = ""
    if label.startswith("budget_"):
        b = label[7:]
        wall = " (wall " + ", ".join(open(f"{out}/wall_{r[0]}_{b}.txt").read().split()[-1] + " s" for r in rs) + ")"
    cells = "; ".join(f"{r[0]}: {r[1]}, {r[2]} s, {r[3]:.4f} / {r[4]:.4f}" for r in rs)
    ratio = f"{mae / dm[0]:.2f}x / {rmse / dm[1]:.2f}x" if dm else "-"
    lines.append(f"| {label}{wall} | {cells} | {mae:.4f} / {rmse:.4f} | {ratio} |")
open(out + "/table.md", "w").write("\n".join(lines) + "\n")
print("\n".join(lines))
PY
