#!/usr/bin/env bash
# What the background prior costs when the scene's views have no background image at their
# pose: `rnerf train --steps 1` on a scene (the prior, one step, the model written), wall time
# of the whole command, three ways — every view against the background rendered at its pose
# (no --background-data) with the registration on, the same with it off, and every view against
# the background image at its pose (--background-data, the dev set's case). Each prints the
# prior's and the registration's lines. Run it alone, in its own autogroup (BENCHMARKS.md).
# usage: scripts/prior_cost.sh RNERF DEV_DIR BG_MODEL [SCENE]   (SCENE: default glass_up)
#   RNERF_CPU_LEVEL=avx2 to measure the level robots have
set -euo pipefail
rnerf=$1 dev=$2 bg=$3 scene=${4:-glass_up}
out=$(mktemp -d)
run() {
  local name=$1; shift
  local s e
  s=$(date +%s.%N)
  "$rnerf" train --data "$dev/$scene" --background "$bg" --out "$out/$name.safetensors" --seed 0 --steps 1 "$@" 2>&1 |
    tr '\r' '\n' | grep -E 'background prior|registration:' || true
  e=$(date +%s.%N)
  echo "$name: wall $(python3 -c "print(round($e - $s, 1))") s"
}
run rendered-registered
run rendered-unregistered --pose-registration off
run same-pose-images --background-data "$dev/background"
rm -rf "$out"
