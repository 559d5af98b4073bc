//! The paper's claim on a small synthesised workspace, inside `cargo test`: after training a
//! background NeRF on the empty workspace, a Residual-NeRF (residual + Mixnet over the frozen
//! background) trained on the scene with the glass sphere has a lower Dex-NeRF threshold-depth
//! error inside the glass crops than a plain NeRF (Dex-NeRF) trained on the same scene views
//! for the same number of steps; and so it does when both captures come through a lens. A tall
//! object standing in what was empty air in the background is found by Residual-NeRF as by
//! Dex-NeRF.

use residual_nerf::data::workspace::{self, Capture, Glass, SKY};
use residual_nerf::eval::DepthErrors;
use residual_nerf::field::mix::{DensityMix, MixKind};
use residual_nerf::field::mixnet::MixnetEncoding;
use residual_nerf::field::residual::ResidualConfig;
use residual_nerf::geometry::Distortion;
use residual_nerf::render::view::{render_view, Scene};
use residual_nerf::simd::Isa;
use residual_nerf::train::trainer::{train_nerf, train_residual};

/// Glass-crop threshold-depth errors of Dex-NeRF and Residual-NeRF trained on captures through
/// `capture` (background and scene alike), scored on exact pinhole test views (the depth a robot
/// asks for); the mean β on the glass and elsewhere.
fn glass_crop_errors(capture: &Capture) -> (DepthErrors, DepthErrors, f64, f64) {
    let isa = Isa::detect();
    let size = 24;
    let bg_views = workspace::workspace_capture(size, 24, 0.0, Glass::None, capture);
    let scene_views = workspace::workspace_capture(size, 24, 0.0, Glass::Sphere, capture);
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
        "{:?}: {:.1} s: glass-crop threshold-depth MAE / RMSE / holes: Dex-NeRF {:.4} / {:.4} / {:.1}%, Residual-NeRF {:.4} / {:.4} / {:.1}%; mean β on glass {bi:.3}, elsewhere {bo:.3}",
        capture.distortion,
        t0.elapsed().as_secs_f64(),
        e_dex.mae(),
        e_dex.rmse(),
        100.0 * e_dex.hole_rate(),
        e_res.mae(),
        e_res.rmse(),
        100.0 * e_res.hole_rate()
    );
    (e_dex, e_res, bi, bo)
}

/// The pinhole run, shared by the tests of this file (the first to ask trains it).
fn pinhole() -> &'static (DepthErrors, DepthErrors, f64, f64) {
    static RUN: std::sync::OnceLock<(DepthErrors, DepthErrors, f64, f64)> = std::sync::OnceLock::new();
    RUN.get_or_init(|| glass_crop_errors(&Capture::default()))
}

#[test]
fn residual_nerf_beats_dex_nerf_in_the_glass_crop() {
    let (e_dex, e_res, _, _) = pinhole();
    assert!(e_res.mae() < e_dex.mae(), "Residual-NeRF should have the lower depth error in the glass crop");
}

/// Both captures through a lens (OpenCV's radial-tangential model; the image corners move by
/// ~1 px at 24 px by the model's equations), scored on pinhole test views: each method's glass-crop error stays within
/// 1.5× + 5 mm of what it reaches through a pinhole at the same seed. (At this size the two
/// methods are close through the lens — 0.75 against 0.74 m on the AVX-512 host — so which one
/// wins is not asserted here; the lens's geometry is tested exactly in `tests/camera.rs` and
/// `tests/colmap.rs`.)
#[test]
fn through_a_lens_the_depth_error_stays_within_the_margin() {
    let lens = Capture {
        distortion: Distortion::Radial { k: [-0.15, 0.03, 0.0, 0.0], p: [0.002, -0.001] },
        ..Default::default()
    };
    let (l_dex, l_res, _, _) = glass_crop_errors(&lens);
    let (p_dex, p_res, _, _) = pinhole();
    for (name, l, p) in [("Dex-NeRF", l_dex, p_dex), ("Residual-NeRF", l_res, p_res)] {
        assert!(
            l.mae() <= 1.5 * p.mae() + 0.005,
            "{name}: through the lens {:.4} m against {:.4} m through a pinhole",
            l.mae(),
            p.mae()
        );
    }
}

/// A tall object standing in what was empty air in the background (issue: the mixed field's
/// occupancy starts from the background's, whose air there is empty). The synthesised clear
/// glass cylinder is seen through by every method at sizes a test can afford (object MAE
/// 0.46–0.56 m at 40 px); the same cylinder in amber glass is found by Dex-NeRF, so Residual-
/// NeRF (the crate's default, background-aware method) must find it too: on the object's mask
/// its threshold depth is within 10 cm of the truth on average and within 3 cm of Dex-NeRF's
/// error. Seen through, the error is the distance to the table or wall behind (≥ 0.4 m).
/// 40 px, 32 views, 150 steps (avx2, release: Dex-NeRF 0.050 m, Residual-NeRF 0.017 m).
#[test]
fn a_tall_object_in_former_empty_air_is_found() {
    use residual_nerf::app::{demo_config, train_background};
    use residual_nerf::compare::{run_scene, EvalSet, Method};
    let (isa, size) = (Isa::detect(), 40);
    let bg = workspace::workspace_with(size, 32, 0.0, Glass::None);
    let scene = workspace::workspace_with(size, 32, 0.0, Glass::TallAmber);
    let test = EvalSet::from_synth(&workspace::workspace_with(size, 4, 0.37, Glass::TallAmber));
    let mut cfg = demo_config(150, 0);
    cfg.eval_every = 150; // the final figures only: no curve
    let background = train_background(isa, &bg.views, &cfg).expect("trains");
    let methods = [Method::Dex, Method::RESIDUAL];
    let r = run_scene(isa, "tall", &background, &bg.views, &scene.views, &test, &methods, &cfg, &mut |_, _| {})
        .expect("trains");
    let [dex, res] = [0, 1].map(|i| &r.methods[i].threshold.object);
    eprintln!(
        "tall amber object, object MAE / see-through: Dex-NeRF {:.4} m / {:.1}%, Residual-NeRF {:.4} m / {:.1}%",
        dex.mae(),
        100.0 * dex.see_through_rate(),
        res.mae(),
        100.0 * res.see_through_rate()
    );
    assert!(
        dex.mae() < 0.1,
        "Dex-NeRF does not find the amber cylinder ({:.4} m): the test scene is not learnable",
        dex.mae()
    );
    assert!(
        res.mae() < 0.1 && res.mae() <= dex.mae() + 0.03,
        "Residual-NeRF misses the tall object: {:.4} m against Dex-NeRF's {:.4} m",
        res.mae(),
        dex.mae()
    );
}
