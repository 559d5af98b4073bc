#!/usr/bin/env python3
"""The table of scripts/frozen_coarse.sh's runs in OUT: per coarse setting and seed, each scene's
object MAE / near-crop RMSE (m) and samples kept / evaluated per ray at step 1000, and the
three-scene means; then each run's change against the same scene and seed with the part off.
usage: scripts/frozen_coarse_table.py OUT"""
import glob
import json
import os
import re
import sys

out = sys.argv[1]
SCENES = ("glass_up", "bottle", "wine_flat")
runs = {}
for f in glob.glob(os.path.join(out, "*.eval.json")):
    m = re.fullmatch(r"(.+)_c(.+)_s(\d+)\.eval\.json", os.path.basename(f))
    scene, coarse, seed = m.group(1), m.group(2), int(m.group(3))
    r = json.load(open(f))["regions"]
    train = open(f[: -len(".eval.json")] + ".train.txt").read()
    kept, marched = re.findall(r"(\d+)/(\d+) samples/ray", train)[-1]
    runs[(scene, coarse, seed)] = (r["object"]["mae"], r["near_crop"]["rmse"], kept, marched)

print("| coarse part, seed | " + " | ".join(SCENES) + " | mean |")
print("|---" * (len(SCENES) + 2) + "|")
for coarse, seed in sorted({(c, s) for (_, c, s) in runs}, key=lambda k: (k[0] != "off", k)):
    if not all((sc, coarse, seed) in runs for sc in SCENES):
        continue
    cells = [runs[(sc, coarse, seed)] for sc in SCENES]
    row = [f"{o:.4f} / {n:.4f}; {k} / {m}" for o, n, k, m in cells]
    mean = f"{sum(c[0] for c in cells) / 3:.4f} / {sum(c[1] for c in cells) / 3:.4f}"
    print(f"| {coarse.replace('x', ',')}, seed {seed} | " + " | ".join(row) + f" | {mean} |")
print()
for (scene, coarse, seed), (o, n, _, _) in sorted(runs.items()):
    base = runs.get((scene, "off", seed))
    if coarse != "off" and base:
        print(f"{scene} {coarse.replace('x', ',')} seed {seed}: object {o / base[0] - 1:+.1%}, near crop {n / base[1] - 1:+.1%}")
