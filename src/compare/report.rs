//! Reporting the protocol's results: the markdown tables ([`table`]), the curves (csv and
//! [`curves_png`]) and the depth sheets ([`depth_sheet_png`]); the pictures are drawn by
//! [`super::figures`].

use super::{figures, first_reaching, CurvePoint, EvalSet, Method, MethodResult, SceneResult};
use crate::eval::DepthReport;
use crate::field::mix::MixKind;
use crate::render::DensityThreshold;
use std::fmt::Write as _;

/// A table row: label, errors, training seconds, PSNR.
struct Row<'a> {
    scene: &'a str,
    label: &'static str,
    errors: DepthReport,
    seconds: f64,
    psnr: f64,
}

fn rows(r: &SceneResult) -> Vec<Row<'_>> {
    let mut out = Vec::new();
    for m in &r.methods {
        let row = |label, errors| Row { scene: &r.name, label, errors, seconds: m.seconds, psnr: m.psnr };
        if m.method == Method::Dex {
            out.push(row("NeRF (expected depth)", m.expected));
        }
        out.push(row(m.method.label(), m.threshold));
    }
    out
}

/// Mean over scenes of a method's final threshold-depth object-mask MAE and near-crop RMSE
/// (None when a scene lacks the method).
pub fn mean_errors(results: &[SceneResult], method: Method) -> Option<(f64, f64)> {
    let mut acc = (0.0, 0.0);
    for r in results {
        let m = r.methods.iter().find(|m| m.method == method)?;
        acc.0 += m.threshold.object.mae();
        acc.1 += m.threshold.near.rmse();
    }
    let n = results.len().max(1) as f64;
    Some((acc.0 / n, acc.1 / n))
}

const HEADER: &str = "| scene | method | object MAE (m) | object RMSE (m) | object holes | ≤ 1 cm | ≤ 2.5 cm | \
see-through | floaters | near-crop MAE (m) | near-crop RMSE (m) | crop w/o object MAE (m) | crop RMSE (m) | train (s) | test PSNR (dB) |";

fn pct(x: f64) -> String {
    format!("{:.1}%", 100.0 * x)
}

fn row_cells(e: &DepthReport) -> [f64; 11] {
    let o = &e.object;
    [
        o.mae(),
        o.rmse(),
        o.hole_rate(),
        o.within_1cm_rate(),
        o.within_2_5cm_rate(),
        o.see_through_rate(),
        o.floater_rate(),
        e.near.mae(),
        e.near.rmse(),
        e.rest.mae(),
        e.crop.rmse(),
    ]
}

fn write_row(s: &mut String, scene: &str, label: &str, c: &[f64; 11], seconds: f64, psnr: f64) {
    let _ = writeln!(
        s,
        "| {scene} | {label} | {:.4} | {:.4} | {} | {} | {} | {} | {} | {:.4} | {:.4} | {:.4} | {:.4} | {seconds:.1} | {psnr:.2} |",
        c[0],
        c[1],
        pct(c[2]),
        pct(c[3]),
        pct(c[4]),
        pct(c[5]),
        pct(c[6]),
        c[7],
        c[8],
        c[9],
        c[10]
    );
}

