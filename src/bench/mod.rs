//! Throughput of the hot paths on this machine: what `rnerf bench` prints and `benches/`
//! runs. Every figure is the median over repetitions, with min and max kept as the spread.
//!
//! Limits are measured in the same run so ratios are meaningful on any machine: the fp32
//! FMA peak ([`peak::fma_loop`]) for the MLP, and a bare random-gather loop over a table of
//! the grid's size for the hash grid. The pipeline figures (`train_samples_per_s`,
//! `train_residual_samples_per_s`, `render_depth_ms_200[_residual]`,
//! `occupancy_update_ms[_warmup]`) come from a short training run on the
//! synthetic workspace; the depth figures time trained models instead when given
//! ([`TrainedView`], `rnerf bench --model M --data D`).

pub mod peak;

use crate::data::{Dataset, LoadOptions};
use crate::encoding::{FeatureLevels, HashGrid, HashGridConfig, HashGridParams};
use crate::field::mix::{DensityMix, MixKind};
use crate::field::mixnet::{default_mixnet_grid, MixnetEncoding};
use crate::field::residual::ResidualConfig;
use crate::field::NerfConfig;
use crate::io::LoadedModel;
use crate::mlp::{Activation, Mlp, MlpConfig, MlpContext, MlpParams, MlpWorkspace};
use crate::onboard::{DepthKind, DepthMethod, DepthRenderer, DepthRequest};
use crate::render::{Intrinsics, Pose};
use crate::rng::Rng;
use crate::simd::Isa;
use crate::train::trainer::{train_nerf, train_residual, StepStats, TrainConfig};
use crate::train::{Adam, AdamConfig};
use crate::GradientMode;
use std::hint::black_box;
use std::path::Path;
use std::time::Instant;

/// A trained model whose depth rendering `rnerf bench --model M --data D` times in place of
/// the bench's own short-trained one — those are still foggy, so their depth rays march far
/// (BENCHMARKS.md, "Depth rendering"). Its kind picks the figure: a NeRF `render_depth_ms_200`, a
/// residual model `render_depth_ms_200_residual`.
pub struct TrainedView {
    /// The model, as loaded.
    pub model: LoadedModel,
    /// The first test view of `D`, rescaled to 200 pixels wide.
    pub intrinsics: Intrinsics,
    /// Its pose.
    pub pose: Pose,
}

impl TrainedView {
    /// Loads `model` and the first test view of `data` (errors name the file).
    pub fn load(model: &Path, data: &Path) -> Result<TrainedView, String> {
        let loaded = crate::io::load_model(model)?;
        let opts = LoadOptions { ground_truth: false, ..Default::default() };
        let test = Dataset::load(data, "test", &opts).map_err(|e| e.to_string())?;
        let view = test.views.first().ok_or_else(|| format!("{}: the test split has no views", data.display()))?;
        let (k, s) = (view.intrinsics, 200.0 / view.intrinsics.width as f32);
        let height = ((k.height as f32 * s).round() as u32).max(1);
        let intrinsics = Intrinsics { width: 200, height, fx: k.fx * s, fy: k.fy * s, cx: k.cx * s, cy: k.cy * s, ..k };
        Ok(TrainedView { model: loaded, intrinsics, pose: view.pose })
    }

    /// The figure it is timed under.
    pub fn figure(&self) -> &'static str {
        match self.model {
            LoadedModel::Nerf(_) => "render_depth_ms_200",
            LoadedModel::Residual(_) => "render_depth_ms_200_residual",
        }
    }
}

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

/// Median and spread of one figure.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stat {
    /// Median over repetitions.
    pub median: f64,
    /// Smallest repetition.
    pub min: f64,
    /// Largest repetition.
    pub max: f64,
}

impl Stat {
    fn of(mut v: Vec<f64>) -> Stat {
        assert!(!v.is_empty());
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let median = if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) };
        Stat { median, min: v[0], max: v[n - 1] }
    }
}

/// All figures of one run, in the order measured.
#[derive(Clone, Debug)]
pub struct BenchReport {
    /// CPU level the kernels ran at.
    pub cpu_level: String,
    /// Threads of the rayon pool ("all threads").
    pub threads: usize,
    /// log2 table size of the grid figures.
    pub log2_table_size: u32,
    /// (name, unit, figure).
    pub figures: Vec<(String, &'static str, Stat)>,
}

impl BenchReport {
    /// The median of figure `name`.
    pub fn get(&self, name: &str) -> Option<f64> {
        self.figures.iter().find(|f| f.0 == name).map(|f| f.2.median)
    }

