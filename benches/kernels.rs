//! `cargo bench`: the kernel figures of `rnerf bench` as a table, at every CPU level the
//! host has (so the SIMD speed-up over the scalar twin is visible).
//! Options via environment: `RNERF_BENCH_REPS` (default 5), `RNERF_BENCH_LOG2T` (default: the crate's, 17).

use residual_nerf::bench::{run, BenchOptions};
use residual_nerf::simd::Isa;

fn main() {
    // `cargo test --benches` / `cargo bench -- --list` pass flags; run nothing then.
    if std::env::args().any(|a| a == "--list" || a == "--test") {
        return;
    }
    let reps = std::env::var("RNERF_BENCH_REPS").ok().and_then(|v| v.parse().ok());
    let mut opts = BenchOptions { reps: reps.unwrap_or(5), ..Default::default() };
    if let Some(l) = std::env::var("RNERF_BENCH_LOG2T").ok().and_then(|v| v.parse().ok()) {
        opts.log2_table_size = l;
    }
    for isa in Isa::all() {
        opts.isa = isa;
        println!("{}", run(&opts, Vec::new()).to_table());
    }
}
