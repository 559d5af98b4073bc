//! End to end: train a NeRF on a synthesised tabletop (a textured table top with a sphere on
//! it, under a plain sky) inside `cargo test`, then check held-out colour and Dex-NeRF
//! threshold depth against naive baselines computed on the same views — the mean colour of
//! the test images, and a constant depth equal to the mean ground truth. A pipeline with a
//! broken gradient, sampler, compositor, occupancy grid or optimiser does not clear them.

use residual_nerf::data::synth;
use residual_nerf::encoding::HashGridConfig;
use residual_nerf::eval::{self, DepthErrors};
use residual_nerf::field::NerfConfig;
use residual_nerf::render::{DensityThreshold, OccupancyConfig};
use residual_nerf::simd::Isa;
use residual_nerf::train::trainer::{train_nerf, TrainConfig};

#[test]
fn nerf_learns_a_synthesised_tabletop() {
    let size = 24;
    let train = synth::tabletop(size, 40, 0.0);
    let test = synth::tabletop(size, 3, 0.37);
    let field = NerfConfig {
        grid: HashGridConfig { levels: 12, log2_table_size: 14, base_resolution: 8, finest_resolution: 256 },
        aabb: train.aabb,
    };
    let mut cfg = TrainConfig::with_steps(160);
    cfg.rays_per_step = 512;
    cfg.background = synth::SKY;
    cfg.random_background = false; // the sky shows where rays miss the scene
    cfg.occupancy = OccupancyConfig {
        resolution: 32,
        steps_per_diagonal: 128,
        max_samples: 256,
        warmup_steps: 64,
        decay: 0.95,
        ..Default::default()
    };
    let isa = Isa::detect();
    let t0 = std::time::Instant::now();
    let nerf = train_nerf(isa, &train.views, field, &cfg, 40, |s| eprintln!("{s:?}")).expect("trains");
    let secs = t0.elapsed().as_secs_f64();

    let px: Vec<[f32; 3]> = test.views.iter().flat_map(|v| v.rgb.iter().copied()).collect();
    let mean: [f32; 3] = std::array::from_fn(|k| px.iter().map(|c| c[k]).sum::<f32>() / px.len() as f32);
    let surface: Vec<f32> = test.depth.iter().flatten().copied().filter(|z| z.is_finite()).collect();
    let mean_z = surface.iter().sum::<f32>() / surface.len() as f32;
    let (mut se, mut se_base) = (0.0f64, 0.0f64);
    let (mut errors, mut errors_base) = (DepthErrors::default(), DepthErrors::default());
    for (v, gt) in test.views.iter().zip(&test.depth) {
        let r = nerf.render(isa, &v.intrinsics, &v.pose, cfg.background, DensityThreshold::Sigma(3.0));
        se += eval::mse(&r.rgb, &v.rgb);
        se_base += eval::mse(&vec![mean; v.rgb.len()], &v.rgb);
        let full = [0, 0, size, size];
        errors.add_frame(&r.threshold_z, gt, size, full, None);
        errors_base.add_frame(&vec![mean_z; gt.len()], gt, size, full, None);
    }
    let views = test.views.len() as f64;
    let psnr = |se: f64| eval::psnr(se / views);
    let (mae, mae_base, hole_rate) = (errors.mae(), errors_base.mae(), errors.hole_rate());
    eprintln!(
        "{secs:.1} s: held-out PSNR {:.2} dB (mean-colour baseline {:.2}); threshold-depth MAE {mae:.3} m \
         (constant baseline {mae_base:.3}), holes {:.1}%",
        psnr(se),
        psnr(se_base),
        100.0 * hole_rate
    );
    assert!(psnr(se) > psnr(se_base) + 8.0, "colour not learnt");
    assert!(mae < 0.6 * mae_base, "depth not learnt");
    assert!(hole_rate < 0.05, "too many holes");
}

/// Same seed → the same trained parameters, bit for bit, on 1 and 2 threads (rays through the
/// pixels' centres, jittered over their pixels, and four per pixel through its filter); the
/// jitter and the pixels' footprints each train other parameters.
#[test]
fn training_is_thread_count_independent() {
    let scene = synth::tabletop(12, 6, 0.0);
    let field = NerfConfig {
        grid: HashGridConfig { levels: 8, log2_table_size: 12, base_resolution: 4, finest_resolution: 64 },
        aabb: scene.aabb,
    };
    let mut cfg = TrainConfig::with_steps(20);
    cfg.rays_per_step = 256;
    cfg.background = synth::SKY;
    cfg.random_background = false; // the sky shows where rays miss the scene
    cfg.occupancy = OccupancyConfig {
        resolution: 16,
        steps_per_diagonal: 64,
        max_samples: 64,
        warmup_steps: 8,
        decay: 0.95,
        ..Default::default()
    };
    let run = |threads: usize, cfg: &TrainConfig| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| train_nerf(Isa::detect(), &scene.views, field.clone(), cfg, 0, |_| {}).expect("trains"))
    };
    let (a, b) = (run(1, &cfg), run(2, &cfg));
    assert!(a.params == b.params, "parameters differ between 1 and 2 threads");
    assert!(a.occupancy.occupancy() == b.occupancy.occupancy());
    cfg.pixel_jitter = true;
    let (c, d) = (run(1, &cfg), run(2, &cfg));
    assert!(c.params == d.params, "jittered: parameters differ between 1 and 2 threads");
    assert!(c.params != a.params, "the jitter changed no ray");
    cfg.pixel_jitter = false;
    cfg.pixel_rays = 4;
    let (e, f) = (run(1, &cfg), run(2, &cfg));
    assert!(e.params == f.params, "four rays per pixel: parameters differ between 1 and 2 threads");
    assert!(e.params != a.params && e.params != c.params, "the footprints changed no ray");
}

/// A config for other steps (the background's three times a scene's: `rnerf compare`, the
/// demo) rescales its learning-rate schedule as a default config of those steps has it, and
/// keeps its base rate and every other setting.
#[test]
fn a_rescheduled_config_scales_its_schedule_and_keeps_the_rest() {
    use residual_nerf::train::trainer::{BACKGROUND_STEPS, TRAIN_STEPS};
    let mut cfg = TrainConfig::with_steps(TRAIN_STEPS);
    cfg.schedule.base = 3e-3;
    cfg.rays_per_step = 256;
    cfg.seed = 7;
    let t = cfg.rescheduled(BACKGROUND_STEPS);
    let want = TrainConfig::with_steps(BACKGROUND_STEPS).schedule;
    assert_eq!(t.steps, 3 * TRAIN_STEPS);
    assert_eq!(
        (t.schedule.warmup_steps, t.schedule.decay_start, t.schedule.decay_interval, t.schedule.decay_factor),
        (want.warmup_steps, want.decay_start, want.decay_interval, want.decay_factor)
    );
    assert_eq!(t.schedule.decay_start, 1800, "the decay from 60% of the steps");
    assert_eq!((t.schedule.base, t.rays_per_step, t.seed), (3e-3, 256, 7));
}
