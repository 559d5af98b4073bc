#!/usr/bin/env python3
"""Mean and spread over seeds of `rnerf compare` runs (RESULTS.md's seed tables).

usage: scripts/seeds_summary.py RUN [RUN ...]
  RUN  an `rnerf compare --out` folder or its table.json, one per seed, same scenes and
       methods (scripts/dev_compare.sh writes OUT/views<N>; results/ keeps the tables)

Prints a markdown table: per method, the mean over the scenes of each figure, as the mean over
the runs with the smallest and largest run in brackets; and, per method other than Dex-NeRF,
its ratio to Dex-NeRF per run (of the scene means: object MAE, near-crop RMSE; and per scene)
when the runs have Dex-NeRF.
Only the final rows are read (not the --m-sweep rows); methods are those every run has.
"""
import json
import statistics
import sys

FIGURES = [
    ("object MAE (m)", "object", "mae", 4),
    ("object RMSE (m)", "object", "rmse", 4),
    ("see-through", "object", "see_through", None),
    ("floaters", "object", "floaters", None),
    ("near-crop RMSE (m)", "near_crop", "rmse", 4),
    ("crop w/o object MAE (m)", "crop_without_object", "mae", 4),
]


def rows(path):
    t = json.load(open(path if path.endswith(".json") else path + "/table.json"))
    # The sweep's rows carry their threshold; the final rows do not.
    return {(r["scene"], r["method"]): r for r in t["rows"] if "threshold" not in r}


def fmt(values, digits):
    m, lo, hi = statistics.mean(values), min(values), max(values)
    if digits is None:
        return f"{100 * m:.1f}% [{100 * lo:.1f}–{100 * hi:.1f}]"
    return f"{m:.{digits}f} [{lo:.{digits}f}–{hi:.{digits}f}]"


def main():
    runs = [rows(p) for p in sys.argv[1:]]
    scenes = sorted({s for s, _ in runs[0]})
    methods = [m for m in dict.fromkeys(m for _, m in runs[0]) if all((scenes[0], m) in r for r in runs)]
    print(f"{len(runs)} runs, scenes {', '.join(scenes)}\n")
    print("| method | " + " | ".join(f[0] for f in FIGURES) + " |")
    print("|---|" + "---|" * len(FIGURES))
    for m in methods:
        cells = []
        for _, region, key, digits in FIGURES:
            per_run = [statistics.mean(r[(s, m)][region][key] for s in scenes) for r in runs]
            cells.append(fmt(per_run, digits))
        print(f"| {m} | " + " | ".join(cells) + " |")
    print()
    for m in methods:
        # The ratios need Dex-NeRF's rows (runs of one method alone have none).
        if m == "dex" or "dex" not in methods:
            continue
        for label, region, key in [("object MAE", "object", "mae"), ("near-crop RMSE", "near_crop", "rmse")]:
            # The ratio of the scene means (the compare table's "mean over scenes" ratio).
            ratios = [
                statistics.mean(r[(s, m)][region][key] for s in scenes)
                / statistics.mean(r[(s, "dex")][region][key] for s in scenes)
                for r in runs
            ]
            print(f"{m} / dex, {label} (ratio of the scene means): {fmt(ratios, 2)} (per run: {', '.join(f'{x:.2f}' for x in ratios)})")
        per_scene = {
            s: [r[(s, m)]["object"]["mae"] / r[(s, "dex")]["object"]["mae"] for r in runs] for s in scenes
        }
        print(f"{m} / dex, object MAE per scene: " + ", ".join(f"{s} {fmt(v, 2)}" for s, v in per_scene.items()))


if __name__ == "__main__":
    main()
