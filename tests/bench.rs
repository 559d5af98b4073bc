//! `rnerf bench` end to end at a tiny scale: every figure is measured, positive and finite,
//! and the JSON object and the table carry each one under its name.

use residual_nerf::bench::{run, BenchOptions};
use residual_nerf::simd::Isa;
use std::collections::HashSet;

#[test]
fn bench_reports_every_figure_under_its_name() {
    let opts = BenchOptions { reps: 1, scale: 0.005, log2_table_size: 12, isa: Isa::detect() };
    let report = run(&opts, Vec::new());
    let each = report.each();
    // Every declared figure is there but the tile peak, which only the AMX level measures.
    let declared = report.kernels.each().len() + report.pipeline.each().len() + report.derived.each().len();
    let tile = report.kernels.tile_peak_gflops_1t.is_some();
    assert_eq!(each.len(), declared - usize::from(!tile));
    assert_eq!(each.iter().map(|f| f.0).collect::<HashSet<_>>().len(), each.len(), "figure names are unique");
    let json = report.to_json();
    assert_eq!(json["cpu_level"], opts.isa.to_string());
    let table = report.to_table();
    for (name, unit, s) in &each {
        assert!(s.median.is_finite() && s.median > 0.0, "{name} = {} {unit}", s.median);
        assert!(s.min <= s.median && s.median <= s.max, "{name}: {s:?}");
        assert!(json[name].as_f64().is_some_and(|v| v > 0.0), "{name} missing from the JSON");
        assert_eq!(json["spread"][name].as_array().map(Vec::len), Some(2), "{name}'s spread");
        assert!(table.lines().any(|l| l.starts_with(&format!("{name} "))), "{name} missing from the table");
    }
    // A derived figure follows from the measured ones.
    let k = &report.kernels;
    let scaling = k.mlp_fwd_bwd_gflops.median / k.mlp_fwd_bwd_gflops_1t.median;
    assert_eq!(report.derived.mlp_thread_scaling, scaling);
}

/// The trained models' views: a 200×200 test camera rescaled to 640 wide and cropped to 480
/// rows looks through the same points of the scene (a point of the old image lands at the
/// rescaled, shifted position), and rescaling to 200 keeps the camera as it is.
#[test]
fn a_resized_view_sees_the_same_scene() {
    use residual_nerf::bench::resized;
    use residual_nerf::geometry::{image_ray, Intrinsics, Pose};
    let k = Intrinsics::pinhole(200, 200, 240.0, 236.0, 97.5, 103.0);
    assert_eq!(resized(k, 200, None), k);
    let big = resized(k, 640, Some(480));
    assert_eq!((big.width, big.height), (640, 480));
    let pose = Pose { rotation: glam::Mat3::IDENTITY, translation: glam::Vec3::ZERO };
    for (x, y) in [(0.0f32, 0.0f32), (100.0, 100.0), (37.5, 180.25), (200.0, 140.0)] {
        let a = image_ray(&k, &pose, x, y);
        let b = image_ray(&big, &pose, x * 3.2, y * 3.2 - 80.0);
        assert!((a.dir - b.dir).length() < 1e-5, "({x}, {y}): {:?} against {:?}", a.dir, b.dir);
    }
}

/// Time to quality on a small synthesised pair (the path of `rnerf bench --background-data BG
/// --scene S`): the scene phase's figures are always there and consistent with each other; the
/// background's are there exactly when its test PSNR reached the target, at a curve point.
#[test]
fn time_to_quality_reports_consistent_figures() {
    use residual_nerf::app::demo_config;
    use residual_nerf::bench::quality::{measure, QualityInputs, CURVE_EVERY};
    use residual_nerf::compare::EvalSet;
    use residual_nerf::data::workspace::{self, Glass};
    let size = 16;
    let bg = workspace::workspace_with(size, 12, 0.0, Glass::None);
    let bg_test = workspace::workspace_with(size, 3, 0.37, Glass::None);
    let scene = workspace::workspace_with(size, 12, 0.0, Glass::TallAmber);
    let test = EvalSet::from_synth(&workspace::workspace_with(size, 2, 0.37, Glass::TallAmber));
    let isa = Isa::detect();
    // 150 steps: a curve point and the end (10 dB is reached by the first); the unreachable
    // target's run is one curve point long. 128 rays a step (the demo's 512 would only make the
    // figures better, not more consistent).
    for (target, reachable, steps) in [(10.0, true, CURVE_EVERY + 50), (99.0, false, CURVE_EVERY)] {
        let mut cfg = demo_config(steps, 0);
        cfg.train.rays_per_step = 128;
        let input = QualityInputs {
            background_train: &bg.views,
            background_test: &bg_test.views,
            scene_train: &scene.views,
            scene_test: &test,
            cfg: &cfg,
            target_psnr_db: target,
        };
        let q = measure(isa, &input).expect("the pair trains");
        let at = |s: Option<residual_nerf::bench::Stat>| s.map(|s| s.median);
        if reachable {
            let steps_to = at(q.background_steps_to_28db).expect("10 dB is reached");
            assert_eq!(steps_to % CURVE_EVERY as f64, 0.0, "{steps_to}: not a curve point");
            assert!(at(q.background_test_psnr_at_28db).unwrap() >= target);
            assert!(at(q.background_seconds_to_28db).unwrap() > 0.0);
        } else {
            assert!(q.background_seconds_to_28db.is_none() && q.background_steps_to_28db.is_none());
            assert!(q.background_test_psnr_at_28db.is_none());
        }
        let (to, all) = (at(q.scene_seconds_to_quality).unwrap(), at(q.scene_seconds).unwrap());
        assert!(0.0 < to && to <= all, "{to} s to quality of {all} s");
        let step = at(q.scene_steps_to_quality).unwrap();
        assert!(step == steps as f64 || step % CURVE_EVERY as f64 == 0.0, "step {step}");
        assert!(at(q.scene_final_object_mae_m).unwrap().is_finite());
        assert!(at(q.scene_prior_seconds).unwrap() > 0.0);
    }
}
