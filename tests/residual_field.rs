//! The residual field's backward (frozen background + residual NeRF + Mixnet) against central
//! finite differences of its forward, for every mixing rule: gradients reach the residual's
//! grid and networks and the Mixnet's grid and network.

mod common;

use glam::Vec3;
use residual_nerf::encoding::HashGridConfig;
use residual_nerf::field::mix::{DensityMix, MixKind};
use residual_nerf::field::mixnet::MixnetEncoding;
use residual_nerf::field::residual::{ResidualConfig, ResidualContext, ResidualField, ResidualParams};
use residual_nerf::field::{Nerf, NerfConfig};
use residual_nerf::render::Aabb;
use residual_nerf::rng::Rng;
use residual_nerf::GradientMode;

fn grid() -> HashGridConfig {
    HashGridConfig { levels: 4, log2_table_size: 8, base_resolution: 4, finest_resolution: 16 }
}

fn aabb() -> Aabb {
    Aabb { min: Vec3::splat(-1.0), max: Vec3::splat(1.0) }
}

/// A random (untrained) background with a lively table.
fn background(rng: &mut Rng) -> Nerf {
    common::lively_nerf(grid(), rng)
}

/// L = Σ a_i σ_i + Σ b_i · c_i.
fn loss(f: &ResidualField, p: &ResidualParams, pos: &[Vec3], dirs: &[Vec3], a: &[f32], b: &[[f32; 3]]) -> f64 {
    let n = pos.len();
    let (mut sigma, mut rgb) = (vec![0.0; n], vec![[0.0; 3]; n]);
    f.forward(common::best_fp32_isa(), p, pos, dirs, &mut sigma, &mut rgb, &mut ResidualContext::default());
    (0..n).map(|i| a[i] as f64 * sigma[i] as f64 + (0..3).map(|k| (b[i][k] * rgb[i][k]) as f64).sum::<f64>()).sum()
}

/// Indices of the `k` largest-magnitude entries.
fn top(g: &[f32], k: usize) -> Vec<usize> {
    let mut idx: Vec<usize> = (0..g.len()).collect();
    idx.sort_by(|&x, &y| g[y].abs().total_cmp(&g[x].abs()));
    idx.truncate(k);
    idx
}

