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
