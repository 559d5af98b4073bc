//! Shared helpers of the integration tests: proptest case counts and f64 reference
//! implementations written from DESIGN §2.1, independent of the crate's kernels.
#![allow(dead_code)]

use proptest::test_runner::Config;
use residual_nerf::encoding::hashgrid::{unpack_entry, LevelInfo, PRIME_Y, PRIME_Z};
use residual_nerf::encoding::HashGrid;
use residual_nerf::mlp::{Activation, Mlp};

/// Proptest config: `default` cases unless `PROPTEST_CASES` says otherwise.
pub fn cases(default: u32) -> Config {
    let cases = std::env::var("PROPTEST_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(default);
    Config { cases, failure_persistence: None, ..Config::default() }
}

/// f64 hash-grid encoding of `p` with parameters `params` (entry-major pairs).
pub fn grid_encode_f64(grid: &HashGrid, params: &[f64], p: [f64; 3]) -> Vec<f64> {
    let mut out = vec![0.0; grid.output_width()];
    for (l, level) in grid.levels().iter().enumerate() {
        if !p.iter().all(|v| (0.0..=1.0).contains(v)) {
            continue;
        }
        let r = level.resolution as f64;
        let mut cell = [0u32; 3];
        let mut w = [0f64; 3];
        for k in 0..3 {
            let q = p[k] * r;
            let f = q.floor().min(r - 1.0);
            cell[k] = f as u32;
            w[k] = q - f;
        }
        for c in 0..8u32 {
            let b = [c & 1, (c >> 1) & 1, (c >> 2) & 1];
            let i = ref_index(level, cell[0] + b[0], cell[1] + b[1], cell[2] + b[2]);
            let mut wt = 1.0;
            for k in 0..3 {
                wt *= if b[k] == 1 { w[k] } else { 1.0 - w[k] };
            }
            let e = level.offset + i as usize;
            out[2 * l] += wt * params[2 * e];
            out[2 * l + 1] += wt * params[2 * e + 1];
        }
    }
    out
}

/// DESIGN §2.1's index: dense `x + y(N+1) + z(N+1)²` or `(x ⊕ y·π₂ ⊕ z·π₃) mod T`.
pub fn ref_index(level: &LevelInfo, x: u32, y: u32, z: u32) -> u64 {
    if level.dense {
        let s = level.resolution as u64 + 1;
        x as u64 + y as u64 * s + z as u64 * s * s
    } else {
        let h = (x as u64) ^ ((y as u64 * PRIME_Y as u64) & 0xFFFF_FFFF) ^ ((z as u64 * PRIME_Z as u64) & 0xFFFF_FFFF);
        h % level.size as u64
    }
}

/// The table's fp16 values as f64 parameters.
pub fn table_as_f64(table: &[u32]) -> Vec<f64> {
    table.iter().flat_map(|&e| unpack_entry(e)).map(|v| v as f64).collect()
}

/// f64 MLP forward over one input row (unpadded width `input`), weights in the crate's
/// padded layout; returns every layer's activated output (unpadded widths).
pub fn mlp_forward_f64<const W: usize>(mlp: &Mlp<W>, params: &[f64], x: &[f64]) -> Vec<Vec<f64>> {
    let cfg = mlp.config();
    let last = mlp.layers().len() - 1;
    let mut acts: Vec<Vec<f64>> = Vec::new();
    let mut cur = x.to_vec();
    for (l, s) in mlp.layers().iter().enumerate() {
        let act = if l == last { cfg.output_activation } else { cfg.hidden_activation };
        let y: Vec<f64> = (0..s.o_real)
            .map(|j| {
                let z: f64 = (0..s.k_real).map(|kk| cur[kk] * params[s.offset + kk * s.o + j]).sum();
                act_f64(act, z)
            })
            .collect();
        acts.push(y.clone());
        cur = y;
    }
    acts
}

/// Smallest |pre-activation| of the hidden layers for one input row: how close the row is to
/// a ReLU kink (where finite differences and f32-vs-f64 comparisons are not meaningful).
pub fn mlp_kink_margin_f64<const W: usize>(mlp: &Mlp<W>, params: &[f64], x: &[f64]) -> f64 {
    let cfg = mlp.config();
    let last = mlp.layers().len() - 1;
    let mut cur = x.to_vec();
    let mut margin = f64::INFINITY;
    for s in mlp.layers().iter().take(last) {
        let z: Vec<f64> =
            (0..s.o_real).map(|j| (0..s.k_real).map(|kk| cur[kk] * params[s.offset + kk * s.o + j]).sum()).collect();
        margin = z.iter().fold(margin, |m, v| m.min(v.abs()));
        cur = z.iter().map(|&v| act_f64(cfg.hidden_activation, v)).collect();
    }
    margin
}

pub fn act_f64(a: Activation, x: f64) -> f64 {
    match a {
        Activation::None => x,
        Activation::Relu => x.max(0.0),
        Activation::Sigmoid => 1.0 / (1.0 + (-x).exp()),
        Activation::TruncExp => x.exp(),
    }
}

/// |a − b| ≤ atol + rtol·|b|, with a message naming `what` and the index.
pub fn assert_close(a: &[f32], b: &[f32], atol: f32, rtol: f32, what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: lengths differ");
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        assert!((x - y).abs() <= atol + rtol * y.abs(), "{what}[{i}]: {x} vs {y} (atol {atol}, rtol {rtol})");
    }
}

