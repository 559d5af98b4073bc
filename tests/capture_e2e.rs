//! A real capture's departures, end to end through the background-aware Residual-NeRF as
//! `rnerf compare` runs it (the prior, its exposure correction and its registration included):
//! with the scene's exposure and white balance changed against the background's, or its poses
//! off like a robot arm's, the glass's object-mask depth error stays within a stated margin of
//! the exact capture's (1.5× plus 5 mm).
//!
//! The size is the real-capture trials' (RESULTS.md; `examples/capture_trials.rs` trains the
//! same captures at the same seed, so `capture_trials 96 600 none,exposure,pose5-scene-noise,
//! pose5-scene-noise-unregistered` reproduces these figures and the unregistered one).
//! Measured (2026-12-05, commit ce0b0ee, `RNERF_CPU_LEVEL=avx2`; the first three printed by
//! their tests): the exact capture 0.0324 m; the exposure ×(1.2, 1.1, 0.9), corrected, 0.0322 m;
//! the scene's poses off by 5 mm and 0.5°, registered, 0.0466 m; the same unregistered 0.0652 m
//! (`capture_trials`, `results/prior_stop/`), outside the margin (0.0536 m), so the pose test can
//! fail. At 64 px and 300 steps, where this test ran before, the glass was already mostly seen
//! through on the exact capture (0.153 m) and 2 mm and 0.2° lost it whether registered or not
//! (0.46 / 0.41 m), so nothing about poses could be shown there.
//!
//! The registration itself is tested here too, over the same background: poses a robot arm
//! gives (millimetres and tenths of a degree off) come back near the true ones; exact poses are
//! left alone.

use residual_nerf::app::{demo_config, train_background};
use residual_nerf::compare::{run_scene, CompareConfig, EvalSet, Method};
use residual_nerf::data::workspace::{self, Capture, Glass};
use residual_nerf::data::View;
use residual_nerf::field::Nerf;
use residual_nerf::geometry::{pixel_ray, Intrinsics, Pose};
use residual_nerf::render::DensityThreshold;
use residual_nerf::simd::Isa;
use residual_nerf::train::register::{pose_difference, register};

const SIZE: u32 = 96;
const VIEWS: usize = 32;
const STEPS: u32 = 600;

/// Object-mask MAE (m) of the background-aware Residual-NeRF on scene views captured through
/// `capture` at the background's poses, over `background` trained on `bg_views`.
fn object_mae(isa: Isa, background: &Nerf, bg_views: &[View], capture: &Capture, cfg: &CompareConfig) -> f64 {
    let scene = workspace::workspace_capture(SIZE, VIEWS, 0.0, Glass::Sphere, capture);
    let test = EvalSet::from_synth(&workspace::workspace_with(SIZE, 4, 0.37, Glass::Sphere));
    let methods = [Method::RESIDUAL];
    let r = run_scene(isa, "capture", background, bg_views, &scene.views, &test, &methods, cfg, &mut |_, _| {})
        .expect("the scene trains");
    r.methods[0].threshold.object.mae()
}

/// The background (trained on the exact capture) and the run settings, shared by the tests of
/// this file (the first test to ask trains it).
struct Shared {
    cfg: CompareConfig,
    bg_views: Vec<View>,
    background: Nerf,
}

fn shared() -> &'static Shared {
    static SHARED: std::sync::OnceLock<Shared> = std::sync::OnceLock::new();
    SHARED.get_or_init(|| {
        let mut cfg = demo_config(STEPS, 0);
        cfg.eval_every = cfg.train.steps;
        let bg = workspace::workspace(SIZE, VIEWS, 0.0, false);
        let background = train_background(Isa::detect(), &bg.views, &cfg).expect("the background trains");
        Shared { cfg, bg_views: bg.views, background }
    })
}

/// The exact scene capture's object MAE, the margins' reference (the first test to ask runs it;
/// the registration test, which needs the background only, goes on meanwhile).
fn ideal() -> f64 {
    static IDEAL: std::sync::OnceLock<f64> = std::sync::OnceLock::new();
    *IDEAL.get_or_init(|| {
        let s = shared();
        object_mae(Isa::detect(), &s.background, &s.bg_views, &Capture::default(), &s.cfg)
    })
}

/// The margin: 1.5× the unchanged capture's error plus 5 mm.
fn within_margin(mae: f64, ideal: f64) -> bool {
    mae <= 1.5 * ideal + 0.005
}

