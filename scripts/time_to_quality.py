#!/usr/bin/env python3
"""Time to quality from `rnerf compare --eval-every N` curves (curves.csv files).

For each scene: the baseline's final object MAE (default method `dex`), the first curve point
where the method (default `residual`) reaches it, in steps and training seconds, and that as a
share of the baseline's training seconds; then the first point where the method is within 5% of
its own final object MAE.

    scripts/time_to_quality.py CURVES [...] [--method residual] [--baseline dex]
        [--baseline-evals DIR:NAME:SEED]

CURVES is an `rnerf compare` curves.csv, optionally `FILE:METHOD,METHOD` to take only those
methods' rows (e.g. the baseline's curves from an earlier run whose training it still is). A
(scene, method, step) point met twice is an error; a scene without the baseline's curves gets
the method's own columns only. `--baseline-evals DIR:NAME:SEED` takes the baseline's final object
MAE from `scripts/residual_variant.sh` outputs instead (DIR/SCENE_NAME_sSEED.eval.json) and its
training seconds from the run's log beside it (DIR/SCENE_NAME_sSEED.train.txt, the last step's
line), for a baseline trained by `rnerf train` rather than `rnerf compare`.
"""
import csv
import json
import os
import re
import sys


def eval_point(d, name, seed, scene):
    """The baseline's (step, seconds, object MAE) from a residual_variant.sh run, or None."""
    stem = f"{d}/{scene}_{name}_s{seed}"
    if not os.path.exists(f"{stem}.eval.json"):
        return None
    mae = json.load(open(f"{stem}.eval.json"))["regions"]["object"]["mae"]
    steps = [re.match(r"train (\d+)/\d+ .* ([0-9.]+) s ", l) for l in open(f"{stem}.train.txt")]
    step, secs = [(int(m.group(1)), float(m.group(2))) for m in steps if m][-1]
    return step, secs, mae


def main(argv):
    method, baseline, files, evals = "residual", "dex", [], None
    it = iter(argv)
    for a in it:
        if a == "--method":
            method = next(it)
        elif a == "--baseline":
            baseline = next(it)
        elif a == "--baseline-evals":
            evals = next(it).split(":")
        else:
            files.append(a)
    if not files:
        sys.exit(__doc__)
    rows, seen = [], set()
    for f in files:
        f, _, only = f.partition(":")
        only = set(only.split(",")) if only else None
        with open(f, newline="") as fh:
            for r in csv.DictReader(fh):
                if only is not None and r["method"] not in only:
                    continue
                key = (r["scene"], r["method"], r["step"])
                if key in seen:
                    sys.exit(f"{f}: point {key} met twice")
                seen.add(key)
                rows.append(r)
    scenes = sorted({r["scene"] for r in rows}, key=[r["scene"] for r in rows].index)
    print(f"| scene | {baseline} final object MAE (m), its seconds | {method} reaches it at step (s), share of {baseline}'s seconds | {method} final object MAE (m) | within 5% of it at step (s) |")
    print("|---|---|---|---|---|")
    for s in scenes:
        curve = lambda m: sorted(
            ((int(r["step"]), float(r["seconds"]), float(r["object_mae"])) for r in rows if r["scene"] == s and r["method"] == m)
        )
        b, m = curve(baseline), curve(method)
        if evals:
            point = eval_point(*evals, s)
            b = [point] if point else []
        if not m:
            print(f"| {s} | missing curves for {method} |")
            continue
        m_final = m[-1][2]
        near = next(((st, sec) for st, sec, mae in m if mae <= 1.05 * m_final), None)
        if b:
            b_final, b_secs = b[-1][2], b[-1][1]
            reach = next(((st, sec) for st, sec, mae in m if mae <= b_final), None)
            reach_text = f"{reach[0]} ({reach[1]:.1f} s), {reach[1] / b_secs:.2f}×" if reach else "never"
            base_text = f"{b_final:.4f}, {b_secs:.1f} s"
        else:
            base_text, reach_text = f"no {baseline} curves", "–"
        print(f"| {s} | {base_text} | {reach_text} | {m_final:.4f} | {near[0]} ({near[1]:.1f} s) |")


if __name__ == "__main__":
    main(sys.argv[1:])
