//! Train a NeRF on the synthesised tabletop and report held-out colour and Dex-NeRF threshold
//! depth (z, metres) against the analytic ground truth.
//!
//! `cargo run --release --example 01_train_tabletop [-- STEPS]`

use residual_nerf::data::synth;
use residual_nerf::encoding::HashGridConfig;
use residual_nerf::eval::{self, DepthErrors};
use residual_nerf::field::NerfConfig;
use residual_nerf::render::{DensityThreshold, OccupancyConfig};
use residual_nerf::simd::Isa;
use residual_nerf::train::trainer::{train_nerf, TrainConfig};

fn main() {
    let steps = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(400);
    let size = 48;
    let train = synth::tabletop(size, 60, 0.0);
    let test = synth::tabletop(size, 5, 0.37);
    let field = NerfConfig {
        grid: HashGridConfig { log2_table_size: 16, finest_resolution: 512, ..Default::default() },
        aabb: train.aabb,
    };
    let mut cfg = TrainConfig::with_steps(steps);
    cfg.rays_per_step = 2048;
    cfg.background = synth::SKY;
    cfg.random_background = false; // the sky shows where rays miss the scene
    cfg.occupancy = OccupancyConfig { resolution: 64, steps_per_diagonal: 256, max_samples: 512, ..Default::default() };
    let isa = Isa::detect();
    println!("training {steps} steps on {} views of {size}×{size} (cpu level {isa})", train.views.len());
    let nerf = train_nerf(isa, &train.views, field, &cfg, 50, |s| {
        println!(
            "step {:>5}  loss {:.5}  {:.1} samples/ray  occupancy {:.2}  {:.1} s",
            s.step + 1,
            s.loss,
            s.samples_per_ray,
            s.occupancy,
            s.seconds
        )
    })
    .expect("the synthesised tabletop trains");
    for (vi, (v, gt)) in test.views.iter().zip(&test.depth).enumerate() {
        let r = nerf.render(isa, &v.intrinsics, &v.pose, cfg.background, DensityThreshold::Sigma(3.0));
        let mut errors = DepthErrors::default();
        errors.add_frame(&r.threshold_z, gt, size, [0, 0, size, size], None);
        println!(
            "test view {vi}: PSNR {:.2} dB, threshold-depth MAE {:.4} m (holes as 0) over {} surface pixels, {} holes",
            eval::psnr(eval::mse(&r.rgb, &v.rgb)),
            errors.mae(),
            errors.pixels,
            errors.holes
        );
    }
}
