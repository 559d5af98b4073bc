#!/usr/bin/env python3
"""How far a capture's viewing axes pass the least-squares point nearest to them, as a share of
the cameras' median distance to it: the quantity `geometry::camera::capture_focus` compares
with `FOCUS_SPREAD` (0.1) before it takes that point as the one the cameras look at.

Prints it for each transforms json given, and for synthesised captures: a 7x7 grid of cameras
5 cm apart (30 cm across) that all look ahead, each tilted at random (normal, the given
standard deviation in degrees); and the same grid aimed at one point 0.6 m ahead with aim errors
of that size.

usage: scripts/focus_spread.py [TRANSFORMS_JSON...]   (needs numpy)
"""
import json
import sys

import numpy as np


def spread(centres, dirs):
    """The least-squares point, its root-mean-square distance from the axes over the median
    distance of the cameras to it, and that median distance."""
    a, b = np.zeros((3, 3)), np.zeros(3)
    for c, d in zip(centres, dirs):
        m = np.eye(3) - np.outer(d, d)
        a += m
        b += m @ c
    f = np.linalg.solve(a, b)
    miss = np.sqrt(np.mean([np.sum(((np.eye(3) - np.outer(d, d)) @ (f - c)) ** 2) for c, d in zip(centres, dirs)]))
    dist = np.median([np.linalg.norm(f - c) for c in centres])
    return f, miss / dist, dist


def unit(v):
    return v / np.linalg.norm(v)


def main():
    for path in sys.argv[1:]:
        frames = json.load(open(path))["frames"]
        m = [np.array(f["transform_matrix"], dtype=float) for f in frames]
        f, ratio, dist = spread([x[:3, 3] for x in m], [unit(-x[:3, 2]) for x in m])
        print(f"{path}: point {np.round(f, 3)}, median distance {dist:.3f}, axes pass it at {ratio:.3f} of it")
    rng = np.random.default_rng(1)
    grid = [np.array([i * 0.05, j * 0.05, 0.0]) for i in range(7) for j in range(7)]
    target = np.array([0.15, 0.15, -0.6])
    for deg in (1, 2, 3):
        dirs = [unit(np.array([*np.sin(np.radians(deg) * rng.standard_normal(2)), -1.0])) for _ in grid]
        f, ratio, dist = spread(grid, dirs)
        print(f"forward-facing grid tilted by {deg} deg: point {dist:.2f} away, axes pass it at {ratio:.3f}")
    for deg in (0.5, 2):
        dirs = [unit(unit(target - c) + np.radians(deg) * rng.standard_normal(3)) for c in grid]
        f, ratio, dist = spread(grid, dirs)
        print(f"grid aimed 0.6 m ahead, {deg} deg of aim error: point {dist:.2f} away, axes pass it at {ratio:.3f}")


if __name__ == "__main__":
    main()
