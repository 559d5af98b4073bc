#!/usr/bin/env bash
# The tests' dependencies at opt-level 0 against 1 (Cargo.toml, `[profile.test.package."*"]`):
# the build times in fresh target directories, x86 (the benches' build, then the tests') and,
# with the cross tools of DEVELOPERS.md, the aarch64 kernel tests' build as `.ci/run` makes it;
# then residual_e2e and cli_train run at each level, alternated (0, 1, 0, 1).
# Run it alone, in its own autogroup: about 25 minutes on 2 cores.
#
# usage: scripts/test_deps_opt.sh [SCRATCH_DIR]   (default: target/deps_opt)
set -euo pipefail
cd "$(dirname "$0")/.."
scratch=${1:-target/deps_opt}
export CARGO_INCREMENTAL=0 CARGO_TERM_COLOR=never RUSTFLAGS="-D warnings"
export RUSTC_WORKSPACE_WRAPPER="$(rustc --print sysroot)/bin/clippy-driver"
CHECKED=(--config 'profile.test.package.residual-nerf.debug-assertions=true'
  --config 'profile.test.package.residual-nerf.overflow-checks=true')
timed() { local s=$SECONDS; "$@" > /dev/null 2>&1; echo $((SECONDS - s)); }

for v in 0 1; do
  level=(--config "profile.test.package.\"*\".opt-level=$v")
  export CARGO_TARGET_DIR=$scratch/x86_$v
  rm -rf "$CARGO_TARGET_DIR"
  echo "opt-level $v: benches' build $(timed cargo test "${level[@]}" --no-run --benches) s," \
    "tests' build $(timed cargo test "${level[@]}" --no-run) s"
done
if command -v aarch64-linux-gnu-gcc > /dev/null; then
  export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc
  for v in 0 1; do
    level=(--config "profile.test.package.\"*\".opt-level=$v")
    export CARGO_TARGET_DIR=$scratch/arm_$v
    rm -rf "$CARGO_TARGET_DIR"
    echo "opt-level $v: aarch64 kernel tests' build $(timed cargo test "${CHECKED[@]}" "${level[@]}" \
      --target aarch64-unknown-linux-gnu --lib --test simd_vs_scalar --test gradients --test hashgrid_cases --no-run) s"
  done
fi
for v in 0 1 0 1; do
  level=(--config "profile.test.package.\"*\".opt-level=$v")
  export CARGO_TARGET_DIR=$scratch/x86_$v
  for t in residual_e2e cli_train; do
    cargo test "${level[@]}" --test $t 2>&1 | grep "finished in" | sed "s/^/opt-level $v, $t: /"
  done
done
