#!/usr/bin/env python3
"""The default Residual-NeRF's figures over backgrounds trained with different seeds.

usage: scripts/background_spread.py DIR0:NAME0 DIR1:NAME1 DIR2:NAME2
           [--dex DIR] [--dex-v25 DIR] [--dex-evals DIR:NAME] [--paired]

Each DIRb:NAMEb holds `scripts/residual_variant.sh` outputs (SCENE_NAME_sSEED.eval.json and,
for 25 views, SCENE_NAME-v25_sSEED.eval.json) of the default residual over background b.
Prints, for 100 and 25 views, three-scene means of object MAE / near-crop RMSE (m): over each
background at scene seed 0 (the background's effect alone), and with the background's seed and
the scene's seed varied together (background b, scene seed b), each with its ratio to
Dex-NeRF's three-scene means at that scene seed.

Dex-NeRF's figures are the last `dex` row of its `rnerf compare` curves, as
`scripts/variant_table.py --dex` reads them: DIR/SCENE_seedS_curves.csv at 100 views (default
results/time_to_quality, RESULTS.md's Dex-NeRF rows) and DIR/SCENE_views25_rays512_seedS_curves.csv
at 25 (default results/capture_rays/dex_views25). `--dex-evals DIR:NAME` takes them from
`rnerf eval --json` outputs DIR/SCENE_NAME_sS.eval.json instead, and DIR/SCENE_NAME-v25_sS.eval.json
at 25 views (25 views are not printed when the first of those is missing). `--paired` reads only
the runs at the background's own seed (background b, scene seed b), for a default whose
backgrounds and scenes were run together only.
"""
import csv
import json
import os
import sys

SCENES = ["glass_up", "bottle", "wine_flat"]


def take(args, flag, default):
    if flag in args:
        i = args.index(flag)
        value = args[i + 1]
        del args[i:i + 2]
        return value
    return default


def eval_figures(path):
    r = json.load(open(path))["regions"]
    return r["object"]["mae"], r["near_crop"]["rmse"]


def curves_figures(path):
    rows = [r for r in csv.DictReader(open(path)) if r["method"] == "dex"]
    return float(rows[-1]["object_mae"]), float(rows[-1]["near_rmse"])


def mean(per):
    return [sum(p[i] for p in per) / len(per) for i in range(2)]


def main(args):
    dex100 = take(args, "--dex", "results/time_to_quality")
    dex25 = take(args, "--dex-v25", "results/capture_rays/dex_views25")
    dex_evals = take(args, "--dex-evals", None)
    paired_only = "--paired" in args
    args = [a for a in args if a != "--paired"]
    if dex_evals:
        ddir, dname = dex_evals.split(":")
        dex = {"100": lambda sc, s: eval_figures(f"{ddir}/{sc}_{dname}_s{s}.eval.json")}
        if os.path.exists(f"{ddir}/{SCENES[0]}_{dname}-v25_s0.eval.json"):
            dex["25"] = lambda sc, s: eval_figures(f"{ddir}/{sc}_{dname}-v25_s{s}.eval.json")
    else:
        dex = {
            "100": lambda sc, s: curves_figures(f"{dex100}/{sc}_seed{s}_curves.csv"),
            "25": lambda sc, s: curves_figures(f"{dex25}/{sc}_views25_rays512_seed{s}_curves.csv"),
        }
    bgs = [a.split(":") for a in args]
    for views, suffix in (("100", ""), ("25", "-v25")):
        if views not in dex:
            continue
        print(f"## {views} views")
        print("| background | scene seed | glass_up | bottle | wine_flat | mean | / Dex-NeRF |")
        print("|---|---|---|---|---|---|---|")
        fixed, paired = [], []
        for b, (d, name) in enumerate(bgs):
            # Scene seed 0, then the background's own seed (the same run for background 0).
            for seed in [b] if paired_only else sorted({0, b}):
                per = [eval_figures(f"{d}/{sc}_{name}{suffix}_s{seed}.eval.json") for sc in SCENES]
                m = mean(per)
                dm = mean([dex[views](sc, seed) for sc in SCENES])
                ratio = [m[i] / dm[i] for i in range(2)]
                if seed == 0:
                    fixed.append(ratio)
                if seed == b:
                    paired.append(ratio)
                cells = " | ".join(f"{o:.4f} / {n:.4f}" for o, n in per)
                print(f"| {b} | {seed} | {cells} | {m[0]:.4f} / {m[1]:.4f} | {ratio[0]:.2f}× / {ratio[1]:.2f}× |")
                if dex_evals:
                    dex_cells = " | ".join(f"{o:.4f} / {n:.4f}" for o, n in (dex[views](sc, seed) for sc in SCENES))
                    print(f"| Dex-NeRF | {seed} | {dex_cells} | {dm[0]:.4f} / {dm[1]:.4f} | – |")
        for r, label in ((fixed, "scene seed 0, backgrounds 0-2"), (paired, "background seed = scene seed, 0-2")):
            if paired_only and r is fixed:
                continue
            m = mean(r)
            lo = [min(x[i] for x in r) for i in range(2)]
            hi = [max(x[i] for x in r) for i in range(2)]
            print(f"\n{label}: mean of the ratios {m[0]:.2f}× / {m[1]:.2f}× "
                  f"(object {lo[0]:.2f}–{hi[0]:.2f}×, near crop {lo[1]:.2f}–{hi[1]:.2f}×)")
        print()


if __name__ == "__main__":
    main(sys.argv[1:])