#[test]
fn residual_gradients_match_finite_differences() {
    // Finite differences through the field's own forward: an fp32 level (see best_fp32_isa).
    let isa = common::best_fp32_isa();
    let own =
        MixnetEncoding::Own(HashGridConfig { levels: 2, log2_table_size: 6, base_resolution: 4, finest_resolution: 8 });
    // The last two: colour-only mixing where the background is solid, its level the median
    // background density of the points (half of them mix colour only).
    for (kind, mixnet, solid) in [
        (MixKind::Mixnet(DensityMix::Activated), own, false),
        (MixKind::Mixnet(DensityMix::Raw), own, false),
        (MixKind::Mixnet(DensityMix::Activated), MixnetEncoding::Shared, false),
        (MixKind::Mixnet(DensityMix::Raw), MixnetEncoding::Shared, false),
        (MixKind::Sum, own, false),
        (MixKind::Mixnet(DensityMix::Raw), own, true),
        (MixKind::Mixnet(DensityMix::Activated), own, true),
    ] {
        let mut rng = Rng::new(3);
        let bg = background(&mut rng);
        let cfg = ResidualConfig { residual: NerfConfig { grid: grid(), aabb: aabb() }, kind, mixnet };
        let mut f = ResidualField::new(bg.clone(), cfg);
        let mut p = f.init_params(&mut rng);
        p.residual.grid.master.iter_mut().for_each(|v| *v = rng.uniform(-1.0, 1.0));
        p.residual.grid.sync_mirror();
        p.mixnet.grid.master.iter_mut().for_each(|v| *v = rng.uniform(-1.0, 1.0));
        p.mixnet.grid.sync_mirror();
        // The output layer starts at zero (β = ½); give it real (unpadded) weights.
        let last = *f.mixnet().mlp().layers().last().unwrap();
        let w = p.mixnet.mlp.weights_mut();
        for k in 0..last.k_real {
            w[last.offset + k * last.o] = rng.uniform(-0.3, 0.3);
        }
        p.mixnet.mlp.sync();
        let n = 6;
        let pos: Vec<Vec3> =
            (0..n).map(|_| Vec3::new(rng.uniform(-0.9, 0.9), rng.uniform(-0.9, 0.9), rng.uniform(-0.9, 0.9))).collect();
        let dirs: Vec<Vec3> =
            (0..n).map(|_| Vec3::new(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), 0.5).normalize()).collect();
        let a: Vec<f32> = (0..n).map(|_| rng.uniform(-1.0, 1.0)).collect();
        let b: Vec<[f32; 3]> =
            (0..n).map(|_| [rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0)]).collect();
        if solid {
            f = f.with_solid_background(median_background_sigma(&bg, &pos));
        }

        let mut ctx = ResidualContext::default();
        let (mut sigma, mut rgb) = (vec![0.0; n], vec![[0.0; 3]; n]);
        f.forward(isa, &p, &pos, &dirs, &mut sigma, &mut rgb, &mut ctx);
        let mut g = f.zero_grads();
        f.backward(isa, &p, &mut ctx, &a, &b, &mut g, GradientMode::Overwrite);
        assert!(f.background.params == bg.params, "the background must not change");

        let check = |name: &str, analytic: f32, perturb: &dyn Fn(&mut ResidualParams, f32), h: f32| {
            let (mut up, mut down) = (p.clone(), p.clone());
            perturb(&mut up, h);
            perturb(&mut down, -h);
            let fd = (loss(&f, &up, &pos, &dirs, &a, &b) - loss(&f, &down, &pos, &dirs, &a, &b)) / (2.0 * h as f64);
            let tol = 0.05 * fd.abs().max(analytic.abs() as f64) + 2e-3;
            assert!(
                (analytic as f64 - fd).abs() <= tol,
                "{kind:?} {mixnet:?} {name}: analytic {analytic} vs finite difference {fd}"
            );
        };
        for i in top(&g.residual.grid, 3) {
            check(
                "residual grid",
                g.residual.grid[i],
                &|q, h| {
                    q.residual.grid.master[i] += h;
                    q.residual.grid.sync_mirror();
                },
                0.05,
            );
        }
        for i in top(&g.residual.density, 2) {
            check(
                "residual density weight",
                g.residual.density[i],
                &|q, h| {
                    q.residual.density.weights_mut()[i] += h;
                    q.residual.density.sync();
                },
                1e-3,
            );
        }
        for i in top(&g.residual.colour, 2) {
            check(
                "residual colour weight",
                g.residual.colour[i],
                &|q, h| {
                    q.residual.colour.weights_mut()[i] += h;
                    q.residual.colour.sync();
                },
                1e-3,
            );
        }
        if kind == MixKind::Sum {
            assert!(g.mixnet.grid.iter().chain(&g.mixnet.mlp).all(|&v| v == 0.0), "Sum has no Mixnet");
            continue;
        }
        assert!(g.mixnet.mlp.iter().any(|&v| v != 0.0), "{kind:?}: the Mixnet must be trained");
        if mixnet == MixnetEncoding::Shared {
            // Its dL/dh(x) is in the residual grid's gradient, checked against finite
            // differences of the whole mixed field above.
            assert!(g.mixnet.grid.is_empty(), "a shared Mixnet has no grid of its own");
        }
        for i in top(&g.mixnet.grid, 2) {
            check(
                "mixnet grid",
                g.mixnet.grid[i],
                &|q, h| {
                    q.mixnet.grid.master[i] += h;
                    q.mixnet.grid.sync_mirror();
                },
                0.05,
            );
        }
        for i in top(&g.mixnet.mlp, 2) {
            check(
                "mixnet weight",
                g.mixnet.mlp[i],
                &|q, h| {
                    q.mixnet.mlp.weights_mut()[i] += h;
                    q.mixnet.mlp.sync();
                },
                1e-3,
            );
        }
    }
}

/// A background σ splitting the points at `pos` in half: halfway (in log density) between the
/// two middle ones, so no point sits on the level (the field's own background evaluation may
/// differ from this density-only one in the last bit).
fn median_background_sigma(bg: &Nerf, pos: &[Vec3]) -> f32 {
    let mut s = vec![0.0; pos.len()];
    bg.field.density(common::best_fp32_isa(), &bg.params, pos, &mut s, &mut Default::default());
    s.sort_by(f32::total_cmp);
    let k = s.len() / 2;
    (0.5 * (s[k - 1] + s[k])).exp()
}

/// A residual field of `kind` with its own small Mixnet grid over a random background, its
/// residual grid drawn uniformly from ±`spread`, and `n` random points inside the box.
fn random_field(
    kind: MixKind,
    spread: f32,
    n: usize,
    rng: &mut Rng,
) -> (Nerf, ResidualField, ResidualParams, Vec<Vec3>) {
    let bg = background(rng);
    let own =
        MixnetEncoding::Own(HashGridConfig { levels: 2, log2_table_size: 6, base_resolution: 4, finest_resolution: 8 });
    let cfg = ResidualConfig { residual: NerfConfig { grid: grid(), aabb: aabb() }, kind, mixnet: own };
    let field = ResidualField::new(bg.clone(), cfg);
    let mut p = field.init_params(rng);
    p.residual.grid.master.iter_mut().for_each(|v| *v = rng.uniform(-spread, spread));
    p.residual.grid.sync_mirror();
    let pos: Vec<Vec3> =
        (0..n).map(|_| Vec3::new(rng.uniform(-0.9, 0.9), rng.uniform(-0.9, 0.9), rng.uniform(-0.9, 0.9))).collect();
    (bg, field, p, pos)
}

