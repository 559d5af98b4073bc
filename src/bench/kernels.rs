//! The kernels alone, each against the machine limit it is bound by: the fp32 FMA peak
//! ([`super::peak`]) for the MLP, a bare random-gather loop over a table of the grid's size for
//! the hash grid; then Adam over the grid's parameters.

use super::report::{KernelFigures, Stat};
use super::{on_all_threads, single_thread_pool, time_reps, BenchOptions, Progress};
use crate::encoding::{FeatureLevels, HashGrid, HashGridConfig, HashGridParams};
use crate::field::mixnet::default_mixnet_grid;
use crate::field::{NerfConfig, NerfField};
use crate::geometry::Aabb;
use crate::mlp::{Mlp, MlpContext, MlpParams, MlpWorkspace};
use crate::rng::Rng;
use crate::simd::Isa;
use crate::train::{Adam, AdamConfig};
use crate::GradientMode;
use glam::Vec3;
use std::hint::black_box;

/// Positions along rays (32 samples per ray, Instant-NGP's minimum step √3/1024 in the unit
/// cube): the locality a NeRF batch has.
pub fn ray_coherent_positions(n: usize, rng: &mut Rng) -> Vec<[f32; 3]> {
    let step = 3f32.sqrt() / 1024.0;
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        let o = [rng.f32(), rng.f32(), rng.f32()];
        let mut d = [rng.f32() - 0.5, rng.f32() - 0.5, rng.f32() - 0.5];
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().max(1e-3);
        d.iter_mut().for_each(|v| *v /= len);
        for s in 0..32.min(n - out.len()) {
            out.push(std::array::from_fn(|k| {
                let v = o[k] + d[k] * step * s as f32;
                (v - v.floor()).min(0.999_999)
            }));
        }
    }
    out
}

/// The NeRF's two networks as [`NerfField::new`] builds them (DESIGN §2.1).
pub fn nerf_mlps() -> (Mlp<64>, Mlp<64>) {
    let unit = Aabb { min: Vec3::ZERO, max: Vec3::ONE };
    let field = NerfField::new(NerfConfig { grid: HashGridConfig::default(), aabb: unit });
    let (density, colour) = field.networks();
    (density.clone(), colour.clone())
}

/// State of one thread's MLP forward+backward loop.
struct MlpBench {
    nets: (Mlp<64>, Mlp<64>),
    params: (MlpParams, MlpParams),
    grads: (Vec<f32>, Vec<f32>),
    inputs: (Vec<f32>, Vec<f32>),
    d_out: (Vec<f32>, Vec<f32>),
    d_in: (Vec<f32>, Vec<f32>),
    ctx: (MlpContext, MlpContext),
    ws: MlpWorkspace,
}

impl MlpBench {
    /// Samples per fused call: one chunk of the training step, small enough that every
    /// activation, weight and gradient stays in L1/L2 and within the data-TLB reach
    /// (measured here: 128 rows run at ~1.7× the speed of 192; see BENCHMARKS.md).
    const BATCH: usize = 64;

    fn new(seed: u64) -> MlpBench {
        let mut rng = Rng::new(seed);
        let nets = nerf_mlps();
        let rand = |n: usize, rng: &mut Rng| (0..n).map(|_| rng.uniform(-1.0, 1.0)).collect::<Vec<f32>>();
        let n = Self::BATCH;
        MlpBench {
            params: (nets.0.init_params(&mut rng), nets.1.init_params(&mut rng)),
            grads: (vec![0.0; nets.0.n_params()], vec![0.0; nets.1.n_params()]),
            inputs: (rand(n * nets.0.input_stride(), &mut rng), rand(n * nets.1.input_stride(), &mut rng)),
            d_out: (rand(n * nets.0.output_stride(), &mut rng), rand(n * nets.1.output_stride(), &mut rng)),
            d_in: (vec![0.0; n * nets.0.input_stride()], vec![0.0; n * nets.1.input_stride()]),
            ctx: Default::default(),
            ws: MlpWorkspace::default(),
            nets,
        }
    }

    /// FLOPs (2 per multiply-add, as executed: [`Mlp::fwd_bwd_macs_per_sample`]) of one
    /// `run`: forward, dL/dinput and dL/dweights of both networks.
    fn flops(&self) -> f64 {
        let macs = self.nets.0.fwd_bwd_macs_per_sample() + self.nets.1.fwd_bwd_macs_per_sample();
        (2 * macs * Self::BATCH) as f64
    }

