//! Gradients against f64 central finite differences of independent f64 references
//! (tests/common), and Adam / activations against closed forms. Every check runs on every
//! CPU level the host has.

mod common;

use common::{
    act_f64, cases, grid_encode_f64, kink_is_clear, mlp_forward_f64, mlp_kink_margin_f64, mlp_tol, table_as_f64,
};
use proptest::prelude::*;
use residual_nerf::encoding::hashgrid::pack_entry;
use residual_nerf::encoding::{HashGrid, HashGridConfig, HashGridParams};
use residual_nerf::mlp::{Activation, Mlp, MlpConfig, MlpContext, MlpWorkspace};
use residual_nerf::rng::Rng;
use residual_nerf::simd::Isa;
use residual_nerf::train::{Adam, AdamConfig, LrSchedule};
use residual_nerf::GradientMode;

fn small_grid() -> impl Strategy<Value = HashGridConfig> {
    (1usize..=4, 5u32..=8, 2u32..=6, 1u32..=8).prop_map(|(levels, log2t, base, extra)| HashGridConfig {
        levels,
        log2_table_size: log2t,
        base_resolution: base,
        finest_resolution: base * extra,
    })
}

/// A table whose values are exact in fp16, so f32 kernels and the f64 reference share them.
fn fp16_exact_params(grid: &HashGrid, rng: &mut Rng) -> HashGridParams {
    let master: Vec<f32> = (0..grid.n_params()).map(|_| half::f16::from_f32(rng.uniform(-1.0, 1.0)).to_f32()).collect();
    HashGridParams::from_master(master)
}

