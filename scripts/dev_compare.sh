#!/usr/bin/env bash
# The dev-set comparison of RESULTS.md: Dex-NeRF, the fine-tuned background, the paper's
# Residual-NeRF and the background-aware Residual-NeRF on the three dev scenes, at the AVX2
# level (robots have AVX2 or NEON; override with RNERF_CPU_LEVEL), in its own autogroup.
# usage: scripts/dev_compare.sh DEV_DIR BG_MODEL OUT_DIR [SEED] [VIEWS...]
#   DEV_DIR   ../shared/data/dev (background/, glass_up/, bottle/, wine_flat/)
#   BG_MODEL  the background: rnerf train --data DEV_DIR/background --out BG_MODEL --steps 3000
#   VIEWS     scene training views, one run per value (default: 100)
set -euo pipefail
dev=$1 bg=$2 out=$3 seed=${4:-0}
shift $(( $# < 4 ? $# : 4 ))
views=("$@"); [ ${#views[@]} -gt 0 ] || views=(100)
bin=${RNERF_BIN:-./target/release/rnerf}
for v in "${views[@]}"; do
  setsid bash -c "echo -10 > /proc/self/autogroup 2>/dev/null; exec env RNERF_CPU_LEVEL=${RNERF_CPU_LEVEL:-avx2} \
    $bin compare --background $dev/background --background-model $bg \
    --scene $dev/glass_up --scene $dev/bottle --scene $dev/wine_flat \
    --methods ${METHODS:-dex,finetune,residual-paper,residual} --scene-views $v --seed $seed \
    --eval-every 100 --m-sweep 10 --out $out/views$v"
done
