//! Whole-view rendering: the segmented, early-stopping [`ViewRenderer`] gives what marching
//! each ray in one go and compositing it whole gives (colour, expected and threshold z-depth),
//! and the depth-only path gives the same threshold depth as the full one.

use residual_nerf::data::synth;
use residual_nerf::encoding::HashGridConfig;
use residual_nerf::field::NerfConfig;
use residual_nerf::mlp::Activation;
use residual_nerf::render::{
    composite_ray, pixel_ray, threshold_depth, DensityThreshold, FullOutputs, OccupancyConfig, PackedSamples,
    ViewRenderer,
};
use residual_nerf::simd::Isa;
use residual_nerf::train::trainer::{train_nerf, TrainConfig};

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
            let mut hits = 0;
            for p in 0..n {
                let ray = pixel_ray(k, &v.pose, p as u32 % k.width, p as u32 / k.width);
                let mut s = PackedSamples::default();
                nerf.occupancy.march(ray.origin, ray.dir, &mut s);
                let pos: Vec<_> = s.t.iter().map(|&t| ray.at(t)).collect();
                let dirs = vec![ray.dir; pos.len()];
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
