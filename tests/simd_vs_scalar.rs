//! Every SIMD kernel equals its scalar twin, on every CPU level the host has, over sizes that
//! include 0, 1, a prime and lane counts ± 1. Tolerances are stated per kernel.
//!
//! `RNERF_REQUIRE_LEVEL=avx2` (or `avx512`, `neon`) makes `required_level_is_tested` fail when that
//! level was not among the levels tested — so a CI run cannot silently skip the SIMD path.

mod common;

use common::{assert_close, cases};
use proptest::prelude::*;
use residual_nerf::encoding::{HashGrid, HashGridConfig, HashGridParams};
use residual_nerf::mlp::scalar::{matmul_bf16, matmul_tn_acc_bf16};
use residual_nerf::mlp::{
    matmul_first_with, matmul_tn_acc_with, matmul_with, Activation, Mlp, MlpConfig, MlpContext, MlpWorkspace,
};
use residual_nerf::rng::Rng;
use residual_nerf::simd::{CpuLevel, Isa};
use residual_nerf::train::adam::{step_kernel, AdamStep};
use residual_nerf::GradientMode;

/// Sizes that hit every tail: empty, single, lane counts ± 1 (4 and 8 lanes), primes, > one chunk.
const SIZES: &[usize] = &[0, 1, 2, 3, 4, 5, 7, 8, 9, 13, 31, 63, 64, 65, 251, 257, 600];

/// The SIMD levels (everything above scalar) this run tests.
fn simd_levels() -> Vec<Isa> {
    Isa::all().into_iter().filter(|i| i.level() != CpuLevel::Scalar).collect()
}

#[test]
fn required_level_is_tested() {
    let Ok(req) = std::env::var("RNERF_REQUIRE_LEVEL") else { return };
    let level = CpuLevel::parse(&req).unwrap_or_else(|| panic!("RNERF_REQUIRE_LEVEL={req} is not a level"));
    assert!(
        Isa::all().iter().any(|i| i.level() == level),
        "RNERF_REQUIRE_LEVEL={req}, but the levels tested are {:?}: the {req} kernels were skipped",
        Isa::all()
    );
}

fn positions(rng: &mut Rng, n: usize) -> Vec<[f32; 3]> {
    (0..n)
        .map(|i| match i % 11 {
            // Some points outside the cube, some on its faces, one NaN.
            0 => [rng.uniform(-0.2, 1.2), rng.uniform(-0.2, 1.2), rng.uniform(-0.2, 1.2)],
            1 => [1.0, rng.f32(), 0.0],
            2 if i % 3 == 0 => [f32::NAN, 0.5, 0.5],
            _ => [rng.f32(), rng.f32(), rng.f32()],
        })
        .collect()
}

fn grid_strategy() -> impl Strategy<Value = HashGridConfig> {
    (1usize..=16, 4u32..=14, 1u32..=16, 1u32..=64).prop_map(|(levels, log2t, base, extra)| HashGridConfig {
        levels,
        log2_table_size: log2t,
        base_resolution: base,
        finest_resolution: base * extra,
    })
}

