#!/usr/bin/env python3
"""A method trained another way against its default runs, and residual runs against the variant.

Reads:
- the variant's `rnerf eval --json --depth-only` outputs, VARIANT_DIR/SCENE_NAME_sSEED.eval.json;
- the default's runs: the METHOD row (default `dex`) of the `rnerf compare` tables in
  DEFAULT_DIR, named by PATTERN (default `{scene}_seed{seed}.json`);
- optionally residual runs of scripts/residual_variant.sh, RUN_DIR/SCENE_RUN_sSEED.eval.json.

For every seed that has the variant and the default on all three scenes it prints:
- both three-scene means of object MAE / near-crop RMSE (m);
- each scene's change;
- each residual setting's means and its ratios to the variant.
The last lines give the mean of the seeds' ratios.

usage: scripts/variant_vs_compare.py VARIANT_DIR NAME DEFAULT_DIR [--method METHOD]
         [--pattern PATTERN] [RUN_DIR:RUN ...]"""
import json
import os
import sys

from script_args import take

args = sys.argv[1:]
method = take(args, "--method", "dex")
pattern = take(args, "--pattern", "{scene}_seed{seed}.json")
if len(args) < 3:
    sys.exit(__doc__)
variant_dir, name, default_dir = args[:3]
runs = [a.split(":") for a in args[3:]]
SCENES = ("glass_up", "bottle", "wine_flat")


def figures(regions):
    return regions["object"]["mae"], regions["near_crop"]["rmse"]


def eval_json(directory, run, scene, seed):
    f = os.path.join(directory, f"{scene}_{run}_s{seed}.eval.json")
    return figures(json.load(open(f))["regions"]) if os.path.exists(f) else None


def default(scene, seed):
    f = os.path.join(default_dir, pattern.format(scene=scene, seed=seed))
    if not os.path.exists(f):
        return None
    rows = [r for r in json.load(open(f))["rows"] if r["method"] == method]
    return figures(rows[0]) if rows else None


def mean(xs):
    return tuple(sum(x[i] for x in xs) / len(xs) for i in range(2))


ratios = {run: [] for _, run in runs}
stems = [f[: -len(".eval.json")] for f in os.listdir(variant_dir) if f.endswith(".eval.json")]
seeds = sorted({int(st.rsplit("_s", 1)[1]) for st in stems if st.rsplit("_s", 1)[0].endswith(f"_{name}")})
for seed in seeds:
    v = [eval_json(variant_dir, name, s, seed) for s in SCENES]
    d = [default(s, seed) for s in SCENES]
    if None in v or None in d:
        continue
    vm, dm = mean(v), mean(d)
    print(f"seed {seed}: {method} default {dm[0]:.4f} / {dm[1]:.4f}, {name} {vm[0]:.4f} / {vm[1]:.4f}")
    for s, a, b in zip(SCENES, v, d):
        print(f"  {s}: {a[0]:.4f} / {a[1]:.4f} against {b[0]:.4f} / {b[1]:.4f}: "
              f"object {100 * (a[0] / b[0] - 1):+.1f}%, near crop {100 * (a[1] / b[1] - 1):+.1f}%")
    for run_dir, run in runs:
        r = [eval_json(run_dir, run, s, seed) for s in SCENES]
        if None in r:
            continue
        rm = mean(r)
        ratios[run].append((rm[0] / vm[0], rm[1] / vm[1]))
        print(f"  {run}: {rm[0]:.4f} / {rm[1]:.4f}, / {name}: {rm[0] / vm[0]:.2f}x / {rm[1] / vm[1]:.2f}x")
for run, rs in ratios.items():
    if rs:
        m = mean(rs)
        print(f"{run}: mean of the seeds' ratios to {name}: {m[0]:.2f}x / {m[1]:.2f}x over {len(rs)} seeds")
