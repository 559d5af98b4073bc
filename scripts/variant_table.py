#!/usr/bin/env python3
"""The table of scripts/residual_variant.sh's runs in OUT (files SCENE_NAME_sSEED.eval.json and
.train.txt): per setting and seed, each scene's object MAE / near-crop RMSE (m) and samples kept /
evaluated per ray at the last step, the three-scene means, and the means over the seeds that
every setting ran; then each run's change against the same scene and seed under BASE (default
"default"). Runs of other directories in the same layout can be added as further arguments;
--names keeps only the settings named (and BASE).
usage: scripts/variant_table.py OUT [OUT2 ...] [--base NAME] [--names NAME,NAME,...]"""
import glob
import json
import os
import re
import sys

args = sys.argv[1:]
def option(flag, default):
    if flag not in args:
        return default
    i = args.index(flag)
    value = args[i + 1]
    del args[i : i + 2]
    return value


base = option("--base", "default")
only = option("--names", None)
SCENES = ("glass_up", "bottle", "wine_flat")
runs = {}
for out in args:
    for f in glob.glob(os.path.join(out, "*.eval.json")):
        stem = os.path.basename(f)[: -len(".eval.json")]
        scene = next((s for s in SCENES if stem.startswith(s + "_")), None)
        m = re.fullmatch(r"(.+)_s(\d+)", stem[len(scene) + 1 :]) if scene else None
        if not m:
            continue
        name, seed = m.group(1), int(m.group(2))
        if only is not None and name != base and name not in only.split(","):
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

names = sorted({n for (_, n, _) in runs}, key=lambda n: (n != base, n))
print("| setting, seed | " + " | ".join(SCENES) + " | mean |")
print("|---" * (len(SCENES) + 2) + "|")
for name in names:
    for seed in sorted({s for (_, n, s) in runs if n == name}):
        if not all((sc, name, seed) in runs for sc in SCENES):
            continue
        cells = [runs[(sc, name, seed)] for sc in SCENES]
        row = [f"{o:.4f} / {n:.4f}; {k[0]} / {k[1]}" for o, n, k, _ in cells]
        mean = f"{sum(c[0] for c in cells) / 3:.4f} / {sum(c[1] for c in cells) / 3:.4f}"
        print(f"| {name}, seed {seed} | " + " | ".join(row) + f" | {mean} |")
print()
complete = lambda name: {s for (_, n, s) in runs if n == name and all((sc, name, s) in runs for sc in SCENES)}
for name in names:
    seeds = sorted(complete(name) & complete(base))
    if not seeds:
        continue
    o = sum(runs[(sc, name, s)][0] for sc in SCENES for s in seeds) / (3 * len(seeds))
    n = sum(runs[(sc, name, s)][1] for sc in SCENES for s in seeds) / (3 * len(seeds))
    print(f"{name}: mean over seeds {seeds}: object MAE {o:.4f} m, near-crop RMSE {n:.4f} m")
print()
for (scene, name, seed), (o, n, _, t) in sorted(runs.items()):
    b = runs.get((scene, base, seed))
    if name != base and b:
        print(f"{scene} {name} seed {seed}: object {o / b[0] - 1:+.1%}, near crop {n / b[1] - 1:+.1%}; {t:.1f} s against {b[3]:.1f} s")