/// A small NeRF of the synthesised tabletop (12 views of 16×16, 40 steps × 512 rays, 8-level
/// grid with log2T = 12): a trained model for rendering tests, a few seconds to make.
pub fn trained_tabletop() -> residual_nerf::field::Nerf {
    use residual_nerf::data::synth;
    use residual_nerf::encoding::HashGridConfig;
    use residual_nerf::field::NerfConfig;
    use residual_nerf::render::OccupancyConfig;
    use residual_nerf::train::trainer::{train_nerf, TrainConfig};
    let scene = synth::tabletop(16, 12, 0.0);
    let field = NerfConfig {
        grid: HashGridConfig { levels: 8, log2_table_size: 12, base_resolution: 4, finest_resolution: 64 },
        aabb: scene.aabb,
    };
    let mut cfg = TrainConfig::with_steps(40);
    cfg.rays_per_step = 512;
    cfg.background = synth::SKY;
    cfg.random_background = false; // the sky shows where rays miss the scene
    cfg.occupancy = OccupancyConfig { resolution: 16, steps_per_diagonal: 128, warmup_steps: 16, ..Default::default() };
    train_nerf(residual_nerf::simd::Isa::detect(), &scene.views, field, &cfg, 0, |_| {}).expect("trains")
}

/// A random NeRF over the box [-1, 1]³ with a lively grid (every table entry uniform in
/// [-1, 1], so densities and colours are far from constant) and a 4³ occupancy grid.
pub fn lively_nerf(
    grid: residual_nerf::encoding::HashGridConfig,
    rng: &mut residual_nerf::rng::Rng,
) -> residual_nerf::field::Nerf {
    use residual_nerf::field::{Nerf, NerfConfig, NerfField};
    use residual_nerf::render::{Aabb, OccupancyConfig, OccupancyGrid};
    let aabb = Aabb { min: glam::Vec3::splat(-1.0), max: glam::Vec3::splat(1.0) };
    let field = NerfField::new(NerfConfig { grid, aabb });
    let mut params = field.init_params(rng);
    params.grid.master.iter_mut().for_each(|v| *v = rng.uniform(-1.0, 1.0));
    params.grid.sync_mirror();
    let occupancy = OccupancyGrid::new(aabb, OccupancyConfig { resolution: 4, ..Default::default() });
    Nerf { field, params, occupancy }
}

/// Tolerance of a check against the f64 reference at `isa`: `fp32` at the fp32 levels; at the
/// AMX level, whose MLP forward and dL/dx products take bf16 operands (8 significant bits),
/// at least 3e-2.
pub fn mlp_tol(isa: residual_nerf::simd::Isa, fp32: f64) -> f64 {
    if isa.level().mlp_is_fp32() {
        fp32
    } else {
        fp32.max(3e-2)
    }
}

/// Whether a case whose pre-activations lie `margin` from the nearest ReLU kink is checked
/// against the f64 reference at `isa`: always at the fp32 levels (their callers skip cases
/// within rounding of a kink); at the AMX level only beyond 5e-2: bf16 rounding of a layer's
/// inputs and weights moves a pre-activation by ~1e-2 (measured: at 2e-2, a case whose nearest
/// unit was 0.037 from its kink failed once in 1264), and a flipped unit changes a gradient by O(1).
pub fn kink_is_clear(isa: residual_nerf::simd::Isa, margin: f64) -> bool {
    isa.level().mlp_is_fp32() || margin > 5e-2
}

/// The best level whose MLP products are fp32: for finite differences through the crate's own
/// forward, which the AMX level's bf16 operands make piecewise constant at small steps.
pub fn best_fp32_isa() -> residual_nerf::simd::Isa {
    residual_nerf::simd::Isa::all().into_iter().rfind(|i| i.level().mlp_is_fp32()).expect("scalar is always there")
}

/// The gain per channel that turned `plain` into `shot` (the same view rendered at two
/// exposures): `Σ shot / Σ plain` over the pixels neither saturates.
pub fn observed_gain(plain: &[[f32; 3]], shot: &[[f32; 3]]) -> [f64; 3] {
    std::array::from_fn(|c| {
        let (mut num, mut den) = (0.0f64, 0.0f64);
        for (p, s) in plain.iter().zip(shot) {
            if p[c] < 0.8 && s[c] < 0.98 {
                (num, den) = (num + s[c] as f64, den + p[c] as f64);
            }
        }
        num / den
    })
}