    fn run(&mut self, isa: Isa) {
        let n = Self::BATCH;
        let s = self;
        s.nets.0.forward(isa, &s.params.0, &s.inputs.0, n, &mut s.ctx.0);
        s.nets.1.forward(isa, &s.params.1, &s.inputs.1, n, &mut s.ctx.1);
        s.nets.1.backward(
            isa,
            &s.params.1,
            &s.inputs.1,
            &s.ctx.1,
            &s.d_out.1,
            &mut s.grads.1,
            GradientMode::Accumulate,
            Some(&mut s.d_in.1),
            &mut s.ws,
        );
        s.nets.0.backward(
            isa,
            &s.params.0,
            &s.inputs.0,
            &s.ctx.0,
            &s.d_out.0,
            &mut s.grads.0,
            GradientMode::Accumulate,
            Some(&mut s.d_in.0),
            &mut s.ws,
        );
        black_box(&s.d_in);
    }
}

/// A bare random-gather loop over a table laid out like `grid`: per sample, 8 random 4-byte
/// reads in each level's slice (the memory traffic of one encoding, without its arithmetic).
/// Returns a checksum.
pub fn bare_gather(grid: &HashGrid, table: &[u32], samples: usize, seed: u32) -> u32 {
    let mut h = seed.wrapping_mul(0x9E37_79B1) | 1;
    let mut acc = 0u32;
    for _ in 0..samples {
        for level in grid.levels() {
            let t = &table[level.offset..level.offset + level.size];
            for _ in 0..8 {
                // xorshift32: cheap, full-period index stream
                h ^= h << 13;
                h ^= h >> 17;
                h ^= h << 5;
                // multiply-shift range reduction: uniform over the level, no division
                acc = acc.wrapping_add(t[((h as u64 * t.len() as u64) >> 32) as usize]);
            }
        }
    }
    acc
}

