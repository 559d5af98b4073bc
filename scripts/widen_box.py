#!/usr/bin/env python3
"""A capture whose scene box is K times wider about its centre, the images and truth unchanged:
what a room K times larger does to a NeRF's sampling while the glass and its views stay the same
(the occupancy grid's and the change region's cells scale with the box; the march's step and the
hash grids' finest cells do too up to the dev box's size, and stay as many millimetres beyond it:
`train::sizing`).

Every json of each scene gets `aabb` scaled by K about the box's centre; the image, depth and
mask files are symbolic links to the originals (absolute paths), so the copy costs nothing.

usage: scripts/widen_box.py SRC_DIR DST_DIR K [SCENE...]
       (default scenes: background glass_up bottle wine_flat)
"""
import json
import os
import sys


def main():
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    src, dst, k = os.path.abspath(sys.argv[1]), sys.argv[2], float(sys.argv[3])
    scenes = sys.argv[4:] or ['background', 'glass_up', 'bottle', 'wine_flat']
    for scene in scenes:
        os.makedirs(os.path.join(dst, scene), exist_ok=True)
        for name in sorted(os.listdir(os.path.join(src, scene))):
            path = os.path.join(src, scene, name)
            out = os.path.join(dst, scene, name)
            if name.startswith('transforms_') and name.endswith('.json'):
                d = json.load(open(path))
                lo, hi = d['aabb']
                c = [(a + b) / 2 for a, b in zip(lo, hi)]
                h = [(b - a) / 2 * k for a, b in zip(lo, hi)]
                d['aabb'] = [[ci - hi_ for ci, hi_ in zip(c, h)], [ci + hi_ for ci, hi_ in zip(c, h)]]
                json.dump(d, open(out, 'w'), indent=1)
            elif not os.path.lexists(out):
                os.symlink(path, out)
        print(f'{scene}: done')


if __name__ == '__main__':
    main()
