//! The paper's claim on a small synthesised workspace, inside `cargo test`: after training a
//! background NeRF on the empty workspace, a Residual-NeRF (residual + Mixnet over the frozen
//! background) trained on the scene with the glass sphere has a lower Dex-NeRF threshold-depth
//! error inside the glass crops than a plain NeRF (Dex-NeRF) trained on the same scene views
//! for the same number of steps.

use residual_nerf::data::workspace::{self, SKY};
use residual_nerf::eval::DepthErrors;
use residual_nerf::field::mix::{DensityMix, MixKind};
use residual_nerf::field::mixnet::MixnetEncoding;
use residual_nerf::field::residual::ResidualConfig;
use residual_nerf::render::view::{render_view, Scene};
use residual_nerf::simd::Isa;
use residual_nerf::train::trainer::{train_nerf, train_residual};

#[test]
fn residual_nerf_beats_dex_nerf_in_the_glass_crop() {
    let isa = Isa::detect();
    let size = 24;
    let bg_views = workspace::workspace(size, 24, 0.0, false);
    let scene_views = workspace::workspace(size, 24, 0.0, true);
    let test = workspace::workspace(size, 4, 0.37, true);
    // The demo's small-scene settings: 300 steps × 512 rays, 12-level grid, 32³ occupancy,
    // random background colours, threshold σ ≥ 10/m.
    let demo = residual_nerf::app::demo_config(300, 0);
    let (field, cfg, m) = (demo.field, demo.train, demo.m);
    let t0 = std::time::Instant::now();
    let background = train_nerf(isa, &bg_views.views, field.clone(), &cfg, 0, |_| {}).expect("trains");
    let dex = train_nerf(isa, &scene_views.views, field.clone(), &cfg, 0, |_| {}).expect("trains");
    let config =
        ResidualConfig { residual: field, kind: MixKind::Mixnet(DensityMix::Raw), mixnet: MixnetEncoding::default() };
    let residual = train_residual(isa, background, &scene_views.views, config, &cfg, 0, |_| {}).expect("trains");
    let (mut e_dex, mut e_res) = (DepthErrors::default(), DepthErrors::default());
    let mut beta_in = (0.0, 0);
    let mut beta_out = (0.0, 0);
    for (i, v) in test.views.iter().enumerate() {
        let crop = test.crops[i];
        let d = render_view(isa, &Scene::from(&dex), &v.intrinsics, &v.pose, SKY, m);
        let r = render_view(isa, &Scene::from(&residual), &v.intrinsics, &v.pose, SKY, m);
        e_dex.add_frame(&d.threshold_z, &test.depth[i], size, crop, None);
        e_res.add_frame(&r.threshold_z, &test.depth[i], size, crop, None);
        for (p, &b) in r.beta.iter().enumerate() {
            let acc = if test.masks[i][p] { &mut beta_in } else { &mut beta_out };
            acc.0 += b as f64;
            acc.1 += 1;
        }
    }
    let (bi, bo) = (beta_in.0 / beta_in.1 as f64, beta_out.0 / beta_out.1 as f64);
    eprintln!(
        "{:.1} s: glass-crop threshold-depth MAE / RMSE / holes: Dex-NeRF {:.4} / {:.4} / {:.1}%, Residual-NeRF {:.4} / {:.4} / {:.1}%; mean β on glass {bi:.3}, elsewhere {bo:.3}",
        t0.elapsed().as_secs_f64(),
        e_dex.mae(),
        e_dex.rmse(),
        100.0 * e_dex.hole_rate(),
        e_res.mae(),
        e_res.rmse(),
        100.0 * e_res.hole_rate()
    );
    assert!(e_res.mae() < e_dex.mae(), "Residual-NeRF should have the lower depth error in the glass crop");
}
