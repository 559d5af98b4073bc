#!/usr/bin/env python3
"""Idle parameters of a training checkpoint: per Adam group, the share of parameters whose two
moments are both exactly zero (no gradient has reached them yet), singly and in blocks of 64
(what `Adam::step` skips, src/train/adam/mod.rs `IDLE_BLOCK`).

    scripts/idle_moments.py MODEL.ckpt.safetensors

A checkpoint is written by `rnerf train --checkpoint-every N` or on SIGINT, e.g.
`timeout -s INT 10 rnerf train --data DEV/glass_up --background bg.safetensors
--background-data DEV/background --rays 256 --out M.safetensors` (its step is in the log).
"""
import array
import json
import struct
import sys

BLOCK = 64


def main(path):
    raw = open(path, "rb").read()
    n = struct.unpack("<Q", raw[:8])[0]
    header = json.loads(raw[8:8 + n])
    base = 8 + n

    def floats(name):
        a, b = header[name]["data_offsets"]
        out = array.array("f")
        out.frombytes(raw[base + a:base + b])
        return out

    groups = sorted({k.rsplit(".", 1)[0] for k in header if k.startswith("train.adam.") and k.endswith(".m")})
    print("| group | parameters | both moments zero | idle blocks of 64 |")
    print("|---|---|---|---|")
    for g in groups:
        m, v = floats(g + ".m"), floats(g + ".v")
        idle = [x == 0.0 and y == 0.0 for x, y in zip(m, v)]
        blocks = [all(idle[i:i + BLOCK]) for i in range(0, len(idle), BLOCK)]
        print(f"| {g} | {len(m)} | {100 * sum(idle) / max(1, len(m)):.1f}% | {100 * sum(blocks) / max(1, len(blocks)):.1f}% |")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(sys.argv[1])
