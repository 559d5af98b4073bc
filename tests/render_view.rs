//! Whole-view rendering: the segmented, early-stopping [`ViewRenderer`] gives what marching
//! each ray in one go and compositing it whole gives (colour, expected and threshold z-depth),
//! and the depth-only path gives the same threshold depth as the full one, for any number of
//! samples per round; an earlier compositing stop moves colours by less than the stop and
//! leaves threshold depth alone, and filled with the ray's own colour it renders a field of
//! one colour exactly; the colour tail leaves threshold depth alone too.

use glam::Vec3;
use residual_nerf::data::synth;
use residual_nerf::encoding::HashGridConfig;
use residual_nerf::field::{Nerf, NerfConfig, NerfField};
use residual_nerf::mlp::Activation;
use residual_nerf::render::view::COLOUR_TAIL;
use residual_nerf::render::{
    composite_ray, pixel_ray, threshold_depth, DensityThreshold, FullOutputs, Intrinsics, OccupancyConfig,
    OccupancyGrid, PackedSamples, Pose, Ray, StopFill, ViewRenderer,
};
use residual_nerf::rng::Rng;
use residual_nerf::simd::Isa;
use residual_nerf::train::trainer::{train_nerf, TrainConfig};

/// Pixel `p`'s ray marched whole on `occupancy` in one go: the ray, its samples, their
/// positions and directions (the reference the renderer's segments are checked against).
fn whole_ray(
    occupancy: &OccupancyGrid,
    k: &Intrinsics,
    pose: &Pose,
    p: usize,
) -> (Ray, PackedSamples, Vec<Vec3>, Vec<Vec3>) {
    let ray = pixel_ray(k, pose, p as u32 % k.width, p as u32 / k.width);
    let mut s = PackedSamples::default();
    occupancy.march(ray.origin, ray.dir, &mut s);
    let pos: Vec<Vec3> = s.t.iter().map(|&t| ray.at(t)).collect();
    let dirs = vec![ray.dir; pos.len()];
    (ray, s, pos, dirs)
}

/// The bits of `z`, for comparisons that must be exact.
fn bits(z: &[f32]) -> Vec<u32> {
    z.iter().map(|x| x.to_bits()).collect()
}

/// Per pixel, how far the colour `a` moved from `b` (the largest channel's difference).
fn moved(a: &[[f32; 3]], b: &[[f32; 3]]) -> Vec<f32> {
    a.iter().zip(b).map(|(a, b)| (0..3).map(|c| (a[c] - b[c]).abs()).fold(0f32, f32::max)).collect()
}

