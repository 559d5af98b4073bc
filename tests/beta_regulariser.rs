//! The β regularisers of the background-aware residual model (`train::beta`): the penalty on
//! unchanged rays and the entropy, against f64 finite differences — of one ray's terms with
//! respect to the Mixnet logits, and through the residual field's chunk path into the Mixnet's
//! weights.

mod common;

use glam::Vec3;
use proptest::prelude::*;
use residual_nerf::encoding::HashGridConfig;
use residual_nerf::field::mix::{DensityMix, MixKind};
use residual_nerf::field::mixnet::MixnetEncoding;
use residual_nerf::field::model::Model;
use residual_nerf::field::residual::{ResidualConfig, ResidualField, ResidualParams};
use residual_nerf::field::NerfConfig;
use residual_nerf::render::Aabb;
use residual_nerf::rng::Rng;
use residual_nerf::train::beta::beta_terms;

/// The terms in f64 as functions of the logits m (β = sigmoid(m)); σ fixes the weights T_i δ_i.
fn reference(sigma: &[f32], delta: &[f32], m: &[f64], u: f64, e: f64) -> f64 {
    let mut log_t = 0.0f64;
    let mut loss = 0.0;
    for i in 0..m.len() {
        let b = 1.0 / (1.0 + (-m[i]).exp());
        let h = -(b * b.ln() + (1.0 - b) * (1.0 - b).ln());
        loss += log_t.exp() * delta[i] as f64 * (u * b + e * h);
        log_t -= sigma[i] as f64 * delta[i] as f64;
    }
    loss
}

proptest! {
    #![proptest_config(common::cases(64))]

    /// dL/dm_i = dL/dβ_i · β_i(1−β_i) from `beta_terms` against central differences of the f64
    /// terms, and the loss itself against the f64 terms.
    #[test]
    fn beta_terms_match_finite_differences(
        sigma in prop::collection::vec(0.0f32..30.0, 1..24),
        seed in 0u64..1000,
        u in 0.0f32..2.0,
        e in 0.0f32..2.0,
    ) {
        let n = sigma.len();
        let mut rng = Rng::new(seed);
        let delta: Vec<f32> = (0..n).map(|_| rng.uniform(0.001, 0.05)).collect();
        let m: Vec<f32> = (0..n).map(|_| rng.uniform(-6.0, 6.0)).collect();
        let beta: Vec<f32> = m.iter().map(|&x| 1.0 / (1.0 + (-x).exp())).collect();
        let mut d_beta = vec![0.0; n];
        let loss = beta_terms(&sigma, &delta, &beta, u, e, &mut d_beta);
        let m64: Vec<f64> = m.iter().map(|&x| x as f64).collect();
        let want = reference(&sigma, &delta, &m64, u as f64, e as f64);
        prop_assert!((loss as f64 - want).abs() <= 1e-4 * want.abs() + 1e-6, "loss {loss} vs {want}");
        let h = 1e-5;
        for i in 0..n {
            let (mut up, mut down) = (m64.clone(), m64.clone());
            up[i] += h;
            down[i] -= h;
            let fd = (reference(&sigma, &delta, &up, u as f64, e as f64)
                - reference(&sigma, &delta, &down, u as f64, e as f64)) / (2.0 * h);
            let analytic = d_beta[i] as f64 * beta[i] as f64 * (1.0 - beta[i] as f64);
            prop_assert!((analytic - fd).abs() <= 1e-3 * fd.abs() + 1e-6, "sample {i}: {analytic} vs {fd}");
        }
    }
}