/// With colour-only mixing where the background is solid, the mixed density there is the
/// background's whatever the residual and β are, and the residual's density gets no gradient
/// from it; the colour still mixes. Elsewhere the density mixes as without it.
#[test]
fn colour_only_mixing_keeps_the_solid_backgrounds_density() {
    let isa = common::best_fp32_isa();
    for kind in [MixKind::Mixnet(DensityMix::Raw), MixKind::Mixnet(DensityMix::Activated)] {
        let n = 64;
        let (bg, plain, p, pos) = random_field(kind, 1.0, n, &mut Rng::new(8));
        let dirs = vec![Vec3::Z; n];
        let level = median_background_sigma(&bg, &pos);
        let gated = plain.clone().with_solid_background(level);
        let mut s_bg = vec![0.0; n];
        bg.field.density(isa, &bg.params, &pos, &mut s_bg, &mut Default::default());
        let run = |f: &ResidualField| {
            let (mut sigma, mut rgb) = (vec![0.0; n], vec![[0.0f32; 3]; n]);
            let mut ctx = ResidualContext::default();
            f.forward(isa, &p, &pos, &dirs, &mut sigma, &mut rgb, &mut ctx);
            let mut g = f.zero_grads();
            // dL/dσ = 1 at every point: the residual's density gets a gradient only where it mixes.
            f.backward(isa, &p, &mut ctx, &vec![1.0; n], &vec![[0.0; 3]; n], &mut g, GradientMode::Overwrite);
            (sigma, rgb, g)
        };
        let (sp, cp, _) = run(&plain);
        let (sg, cg, gg) = run(&gated);
        let (mut solid, mut air) = (0, 0);
        for i in 0..n {
            if s_bg[i].exp() >= level {
                solid += 1;
                let want = s_bg[i].exp();
                assert!((sg[i] - want).abs() <= 1e-5 * want, "{kind:?}: σ {} against the background's {want}", sg[i]);
            } else {
                air += 1;
                assert_eq!(sg[i], sp[i], "{kind:?}: the density mixes as before in the background's air");
            }
            assert_eq!(cg[i], cp[i], "{kind:?}: the colour mixes as before");
        }
        assert!(solid > 0 && air > 0);
        // Solid points pass no density gradient to the residual: with every point solid, none.
        let all = plain.clone().with_solid_background(1e-30);
        let (_, _, g_all) = run(&all);
        assert!(
            g_all.residual.density.iter().all(|&v| v == 0.0),
            "{kind:?}: a solid point trained the residual's density"
        );
        assert!(gg.residual.density.iter().any(|&v| v != 0.0), "{kind:?}: the air's points train it");
    }
}

/// The depth-only chunk path with the threshold given skips the Mixnet where the two densities
/// lie on one side of it: every sample lands on the same side of the threshold as with the
/// Mixnet evaluated everywhere (with β pushed towards 1 and towards 0, so a wrongly skipped
/// sample shows), and at a threshold near the field's densities both kinds of sample occur.
/// For both density mixes, with and without colour-only mixing where the background is solid.
#[test]
fn the_depth_only_path_skips_the_mixnet_only_where_beta_cannot_cross_the_threshold() {
    use residual_nerf::field::model::Model;
    let isa = common::best_fp32_isa();
    for kind in [MixKind::Mixnet(DensityMix::Raw), MixKind::Mixnet(DensityMix::Activated)] {
        let n = 256;
        let (bg, plain, mut p, pos) = random_field(kind, 1.5, n, &mut Rng::new(11));
        let m = median_background_sigma(&bg, &pos);
        // Mixnets that have left β = ½ (the output layer starts at zero) for either end: β near 1
        // and near 0, so a sample skipped where its densities straddle m lands on the wrong side
        // in one of the two, and a skipped sample's σ (the mix at β = ½) differs from the
        // evaluated one.
        for weight in [50.0, -50.0] {
            let last = *plain.mixnet().mlp().layers().last().unwrap();
            let w = p.mixnet.mlp.weights_mut();
            for k in 0..last.k_real {
                w[last.offset + k * last.o] = weight;
            }
            p.mixnet.mlp.sync();
            for field in [plain.clone(), plain.clone().with_solid_background(m)] {
                let mut chunk = Default::default();
                let mut exact = vec![0.0; n];
                Model::chunk_density_only(&field, isa, &p, &pos, None, &mut exact, &mut chunk);
                let mut skipped = vec![0.0; n];
                Model::chunk_density_only(&field, isa, &p, &pos, Some(m), &mut skipped, &mut chunk);
                let (mut same, mut differ) = (0, 0);
                for i in 0..n {
                    assert_eq!(skipped[i] >= m, exact[i] >= m, "{kind:?}: sample {i} moved across the threshold");
                    if skipped[i].to_bits() == exact[i].to_bits() {
                        same += 1;
                    } else {
                        differ += 1;
                    }
                }
                assert!(same > 0 && differ > 0, "{kind:?}: {same} samples evaluated β, {differ} skipped it");
            }
        }
    }
}
