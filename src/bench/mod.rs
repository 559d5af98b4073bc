//! Throughput of the hot paths on this machine: what `rnerf bench` prints and `benches/`
//! runs. Every figure is the median over repetitions, with min and max kept as the spread.
//!
//! - [`kernels`]: the MLP, the hash grids and Adam alone, each beside the machine limit it is
//!   bound by, measured in the same run so ratios are meaningful on any machine ([`peak`]: the
//!   fp32 FMA peak, the AMX tile unit's);
//! - [`pipeline`]: short training runs of a NeRF and a residual model on the synthetic
//!   workspace, threshold-depth views (of trained models instead when given: [`TrainedView`],
//!   `rnerf bench --model M --data D`) and occupancy-grid updates;
//! - [`quality`]: training time to quality on a captured background and scene (`rnerf bench
//!   --background-data BG --scene S`): the background's seconds to 28 dB, the scene phase's
//!   seconds to its final object-mask depth error;
//! - [`report`]: the figures as typed structs, the derived bounds and ratios, JSON and table.

pub mod kernels;
pub mod peak;
pub mod pipeline;
pub mod quality;
pub mod report;

pub use kernels::{bare_gather, nerf_mlps, ray_coherent_positions};
pub use pipeline::{resized, TrainedView};
pub use report::{BenchReport, DerivedFigures, KernelFigures, PipelineFigures, QualityFigures, Stat};

use crate::encoding::HashGridConfig;
use crate::simd::Isa;
use std::time::Instant;

/// What to measure and how long.
#[derive(Clone, Debug)]
pub struct BenchOptions {
    /// Repetitions per figure. Defaults to 5.
    pub reps: usize,
    /// Work per repetition relative to the default (≈0.1–0.3 s per figure). Defaults to 1.0;
    /// tests use a tiny value to exercise the code.
    pub scale: f64,
    /// Hash-grid table size. Defaults to the grid's default.
    pub log2_table_size: u32,
    /// The CPU level to run. Defaults to [`Isa::detect`].
    pub isa: Isa,
}

impl Default for BenchOptions {
    fn default() -> Self {
        BenchOptions {
            reps: 5,
            scale: 1.0,
            log2_table_size: HashGridConfig::default().log2_table_size,
            isa: Isa::detect(),
        }
    }
}

impl BenchOptions {
    /// `n` units of work at this scale (at least one).
    fn scaled(&self, n: f64) -> usize {
        ((n * self.scale).round() as usize).max(1)
    }
}

/// Runs every benchmark.
pub fn run(opts: &BenchOptions, trained: Vec<TrainedView>) -> BenchReport {
    let mut progress = Progress(Instant::now());
    let kernels = kernels::measure(opts, &mut progress);
    let (pipeline, mixnet_mac_share) = pipeline::measure(opts, trained, &mut progress);
    let derived = DerivedFigures::of(&kernels, &pipeline, mixnet_mac_share);
    BenchReport {
        cpu_level: opts.isa.to_string(),
        threads: rayon::current_num_threads(),
        log2_table_size: opts.log2_table_size,
        kernels,
        pipeline,
        derived,
        quality: QualityFigures::none(),
    }
}

/// Progress on stderr: which part runs, seconds since the start.
struct Progress(Instant);

impl Progress {
    fn start(&mut self, part: &str) {
        eprintln!("rnerf bench: {part} ({:.0} s)", self.0.elapsed().as_secs_f64());
    }
}

/// Times `f` `reps` times; returns seconds per repetition.
fn time_reps(reps: usize, mut f: impl FnMut()) -> Vec<f64> {
    f(); // warm caches and lazily sized buffers
    (0..reps)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .collect()
}

/// Runs `f(thread_index)` once on every thread of the current rayon pool, all at once.
fn on_all_threads(f: impl Fn(usize) + Sync) {
    rayon::broadcast(|ctx| f(ctx.index()));
}

fn single_thread_pool() -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("cannot start a rayon thread")
}