/// Through the residual field's fused chunk path: a dL/dβ given to the chunk reaches the
/// Mixnet's weights as the finite differences of Σ g_i β_i say, with no density or colour
/// gradient.
#[test]
fn a_beta_gradient_reaches_the_mixnet_weights() {
    let isa = common::best_fp32_isa();
    let grid = HashGridConfig { levels: 4, log2_table_size: 8, base_resolution: 4, finest_resolution: 16 };
    let aabb = Aabb { min: Vec3::splat(-1.0), max: Vec3::splat(1.0) };
    let mut rng = Rng::new(5);
    let bg = common::lively_nerf(grid, &mut rng);
    let own =
        MixnetEncoding::Own(HashGridConfig { levels: 2, log2_table_size: 6, base_resolution: 4, finest_resolution: 8 });
    for kind in [MixKind::Mixnet(DensityMix::Raw), MixKind::Mixnet(DensityMix::Activated)] {
        let cfg = ResidualConfig { residual: NerfConfig { grid, aabb }, kind, mixnet: own };
        let f = ResidualField::new(bg.clone(), cfg);
        let mut p = Model::init_params(&f, &mut rng);
        p.mixnet.grid.master.iter_mut().for_each(|v| *v = rng.uniform(-1.0, 1.0));
        p.mixnet.grid.sync_mirror();
        let w = p.mixnet.mlp.weights_mut();
        for x in w.iter_mut() {
            *x = rng.uniform(-0.5, 0.5);
        }
        p.mixnet.mlp.sync();
        let n = 12;
        let pos: Vec<Vec3> =
            (0..n).map(|_| Vec3::new(rng.uniform(-0.9, 0.9), rng.uniform(-0.9, 0.9), rng.uniform(-0.9, 0.9))).collect();
        let dirs = vec![Vec3::Z; n];
        let g: Vec<f32> = (0..n).map(|_| rng.uniform(-1.0, 1.0)).collect();
        let keep: Vec<u32> = (0..n as u32).collect();
        // L(params) = Σ g_i β_i, β from the chunk path.
        let loss = |q: &ResidualParams| -> f64 {
            let mut c = Default::default();
            let (mut s, mut rgb) = (vec![0.0; n], vec![[0.0; 3]; n]);
            Model::chunk_density(&f, isa, q, 0, &pos, &mut s, &mut c);
            Model::chunk_colour(&f, isa, q, &keep, &dirs, &mut rgb, &mut c);
            let (beta, _) = Model::chunk_beta(&f, &mut c).expect("a Mixnet has β");
            beta.iter().zip(&g).map(|(&b, &g)| b as f64 * g as f64).sum()
        };
        let mut c = Default::default();
        let (mut s, mut rgb) = (vec![0.0; n], vec![[0.0; 3]; n]);
        Model::chunk_density(&f, isa, &p, 0, &pos, &mut s, &mut c);
        Model::chunk_colour(&f, isa, &p, &keep, &dirs, &mut rgb, &mut c);
        let (_, d_beta) = Model::chunk_beta(&f, &mut c).unwrap();
        assert_zeroed(d_beta);
        d_beta.copy_from_slice(&g);
        let mut slot = Default::default();
        Model::begin_slot(&f, &mut slot);
        Model::chunk_backward(&f, isa, &p, &mut c, &vec![0.0; n], &vec![[0.0; 3]; n], &mut slot);
        let mut grads = Model::zero_grads(&f);
        Model::finish_step(&f, isa, std::slice::from_ref(&slot), &mut grads);
        assert!(grads.residual.density.iter().chain(&grads.residual.colour).all(|&x| x == 0.0));
        let mlp = &grads.mixnet.mlp;
        let mut idx: Vec<usize> = (0..mlp.len()).collect();
        idx.sort_by(|&a, &b| mlp[b].abs().total_cmp(&mlp[a].abs()));
        assert!(mlp[idx[0]].abs() > 1e-4, "{kind:?}: no gradient reached the Mixnet");
        for &i in &idx[..4] {
            let h = 1e-2;
            let (mut up, mut down) = (p.clone(), p.clone());
            up.mixnet.mlp.weights_mut()[i] += h;
            up.mixnet.mlp.sync();
            down.mixnet.mlp.weights_mut()[i] -= h;
            down.mixnet.mlp.sync();
            let fd = (loss(&up) - loss(&down)) / (2.0 * h as f64);
            let tol = 0.03 * fd.abs().max(mlp[i].abs() as f64) + 1e-4;
            assert!((mlp[i] as f64 - fd).abs() <= tol, "{kind:?} weight {i}: analytic {} vs {fd}", mlp[i]);
        }
    }
}

/// The chunk hands out a zeroed dL/dβ buffer.
fn assert_zeroed(d_beta: &[f32]) {
    assert!(d_beta.iter().all(|&x| x == 0.0), "the chunk's dL/dβ buffer starts at zero");
}

/// In the trainer: with every pixel changed the β penalty never applies (the run is the run
/// without it, bit for bit); with none changed it reaches the Mixnet.
#[test]
fn the_trainer_penalises_beta_on_unchanged_rays_only() {
    use residual_nerf::data::workspace;
    use residual_nerf::render::{OccupancyConfig, OccupancyGrid};
    use residual_nerf::train::beta::BetaRegulariser;
    use residual_nerf::train::trainer::{Focus, TrainConfig, Trainer};
    let isa = common::best_fp32_isa();
    let grid = HashGridConfig { levels: 4, log2_table_size: 8, base_resolution: 4, finest_resolution: 16 };
    let mut rng = Rng::new(9);
    let bg = common::lively_nerf(grid, &mut rng);
    let views = workspace::workspace(12, 3, 0.0, true).views;
    let cfg = ResidualConfig {
        residual: NerfConfig { grid, aabb: bg.field.config().aabb },
        kind: MixKind::Mixnet(DensityMix::Raw),
        mixnet: MixnetEncoding::default(),
    };
    let f = ResidualField::new(bg.clone(), cfg);
    let params = Model::init_params(&f, &mut rng);
    let run = |pixels: Vec<(u32, u32)>, unchanged: f32| {
        let mut c = TrainConfig::with_steps(3);
        c.rays_per_step = 64;
        c.occupancy = OccupancyConfig { resolution: 8, ..Default::default() };
        c.focus = Some(Focus { share: 0.0, pixels: std::sync::Arc::new(pixels), reach: None, spared: None });
        c.beta = BetaRegulariser { unchanged, entropy: 0.0, entropy_from: 0.0 };
        let occupancy = OccupancyGrid::new(bg.field.config().aabb, c.occupancy.clone());
        let mut t = Trainer::starting_at(isa, &f, &views, &c, params.clone(), occupancy);
        while !t.is_done() {
            t.step().expect("trains");
        }
        t.into_state().params.mixnet.mlp.weights().to_vec()
    };
    let all: Vec<(u32, u32)> = (0..views.len() as u32).flat_map(|v| (0..144).map(move |p| (v, p))).collect();
    let off = run(all.clone(), 0.0);
    assert_eq!(run(all, 1.0), off, "a penalty on rays that all changed");
    assert_ne!(run(Vec::new(), 1.0), off, "the penalty on unchanged rays did not reach the Mixnet");
}
