#!/usr/bin/env python3
"""A capture at half the resolution, for measuring the methods where a glass spans half as many
pixels (a camera of fewer pixels, or the glass twice as far).

Each image becomes its 2x-smaller version: lo-res pixel (i, j) averages the hi-res pixels around
hi-res pixel (2i+1, 2j+1) with a tent filter (weights 1/4, 1/2, 1/4 along each axis, in linear
light, edges clamped), a footprint one lo-res pixel wide centred on that hi-res pixel's centre.
The intrinsics are halved and the principal point moved by -1/4 lo-res pixel (cx' = cx/2 - 1/4),
so lo-res pixel (i, j)'s centre ray IS hi-res pixel (2i+1, 2j+1)'s centre ray: the ground truth
(planar depth, object mask: first hits at pixel centres) is taken from that hi-res pixel and is
exact. Each test frame's crop is recomputed from its new mask by the dev set's rule (the mask's
bounding box grown by ceil(10% of its larger side) on each side, clamped; the full image when
the mask is empty). Poses, scene box and everything else in the jsons are kept.

usage: scripts/downscale_capture.py SRC_DIR DST_DIR [SCENE...]
       (default scenes: background glass_up bottle wine_flat; needs numpy, pillow, OpenEXR)
"""
import json
import math
import os
import sys

import numpy as np
import OpenEXR
from PIL import Image


def srgb_to_linear(c):
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(c):
    c = np.clip(c, 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * c ** (1 / 2.4) - 0.055)


def tent_half(a):
    """2x downscale along axes 0 and 1: out[i] = a[2i]/4 + a[2i+1]/2 + a[2i+2]/4 (clamped)."""
    for axis in (0, 1):
        n = a.shape[axis] // 2
        idx = np.arange(n)
        take = lambda k: np.take(a, np.minimum(k, a.shape[axis] - 1), axis=axis)
        a = 0.25 * take(2 * idx) + 0.5 * take(2 * idx + 1) + 0.25 * take(2 * idx + 2)
    return a


def centre_samples(a):
    """Hi-res pixel (2i+1, 2j+1) of every lo-res pixel."""
    return a[1::2, 1::2]


def read_depth(path):
    with OpenEXR.File(path) as f:
        ch = f.channels()
        return np.asarray(ch['Y'].pixels, dtype=np.float32)


def write_depth(path, z):
    header = {'compression': OpenEXR.ZIP_COMPRESSION, 'type': OpenEXR.scanlineimage}
    OpenEXR.File(header, {'Y': np.ascontiguousarray(z, dtype=np.float32)}).write(path)


def crop_of(mask):
    h, w = mask.shape
    ys, xs = np.nonzero(mask)
    if len(xs) == 0:
        return [0, 0, w, h]
    x0, x1, y0, y1 = xs.min(), xs.max() + 1, ys.min(), ys.max() + 1
    g = math.ceil(0.1 * max(x1 - x0, y1 - y0))
    return [int(max(0, x0 - g)), int(max(0, y0 - g)), int(min(w, x1 + g)), int(min(h, y1 + g))]


def convert(src, dst, scene, split):
    path = os.path.join(src, scene, f'transforms_{split}.json')
    if not os.path.exists(path):
        return
    d = json.load(open(path))
    for key in ('fl_x', 'fl_y'):
        if key in d:
            d[key] = d[key] / 2
    for key, size in (('cx', 'w'), ('cy', 'h')):
        d[key] = d.get(key, d[size] / 2) / 2 - 0.25
    d['w'], d['h'] = d['w'] // 2, d['h'] // 2
    os.makedirs(os.path.join(dst, scene, split), exist_ok=True)
    for fr in d['frames']:
        rel = fr['file_path'] + '.png'
        rgb = np.asarray(Image.open(os.path.join(src, scene, rel)).convert('RGB'), dtype=np.float64) / 255.0
        lo = linear_to_srgb(tent_half(srgb_to_linear(rgb)))
        Image.fromarray(np.round(lo * 255).astype(np.uint8)).save(os.path.join(dst, scene, rel))
        if 'depth_file_path' in fr:
            z = read_depth(os.path.join(src, scene, fr['depth_file_path']))
            write_depth(os.path.join(dst, scene, fr['depth_file_path']), centre_samples(z))
        if 'mask_path' in fr:
            m = np.asarray(Image.open(os.path.join(src, scene, fr['mask_path'])).convert('L'))
            m = centre_samples(m)
            Image.fromarray(m).save(os.path.join(dst, scene, fr['mask_path']))
            fr['crop'] = crop_of(m > 127)
    json.dump(d, open(os.path.join(dst, scene, f'transforms_{split}.json'), 'w'), indent=1)


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    src, dst = sys.argv[1], sys.argv[2]
    scenes = sys.argv[3:] or ['background', 'glass_up', 'bottle', 'wine_flat']
    for scene in scenes:
        for split in ('train', 'test'):
            convert(src, dst, scene, split)
        print(f'{scene}: done')


if __name__ == '__main__':
    main()