/// The comparison table (Markdown): per scene and method the object-mask figures (MAE, RMSE,
/// holes, shares within 1 and 2.5 cm, see-through and floater rates), the near crop's MAE and
/// RMSE, the crop without the object, the whole crop's RMSE (the paper's figure), training time
/// and PSNR; the mean over scenes per method; each method's ratios to Dex-NeRF; and the time each
/// method takes to reach Dex-NeRF's final object-mask MAE.
pub fn table(results: &[SceneResult]) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "{HEADER}");
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for r in results {
        for row in rows(r) {
            write_row(&mut s, row.scene, row.label, &row_cells(&row.errors), row.seconds, row.psnr);
        }
    }
    if results.len() > 1 {
        let n = results.len() as f64;
        let all: Vec<Vec<Row<'_>>> = results.iter().map(rows).collect();
        for (i, row) in all[0].iter().enumerate() {
            let (mut c, mut secs, mut ps) = ([0.0; 11], 0.0, 0.0);
            for r in &all {
                let x = &r[i];
                c.iter_mut().zip(row_cells(&x.errors)).for_each(|(a, b)| *a += b / n);
                (secs, ps) = (secs + x.seconds / n, ps + x.psnr / n);
            }
            write_row(&mut s, "**mean**", row.label, &c, secs, ps);
        }
    }
    for r in results {
        if let Some(p) = &r.prior {
            let _ = writeln!(
                s,
                "\n{}: background prior: {} of the training pixels changed ({}/{} views against a background image at \
                 the same pose, the rest against the rendered background; {} poses registered); change region {} cells ({:.4} m³), crossed by the rays of {} of the pixels; {:.1} s",
                r.name,
                pct(p.changed_pixels),
                p.matched_views,
                p.views,
                p.registered_views,
                p.region_cells,
                p.region_volume,
                pct(p.reach_pixels),
                p.seconds
            );
        }
    }
    s.push_str(&sweep_table(results));
    let dex = mean_errors(results, Method::Dex);
    let methods: Vec<Method> =
        results.first().map(|r| r.methods.iter().map(|m| m.method).collect()).unwrap_or_default();
    let _ = writeln!(s);
    for &method in methods.iter().filter(|&&m| m != Method::Dex) {
        if let (Some(d), Some(r)) = (dex, mean_errors(results, method)) {
            let _ = writeln!(
                s,
                "{} / Dex-NeRF (mean over scenes): object MAE {:.2}x, near-crop RMSE {:.2}x",
                method.label(),
                r.0 / d.0,
                r.1 / d.1
            );
        }
    }
    for r in results {
        let Some(d) = r.methods.iter().find(|m| m.method == Method::Dex) else { continue };
        let target = d.threshold.object.mae();
        let _ = writeln!(
            s,
            "\n{}: time to Dex-NeRF's final object MAE {target:.4} m (Dex-NeRF: {:.1} s):",
            r.name, d.seconds
        );
        for m in r.methods.iter().filter(|m| m.method != Method::Dex) {
            let _ = match first_reaching(&m.curve, target) {
                Some(p) => writeln!(
                    s,
                    "- {}: step {}, {:.1} s = {:.2}x of Dex-NeRF's time",
                    m.method.label(),
                    p.step,
                    p.seconds,
                    p.seconds / d.seconds
                ),
                None => writeln!(s, "- {}: not reached (final {:.4} m)", m.method.label(), m.threshold.object.mae()),
            };
        }
    }
    s
}

fn threshold_name(m: DensityThreshold) -> String {
    match m {
        DensityThreshold::Sigma(v) => format!("σ ≥ {v}"),
        DensityThreshold::Raw(v) => format!("s ≥ {v} (raw)"),
    }
}

/// Mean over scenes of the threshold sweep (Markdown), one row per method and threshold;
/// empty without a sweep.
fn sweep_table(results: &[SceneResult]) -> String {
    let mut s = String::new();
    let Some(first) = results.first() else { return s };
    if first.methods.iter().all(|m| m.sweep.is_empty()) {
        return s;
    }
    let _ = writeln!(s, "\nThreshold sweep (mean over {} scene(s), same trained models):\n", results.len());
    let _ = writeln!(s, "| method | threshold | object MAE (m) | object holes | near-crop RMSE (m) | crop MAE (m) |");
    let _ = writeln!(s, "|---|---|---|---|---|---|");
    let n = results.len() as f64;
    for (k, m) in first.methods.iter().enumerate() {
        for (j, (th, _)) in m.sweep.iter().enumerate() {
            let mut c = [0.0; 4];
            for r in results {
                let e = &r.methods[k].sweep[j].1;
                let x = [e.object.mae(), e.object.hole_rate(), e.near.rmse(), e.crop.mae()];
                c.iter_mut().zip(x).for_each(|(a, b)| *a += b / n);
            }
            let _ = writeln!(
                s,
                "| {} | {} | {:.4} | {} | {:.4} | {:.4} |",
                m.method.label(),
                threshold_name(*th),
                c[0],
                pct(c[1]),
                c[2],
                c[3]
            );
        }
    }
    s
}

