#!/usr/bin/env python3
"""Merges `rnerf compare` tables of one seed into one table.json (e.g. Dex-NeRF from a
three-scene run and Residual-NeRF from one run per scene), for scripts/seeds_summary.py.

usage: scripts/merge_tables.py OUT.json RUN [RUN ...]
  RUN  an `rnerf compare --out` folder or its table.json, optionally `RUN:METHOD,METHOD` to
       take only those methods' rows. A (scene, method) row met twice is an error; runs of
       different seeds, steps or rays are refused (runs whose rays each scene's capture chose
       carry `rays_per_step: null` on top and the count on every row).
"""
import json
import sys


def main():
    out, runs = sys.argv[1], sys.argv[2:]
    merged, seen, sources = None, set(), []
    for run in runs:
        run, _, only = run.partition(":")
        only = set(only.split(",")) if only else None
        path = run if run.endswith(".json") else run + "/table.json"
        t = json.load(open(path))
        key = (t["seed"], t["steps"], t["rays_per_step"])
        if merged is None:
            merged = {k: v for k, v in t.items() if k != "rows"}
            merged["rows"], first = [], key
        elif key != first:
            sys.exit(f"{path}: seed/steps/rays {key} differ from {first}")
        for r in t["rows"]:
            if only is not None and r["method"] not in only:
                continue
            k = (r["scene"], r["method"], r.get("threshold"))
            if k in seen:
                sys.exit(f"{path}: row {k} met twice")
            seen.add(k)
            merged["rows"].append(r)
        sources.append({"table": path, "methods": sorted(only) if only else "all", "prior": t.get("prior")})
    merged["merged_from"] = sources
    merged.pop("prior", None)
    json.dump(merged, open(out, "w"), indent=1)


if __name__ == "__main__":
    main()