proptest! {
    #![proptest_config(cases(12))]

    /// Forward: features agree to 2e-6 (FMA vs separate multiply-add over 8 corners of
    /// fp16 values in [−1, 1]). Backward: bit-identical (same weights, same scatter order).
    #[test]
    fn hash_grid_matches_scalar(config in grid_strategy(), seed in any::<u64>()) {
        let grid = HashGrid::new(config);
        let mut rng = Rng::new(seed);
        let params = HashGridParams::from_master((0..grid.n_params()).map(|_| rng.uniform(-1.0, 1.0)).collect());
        for &n in SIZES {
            let pos = positions(&mut rng, n);
            let mut want = vec![0.0; n * grid.output_width()];
            grid.forward(Isa::scalar(), &params.table, &pos, &mut want);
            let d: Vec<f32> = (0..want.len()).map(|_| rng.uniform(-1.0, 1.0)).collect();
            let mut want_g = vec![0.0; grid.n_params()];
            grid.backward_params(Isa::scalar(), &pos, &d, &mut want_g, GradientMode::Overwrite);
            let mut x86: Option<(Isa, Vec<f32>)> = None;
            for isa in simd_levels() {
                let mut got = vec![f32::NAN; want.len()];
                grid.forward(isa, &params.table, &pos, &mut got);
                assert_close(&got, &want, 2e-6, 0.0, &format!("{isa} grid forward n={n}"));
                // AVX2 and AVX-512 run the same weights and FMA chain: the same bits.
                if matches!(isa.level(), CpuLevel::Avx2 | CpuLevel::Avx512) {
                    match &x86 {
                        Some((first, y)) => prop_assert!(
                            got.iter().zip(y).all(|(a, b)| a.to_bits() == b.to_bits()),
                            "{} and {} grid forward differ: n={}", first, isa, n
                        ),
                        None => x86 = Some((isa, got.clone())),
                    }
                }
                let mut got_g = vec![1.0; grid.n_params()];
                grid.backward_params(isa, &pos, &d, &mut got_g, GradientMode::Overwrite);
                prop_assert!(got_g == want_g, "{} grid backward n={} differs from scalar", isa, n);
            }
        }
    }

    /// Layer kernels: |Δ| ≤ 1e-5 · (1 + k) per output (inputs in [−1, 1]) against the scalar
    /// spec — at the AMX level against its bf16 twins `matmul_bf16` and `matmul_tn_acc_bf16`
    /// (the rounding is the same, the tile unit's summation order is its own); the fp32 x86
    /// levels (AVX2, AVX-512: the same FMA chain per output, tiled differently) agree bit for
    /// bit.
    #[test]
    fn matmul_kernels_match_scalar(k in prop::sample::select(vec![8usize, 16, 24, 32, 48, 64]), o in prop::sample::select(vec![16usize, 32, 48, 64]), relu in any::<bool>(), seed in any::<u64>()) {
        let mut rng = Rng::new(seed);
        let w: Vec<f32> = (0..k * o).map(|_| rng.uniform(-1.0, 1.0)).collect();
        for &rows in SIZES {
            let x: Vec<f32> = (0..rows * k).map(|_| rng.uniform(-1.0, 1.0)).collect();
            let dz: Vec<f32> = (0..rows * o).map(|_| rng.uniform(-1.0, 1.0)).collect();
            let mut want = vec![0.0; rows * o];
            matmul_with(Isa::scalar(), &x, rows, k, &w, o, &mut want, relu);
            let mut want_bf16 = vec![0.0; rows * o];
            matmul_bf16(&x, rows, k, &w, o, &mut want_bf16, relu);
            let mut want_dw: Vec<f32> = (0..k * o).map(|i| i as f32 * 0.01).collect();
            let mut want_dw_bf16 = want_dw.clone();
            matmul_tn_acc_with(Isa::scalar(), &x, rows, k, &dz, o, &mut want_dw);
            matmul_tn_acc_bf16(&x, rows, k, &dz, o, &mut want_dw_bf16);
            let mut x86: Option<(Isa, Vec<f32>, Vec<f32>)> = None;
            for isa in simd_levels() {
                let mut got = vec![f32::NAN; rows * o];
                matmul_with(isa, &x, rows, k, &w, o, &mut got, relu);
                let want = if isa.level().mlp_is_fp32() { &want } else { &want_bf16 };
                assert_close(&got, want, 1e-5 * (1.0 + k as f32), 0.0, &format!("{isa} matmul rows={rows} k={k} o={o}"));
                let mut got_dw: Vec<f32> = (0..k * o).map(|i| i as f32 * 0.01).collect();
                matmul_tn_acc_with(isa, &x, rows, k, &dz, o, &mut got_dw);
                let want_dw = if isa.level().mlp_is_fp32() { &want_dw } else { &want_dw_bf16 };
                assert_close(&got_dw, want_dw, 1e-5 * (1.0 + rows as f32), 1e-6, &format!("{isa} matmul_tn_acc rows={rows} k={k} o={o}"));
                if matches!(isa.level(), CpuLevel::Avx2 | CpuLevel::Avx512) {
                    if let Some((first, y, dw)) = &x86 {
                        let same = |a: &[f32], b: &[f32]| a.iter().zip(b).all(|(a, b)| a.to_bits() == b.to_bits());
                        prop_assert!(same(&got, y) && same(&got_dw, dw), "{} and {} differ: rows={} k={} o={}", first, isa, rows, k, o);
                    } else {
                        x86 = Some((isa, got, got_dw));
                    }
                }
            }
            // The first-column kernel is column 0 of each level's own matmul, bit for bit.
            for isa in std::iter::once(Isa::scalar()).chain(simd_levels()) {
                let mut full = vec![f32::NAN; rows * o];
                matmul_with(isa, &x, rows, k, &w, o, &mut full, relu);
                let mut first = vec![f32::NAN; rows];
                matmul_first_with(isa, &x, rows, k, &w, o, &mut first, relu);
                let col0: Vec<f32> = full.chunks(o).map(|r| r[0]).collect();
                prop_assert!(first.iter().zip(&col0).all(|(a, b)| a.to_bits() == b.to_bits()), "{} matmul_first rows={} k={} o={} is not matmul's column 0", isa, rows, k, o);
            }
        }
    }

    /// Whole MLP (the NeRF's colour network shape and a W=16/32 net with every activation):
    /// outputs, weight gradients and input gradients within 1e-4 relative.
    #[test]
    fn mlp_matches_scalar(hidden in 1usize..=3, input in 1usize..=40, output in 1usize..=20, act in 0usize..4, seed in any::<u64>()) {
        let acts = [Activation::None, Activation::Relu, Activation::Sigmoid, Activation::TruncExp];
        let cfg = MlpConfig { input, output, hidden_layers: hidden, hidden_activation: Activation::Relu, output_activation: acts[act] };
        check_mlp(Mlp::<64>::new(cfg.clone()), seed);
        check_mlp(Mlp::<32>::new(cfg.clone()), seed);
        check_mlp(Mlp::<16>::new(cfg), seed);
    }

    /// Adam: parameters and moments within 1e-6 relative (FMA); the fp16 mirror is exactly
    /// the round-to-nearest-even of each level's own parameters.
    #[test]
    fn adam_matches_scalar(seed in any::<u64>(), l2 in prop::sample::select(vec![0.0f32, 1e-3])) {
        let mut rng = Rng::new(seed);
        let hp = AdamStep { lr_t: 1e-2, beta1: 0.9, beta2: 0.99, epsilon: 1e-15, l2 };
        for &n in SIZES {
            let p0: Vec<f32> = (0..n).map(|_| rng.uniform(-1.0, 1.0)).collect();
            let g: Vec<f32> = (0..n).map(|_| rng.uniform(-1.0, 1.0)).collect();
            let m0: Vec<f32> = (0..n).map(|_| rng.uniform(-0.1, 0.1)).collect();
            let v0: Vec<f32> = (0..n).map(|_| rng.uniform(0.0, 0.1)).collect();
            let run = |isa: Isa| {
                let (mut p, mut m, mut v, mut h) = (p0.clone(), m0.clone(), v0.clone(), vec![0u16; n]);
                step_kernel(isa, hp, &mut p, &g, &mut m, &mut v, Some(&mut h));
                (p, m, v, h)
            };
            let want = run(Isa::scalar());
            for isa in simd_levels() {
                let got = run(isa);
                assert_close(&got.0, &want.0, 1e-6, 1e-6, &format!("{isa} adam p n={n}"));
                assert_close(&got.1, &want.1, 1e-7, 1e-6, &format!("{isa} adam m n={n}"));
                assert_close(&got.2, &want.2, 1e-7, 1e-6, &format!("{isa} adam v n={n}"));
                for (i, (&h, &p)) in got.3.iter().zip(&got.0).enumerate() {
                    prop_assert_eq!(h, half::f16::from_f32(p).to_bits(), "{} mirror[{}]", isa, i);
                }
            }
        }
    }
}

