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
//! `tests/register.rs` tests the registration itself.

use residual_nerf::app::{demo_config, train_background};
use residual_nerf::compare::{run_scene, CompareConfig, EvalSet, Method};
use residual_nerf::data::workspace::{self, Capture, Glass};
use residual_nerf::data::View;
use residual_nerf::field::Nerf;
use residual_nerf::simd::Isa;

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
/// this file, and the exact scene capture's object MAE (the first test to ask trains them).
struct Shared {
    cfg: CompareConfig,
    bg_views: Vec<View>,
    background: Nerf,
    ideal: f64,
}

fn shared() -> &'static Shared {
    static SHARED: std::sync::OnceLock<Shared> = std::sync::OnceLock::new();
    SHARED.get_or_init(|| {
        let isa = Isa::detect();
        let mut cfg = demo_config(STEPS, 0);
        cfg.eval_every = cfg.train.steps;
        let bg = workspace::workspace(SIZE, VIEWS, 0.0, false);
        let background = train_background(isa, &bg.views, &cfg).expect("the background trains");
        let ideal = object_mae(isa, &background, &bg.views, &Capture::default(), &cfg);
        Shared { cfg, bg_views: bg.views, background, ideal }
    })
}

/// The margin: 1.5× the unchanged capture's error plus 5 mm.
fn within_margin(mae: f64, ideal: f64) -> bool {
    mae <= 1.5 * ideal + 0.005
}

#[test]
fn an_exposure_change_keeps_the_glass_within_the_margin() {
    let s = shared();
    let changed = Capture { gain: [1.2, 1.1, 0.9], ..Default::default() };
    let mae = object_mae(Isa::detect(), &s.background, &s.bg_views, &changed, &s.cfg);
    eprintln!("exposure x(1.2, 1.1, 0.9): object MAE {mae:.4} m against the unchanged capture's {:.4} m", s.ideal);
    assert!(within_margin(mae, s.ideal), "{mae:.4} m against {:.4} m", s.ideal);
}

/// Scene poses off by 5 mm and 0.5° in a random direction each (a robot arm's kinematic error;
/// the background's exact), registered against the background (the prior's default).
#[test]
fn scene_poses_off_like_a_robot_arms_keep_the_glass_within_the_margin() {
    let s = shared();
    let noisy = Capture { pose_noise: Some((0.005, 0.5, 2)), ..Default::default() };
    let mae = object_mae(Isa::detect(), &s.background, &s.bg_views, &noisy, &s.cfg);
    eprintln!("scene poses off by 5 mm and 0.5 deg: object MAE {mae:.4} m against the exact poses' {:.4} m", s.ideal);
    assert!(within_margin(mae, s.ideal), "{mae:.4} m against {:.4} m", s.ideal);
}