#[test]
fn segmented_rendering_equals_whole_ray_compositing() {
    let scene = synth::tabletop(16, 12, 0.0);
    let field = NerfConfig {
        grid: HashGridConfig { levels: 8, log2_table_size: 12, base_resolution: 4, finest_resolution: 64 },
        aabb: scene.aabb,
    };
    let mut cfg = TrainConfig::with_steps(60);
    cfg.rays_per_step = 512;
    cfg.background = synth::SKY;
    cfg.random_background = false; // the sky shows where rays miss the scene
    cfg.occupancy = OccupancyConfig {
        resolution: 16,
        steps_per_diagonal: 128,
        max_samples: 200,
        warmup_steps: 16,
        decay: 0.95,
        ..Default::default()
    };
    let isa = Isa::detect();
    let nerf = train_nerf(isa, &scene.views, field, &cfg, 0, |_| {}).expect("trains");
    let test = synth::tabletop(16, 2, 0.4);
    let mut renderer = ViewRenderer::new();
    for m in [DensityThreshold::Sigma(3.0), DensityThreshold::Raw(1.0)] {
        for v in &test.views {
            let k = &v.intrinsics;
            let n = (k.width * k.height) as usize;
            let (mut rgb, mut ez, mut tz, mut dz) = (vec![[0.0; 3]; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
            renderer.full(
                isa,
                &(&nerf).into(),
                k,
                &v.pose,
                cfg.background,
                m,
                FullOutputs { rgb: &mut rgb, expected_z: &mut ez, threshold_z: &mut tz, beta: &mut [] },
            );
            renderer.depth(isa, &(&nerf).into(), k, &v.pose, m, &mut dz);
            // Rounds of any length continue where the last stopped: the same bits.
            for round in [1, 3, 4, 64] {
                let mut other = ViewRenderer::new();
                other.set_depth_round(round);
                let mut oz = vec![0.0; n];
                other.depth(isa, &(&nerf).into(), k, &v.pose, m, &mut oz);
                assert_eq!(bits(&oz), bits(&dz), "depth rounds of {round} samples");
            }
            // The full pass of a renderer set up another way: its colours and threshold depths.
            let full = |r: &mut ViewRenderer| {
                let (mut rgb, mut tz) = (vec![[0.0; 3]; n], vec![0.0; n]);
                let out = FullOutputs { rgb: &mut rgb, expected_z: &mut [], threshold_z: &mut tz, beta: &mut [] };
                r.full(isa, &(&nerf).into(), k, &v.pose, cfg.background, m, out);
                (rgb, tz)
            };
            // An earlier stop moves every colour channel by less than the stop and leaves the
            // threshold depth's bits; at the default it is the same render.
            for stop in [1e-4, 0.01, 0.1] {
                let mut early = ViewRenderer::new();
                early.set_early_stop(stop, StopFill::Background);
                let (erg, etz) = full(&mut early);
                assert_eq!(bits(&etz), bits(&tz), "threshold depth with the stop at {stop}");
                let moved = moved(&erg, &rgb);
                let most = moved.iter().fold(0f32, |a, &b| a.max(b));
                assert!(most < stop, "stop {stop}: a colour moved by {most}");
                match stop == 1e-4 {
                    true => assert_eq!(bits(erg.as_flattened()), bits(rgb.as_flattened()), "the default stop"),
                    false => assert!(moved.iter().any(|&d| d > 0.0), "stop {stop} changed no colour"),
                }
            }
            // The colour tail keeps the threshold depth's bits and moves colours by its
            // quadrature error: little on average at the measured reach, and not at all when off.
            for reach in [0.0, COLOUR_TAIL, 4.0] {
                let mut tail = ViewRenderer::new();
                tail.set_colour_tail(reach);
                let (trg, ttz) = full(&mut tail);
                assert_eq!(bits(&ttz), bits(&tz), "threshold depth with the colour tail at {reach}");
                let moved = moved(&trg, &rgb);
                let mean = moved.iter().sum::<f32>() / n as f32;
                match reach {
                    0.0 => assert_eq!(bits(trg.as_flattened()), bits(rgb.as_flattened()), "the tail off"),
                    COLOUR_TAIL => {
                        assert!(mean < 0.01, "the colour tail at {reach} moved colours by {mean} on average")
                    }
                    _ => assert!(moved.iter().any(|&d| d > 0.0), "the colour tail at {reach} changed no colour"),
                }
            }
            let mut hits = 0;
            for p in 0..n {
                let (ray, s, pos, dirs) = whole_ray(&nerf.occupancy, k, &v.pose, p);
                let (mut raw, mut crgb) = (vec![0.0; pos.len()], vec![[0.0; 3]; pos.len()]);
                let mut ctx = Default::default();
                if !pos.is_empty() {
                    nerf.field.forward(isa, &nerf.params, &pos, &dirs, &mut raw, &mut crgb, &mut ctx);
                }
                let sigma: Vec<f32> = raw.iter().map(|&r| Activation::TruncExp.forward(r)).collect();
                let c: Vec<[f32; 3]> = crgb.iter().map(|c| c.map(|x| Activation::Sigmoid.forward(x))).collect();
                let whole = composite_ray(&sigma, &s.delta, &s.t, &c, cfg.background);
                let want_t = threshold_depth(&s.t, &raw, m).map_or(f32::NAN, |t| ray.range_to_z(t));
                for ch in 0..3 {
                    assert!(
                        (rgb[p][ch] - whole.rgb[ch]).abs() < 1e-4,
                        "pixel {p}: colour {:?} vs {:?}",
                        rgb[p],
                        whole.rgb
                    );
                }
                assert!((ez[p] - ray.range_to_z(whole.depth)).abs() < 1e-3, "pixel {p}: expected depth");
                let same = |a: f32, b: f32| (a.is_nan() && b.is_nan()) || (a - b).abs() < 1e-5;
                assert!(same(tz[p], want_t), "pixel {p}: threshold {} vs {want_t}", tz[p]);
                assert!(same(dz[p], tz[p]), "pixel {p}: depth-only {} vs full {}", dz[p], tz[p]);
                hits += want_t.is_finite() as usize;
            }
            assert!(hits > n / 4, "the trained model should have solid surfaces ({hits} of {n} pixels hit)");
        }
    }
}

/// The full path of a residual model (the training step's chunk path, colour and β only of
/// the samples a ray composites) against compositing each whole ray from the batch forward:
/// the same colour, expected depth and β, and the threshold depth bit for bit.
#[test]
fn a_residual_models_full_render_equals_whole_ray_compositing() {
    use residual_nerf::data::workspace;
    use residual_nerf::field::mix::{DensityMix, MixKind};
    use residual_nerf::field::mixnet::{default_mixnet_grid, MixnetEncoding};
    use residual_nerf::field::residual::ResidualConfig;
    use residual_nerf::render::view::Scene;
    use residual_nerf::train::trainer::train_residual;
    let isa = Isa::detect();
    let (bg, glass) = (workspace::workspace(16, 12, 0.0, false), workspace::workspace(16, 12, 0.0, true));
    let field = NerfConfig {
        grid: HashGridConfig { levels: 8, log2_table_size: 12, base_resolution: 4, finest_resolution: 64 },
        aabb: bg.aabb,
    };
    let mut cfg = TrainConfig::with_steps(40);
    cfg.rays_per_step = 256;
    cfg.occupancy = OccupancyConfig {
        resolution: 16,
        steps_per_diagonal: 128,
        max_samples: 200,
        warmup_steps: 16,
        ..Default::default()
    };
    let nerf = train_nerf(isa, &bg.views, field.clone(), &cfg, 0, |_| {}).expect("trains");
    let config = ResidualConfig {
        residual: field,
        kind: MixKind::Mixnet(DensityMix::Raw),
        mixnet: MixnetEncoding::Own(default_mixnet_grid()),
    };
    let model = train_residual(isa, nerf, &glass.views, config, &cfg, 0, |_| {}).expect("trains");
    let scene = Scene::from(&model);
    let m = DensityThreshold::Sigma(3.0);
    let bgc = [0.2, 0.5, 0.9];
    let v = &workspace::workspace(16, 2, 0.4, true).views[1];
    let k = &v.intrinsics;
    let n = (k.width * k.height) as usize;
    let (mut rgb, mut ez, mut tz, mut beta) = (vec![[0.0; 3]; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let out = FullOutputs { rgb: &mut rgb, expected_z: &mut ez, threshold_z: &mut tz, beta: &mut beta };
    ViewRenderer::new().full(isa, &scene, k, &v.pose, bgc, m, out);
    let (mut some_beta, mut hits) = (false, 0);
    for p in 0..n {
        let (ray, s, pos, dirs) = whole_ray(&model.occupancy, k, &v.pose, p);
        let (mut sigma, mut c, mut b) = (vec![0.0; pos.len()], vec![[0.0; 3]; pos.len()], Vec::new());
        let mut ctx = Default::default();
        if !pos.is_empty() {
            model.field.forward(isa, &model.params, &pos, &dirs, &mut sigma, &mut c, &mut ctx);
            model.field.betas(&ctx, &mut b);
        }
        let whole = composite_ray(&sigma, &s.delta, &s.t, &c, bgc);
        let mut weights = vec![0.0; sigma.len()];
        residual_nerf::render::composite::weights_from_density(&sigma, &s.delta, &mut weights);
        let want_beta: f32 = weights.iter().zip(&b).map(|(w, b)| w * b).sum();
        let want_t =
            s.t.iter().zip(&sigma).find(|(_, &x)| x >= m.min_sigma()).map_or(f32::NAN, |(&t, _)| ray.range_to_z(t));
        for ch in 0..3 {
            assert!((rgb[p][ch] - whole.rgb[ch]).abs() < 1e-4, "pixel {p}: colour {:?} vs {:?}", rgb[p], whole.rgb);
        }
        assert!((ez[p] - ray.range_to_z(whole.depth)).abs() < 1e-3, "pixel {p}: expected depth");
        assert!((beta[p] - want_beta).abs() < 1e-4, "pixel {p}: β {} vs {want_beta}", beta[p]);
        assert!(
            tz[p].to_bits() == want_t.to_bits() || (tz[p].is_nan() && want_t.is_nan()),
            "pixel {p}: threshold {} vs {want_t}",
            tz[p]
        );
        some_beta |= want_beta > 1e-3;
        hits += want_t.is_finite() as usize;
    }
    assert!(some_beta, "the model should mix somewhere");
    assert!(hits > n / 8, "the model should have solid surfaces ({hits} of {n} pixels hit)");
}

/// An early stop filled with the ray's own colour ([`StopFill::RayColour`]): on a field of one
/// colour (the colour network's weights zero, so every sample is sigmoid(0) = ½) every ray it
/// stops renders ½ whatever the stop, where the background fill pulls it towards the
/// background (pure red here) by up to the stop; rays it does not stop render as with the
/// background fill; threshold depth keeps its bits.
#[test]
fn the_rays_own_colour_fills_an_early_stop_exactly_on_a_field_of_one_colour() {
    let isa = Isa::detect();
    let scene = synth::tabletop(16, 1, 0.0);
    let grid = HashGridConfig { levels: 6, log2_table_size: 10, base_resolution: 4, finest_resolution: 32 };
    let field = NerfField::new(NerfConfig { grid, aabb: scene.aabb });
    let mut rng = Rng::new(5);
    let mut params = field.init_params(&mut rng);
    params.grid.master.iter_mut().for_each(|v| *v = rng.uniform(-4.0, 4.0));
    params.grid.sync_mirror();
    // Dense enough that most rays turn opaque inside the box.
    params.density.weights_mut().iter_mut().for_each(|w| *w *= 3.0);
    params.density.sync();
    params.colour.weights_mut().fill(0.0);
    params.colour.sync();
    let occupancy = OccupancyGrid::new(
        scene.aabb,
        OccupancyConfig { resolution: 16, steps_per_diagonal: 128, max_samples: 400, ..Default::default() },
    );
    let nerf = Nerf { field, params, occupancy };
    let red = [1.0, 0.0, 0.0];
    let m = DensityThreshold::Sigma(3.0);
    let v = &scene.views[0];
    let n = (v.intrinsics.width * v.intrinsics.height) as usize;
    let render = |stop: f32, fill: StopFill| {
        let mut r = ViewRenderer::new();
        r.set_early_stop(stop, fill);
        let (mut rgb, mut tz) = (vec![[0.0; 3]; n], vec![0.0; n]);
        let out = FullOutputs { rgb: &mut rgb, expected_z: &mut [], threshold_z: &mut tz, beta: &mut [] };
        r.full(isa, &(&nerf).into(), &v.intrinsics, &v.pose, red, m, out);
        (rgb, tz.iter().map(|z| z.to_bits()).collect::<Vec<_>>())
    };
    let (_, default_z) = render(1e-4, StopFill::Background);
    for stop in [0.05, 0.3] {
        let (own, own_z) = render(stop, StopFill::RayColour);
        let (bg, bg_z) = render(stop, StopFill::Background);
        assert_eq!(own_z, default_z, "threshold depth, the ray's colour at {stop}");
        assert_eq!(bg_z, default_z, "threshold depth, the background at {stop}");
        let mut stopped = 0;
        for (p, (o, b)) in own.iter().zip(&bg).enumerate() {
            let flat = o.iter().all(|&c| (c - 0.5).abs() < 1e-5);
            if o != b {
                assert!(flat, "stop {stop}, pixel {p}: {o:?} (the background fill: {b:?})");
                assert!(
                    b.iter().all(|&c| (c - 0.5).abs() <= stop),
                    "stop {stop}, pixel {p}: the background fill {b:?}"
                );
                stopped += 1;
            } else if !flat {
                // Not stopped: what the background let through is mixed in either way.
                assert!(b[0] > b[1], "stop {stop}, pixel {p}: {b:?}");
            }
        }
        assert!(stopped > n / 4, "stop {stop}: only {stopped} of {n} rays stopped early");
    }
}
