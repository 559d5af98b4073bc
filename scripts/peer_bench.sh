#!/usr/bin/env bash
# The training step against the PyTorch peer, side by side in one run: rnerf bench, the peer
# eager, the peer with torch.compile, rnerf bench again (so a slow phase of the host shows as a
# spread between the two rnerf runs), each in its own high-priority autogroup; same table size
# (log2T = 17, the crate's default) and 4096 rays × 32 samples for the peer.
# usage: PEER=../shared/bench/torch_ngp_cpu.py PYTHON=.venv-torch/bin/python scripts/peer_bench.sh [OUT_DIR]
#   RNERF_CPU_LEVEL=avx2 to measure the level robots have (default: the host's best)
set -euo pipefail
cd "$(dirname "$0")/.."
: "${PEER:?set PEER to torch_ngp_cpu.py}"
py=${PYTHON:-python3}
out=${1:-peer-$(date -u +%F)-$(git rev-parse --short HEAD)}
mkdir -p "$out"
cargo build --release --quiet
bin=$PWD/target/release/rnerf
prio() { setsid bash -c 'echo -10 > /proc/self/autogroup 2>/dev/null; exec "$@"' _ "$@"; }
prio "$bin" bench --json --reps 5 > "$out/rnerf_1.json"
prio "$py" "$PEER" train --rays 4096 --samples 32 --log2t 17 --steps 10 > "$out/peer_eager.log"
prio "$py" "$PEER" train --rays 4096 --samples 32 --log2t 17 --steps 10 --compile > "$out/peer_compile.log"
prio "$bin" bench --json --reps 5 > "$out/rnerf_2.json"
python3 - "$out" <<'PY'
import json, sys, os
out = sys.argv[1]
def last_json(p):
    for line in reversed(open(p).read().strip().splitlines()):
        if line.startswith("{"):
            return json.loads(line)
peer = {m: last_json(os.path.join(out, f"peer_{m}.log"))["result"]["samples_per_s_median"] for m in ("eager", "compile")}
print(f"peer: eager {peer['eager']/1e3:.1f} k samples/s, torch.compile {peer['compile']/1e3:.1f} k samples/s")
for run in (1, 2):
    b = last_json(os.path.join(out, f"rnerf_{run}.json"))
    s = b["train_samples_per_s"]
    print(f"rnerf run {run} ({b['cpu_level']}): {s/1e3:.0f} k samples/s = {s/peer['eager']:.1f}x eager, "
          f"{s/peer['compile']:.1f}x compiled; fraction of its roofline {b.get('train_fraction_of_kernel_bound', float('nan')):.2f}")
PY