#[test]
fn an_exposure_change_keeps_the_glass_within_the_margin() {
    let (s, ideal) = (shared(), ideal());
    let changed = Capture { gain: [1.2, 1.1, 0.9], ..Default::default() };
    let mae = object_mae(Isa::detect(), &s.background, &s.bg_views, &changed, &s.cfg);
    eprintln!("exposure x(1.2, 1.1, 0.9): object MAE {mae:.4} m against the unchanged capture's {ideal:.4} m");
    assert!(within_margin(mae, ideal), "{mae:.4} m against {ideal:.4} m");
}

/// Scene poses off by 5 mm and 0.5° in a random direction each (a robot arm's kinematic error;
/// the background's exact), registered against the background (the prior's default).
#[test]
fn scene_poses_off_like_a_robot_arms_keep_the_glass_within_the_margin() {
    let (s, ideal) = (shared(), ideal());
    let noisy = Capture { pose_noise: Some((0.005, 0.5, 2)), ..Default::default() };
    let mae = object_mae(Isa::detect(), &s.background, &s.bg_views, &noisy, &s.cfg);
    eprintln!("scene poses off by 5 mm and 0.5 deg: object MAE {mae:.4} m against the exact poses' {ideal:.4} m");
    assert!(within_margin(mae, ideal), "{mae:.4} m against {ideal:.4} m");
}

/// Mean image distance (pixels) between where the true camera sees the points of its depth
/// map and where `pose` would see them.
fn reprojection(k: &Intrinsics, truth: &Pose, z: &[f32], pose: &Pose) -> f64 {
    let (mut sum, mut n) = (0.0, 0);
    for j in 0..k.height {
        for i in 0..k.width {
            let zz = z[(j * k.width + i) as usize];
            if !zz.is_finite() {
                continue;
            }
            let ray = pixel_ray(k, truth, i, j);
            let x = ray.at(ray.z_to_range(zz));
            let c = pose.rotation.transpose() * (x - pose.translation);
            if let Some((u, v)) = k.project(c) {
                sum += (((u - i as f32 - 0.5).powi(2) + (v - j as f32 - 0.5).powi(2)) as f64).sqrt();
                n += 1;
            }
        }
    }
    sum / n as f64
}

/// The shared background (the capture trials' size: 96 px, 32 views, 600 steps); scene views
/// of the workspace with the glass from other poses, their poses off by 5 mm and 0.5° (as the
/// trials' `pose5`): registration brings the mean reprojection error of the true surfaces at
/// least halfway back. From the exact poses it ends, on the mean, within half a pixel of them
/// (about where the noisy ones end: the small background's own error in its frame). Printed
/// (2026-12-06, avx2): 1.01 px → 0.30 px, exact poses moved 0.35 px.
#[test]
fn registration_brings_noisy_poses_back_to_the_true_ones() {
    let (isa, background) = (Isa::detect(), &shared().background);
    let m = DensityThreshold::Sigma(10.0);
    let truth = workspace::workspace_capture(SIZE, 8, 0.5, Glass::Sphere, &Capture::default());
    let noisy = Capture { pose_noise: Some((0.005, 0.5, 3)), ..Default::default() };
    let scene = workspace::workspace_capture(SIZE, 8, 0.5, Glass::Sphere, &noisy);
    let (mut before, mut after, mut exact_moved) = (0.0, 0.0, 0.0);
    for ((v, t), z) in scene.views.iter().zip(&truth.views).zip(&truth.depth) {
        let r = background.render(isa, &v.intrinsics, &v.pose, workspace::SKY, m);
        let reg = register(v, &r.rgb, &r.threshold_z);
        let (b, a) =
            (reprojection(&v.intrinsics, &t.pose, z, &v.pose), reprojection(&v.intrinsics, &t.pose, z, &reg.pose));
        let (deg, dist) = pose_difference(&t.pose, &reg.pose);
        eprintln!("noisy pose: {b:.2} px -> {a:.2} px ({deg:.3} deg, {:.1} mm from the truth; {reg:?})", dist * 1e3);
        (before, after) = (before + b / 8.0, after + a / 8.0);
        let r = background.render(isa, &t.intrinsics, &t.pose, workspace::SKY, m);
        let exact = register(t, &r.rgb, &r.threshold_z);
        exact_moved += reprojection(&t.intrinsics, &t.pose, z, &exact.pose) / 8.0;
    }
    eprintln!("mean reprojection error {before:.2} px -> {after:.2} px; exact poses moved {exact_moved:.2} px");
    assert!(exact_moved < 0.5, "exact poses moved by {exact_moved:.2} px on the mean");
    assert!(before > 0.5, "the noise should be visible: {before:.2} px");
    assert!(after < 0.5 * before, "registration left {after:.2} px of {before:.2} px");
}
