#!/usr/bin/env python3
"""The default Residual-NeRF's figures over backgrounds trained with different seeds.

usage: scripts/background_spread.py DIR0:NAME0 DIR1:NAME1 DIR2:NAME2 [--dex DEX_MEANS]

Each DIRb:NAMEb holds `scripts/residual_variant.sh` outputs (SCENE_NAME_sSEED.eval.json and,
for 25 views, SCENE_NAME-v25_sSEED.eval.json) of the default residual over background b.
Prints, for 100 and 25 views, three-scene means of object MAE / near-crop RMSE (m): over each
background at scene seed 0 (the background's effect alone), and with the background's seed and
the scene's seed varied together (background b, scene seed b), each with its ratio to
Dex-NeRF's three-scene means at that scene seed (DEX_MEANS: the JSON file
{"100": [[obj, near] per seed], "25": [...]}; the default is RESULTS.md's Dex-NeRF rows).
"""
import json
import sys

SCENES = ["glass_up", "bottle", "wine_flat"]
DEX = {  # RESULTS.md, "The default ...": Dex-NeRF's three-scene means, seeds 0, 1, 2
    "100": [[0.0237, 0.0695], [0.0327, 0.0823], [0.0232, 0.0675]],
    "25": [[0.0661, 0.1255], [0.0717, 0.1385], [0.1559, 0.2495]],
}


def figures(d, name, seed):
    per = []
    for s in SCENES:
        r = json.load(open(f"{d}/{s}_{name}_s{seed}.eval.json"))["regions"]
        per.append((r["object"]["mae"], r["near_crop"]["rmse"]))
    mean = [sum(p[i] for p in per) / len(per) for i in range(2)]
    return per, mean


def main(argv):
    dex = DEX
    if "--dex" in argv:
        i = argv.index("--dex")
        dex = json.load(open(argv[i + 1]))
        argv = argv[:i] + argv[i + 2:]
    bgs = [a.split(":") for a in argv]
    for views, suffix in (("100", ""), ("25", "-v25")):
        print(f"## {views} views")
        print("| background | scene seed | glass_up | bottle | wine_flat | mean | / Dex-NeRF |")
        print("|---|---|---|---|---|---|---|")
        rows = {"fixed": [], "paired": []}
        for b, (d, name) in enumerate(bgs):
            for seed, kind in ((0, "fixed"), (b, "paired")):
                if kind == "paired" and b == 0:
                    continue  # the same run as the fixed one
                per, mean = figures(d, name + suffix, seed)
                ratio = [mean[i] / dex[views][seed][i] for i in range(2)]
                rows[kind].append(ratio)
                if b == 0:
                    rows["paired"].append(ratio)
                cells = " | ".join(f"{o:.4f} / {n:.4f}" for o, n in per)
                print(f"| {b} | {seed} | {cells} | {mean[0]:.4f} / {mean[1]:.4f} | {ratio[0]:.2f}× / {ratio[1]:.2f}× |")
        for kind, label in (("fixed", "scene seed 0, backgrounds 0-2"), ("paired", "background seed = scene seed, 0-2")):
            r = rows[kind]
            m = [sum(x[i] for x in r) / len(r) for i in range(2)]
            lo = [min(x[i] for x in r) for i in range(2)]
            hi = [max(x[i] for x in r) for i in range(2)]
            print(f"\n{label}: mean of the ratios {m[0]:.2f}× / {m[1]:.2f}× "
                  f"(object {lo[0]:.2f}–{hi[0]:.2f}×, near crop {lo[1]:.2f}–{hi[1]:.2f}×)")
        print()


if __name__ == "__main__":
    main(sys.argv[1:])