/// Measures every kernel figure.
pub(super) fn measure(opts: &BenchOptions, progress: &mut Progress) -> KernelFigures {
    let (isa, reps) = (opts.isa, opts.reps.max(1));
    let threads = rayon::current_num_threads();
    let scaled = |n: f64| opts.scaled(n);
    let per_s = |v: Vec<f64>, work: f64| Stat::of(v.iter().map(|s| work / s).collect());

    // fp32 FMA peak, 1 thread and all threads; the AMX level's tile unit (bf16 products, fp32
    // sums), 1 thread.
    progress.start("FMA and tile peaks");
    let iters = scaled(4e7) as u64;
    let flop = peak_flops(isa, iters);
    let fma_peak_gflops_1t =
        per_s(time_reps(reps, || _ = black_box(super::peak::fma_loop(isa, iters, 1.0))), flop / 1e9);
    let all = time_reps(reps, || on_all_threads(|t| _ = black_box(super::peak::fma_loop(isa, iters, t as f32))));
    let fma_peak_gflops = per_s(all, flop * threads as f64 / 1e9);
    let tile_iters = scaled(4e6) as u64;
    let tile_peak_gflops_1t = super::peak::tile_loop(isa, 1).map(|per_iter| {
        let v = time_reps(reps, || _ = super::peak::tile_loop(isa, tile_iters));
        per_s(v, per_iter * tile_iters as f64 / 1e9)
    });

    // Fused MLP forward + backward (density + colour), 1 thread and all threads.
    progress.start("MLP forward + backward");
    let calls = scaled(200.0);
    let mut one = MlpBench::new(1);
    let flops = one.flops() * calls as f64;
    let samples_1t = (calls * MlpBench::BATCH) as f64;
    let v = time_reps(reps, || (0..calls).for_each(|_| one.run(isa)));
    let (mlp_fwd_bwd_gflops_1t, mlp_fwd_bwd_samples_per_s_1t) = (per_s(v.clone(), flops / 1e9), per_s(v, samples_1t));
    let per_thread: Vec<std::sync::Mutex<MlpBench>> =
        (0..threads).map(|t| std::sync::Mutex::new(MlpBench::new(t as u64))).collect();
    let v = time_reps(reps, || {
        on_all_threads(|t| {
            let mut b = per_thread[t].lock().expect("one bench thread per lock");
            (0..calls).for_each(|_| b.run(isa));
        })
    });
    let mlp_fwd_bwd_gflops = per_s(v.clone(), flops * threads as f64 / 1e9);
    let mlp_fwd_bwd_samples_per_s = per_s(v, samples_1t * threads as f64);

    // Hash grid at the requested table size: 1 thread and all threads, ray-coherent samples.
    progress.start("hash grids");
    let grid = HashGrid::new(HashGridConfig { log2_table_size: opts.log2_table_size, ..Default::default() });
    let mut rng = Rng::new(7);
    let mut params = HashGridParams::init(&grid, &mut rng);
    // Spread values so the table is not all near-zero (irrelevant for speed, but realistic).
    params.master.iter_mut().for_each(|p| *p *= 1e3);
    params.sync_mirror();
    let n = scaled(1.0 * (1 << 17) as f64);
    let pos = ray_coherent_positions(n, &mut rng);
    let mut enc = vec![0f32; n * grid.output_width()];
    let d_enc: Vec<f32> = (0..enc.len()).map(|_| rng.uniform(-1.0, 1.0)).collect();
    let mut grads: Vec<f32> = crate::memory::zeroed_vec(grid.n_params());
    let ns = |v: Vec<f64>| Stat::of(v.iter().map(|s| s * 1e9 / n as f64).collect());
    let pool1 = single_thread_pool();
    let hash_grid_fwd_ns_per_sample_1t = ns(time_reps(reps, || grid.forward(isa, &params.table, &pos, &mut enc)));
    // The backward as the training step runs it: feature gradients in the level-major layout.
    let mut levels = FeatureLevels::default();
    levels.append(&grid, &pos, &d_enc);
    let bwd = |grads: &mut Vec<f32>| grid.backward_params_levels(isa, &[&levels], grads, GradientMode::Accumulate);
    let hash_grid_bwd_ns_per_sample_1t = ns(time_reps(reps, || pool1.install(|| bwd(&mut grads))));
    let hash_grid_fwd_ns_per_sample = ns(time_reps(reps, || grid.forward_par(isa, &params.table, &pos, &mut enc)));
    let hash_grid_bwd_ns_per_sample = ns(time_reps(reps, || bwd(&mut grads)));
    let hash_grid_bwd_row_major_ns_per_sample =
        ns(time_reps(reps, || grid.backward_params(isa, &pos, &d_enc, &mut grads, GradientMode::Accumulate)));
    let gather_limit_ns_per_sample_1t = ns(time_reps(reps, || _ = black_box(bare_gather(&grid, &params.table, n, 3))));
    // The Mixnet's own grid (8 levels, 2^15 entries), same samples, all threads.
    let mgrid = HashGrid::new(default_mixnet_grid());
    let mparams = HashGridParams::init(&mgrid, &mut rng);
    let mut menc = vec![0f32; n * mgrid.output_width()];
    let md_enc: Vec<f32> = (0..menc.len()).map(|_| rng.uniform(-1.0, 1.0)).collect();
    let mut mgrads: Vec<f32> = crate::memory::zeroed_vec(mgrid.n_params());
    let mut mlevels = FeatureLevels::default();
    mlevels.append(&mgrid, &pos, &md_enc);
    let mixnet_grid_fwd_ns_per_sample = ns(time_reps(reps, || mgrid.forward_par(isa, &mparams.table, &pos, &mut menc)));
    let mixnet_grid_bwd_ns_per_sample =
        ns(time_reps(reps, || mgrid.backward_params_levels(isa, &[&mlevels], &mut mgrads, GradientMode::Accumulate)));

    // Adam over the grid's parameters with the fp16 mirror.
    progress.start("Adam");
    let mut adam = Adam::new(grid.n_params(), AdamConfig::default());
    let np = grid.n_params() as f64;
    let mut step = |adam: &mut Adam| {
        let half: &mut [u16] = bytemuck::cast_slice_mut(&mut params.table);
        adam.step(isa, 1e-3, &mut params.master, &grads, Some(half));
    };
    let per_param = |v: Vec<f64>| Stat::of(v.iter().map(|s| s * 1e9 / np).collect());
    let adam_ns_per_param_1t = per_param(time_reps(reps, || pool1.install(|| step(&mut adam))));
    let adam_ns_per_param = per_param(time_reps(reps, || step(&mut adam)));

    KernelFigures {
        fma_peak_gflops_1t,
        fma_peak_gflops,
        tile_peak_gflops_1t,
        mlp_fwd_bwd_gflops_1t,
        mlp_fwd_bwd_samples_per_s_1t,
        mlp_fwd_bwd_gflops,
        mlp_fwd_bwd_samples_per_s,
        hash_grid_fwd_ns_per_sample_1t,
        hash_grid_bwd_ns_per_sample_1t,
        hash_grid_fwd_ns_per_sample,
        hash_grid_bwd_ns_per_sample,
        hash_grid_bwd_row_major_ns_per_sample,
        gather_limit_ns_per_sample_1t,
        mixnet_grid_fwd_ns_per_sample,
        mixnet_grid_bwd_ns_per_sample,
        adam_ns_per_param_1t,
        adam_ns_per_param,
    }
}

/// FLOPs of `iters` rounds of the FMA loop at `isa`'s level.
fn peak_flops(isa: Isa, iters: u64) -> f64 {
    super::peak::fma_loop(isa, 1, 0.0).1 * iters as f64
}
