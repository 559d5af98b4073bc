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