/// The AMX level's whole-network tolerance against the fp32 spec (relative to the largest
/// value): bf16 operands carry 8 significant bits (relative rounding ≤ 2⁻⁹ per operand), over
/// up to four layers of products.
const BF16_TOL: f32 = 2e-2;

/// Forward: outputs within 1e-4 relative (AMX: [`BF16_TOL`]) (continuous in the weights, so rounding stays
/// small). Backward: both levels start from the *same* saved activations (the SIMD forward's),
/// since a pre-activation within rounding of 0 can fall on either side of the ReLU kink and
/// flip a sample's gradient mask — a property of ReLU, not of a kernel.
fn check_mlp<const W: usize>(mlp: Mlp<W>, seed: u64) {
    let mut rng = Rng::new(seed);
    let params = mlp.init_params(&mut rng);
    let scale = |v: &[f32]| v.iter().fold(0f32, |a, b| a.max(b.abs())).max(1.0);
    for &n in SIZES {
        let x: Vec<f32> = (0..n * mlp.input_stride())
            .map(|i| if i % mlp.input_stride() < mlp.config().input { rng.uniform(-1.0, 1.0) } else { 0.0 })
            .collect();
        let d: Vec<f32> = (0..n * mlp.output_stride()).map(|_| rng.uniform(-1.0, 1.0)).collect();
        let forward = |isa: Isa| {
            let mut ctx = MlpContext::default();
            mlp.forward(isa, &params, &x, n, &mut ctx);
            ctx
        };
        let backward = |isa: Isa, ctx: &MlpContext| {
            let mut g = vec![0.0; mlp.n_params()];
            let mut dx = vec![0.0; n * mlp.input_stride()];
            mlp.backward(
                isa,
                &params,
                &x,
                ctx,
                &d,
                &mut g,
                GradientMode::Overwrite,
                Some(&mut dx),
                &mut MlpWorkspace::default(),
            );
            (g, dx)
        };
        let want_ctx = forward(Isa::scalar());
        // forward_first is each level's forward column 0, bit for bit.
        for isa in std::iter::once(Isa::scalar()).chain(simd_levels()) {
            let ctx = forward(isa);
            let mut first = vec![f32::NAN; n];
            mlp.forward_first(isa, &params, &x, n, &mut MlpContext::default(), &mut first);
            let col0 = ctx.output().chunks(mlp.output_stride()).map(|r| r[0]);
            assert!(first.iter().zip(col0).all(|(a, b)| a.to_bits() == b.to_bits()), "{isa} W={W} forward_first n={n}");
        }
        // The fp32 x86 levels run the same FMA chains: the same outputs and gradients, bit for bit.
        let x86: Vec<Isa> =
            simd_levels().into_iter().filter(|i| i.level() != CpuLevel::Neon && i.level().mlp_is_fp32()).collect();
        if let [a, b] = x86[..] {
            let (ca, cb) = (forward(a), forward(b));
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<u32>>();
            assert_eq!(bits(ca.output()), bits(cb.output()), "{a}/{b} W={W} mlp output n={n}");
            let ((ga, dxa), (gb, dxb)) = (backward(a, &ca), backward(b, &ca));
            assert_eq!(bits(&ga), bits(&gb), "{a}/{b} W={W} mlp dW n={n}");
            assert_eq!(bits(&dxa), bits(&dxb), "{a}/{b} W={W} mlp dx n={n}");
        }
        for isa in simd_levels() {
            let tol = if isa.level().mlp_is_fp32() { 1e-4 } else { BF16_TOL };
            let ctx = forward(isa);
            let (got, want) = (ctx.output(), want_ctx.output());
            assert_close(got, want, tol * scale(want), tol, &format!("{isa} W={W} mlp output n={n}"));
            let (g, dx) = backward(isa, &ctx);
            let (wg, wdx) = backward(Isa::scalar(), &ctx);
            assert_close(&g, &wg, tol * scale(&wg), tol, &format!("{isa} W={W} mlp dW n={n}"));
            assert_close(&dx, &wdx, tol * scale(&wdx), tol, &format!("{isa} W={W} mlp dx n={n}"));
        }
    }
}