proptest! {
    #![proptest_config(cases(8))]

    /// L = Σ g·enc(p). dL/dparams from `backward_params` equals central differences of the
    /// f64 reference encoding w.r.t. every parameter; the forward equals the reference.
    #[test]
    fn hash_grid_param_gradient_matches_finite_differences(config in small_grid(), seed in any::<u64>()) {
        let grid = HashGrid::new(config);
        let mut rng = Rng::new(seed);
        let params = fp16_exact_params(&grid, &mut rng);
        let pos: Vec<[f32; 3]> = (0..5).map(|_| [rng.f32(), rng.f32(), rng.f32()]).collect();
        let g: Vec<f32> = (0..pos.len() * grid.output_width()).map(|_| rng.uniform(-1.0, 1.0)).collect();
        let theta = table_as_f64(&params.table);
        let loss = |th: &[f64]| -> f64 {
            pos.iter().enumerate().map(|(s, p)| {
                let e = grid_encode_f64(&grid, th, p.map(|v| v as f64));
                e.iter().zip(&g[s * grid.output_width()..]).map(|(a, b)| a * *b as f64).sum::<f64>()
            }).sum()
        };
        let h = 1e-3; // the loss is linear in θ: central differences are exact up to rounding
        let mut fd = vec![0.0; theta.len()];
        for i in 0..theta.len() {
            let mut t = theta.clone();
            t[i] += h;
            let up = loss(&t);
            t[i] -= 2.0 * h;
            fd[i] = (up - loss(&t)) / (2.0 * h);
        }
        for isa in Isa::all() {
            let mut enc = vec![0.0; pos.len() * grid.output_width()];
            grid.forward(isa, &params.table, &pos, &mut enc);
            for (s, p) in pos.iter().enumerate() {
                let want = grid_encode_f64(&grid, &theta, p.map(|v| v as f64));
                for (a, b) in enc[s * grid.output_width()..(s + 1) * grid.output_width()].iter().zip(&want) {
                    prop_assert!((*a as f64 - b).abs() < 1e-5, "{} forward {} vs {}", isa, a, b);
                }
            }
            let mut grads = vec![0.0; grid.n_params()];
            grid.backward_params(isa, &pos, &g, &mut grads, GradientMode::Overwrite);
            for (i, (a, b)) in grads.iter().zip(&fd).enumerate() {
                prop_assert!((*a as f64 - b).abs() < 1e-5 * (1.0 + b.abs()), "{} dθ[{}]: {} vs fd {}", isa, i, a, b);
            }
            // Accumulate adds, Ignore leaves the buffer alone.
            let before = grads.clone();
            grid.backward_params(isa, &pos, &g, &mut grads, GradientMode::Accumulate);
            prop_assert!(grads.iter().zip(&before).all(|(a, b)| (a - 2.0 * b).abs() <= 1e-6 * b.abs().max(1.0)));
            let snapshot = grads.clone();
            grid.backward_params(isa, &pos, &g, &mut grads, GradientMode::Ignore);
            prop_assert!(grads == snapshot);
        }
    }

    /// dL/dposition from `backward_positions` equals central differences of the f64 reference.
    #[test]
    fn hash_grid_position_gradient_matches_finite_differences(config in small_grid(), seed in any::<u64>()) {
        let grid = HashGrid::new(config);
        let mut rng = Rng::new(seed);
        let params = fp16_exact_params(&grid, &mut rng);
        let theta = table_as_f64(&params.table);
        let pos: Vec<[f32; 3]> = (0..6).map(|_| [rng.uniform(0.05, 0.95), rng.uniform(0.05, 0.95), rng.uniform(0.05, 0.95)]).collect();
        let g: Vec<f32> = (0..pos.len() * grid.output_width()).map(|_| rng.uniform(-1.0, 1.0)).collect();
        let mut dp = vec![[0.0; 3]; pos.len()];
        grid.backward_positions(&params.table, &pos, &g, &mut dp);
        let max_res = grid.levels().iter().map(|l| l.resolution).max().unwrap() as f64;
        // The encoding's derivative jumps at cell boundaries: keep every point ≥ 1e-3 cell from
        // one on every level (the FD step below is ≤ 1e-4 cell, so it never crosses one).
        prop_assume!(pos.iter().all(|p| grid.levels().iter().all(|l| p.iter().all(|&v| {
            let f = (v as f64 * l.resolution as f64).fract();
            f > 1e-3 && f < 1.0 - 1e-3
        }))));
        for (s, p) in pos.iter().enumerate() {
            let gs = &g[s * grid.output_width()..(s + 1) * grid.output_width()];
            let f = |q: [f64; 3]| grid_encode_f64(&grid, &theta, q).iter().zip(gs).map(|(a, b)| a * *b as f64).sum::<f64>();
            for k in 0..3 {
                // A step far below the finest cell, so it (almost surely) crosses no cell boundary.
                let h = 1e-4 / max_res;
                let mut up = p.map(|v| v as f64);
                let mut dn = up;
                up[k] += h;
                dn[k] -= h;
                let fd = (f(up) - f(dn)) / (2.0 * h);
                prop_assert!((dp[s][k] as f64 - fd).abs() < 1e-3 * (1.0 + fd.abs()), "sample {} axis {}: {} vs fd {}", s, k, dp[s][k], fd);
            }
        }
    }

    /// L = Σ d·y. Weight and input gradients of the MLP equal central differences of the f64
    /// reference MLP, for every activation on the output and ReLU inside.
    #[test]
    fn mlp_gradients_match_finite_differences(input in 1usize..=20, output in 1usize..=5, hidden in 1usize..=2, act in 0usize..4, seed in any::<u64>()) {
        let acts = [Activation::None, Activation::Relu, Activation::Sigmoid, Activation::TruncExp];
        let mlp = Mlp::<16>::new(MlpConfig { input, output, hidden_layers: hidden, hidden_activation: Activation::Relu, output_activation: acts[act] });
        let mut rng = Rng::new(seed);
        let params = mlp.init_params(&mut rng);
        let n = 3;
        let (si, so) = (mlp.input_stride(), mlp.output_stride());
        let x: Vec<f32> = (0..n * si).map(|i| if i % si < input { rng.uniform(-1.0, 1.0) } else { 0.0 }).collect();
        let d: Vec<f32> = (0..n * so).map(|_| rng.uniform(-1.0, 1.0)).collect();
        let loss = |th: &[f64], xs: &[f64]| -> f64 {
            (0..n).map(|b| {
                let y = mlp_forward_f64(&mlp, th, &xs[b * si..b * si + input]);
                y.last().unwrap().iter().enumerate().map(|(j, v)| v * d[b * so + j] as f64).sum::<f64>()
            }).sum()
        };
        let th: Vec<f64> = params.weights().iter().map(|&v| v as f64).collect();
        let xs: Vec<f64> = x.iter().map(|&v| v as f64).collect();
        // Skip inputs within 1e-4 of a ReLU kink (the FD step or f32 rounding could cross it).
        let margin = (0..n).map(|b| mlp_kink_margin_f64(&mlp, &th, &xs[b * si..b * si + input])).fold(f64::INFINITY, f64::min);
        prop_assume!(margin > 1e-4);
        let h = 1e-6;
        for isa in Isa::all().into_iter().filter(|&i| kink_is_clear(i, margin)) {
            let tol = mlp_tol(isa, 2e-3);
            let (mut ctx, mut ws) = (MlpContext::default(), MlpWorkspace::default());
            mlp.forward(isa, &params, &x, n, &mut ctx);
            let mut g = vec![0.0; mlp.n_params()];
            let mut dx = vec![0.0; n * si];
            mlp.backward(isa, &params, &x, &ctx, &d, &mut g, GradientMode::Overwrite, Some(&mut dx), &mut ws);
            for l in mlp.layers() {
                for kk in 0..l.k {
                    for j in 0..l.o {
                        let i = l.offset + kk * l.o + j;
                        let fd = if kk < l.k_real && j < l.o_real {
                            let mut t = th.clone();
                            t[i] += h;
                            let up = loss(&t, &xs);
                            t[i] -= 2.0 * h;
                            (up - loss(&t, &xs)) / (2.0 * h)
                        } else {
                            0.0 // padding never gets a gradient
                        };
                        prop_assert!((g[i] as f64 - fd).abs() < tol * (1.0 + fd.abs()), "{} dW[{}]: {} vs fd {}", isa, i, g[i], fd);
                    }
                }
            }
            for b in 0..n {
                for kk in 0..input {
                    let mut t = xs.clone();
                    t[b * si + kk] += h;
                    let up = loss(&th, &t);
                    t[b * si + kk] -= 2.0 * h;
                    let fd = (up - loss(&th, &t)) / (2.0 * h);
                    let a = dx[b * si + kk] as f64;
                    prop_assert!((a - fd).abs() < tol * (1.0 + fd.abs()), "{} dx[{},{}]: {} vs fd {}", isa, b, kk, a, fd);
                }
            }
        }
    }

    /// Each activation's derivative (from its output) against f64 central differences; the
    /// trunc_exp derivative against its closed form e^clamp(x, −15, 15).
    #[test]
    fn activation_derivatives(x in -20.0f32..20.0) {
        for act in [Activation::None, Activation::Relu, Activation::Sigmoid] {
            if act == Activation::Relu && x.abs() < 1e-3 { continue; }
            let h = 1e-5;
            let fd = (act_f64(act, x as f64 + h) - act_f64(act, x as f64 - h)) / (2.0 * h);
            let got = act.derivative_from_output(act.forward(x)) as f64;
            prop_assert!((got - fd).abs() < 1e-4 * (1.0 + fd.abs()), "{:?} at {}: {} vs {}", act, x, got, fd);
        }
        let want = (x.clamp(-15.0, 15.0) as f64).exp();
        let got = Activation::TruncExp.derivative_from_output(Activation::TruncExp.forward(x)) as f64;
        prop_assert!((got - want).abs() < 1e-5 * want, "trunc_exp' at {}: {} vs {}", x, got, want);
        if x.abs() < 15.0 {
            let fd = ((x as f64 + 1e-5).exp() - (x as f64 - 1e-5).exp()) / 2e-5;
            prop_assert!((got - fd).abs() < 1e-4 * fd);
        }
    }

    /// Adam over several steps against the closed-form recursion in f64, mirror included.
    #[test]
    fn adam_matches_closed_form(seed in any::<u64>(), n in 0usize..40, l2 in prop::sample::select(vec![0.0f32, 1e-2])) {
        let mut rng = Rng::new(seed);
        let cfg = AdamConfig { l2, ..AdamConfig::default() };
        let p0: Vec<f32> = (0..n).map(|_| rng.uniform(-1.0, 1.0)).collect();
        let grads: Vec<Vec<f32>> = (0..5).map(|_| (0..n).map(|_| rng.uniform(-1.0, 1.0)).collect()).collect();
        let lr = 1e-2;
        // f64 reference
        let (b1, b2, eps) = (cfg.beta1 as f64, cfg.beta2 as f64, cfg.epsilon as f64);
        let mut p: Vec<f64> = p0.iter().map(|&v| v as f64).collect();
        let (mut m, mut v) = (vec![0f64; n], vec![0f64; n]);
        for (t, g) in grads.iter().enumerate() {
            let t = t as i32 + 1;
            for i in 0..n {
                let gi = g[i] as f64 + l2 as f64 * p[i];
                m[i] = b1 * m[i] + (1.0 - b1) * gi;
                v[i] = b2 * v[i] + (1.0 - b2) * gi * gi;
                let mhat = m[i] / (1.0 - b1.powi(t));
                let vhat = v[i] / (1.0 - b2.powi(t));
                p[i] -= lr * mhat / (vhat.sqrt() + eps * (1.0 - b2.powi(t)).sqrt().recip());
            }
        }
        for isa in Isa::all() {
            let mut adam = Adam::new(n, cfg.clone());
            let mut params = p0.clone();
            let mut mirror = vec![0u16; n];
            for g in &grads {
                adam.step(isa, lr as f32, &mut params, g, Some(&mut mirror));
            }
            prop_assert_eq!(adam.steps(), 5);
            for i in 0..n {
                prop_assert!((params[i] as f64 - p[i]).abs() < 1e-5, "{} p[{}]: {} vs {}", isa, i, params[i], p[i]);
                prop_assert_eq!(mirror[i], half::f16::from_f32(params[i]).to_bits());
            }
        }
    }

    /// Adam leaves blocks whose gradient and moments are all zero alone after its first step
    /// (a hash-table entry no sample has reached): the result is the full update's, bit for bit
    /// (parameters, moments, mirror), on every level. Blocks of 64 start receiving gradients at a
    /// random step or never, and then get zero gradients at some steps (their moments are not
    /// zero then, so they must be updated).
    #[test]
    fn adams_idle_blocks_keep_the_full_updates_bits(seed in any::<u64>(), n in 0usize..700) {
        use residual_nerf::train::adam::{step_kernel, AdamStep};
        let mut rng = Rng::new(seed);
        let cfg = AdamConfig::default();
        let p0: Vec<f32> = (0..n).map(|_| rng.uniform(-1.0, 1.0)).collect();
        let starts: Vec<usize> = (0..n.div_ceil(64)).map(|_| rng.uniform(0.0, 7.0) as usize).collect();
        let grads: Vec<Vec<f32>> = (0..6)
            .map(|t| {
                (0..n)
                    .map(|i| match t >= starts[i / 64] && rng.uniform(0.0, 1.0) < 0.6 {
                        true => rng.uniform(-1.0, 1.0),
                        false => 0.0,
                    })
                    .collect()
            })
            .collect();
        let lr = 1e-2f32;
        for isa in Isa::all() {
            let mut adam = Adam::new(n, cfg.clone());
            let (mut params, mut mirror) = (p0.clone(), vec![0u16; n]);
            // The full update every step, the same kernel.
            let (mut p, mut h, mut m, mut v) = (p0.clone(), vec![0u16; n], vec![0f32; n], vec![0f32; n]);
            for (t, g) in grads.iter().enumerate() {
                adam.step(isa, lr, &mut params, g, Some(&mut mirror));
                let t = t as i32 + 1;
                let (b1, b2) = (cfg.beta1 as f64, cfg.beta2 as f64);
                let lr_t = (lr as f64 * (1.0 - b2.powi(t)).sqrt() / (1.0 - b1.powi(t))) as f32;
                let hp = AdamStep { lr_t, beta1: cfg.beta1, beta2: cfg.beta2, epsilon: cfg.epsilon, l2: 0.0 };
                step_kernel(isa, hp, &mut p, g, &mut m, &mut v, Some(&mut h));
                let bits = |x: &[f32]| x.iter().map(|v| v.to_bits()).collect::<Vec<u32>>();
                prop_assert_eq!(bits(&params), bits(&p), "{} parameters at step {}", isa, t);
                prop_assert_eq!(&mirror, &h, "{} mirror at step {}", isa, t);
                prop_assert_eq!(bits(adam.moments().0), bits(&m), "{} first moments at step {}", isa, t);
                prop_assert_eq!(bits(adam.moments().1), bits(&v), "{} second moments at step {}", isa, t);
            }
        }
    }
}

#[test]
fn lr_schedule_closed_form() {
    let s = LrSchedule { base: 1e-2, warmup_steps: 4, decay_start: 10, decay_interval: 5, decay_factor: 0.5 };
    let want = [0.25e-2, 0.5e-2, 0.75e-2, 1e-2, 1e-2];
    for (i, w) in want.iter().enumerate() {
        assert!((s.lr(i as u32) - w).abs() < 1e-9, "step {i}");
    }
    assert_eq!(s.lr(9), 1e-2);
    assert_eq!(s.lr(10), 0.5e-2);
    assert_eq!(s.lr(14), 0.5e-2);
    assert_eq!(s.lr(15), 0.25e-2);
    assert_eq!(LrSchedule::default().lr(1_000_000), 1e-2);
}

/// The packed-entry helpers round-trip exactly representable values.
#[test]
fn pack_entry_round_trips() {
    let e = pack_entry(0.5, -2.25);
    assert_eq!(residual_nerf::encoding::hashgrid::unpack_entry(e), [0.5, -2.25]);
}