/// The speed curves as CSV: `scene,method,step,seconds` then MAE, RMSE and hole rate of the
/// object, the near crop and the whole crop, and the object's see-through and floater rates.
pub fn curves_csv(results: &[SceneResult]) -> String {
    let mut s = String::from(
        "scene,method,step,seconds,object_mae,object_rmse,object_holes,object_see_through,object_floaters,\
         near_mae,near_rmse,crop_mae,crop_rmse,crop_holes\n",
    );
    for r in results {
        for m in &r.methods {
            for p in &m.curve {
                let (o, n, c) = (&p.errors.object, &p.errors.near, &p.errors.crop);
                let _ = writeln!(
                    s,
                    "{},{},{},{:.3},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6}",
                    r.name,
                    m.method.name(),
                    p.step,
                    p.seconds,
                    o.mae(),
                    o.rmse(),
                    o.hole_rate(),
                    o.see_through_rate(),
                    o.floater_rate(),
                    n.mae(),
                    n.rmse(),
                    c.mae(),
                    c.rmse(),
                    c.hole_rate()
                );
            }
        }
    }
    s
}

const CURVE_COLOURS: [figures::Colour; 4] = [[214, 39, 40], [31, 119, 180], [44, 160, 44], [148, 103, 189]];

/// The speed curves of one scene as one picture: RMSE and MAE against step and against seconds.
pub fn curves_png(r: &SceneResult) -> Result<Vec<u8>, String> {
    use figures::{plot, Series};
    let series = |x: fn(&CurvePoint) -> f64, y: fn(&CurvePoint) -> f64| -> Vec<Series<'_>> {
        r.methods
            .iter()
            .enumerate()
            .map(|(i, m)| Series {
                label: m.method.label(),
                colour: CURVE_COLOURS[i % CURVE_COLOURS.len()],
                points: m.curve.iter().map(|p| (x(p), y(p))).collect(),
            })
            .collect()
    };
    let step = |p: &CurvePoint| p.step as f64;
    let secs = |p: &CurvePoint| p.seconds;
    let rmse = |p: &CurvePoint| p.errors.near.rmse();
    let mae = |p: &CurvePoint| p.errors.object.mae();
    let (w, h) = (480, 300);
    let panels = [
        plot(&format!("{}: object MAE (m)", r.name), "steps", &series(step, mae), w, h),
        plot(&format!("{}: object MAE (m)", r.name), "seconds", &series(secs, mae), w, h),
        plot(&format!("{}: near-crop RMSE (m)", r.name), "steps", &series(step, rmse), w, h),
        plot(&format!("{}: near-crop RMSE (m)", r.name), "seconds", &series(secs, rmse), w, h),
    ];
    crate::files::export::png_bytes(figures::grid(&panels, 2))
}

/// Test view `i` of a scene side by side: ground truth, then each method's depth (NeRF's
/// expected depth beside Dex-NeRF's threshold depth), then Residual-NeRF's β map; one colour
/// scale (the ground truth's 2nd–98th percentile); the crop outlined.
pub fn depth_sheet_png(r: &SceneResult, test: &EvalSet, i: usize) -> Result<Vec<u8>, String> {
    use figures::Panel;
    let k = &test.views[i].intrinsics;
    let gt = &test.depth[i];
    let (near, far) = crate::files::export::depth_range(gt);
    let mut panels: Vec<(&str, Panel<'_>)> = vec![("truth", Panel::Depth(gt))];
    for m in &r.methods {
        let v = &m.renders[i];
        if m.method == Method::Dex {
            panels.push(("NeRF", Panel::Depth(&v.expected_z)));
        }
        panels.push((m.method.name(), Panel::Depth(&v.threshold_z)));
    }
    // β of the default residual method, else of the first one with a Mixnet.
    let with_beta = |m: &&MethodResult| matches!(m.method, Method::Residual { kind: MixKind::Mixnet(_), .. });
    let shown = r.methods.iter().find(|m| m.method == Method::RESIDUAL).or_else(|| r.methods.iter().find(with_beta));
    if let Some(m) = shown {
        panels.push(("beta", Panel::Gray(&m.renders[i].beta)));
    }
    // The error of the default residual method, else of the last method shown.
    if let Some(m) = r.methods.iter().find(|m| m.method == Method::RESIDUAL).or(r.methods.last()) {
        panels.push(("error 0-10cm", Panel::Error { depth: &m.renders[i].threshold_z, truth: gt }));
    }
    let mask = test.masks[i].as_deref();
    crate::files::export::png_bytes(figures::depth_sheet(&panels, k.width, k.height, test.crops[i], mask, near, far))
}
