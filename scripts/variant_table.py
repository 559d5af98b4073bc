#!/usr/bin/env python3
"""The table of scripts/residual_variant.sh's runs in OUT (files SCENE_NAME_sSEED.eval.json and
.train.txt): per setting and seed, each scene's object MAE / near-crop RMSE (m) and samples kept /
evaluated per ray at the last step, the three-scene means, and the means over the seeds that
every setting ran; then each run's change against the same scene and seed under BASE (default
"default"). Runs of other directories in the same layout can be added as further arguments;
--names keeps only the settings named (and BASE); --scenes the scenes the means are over
(default glass_up,bottle,wine_flat); --dex DIR adds each setting's ratio to Dex-NeRF's final
object MAE and near-crop RMSE (the last `dex` row of DIR/SCENE_seedS_curves.csv, an `rnerf
compare` curves file) on the scene means, per seed and the mean of the seeds' ratios; with
--dex-views N, Dex-NeRF's N-view runs (DIR/SCENE_viewsN_seedS_curves.csv) instead; with
--dex-name NAME, the runs of setting NAME among the OUTs instead (Dex-NeRF trained by
`scripts/residual_variant.sh` with BG_MODEL `-`), which are then not a setting of the table.
usage: scripts/variant_table.py OUT [OUT2 ...] [--base NAME] [--names NAME,NAME,...]
         [--scenes SCENE,SCENE,...] [--dex DIR [--dex-views N] | --dex-name NAME]"""
import csv
import glob
import json
import os
import re
import sys

from script_args import take

args = sys.argv[1:]
base = take(args, "--base", "default")
only = take(args, "--names", None)
SCENES = tuple(take(args, "--scenes", "glass_up,bottle,wine_flat").split(","))
dex_dir = take(args, "--dex", None)
dex_views = take(args, "--dex-views", None)
dex_tag = f"views{dex_views}_" if dex_views else ""
dex_name = take(args, "--dex-name", None)
runs = {}
for out in args:
    for f in glob.glob(os.path.join(out, "*.eval.json")):
        stem = os.path.basename(f)[: -len(".eval.json")]
        scene = next((s for s in SCENES if stem.startswith(s + "_")), None)
        m = re.fullmatch(r"(.+)_s(\d+)", stem[len(scene) + 1 :]) if scene else None
        if not m:
            continue
        name, seed = m.group(1), int(m.group(2))
        if only is not None and name not in (base, dex_name) and name not in only.split(","):
            continue
        try:
            r = json.load(open(f))["regions"]
        except (ValueError, KeyError):
            continue  # a run still being written, or not an eval JSON
        train = open(f[: -len(".eval.json")] + ".train.txt").read()
        kept = re.findall(r"(\d+)/(\d+) samples/ray", train)
        secs = re.findall(r"samples/ray\s+([\d.]+) s", train)
        runs[(scene, name, seed)] = (
            r["object"]["mae"],
            r["near_crop"]["rmse"],
            kept[-1] if kept else ("?", "?"),
            float(secs[-1]) if secs else float("nan"),
        )

names = sorted({n for (_, n, _) in runs if n != dex_name}, key=lambda n: (n != base, n))
print("| setting, seed | " + " | ".join(SCENES) + " | mean |")
print("|---" * (len(SCENES) + 2) + "|")
for name in names:
    for seed in sorted({s for (_, n, s) in runs if n == name}):
        if not all((sc, name, seed) in runs for sc in SCENES):
            continue
        cells = [runs[(sc, name, seed)] for sc in SCENES]
        row = [f"{o:.4f} / {n:.4f}; {k[0]} / {k[1]}" for o, n, k, _ in cells]
        mean = f"{sum(c[0] for c in cells) / len(SCENES):.4f} / {sum(c[1] for c in cells) / len(SCENES):.4f}"
        print(f"| {name}, seed {seed} | " + " | ".join(row) + f" | {mean} |")
print()
complete = lambda name: {s for (_, n, s) in runs if n == name and all((sc, name, s) in runs for sc in SCENES)}
for name in names:
    seeds = sorted(complete(name) & complete(base))
    if not seeds:
        continue
    o = sum(runs[(sc, name, s)][0] for sc in SCENES for s in seeds) / (len(SCENES) * len(seeds))
    n = sum(runs[(sc, name, s)][1] for sc in SCENES for s in seeds) / (len(SCENES) * len(seeds))
    print(f"{name}: mean over seeds {seeds}: object MAE {o:.4f} m, near-crop RMSE {n:.4f} m")
    if dex_dir or dex_name:
        def dex(scene, seed):
            if dex_name:
                return runs[(scene, dex_name, seed)][:2]
            rows = [r for r in csv.DictReader(open(os.path.join(dex_dir, f"{scene}_{dex_tag}seed{seed}_curves.csv"))) if r["method"] == "dex"]
            return float(rows[-1]["object_mae"]), float(rows[-1]["near_rmse"])
        ratios = []
        for s_ in seeds:
            d = [dex(sc, s_) for sc in SCENES]
            mine = [runs[(sc, name, s_)] for sc in SCENES]
            ratios.append((sum(m[0] for m in mine) / sum(x[0] for x in d), sum(m[1] for m in mine) / sum(x[1] for x in d)))
        per = ", ".join(f"{a:.2f} / {b:.2f}" for a, b in ratios)
        mo, mn = (sum(r[i] for r in ratios) / len(ratios) for i in (0, 1))
        print(f"  / Dex-NeRF (object / near crop): seeds {per}; mean {mo:.3f}x / {mn:.3f}x")
print()
for (scene, name, seed), (o, n, _, t) in sorted(runs.items()):
    b = runs.get((scene, base, seed))
    if name not in (base, dex_name) and b:
        print(f"{scene} {name} seed {seed}: object {o / b[0] - 1:+.1%}, near crop {n / b[1] - 1:+.1%}; {t:.1f} s against {b[3]:.1f} s")
