#!/usr/bin/env python3
"""Which pixels the beta penalty on unchanged rays spares, by where they lie: on the object
mask, in the 1-2 px ring around it, 3-8 px out. For each scene's test views 0-9 (those with a
background image at the same pose) the changed pixels are computed as the crate does
(`train::prior::changed_pixels`: 3x3 box filter, max channel difference above the tolerance,
at least 2 changed 8-neighbours) and spared by each rule: the changed pixels dilated by N
(`--beta-margin N`), or closed by a square of radius R with their holes filled, then dilated
by N (`--beta-fill R --beta-margin N`; `train::prior::close_and_fill`).

usage: scripts/spared_share.py DEV_DIR [TOLERANCE]    (needs numpy, scipy, pillow)
"""
import sys
import numpy as np
from PIL import Image
from scipy import ndimage as nd

dev = sys.argv[1]
tol = float(sys.argv[2]) if len(sys.argv) > 2 else 0.03


def load(p):
    return np.asarray(Image.open(p).convert('RGB'), dtype=np.float32) / 255.0


def changed(scene, bg):
    box = lambda a: nd.uniform_filter(a, size=(3, 3, 1), mode='nearest')
    raw = (np.abs(box(scene) - box(bg)) > tol).any(-1)
    neighbours = nd.convolve(raw.astype(int), np.ones((3, 3), int), mode='constant') - raw
    return raw & (neighbours >= 2)


def dilate(m, n):
    return nd.binary_dilation(m, np.ones((2 * n + 1, 2 * n + 1), bool)) if n > 0 else m


def close_fill(m, r):
    if r > 0:
        p = r + 1  # closing as on an image extended by unset pixels
        m = nd.binary_closing(np.pad(m, p), np.ones((2 * r + 1, 2 * r + 1), bool))[p:-p, p:-p] | m
    return nd.binary_fill_holes(m)  # 4-connected holes


rules = [('margin 0', lambda c: c), ('margin 1', lambda c: dilate(c, 1)),
         ('margin 2 (default)', lambda c: dilate(c, 2)), ('fill 0, margin 0', lambda c: close_fill(c, 0)),
         ('fill 2, margin 0', lambda c: close_fill(c, 2)), ('fill 4, margin 0', lambda c: close_fill(c, 4)),
         ('fill 8, margin 0', lambda c: close_fill(c, 8)), ('fill 4, margin 1', lambda c: dilate(close_fill(c, 4), 1)),
         ('fill 4, margin 2', lambda c: dilate(close_fill(c, 4), 2))]
print(f'tolerance {tol}; share of the pixels spared: object mask / 1-2 px ring / 3-8 px out')
for scene in ['glass_up', 'bottle', 'wine_flat']:
    acc = np.zeros((len(rules), 3))
    total = np.zeros(3)
    for i in range(10):
        c = changed(load(f'{dev}/{scene}/test/r_{i}.png'), load(f'{dev}/background/test/r_{i}.png'))
        mask = np.asarray(Image.open(f'{dev}/{scene}/test/r_{i}_mask.png').convert('L')) > 127
        dist = nd.distance_transform_cdt(~mask, metric='chessboard')
        parts = [mask, (dist >= 1) & (dist <= 2), (dist >= 3) & (dist <= 8)]
        total += [p.sum() for p in parts]
        for k, (_, rule) in enumerate(rules):
            s = rule(c)
            acc[k] += [(s & p).sum() for p in parts]
    print(scene)
    for k, (name, _) in enumerate(rules):
        print(f'  {name:20s} ' + ' / '.join(f'{v:.3f}' for v in acc[k] / total))
