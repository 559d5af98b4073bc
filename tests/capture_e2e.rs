//! A real capture's exposure change, end to end through the background-aware Residual-NeRF as
//! `rnerf compare` runs it (the prior and its exposure correction included): with the scene's
//! exposure and white balance changed against the background's, the glass's object-mask depth
//! error stays within a stated margin of the unchanged capture's.
//!
//! Measured at this size (64 px, 24 views, 300 steps; 2026-12-02, commit f5a0ebc, AVX-512
//! host): the unchanged capture 0.153 m, the changed one corrected 0.154 m (both printed by this
//! test). With the correction switched off the changed capture scored 0.495 m, so the margin
//! separates them; at 48 px and 300 steps the glass is lost even unchanged (0.54 m), at 400 steps
//! and 64 px the figures were 0.103 / 0.102 / 0.397 m for a third more time. Poses off as a robot
//! arm's (5 mm and 0.5° on the scene) lose the glass at 64 px and 400 steps with or without
//! registration (0.52 m unregistered, 0.44 m registered), which is why they are not tested end
//! to end here. The figures other than this test's two came from variants of it that were not
//! committed, so they are the reason for its shape, not reproducible results; at the
//! trials' 96 px registration takes back most of the loss (RESULTS.md, "Real-capture trials"),
//! and `tests/register.rs` tests the registration itself.

use residual_nerf::app::{demo_config, train_background};
use residual_nerf::compare::{run_scene, CompareConfig, EvalSet, Method};
use residual_nerf::data::workspace::{self, Capture, Glass};
use residual_nerf::data::View;
use residual_nerf::field::Nerf;
use residual_nerf::simd::Isa;

const SIZE: u32 = 64;
const VIEWS: usize = 24;
const STEPS: u32 = 300;

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

/// The margin: 1.5× the unchanged capture's error plus 5 mm.
#[test]
fn an_exposure_change_keeps_the_glass_within_the_margin() {
    let isa = Isa::detect();
    let mut cfg = demo_config(STEPS, 0);
    cfg.eval_every = cfg.train.steps;
    let bg = workspace::workspace(SIZE, VIEWS, 0.0, false);
    let background = train_background(isa, &bg.views, &cfg).expect("the background trains");
    let ideal = object_mae(isa, &background, &bg.views, &Capture::default(), &cfg);
    let changed = Capture { gain: [1.2, 1.1, 0.9], ..Default::default() };
    let mae = object_mae(isa, &background, &bg.views, &changed, &cfg);
    eprintln!("exposure x(1.2, 1.1, 0.9): object MAE {mae:.4} m against the unchanged capture's {ideal:.4} m");
    assert!(mae <= 1.5 * ideal + 0.005, "{mae:.4} m against {ideal:.4} m");
}
