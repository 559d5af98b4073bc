#!/usr/bin/env bash
# The default residual training of two builds alternated: `rnerf train` of build A, then of
# build B, ROUNDS times, on each SCENE (seed 0, the scene's images against the background
# images at the same poses), at RNERF_CPU_LEVEL (default avx2). Prints per build and scene the
# training seconds of each round (the trainer's own figure, the prior not included) and the
# samples kept / evaluated per ray at the last step, then whether the two builds' models hold
# the same tensors bit for bit (the metadata, such as the training seconds, aside). Run it
# alone on the host, in its own autogroup (BENCHMARKS.md). EXTRA: more `rnerf train` flags for
# both builds (e.g. EXTRA="--rays 256"). BG_B: the background build B trains over (default
# BG_MODEL); with the same binary as A and B, one build over two backgrounds (whose models then
# differ, as they should).
# usage: [EXTRA="..."] [BG_B=MODEL] scripts/ab_train.sh A_RNERF B_RNERF ROUNDS DEV_DIR BG_MODEL SCENE [SCENE ...]
#   (A_/B_RNERF: target/release/rnerf of each build, copied aside)
set -euo pipefail
a=$1 b=$2 rounds=$3 dev=$4 bg_a=$5; shift 5
bg_b=${BG_B:-$bg_a}
out=$(mktemp -d)
for round in $(seq "$rounds"); do
  for build in A B; do
    bin=$a bg=$bg_a; [ "$build" = B ] && bin=$b bg=$bg_b
    for scene in "$@"; do
      RNERF_CPU_LEVEL=${RNERF_CPU_LEVEL:-avx2} "$bin" train --data "$dev/$scene" --background "$bg" \
        --background-data "$dev/background" --seed 0 ${EXTRA:-} --out "$out/${scene}_$build.safetensors" 2>&1 |
        tr '\r' '\n' > "$out/${scene}_${build}_$round.log"
      secs=$(grep -o 'wrote .* (\([0-9.]*\) s)' "$out/${scene}_${build}_$round.log" | grep -o '[0-9.]* s)' | tr -d ' s)')
      per_ray=$(grep -o '[0-9]*/[0-9]* samples/ray' "$out/${scene}_${build}_$round.log" | tail -1)
      echo "$build $scene round $round: $secs s training, $per_ray"
    done
  done
done
for scene in "$@"; do
  python3 - "$out/${scene}_A.safetensors" "$out/${scene}_B.safetensors" "$scene" <<'PY'
import json, struct, sys
def tensors(path):
    b = open(path, "rb").read()
    n = struct.unpack("<Q", b[:8])[0]
    header = json.loads(b[8:8 + n])
    header.pop("__metadata__", None)
    data = b[8 + n:]
    return {k: data[v["data_offsets"][0]:v["data_offsets"][1]] for k, v in header.items()}
a, b = tensors(sys.argv[1]), tensors(sys.argv[2])
same = a.keys() == b.keys() and all(a[k] == b[k] for k in a)
print(f"{sys.argv[3]}: the two builds' models are {'the same bits' if same else 'DIFFERENT'} ({len(a)} tensors)")
PY
done
rm -rf "$out"
