#!/usr/bin/env bash
# The coarse start's passes by pixel angle (`ViewRenderer::set_coarse_spacing`): for each
# MODEL:DATA_DIR pair, the depth of every test view rendered at 3× and 5× its size (600×600
# and 1000×1000 on the dev views: three and four passes at the default spacing) scored against
# the ground truth on the pixels whose rays it holds (`examples/fine_depth`), from the box, in
# two passes (`1@0`) and at the default; then the timing A/B and the pixels moved against
# marching from the box at 200×200 and 640×480 (`examples/coarse_start`, 9 interleaved rounds).
# usage: scripts/coarse_passes.sh OUT_DIR MODEL:DATA_DIR ...
set -euo pipefail
out=$1; shift
mkdir -p "$out"
export RNERF_CPU_LEVEL=${RNERF_CPU_LEVEL:-avx2}
cargo build --release --example fine_depth --example coarse_start 2>/dev/null
for pair in "$@"; do
  model=${pair%%:*} data=${pair#*:}
  name=$(basename "$model" .safetensors)
  for n in 3 5; do
    ./target/release/examples/fine_depth "$model" "$data" $n off,1@0,1 > "$out/fine_${name}_x$n.txt"
  done
  ./target/release/examples/coarse_start "$model" "$data" 1@0,1 9 > "$out/ab_${name}.txt"
done