    /// One JSON object: every figure's median under its name, plus `spread` ([min, max]).
    pub fn to_json(&self) -> serde_json::Value {
        let mut o = serde_json::Map::new();
        o.insert("cpu_level".into(), self.cpu_level.clone().into());
        o.insert("threads".into(), self.threads.into());
        o.insert("log2_table_size".into(), self.log2_table_size.into());
        let mut spread = serde_json::Map::new();
        for (name, _, s) in &self.figures {
            o.insert(name.clone(), round4(s.median).into());
            spread.insert(name.clone(), serde_json::json!([round4(s.min), round4(s.max)]));
        }
        o.insert("spread".into(), spread.into());
        serde_json::Value::Object(o)
    }

    /// A human-readable table.
    pub fn to_table(&self) -> String {
        let mut s = format!(
            "cpu level {}, {} threads, hash grid log2T={}\n",
            self.cpu_level, self.threads, self.log2_table_size
        );
        for (name, unit, st) in &self.figures {
            s += &format!("{name:<44} {:>12.3} [{:>10.3} .. {:>10.3}] {unit}\n", st.median, st.min, st.max);
        }
        s
    }
}

fn round4(x: f64) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    let mag = 10f64.powi(3 - x.abs().log10().floor() as i32);
    (x * mag).round() / mag
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

/// The NeRF's two networks (DESIGN §2.1).
pub fn nerf_mlps() -> (Mlp<64>, Mlp<64>) {
    let density = Mlp::<64>::new(MlpConfig {
        input: 32,
        output: 16,
        hidden_layers: 1,
        hidden_activation: Activation::Relu,
        output_activation: Activation::None,
    });
    let colour = Mlp::<64>::new(MlpConfig {
        input: 31,
        output: 3,
        hidden_layers: 2,
        hidden_activation: Activation::Relu,
        output_activation: Activation::None,
    });
    (density, colour)
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

/// Runs every benchmark. Takes a few seconds at `scale = 1`.
pub fn run(opts: &BenchOptions, trained: Vec<TrainedView>) -> BenchReport {
    let isa = opts.isa;
    let reps = opts.reps.max(1);
    let threads = rayon::current_num_threads();
    let scaled = |n: f64| ((n * opts.scale).round() as usize).max(1);
    let mut figures = Vec::new();
    let t0 = Instant::now();
    let mut push = |name: &str, unit: &'static str, v: Vec<f64>| {
        eprintln!("rnerf bench: {name} ({:.0} s)", t0.elapsed().as_secs_f64());
        figures.push((name.to_string(), unit, Stat::of(v)))
    };

    // fp32 FMA peak, 1 thread and all threads.
    let iters = scaled(4e7) as u64;
    let flop = peak::fma_loop(isa, 1, 0.0).1 * iters as f64;
    push(
        "fma_peak_gflops_1t",
        "GFLOP/s",
        time_reps(reps, || _ = black_box(peak::fma_loop(isa, iters, 1.0))).iter().map(|s| flop / s / 1e9).collect(),
    );
    let fma_all = time_reps(reps, || on_all_threads(|t| _ = black_box(peak::fma_loop(isa, iters, t as f32))));
    push("fma_peak_gflops", "GFLOP/s", fma_all.iter().map(|s| flop * threads as f64 / s / 1e9).collect());
    // The AMX level's tile unit (bf16 products, fp32 sums), 1 thread.
    let tile_iters = scaled(4e6) as u64;
    if let Some(tile_flop) = peak::tile_loop(isa, 1) {
        let tile_flop = tile_flop * tile_iters as f64;
        let v = time_reps(reps, || _ = peak::tile_loop(isa, tile_iters));
        push("tile_peak_gflops_1t", "GFLOP/s", v.iter().map(|s| tile_flop / s / 1e9).collect());
    }

    // Fused MLP forward + backward (density + colour), 1 thread and all threads.
    let calls = scaled(200.0);
    let mut one = MlpBench::new(1);
    let flops = one.flops() * calls as f64;
    let v = time_reps(reps, || (0..calls).for_each(|_| one.run(isa)));
    push("mlp_fwd_bwd_gflops_1t", "GFLOP/s", v.iter().map(|s| flops / s / 1e9).collect());
    push("mlp_fwd_bwd_samples_per_s_1t", "samples/s", v.iter().map(|s| (calls * MlpBench::BATCH) as f64 / s).collect());
    let per_thread: Vec<std::sync::Mutex<MlpBench>> =
        (0..threads).map(|t| std::sync::Mutex::new(MlpBench::new(t as u64))).collect();
    let v = time_reps(reps, || {
        on_all_threads(|t| {
            let mut b = per_thread[t].lock().unwrap();
            (0..calls).for_each(|_| b.run(isa));
        })
    });
    push("mlp_fwd_bwd_gflops", "GFLOP/s", v.iter().map(|s| flops * threads as f64 / s / 1e9).collect());
    let samples = (calls * MlpBench::BATCH * threads) as f64;
    push("mlp_fwd_bwd_samples_per_s", "samples/s", v.iter().map(|s| samples / s).collect());

    // Hash grid at the requested table size: 1 thread and all threads, ray-coherent samples.
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
    let ns = |v: Vec<f64>| v.iter().map(|s| s * 1e9 / n as f64).collect::<Vec<_>>();
    let pool1 = single_thread_pool();
    push(
        "hash_grid_fwd_ns_per_sample_1t",
        "ns/sample",
        ns(time_reps(reps, || grid.forward(isa, &params.table, &pos, &mut enc))),
    );
    // The backward as the training step runs it: feature gradients in the level-major layout.
    let mut levels = FeatureLevels::default();
    levels.append(&grid, &pos, &d_enc);
    let bwd = |grads: &mut Vec<f32>| grid.backward_params_levels(isa, &[&levels], grads, GradientMode::Accumulate);
    push("hash_grid_bwd_ns_per_sample_1t", "ns/sample", ns(time_reps(reps, || pool1.install(|| bwd(&mut grads)))));
    push(
        "hash_grid_fwd_ns_per_sample",
        "ns/sample",
        ns(time_reps(reps, || grid.forward_par(isa, &params.table, &pos, &mut enc))),
    );
    push("hash_grid_bwd_ns_per_sample", "ns/sample", ns(time_reps(reps, || bwd(&mut grads))));
    push(
        "hash_grid_bwd_row_major_ns_per_sample",
        "ns/sample",
        ns(time_reps(reps, || grid.backward_params(isa, &pos, &d_enc, &mut grads, GradientMode::Accumulate))),
    );
    push(
        "gather_limit_ns_per_sample_1t",
        "ns/sample",
        ns(time_reps(reps, || _ = black_box(bare_gather(&grid, &params.table, n, 3)))),
    );
    // The Mixnet's own grid (8 levels, 2^15 entries), same samples, all threads.
    let mgrid = HashGrid::new(default_mixnet_grid());
    let mparams = HashGridParams::init(&mgrid, &mut rng);
    let mut menc = vec![0f32; n * mgrid.output_width()];
    let md_enc: Vec<f32> = (0..menc.len()).map(|_| rng.uniform(-1.0, 1.0)).collect();
    let mut mgrads: Vec<f32> = crate::memory::zeroed_vec(mgrid.n_params());
    let mut mlevels = FeatureLevels::default();
    mlevels.append(&mgrid, &pos, &md_enc);
    push(
        "mixnet_grid_fwd_ns_per_sample",
        "ns/sample",
        ns(time_reps(reps, || mgrid.forward_par(isa, &mparams.table, &pos, &mut menc))),
    );
    push(
        "mixnet_grid_bwd_ns_per_sample",
        "ns/sample",
        ns(time_reps(reps, || mgrid.backward_params_levels(isa, &[&mlevels], &mut mgrads, GradientMode::Accumulate))),
    );

    // Adam over the grid's parameters with the fp16 mirror.
    let mut adam = Adam::new(grid.n_params(), AdamConfig::default());
    let np = grid.n_params() as f64;
    let mut step = |adam: &mut Adam| {
        let half: &mut [u16] = bytemuck::cast_slice_mut(&mut params.table);
        adam.step(isa, 1e-3, &mut params.master, &grads, Some(half));
    };
    push(
        "adam_ns_per_param_1t",
        "ns/param",
        time_reps(reps, || pool1.install(|| step(&mut adam))).iter().map(|s| s * 1e9 / np).collect(),
    );
    push("adam_ns_per_param", "ns/param", time_reps(reps, || step(&mut adam)).iter().map(|s| s * 1e9 / np).collect());

    // The real pipeline: a full fused training step (march, density, early stop, colour,
    // compositing, backward, grid scatter, Adam, occupancy updates amortised) on the synthetic
    // workspace at the default model size (random background colours, as `rnerf train` trains
    // images without alpha), measured over the last quarter of a short run; then a residual
    // model (Mixnet, own grid) over that background on the workspace with the glass sphere.
    // Then threshold depth (σ ≥ 10/m, depth-only path) of one 200×200 view of each model.
    let scene = crate::data::workspace::workspace(64, 30, 0.0, false);
    let field = NerfConfig {
        grid: HashGridConfig { log2_table_size: opts.log2_table_size, ..Default::default() },
        aabb: scene.aabb,
    };
    let cfg = TrainConfig::with_steps(scaled(120.0).max(8) as u32);
    let rates = |log: &[StepStats]| -> (Vec<f64>, Vec<f64>) {
        let w: Vec<&[StepStats]> = log[log.len() * 3 / 4..].windows(2).collect();
        let dt = |w: &[StepStats]| w[1].seconds - w[0].seconds;
        let rays = cfg.rays_per_step as f64;
        (
            w.iter().map(|w| w[1].samples_per_ray as f64 * rays / dt(w)).collect(),
            w.iter().map(|w| rays / dt(w)).collect(),
        )
    };
    let mut log = Vec::new();
    let nerf = train_nerf(isa, &scene.views, field.clone(), &cfg, 1, |s| log.push(s)).expect("the bench scene trains");
    let (samples, rays) = rates(&log);
    push("train_samples_per_s", "samples/s", samples);
    push("train_rays_per_s", "rays/s", rays);
    let glass = crate::data::workspace::workspace(64, 30, 0.0, true);
    let config = ResidualConfig {
        residual: field,
        kind: MixKind::Mixnet(DensityMix::Raw),
        mixnet: MixnetEncoding::Own(default_mixnet_grid()),
    };
    let residual_cfg = TrainConfig { steps: scaled(60.0).max(8) as u32, ..cfg.clone() };
    let mut log = Vec::new();
    let residual = train_residual(isa, nerf.clone(), &glass.views, config, &residual_cfg, 1, |s| log.push(s))
        .expect("the bench scene trains");
    let (samples, rays) = rates(&log);
    // The Mixnet's network against the NeRF's two, in executed forward + backward
    // multiply-adds per sample.
    let nets = nerf_mlps();
    let mixnet_flops = residual.field.mixnet().mlp().fwd_bwd_macs_per_sample() as f64
        / (nets.0.fwd_bwd_macs_per_sample() + nets.1.fwd_bwd_macs_per_sample()) as f64;
    push("train_residual_samples_per_s", "samples/s", samples);
    push("train_residual_rays_per_s", "rays/s", rays);
    let k = Intrinsics::from_fov_x(200, 200, 50f32.to_radians());
    let pose = scene.views[0].pose;
    // The robot's library call: `DepthRenderer` with its defaults (thinned grid), on this pool.
    let request = DepthRequest { method: DepthMethod::default(), kind: DepthKind::Z };
    let mut subjects = vec![
        TrainedView { model: LoadedModel::Nerf(Box::new(nerf.clone())), intrinsics: k, pose },
        TrainedView { model: LoadedModel::Residual(Box::new(residual)), intrinsics: k, pose },
    ];
    for t in trained {
        let same = subjects.iter().position(|s| s.figure() == t.figure()).expect("both kinds are listed");
        subjects[same] = t;
    }
    for s in subjects {
        let (name, k, pose) = (s.figure(), s.intrinsics, s.pose);
        let mut z = vec![0f32; (k.width * k.height) as usize];
        let mut camera = DepthRenderer::new(s.model);
        let v = time_reps(reps, || camera.depth(&k, &pose, request, &mut z).expect("a valid camera and buffer"));
        push(name, "ms", v.iter().map(|s| s * 1e3).collect());
    }
    // Occupancy-grid updates of that model at the default 128³: a warm-up update evaluates
    // every cell, a later one ¼ random + ¼ occupied cells (DESIGN §2.5), all through the
    // density-only path on all threads.
    let mut occ = crate::render::OccupancyGrid::new(nerf.field.config().aabb, Default::default());
    let mut ctx = Default::default();
    let mut orng = Rng::new(11);
    for (name, step) in [("occupancy_update_ms_warmup", 0), ("occupancy_update_ms", u32::MAX)] {
        let v = time_reps(reps, || {
            occ.update(step, &mut orng, |p, sigma| {
                crate::field::model::Model::density(&nerf.field, isa, &nerf.params, p, sigma, &mut ctx)
            })
        });
        push(name, "ms", v.iter().map(|s| s * 1e3).collect());
    }

    let mut report =
        BenchReport { cpu_level: isa.to_string(), threads, log2_table_size: opts.log2_table_size, figures };
    // The pipeline's own roofline: one training sample's three kernels (grid forward, MLP
    // forward + backward, grid backward) at their measured all-thread rates (medians); what a
    // step adds (marching, compositing, densities of samples past the opaque point, Adam,
    // occupancy updates) is overhead on it. A residual training sample: the background's
    // forward (grid forward and the networks' forward, ⅓ of their forward + backward FLOPs),
    // the residual's full pass, and the Mixnet's (its grid measured; its 32 → 32 → 1 network
    // costed by its share of the networks' padded multiply-adds).
    let ns = |name: &str| report.get(name).unwrap_or(f64::NAN);
    let mlp_ns = 1e9 / ns("mlp_fwd_bwd_samples_per_s");
    let (grid_fwd, grid_bwd) = (ns("hash_grid_fwd_ns_per_sample"), ns("hash_grid_bwd_ns_per_sample"));
    let mixnet_ns = ns("mixnet_grid_fwd_ns_per_sample") + ns("mixnet_grid_bwd_ns_per_sample") + mlp_ns * mixnet_flops;
    let bound = 1e9 / (mlp_ns + grid_fwd + grid_bwd);
    let residual_bound = 1e9 / (grid_fwd + mlp_ns / 3.0 + mlp_ns + grid_fwd + grid_bwd + mixnet_ns);
    for (name, v) in
        [("train_kernel_bound_samples_per_s", bound), ("train_residual_kernel_bound_samples_per_s", residual_bound)]
    {
        report.figures.push((name.to_string(), "samples/s", Stat { median: v, min: v, max: v }));
    }
    // Derived ratios (from medians).
    let ratio = |a: &str, b: &str, r: &BenchReport| r.get(a).zip(r.get(b)).map(|(a, b)| a / b).unwrap_or(f64::NAN);
    let derived = [
        ("mlp_fraction_of_fma_peak_1t", ratio("mlp_fwd_bwd_gflops_1t", "fma_peak_gflops_1t", &report)),
        // Against the limit of the unit the level runs the MLP's products on: the tile
        // unit at the AMX level, the FMA units elsewhere.
        ("mlp_fraction_of_level_peak_1t", {
            let peak = report.get("tile_peak_gflops_1t").or(report.get("fma_peak_gflops_1t"));
            report.get("mlp_fwd_bwd_gflops_1t").zip(peak).map(|(a, b)| a / b).unwrap_or(f64::NAN)
        }),
        ("mlp_thread_scaling", ratio("mlp_fwd_bwd_gflops", "mlp_fwd_bwd_gflops_1t", &report)),
        ("train_fraction_of_kernel_bound", ratio("train_samples_per_s", "train_kernel_bound_samples_per_s", &report)),
        (
            "train_residual_fraction_of_kernel_bound",
            ratio("train_residual_samples_per_s", "train_residual_kernel_bound_samples_per_s", &report),
        ),
        (
            "hash_grid_fwd_bwd_over_gather_limit_1t",
            (report.get("hash_grid_fwd_ns_per_sample_1t").unwrap()
                + report.get("hash_grid_bwd_ns_per_sample_1t").unwrap())
                / report.get("gather_limit_ns_per_sample_1t").unwrap(),
        ),
    ];
    for (name, v) in derived {
        report.figures.push((name.to_string(), "ratio", Stat { median: v, min: v, max: v }));
    }
    report
}
