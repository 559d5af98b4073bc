//! The paper's comparison protocol (Experiments; DESIGN §2.6), shared by `rnerf compare` (on a
//! dataset) and `rnerf demo` (on a synthesised workspace).
//!
//! Given a trained background NeRF and a scene (training views, test views with ground-truth
//! z-depth and crops), each [`Method`] is trained on the scene's views with the same
//! [`TrainConfig`] and seed:
//! - [`Method::Dex`]: a plain NeRF; scored twice — its expected depth ("NeRF") and its
//!   threshold depth ("Dex-NeRF");
//! - [`Method::Residual`]: residual NeRF (+ Mixnet) over the frozen background, threshold depth
//!   (Residual-NeRF; with [`MixKind::Sum`] the Residual-NeRF-S ablation of Eq. 6).
//!
//! While a method trains, its threshold depth inside the test crops is scored every
//! `eval_every` steps (the trainer's clock stops meanwhile): the training-speed curves. The
//! background's own training time is not counted (it is pre-trained, as in the paper).

pub mod figures;

use crate::data::synth::SynthScene;
use crate::data::Dataset;
use crate::encoding::HashGridConfig;
use crate::eval::{mse, psnr, DepthErrors};
use crate::field::mix::{DensityMix, MixKind};
use crate::field::mixnet::MixnetEncoding;
use crate::field::residual::{ResidualConfig, ResidualField};
use crate::field::{Nerf, NerfConfig, NerfField};
use crate::render::view::{RenderedView, Scene};
use crate::render::{DensityThreshold, Intrinsics, ViewRenderer};
use crate::simd::Isa;
use crate::train::model::Model;
use crate::train::trainer::{train_model, StepStats, TrainConfig, TrainError, View};
use std::fmt::Write as _;

/// Test views with ground truth: z-depth per pixel (metres, NaN where unknown) and the scoring
/// crop `[x0, y0, x1, y1)` of each.
#[derive(Clone, Debug)]
pub struct EvalSet {
    /// Posed test images.
    pub views: Vec<View>,
    /// Ground-truth z-depth per view.
    pub depth: Vec<Vec<f32>>,
    /// Scoring crop per view.
    pub crops: Vec<[u32; 4]>,
}

impl EvalSet {
    /// The frames of a loaded test split; every frame needs ground-truth depth (frames without
    /// a crop are scored whole).
    pub fn from_dataset(d: &Dataset) -> Result<EvalSet, String> {
        let mut depth = Vec::new();
        let mut crops = Vec::new();
        for (v, f) in d.views.iter().zip(&d.frames) {
            let z = f.depth.clone().ok_or_else(|| {
                format!(
                    "{}: frame {}: field 'depth_file_path': missing; the comparison scores depth",
                    d.json.display(),
                    f.index
                )
            })?;
            depth.push(z);
            crops.push(f.crop.unwrap_or([0, 0, v.intrinsics.width, v.intrinsics.height]));
        }
        Ok(EvalSet { views: d.views.clone(), depth, crops })
    }

    /// The views of a synthesised scene (crops where it has them, else whole images).
    pub fn from_synth(s: &SynthScene) -> EvalSet {
        let crops = s
            .views
            .iter()
            .enumerate()
            .map(|(i, v)| s.crops.get(i).copied().unwrap_or([0, 0, v.intrinsics.width, v.intrinsics.height]))
            .collect();
        let depth = s.depth.iter().map(|d| d.iter().map(|&z| if z.is_finite() { z } else { f32::NAN }).collect());
        EvalSet { views: s.views.clone(), depth: depth.collect(), crops }
    }
}

/// A method of the comparison.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Method {
    /// A plain NeRF on the scene: "NeRF" (expected depth) and "Dex-NeRF" (threshold depth).
    Dex,
    /// Residual NeRF over the frozen background, mixed by `kind`; with `shared`, the Mixnet reads
    /// the residual's encoding instead of its own grid.
    Residual {
        /// Mixing rule.
        kind: MixKind,
        /// Mixnet encoding shared with the residual.
        shared: bool,
    },
}

/// Every method, in table order.
const ALL: [Method; 6] = [
    Method::Dex,
    Method::RESIDUAL,
    Method::Residual { kind: MixKind::Mixnet(DensityMix::Activated), shared: false },
    Method::Residual { kind: MixKind::Mixnet(DensityMix::Raw), shared: true },
    Method::Residual { kind: MixKind::Mixnet(DensityMix::Activated), shared: true },
    Method::RESIDUAL_S,
];

impl Method {
    /// Residual-NeRF with this crate's defaults (raw density mix, the Mixnet's own grid).
    pub const RESIDUAL: Method = Method::Residual { kind: MixKind::Mixnet(DensityMix::Raw), shared: false };
    /// Residual-NeRF-S (paper Eq. 6).
    pub const RESIDUAL_S: Method = Method::Residual { kind: MixKind::Sum, shared: false };

    /// (name in file names, json and `--methods`; label in tables and plots).
    fn name_and_label(&self) -> (&'static str, &'static str) {
        use DensityMix::{Activated, Raw};
        match self {
            Method::Dex => ("dex", "Dex-NeRF"),
            Method::Residual { kind: MixKind::Sum, .. } => ("residual-s", "Residual-NeRF-S"),
            Method::Residual { kind: MixKind::Mixnet(Raw), shared: false } => ("residual", "Residual-NeRF"),
            Method::Residual { kind: MixKind::Mixnet(Activated), shared: false } => {
                ("residual-activated", "Residual-NeRF (activated mix)")
            }
            Method::Residual { kind: MixKind::Mixnet(Raw), shared: true } => {
                ("residual-shared", "Residual-NeRF (shared encoding)")
            }
            Method::Residual { kind: MixKind::Mixnet(Activated), shared: true } => {
                ("residual-activated-shared", "Residual-NeRF (activated, shared)")
            }
        }
    }

    /// The name used in file names, json and `--methods`.
    pub fn name(&self) -> &'static str {
        self.name_and_label().0
    }

    /// The method called `name` (see [`Method::name`]).
    pub fn parse(name: &str) -> Option<Method> {
        ALL.into_iter().find(|m| m.name() == name)
    }

    /// Every method's name, for help and errors.
    pub fn names() -> String {
        ALL.iter().map(|m| m.name()).collect::<Vec<_>>().join(", ")
    }

    /// The paper's methods: Dex-NeRF (with NeRF's expected depth), Residual-NeRF, Residual-NeRF-S.
    pub fn paper() -> Vec<Method> {
        vec![Method::Dex, Method::RESIDUAL, Method::RESIDUAL_S]
    }

    fn label(&self) -> &'static str {
        self.name_and_label().1
    }
}

/// Settings shared by every method of a comparison.
#[derive(Clone, Debug)]
pub struct CompareConfig {
    /// Trainer settings (steps, rays, schedule, occupancy, seed, background colour).
    pub train: TrainConfig,
    /// Field of the scene NeRF and of the residual (the background's scene box).
    pub field: NerfConfig,
    /// The Mixnet's own hash grid.
    pub mixnet_grid: HashGridConfig,
    /// Threshold of threshold depth.
    pub m: DensityThreshold,
    /// Steps between points of the speed curves (0: final point only).
    pub eval_every: u32,
    /// Further thresholds at which the final models are scored in the crops (the `m` sweep
    /// that chooses the default).
    pub m_sweep: Vec<DensityThreshold>,
}

/// A point of a speed curve: threshold-depth errors inside the test crops after `step` steps.
#[derive(Clone, Copy, Debug)]
pub struct CurvePoint {
    /// Steps done.
    pub step: u32,
    /// Training seconds so far (evaluation excluded).
    pub seconds: f64,
    /// Errors inside the crops.
    pub errors: DepthErrors,
}

/// One trained method on one scene.
#[derive(Clone, Debug)]
pub struct MethodResult {
    /// Which method.
    pub method: Method,
    /// Training seconds (evaluation excluded).
    pub seconds: f64,
    /// Threshold-depth errors after every `eval_every` steps and at the end.
    pub curve: Vec<CurvePoint>,
    /// Final threshold-depth errors inside the crops.
    pub threshold: DepthErrors,
    /// Final expected-depth errors inside the crops.
    pub expected: DepthErrors,
    /// Mean test PSNR (dB) over the whole images.
    pub psnr: f64,
    /// Final renders of the test views.
    pub renders: Vec<RenderedView>,
    /// Final threshold-depth errors in the crops at each threshold of [`CompareConfig::m_sweep`].
    pub sweep: Vec<(DensityThreshold, DepthErrors)>,
}

/// All methods on one scene.
#[derive(Clone, Debug)]
pub struct SceneResult {
    /// Scene name (its folder).
    pub name: String,
    /// In the order the methods were given.
    pub methods: Vec<MethodResult>,
}

/// The intrinsics of the sub-window `crop` of `k` (the same rays as those pixels of `k`).
pub fn crop_intrinsics(k: &Intrinsics, crop: [u32; 4]) -> Intrinsics {
    Intrinsics {
        width: crop[2] - crop[0],
        height: crop[3] - crop[1],
        cx: k.cx - crop[0] as f32,
        cy: k.cy - crop[1] as f32,
        ..*k
    }
}

/// Threshold-depth errors of `scene` inside the crops of `test` (renders the crops only).
pub fn crop_errors<M: Model>(
    isa: Isa,
    scene: &Scene<'_, M>,
    test: &EvalSet,
    m: DensityThreshold,
    renderer: &mut ViewRenderer<M>,
    z: &mut Vec<f32>,
    truth: &mut Vec<f32>,
) -> DepthErrors {
    let mut e = DepthErrors::default();
    for ((v, gt), &crop) in test.views.iter().zip(&test.depth).zip(&test.crops) {
        let k = crop_intrinsics(&v.intrinsics, crop);
        z.resize((k.width * k.height) as usize, 0.0);
        renderer.depth(isa, scene, &k, &v.pose, m, z);
        truth.clear();
        for y in crop[1]..crop[3] {
            let row = (y * v.intrinsics.width) as usize;
            truth.extend_from_slice(&gt[row + crop[0] as usize..row + crop[2] as usize]);
        }
        e.add_frame(z, truth, k.width, [0, 0, k.width, k.height], None);
    }
    e
}

fn gcd(a: u32, b: u32) -> u32 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// Trains `model` on `train` with the curve observer, then renders and scores every test view.
fn run_method<M: Model>(
    isa: Isa,
    method: Method,
    model: &M,
    train: &[View],
    test: &EvalSet,
    cfg: &CompareConfig,
    log: &mut dyn FnMut(Method, &StepStats),
) -> Result<MethodResult, TrainError> {
    let mut curve = Vec::new();
    let mut renderer = ViewRenderer::<M>::new();
    let (mut z, mut truth) = (Vec::new(), Vec::new());
    let steps = cfg.train.steps;
    let every = if cfg.eval_every == 0 { steps } else { cfg.eval_every };
    let log_every = gcd(10, every);
    let (params, occupancy) =
        train_model(isa, model, cfg.field.aabb, train, &cfg.train, log_every, |s, params, occupancy| {
            log(method, &s);
            let done = s.step + 1;
            if done % every == 0 || done == steps {
                let scene = Scene { model, params, occupancy };
                let errors = crop_errors(isa, &scene, test, cfg.m, &mut renderer, &mut z, &mut truth);
                curve.push(CurvePoint { step: done, seconds: s.seconds, errors });
            }
        })?;
    let seconds = curve.last().map_or(0.0, |p| p.seconds);
    let scene = Scene { model, params: &params, occupancy: &occupancy };
    let (mut threshold, mut expected) = (DepthErrors::default(), DepthErrors::default());
    let mut psnr_sum = 0.0;
    let mut renders = Vec::new();
    for ((v, gt), &crop) in test.views.iter().zip(&test.depth).zip(&test.crops) {
        let k = &v.intrinsics;
        let r = renderer.render(isa, &scene, k, &v.pose, cfg.train.background, cfg.m);
        threshold.add_frame(&r.threshold_z, gt, k.width, crop, None);
        expected.add_frame(&r.expected_z, gt, k.width, crop, None);
        psnr_sum += psnr(mse(&r.rgb, &v.rgb));
        renders.push(r);
    }
    let psnr = psnr_sum / test.views.len().max(1) as f64;
    let sweep = cfg
        .m_sweep
        .iter()
        .map(|&m| (m, crop_errors(isa, &scene, test, m, &mut renderer, &mut z, &mut truth)))
        .collect();
    Ok(MethodResult { method, seconds, curve, threshold, expected, psnr, renders, sweep })
}

/// Trains and scores every method of `methods` on one scene over the frozen `background`.
/// `log` sees every method's training progress. A method whose training fails ends the scene
/// with an error naming the scene and method.
pub fn run_scene(
    isa: Isa,
    name: &str,
    background: &Nerf,
    train: &[View],
    test: &EvalSet,
    methods: &[Method],
    cfg: &CompareConfig,
    log: &mut dyn FnMut(Method, &StepStats),
) -> Result<SceneResult, String> {
    let results = methods
        .iter()
        .map(|&method| {
            match method {
                Method::Dex => run_method(isa, method, &NerfField::new(cfg.field.clone()), train, test, cfg, log),
                Method::Residual { kind, shared } => {
                    let mixnet = if shared { MixnetEncoding::Shared } else { MixnetEncoding::Own(cfg.mixnet_grid) };
                    let config = ResidualConfig { residual: cfg.field.clone(), kind, mixnet };
                    let field = ResidualField::new(background.clone(), config);
                    run_method(isa, method, &field, train, test, cfg, log)
                }
            }
            .map_err(|e| format!("{name}: {}: {e}", method.name()))
        })
        .collect::<Result<_, _>>()?;
    Ok(SceneResult { name: name.to_string(), methods: results })
}

/// Training seconds after which `curve` first scores an RMSE ≤ `target` (None: never).
pub fn seconds_to_reach(curve: &[CurvePoint], target: f64) -> Option<f64> {
    curve.iter().find(|p| p.errors.rmse() <= target).map(|p| p.seconds)
}

/// A table row: label, errors, training seconds, PSNR.
struct Row<'a> {
    scene: &'a str,
    label: &'static str,
    errors: DepthErrors,
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

/// Mean over scenes of a method's final threshold RMSE and MAE (None when a scene lacks it).
pub fn mean_errors(results: &[SceneResult], method: Method) -> Option<(f64, f64)> {
    let mut acc = (0.0, 0.0);
    for r in results {
        let m = r.methods.iter().find(|m| m.method == method)?;
        acc.0 += m.threshold.rmse();
        acc.1 += m.threshold.mae();
    }
    let n = results.len().max(1) as f64;
    Some((acc.0 / n, acc.1 / n))
}

/// The comparison table (Markdown): per scene and method MAE, RMSE, holes, training time and
/// PSNR; the mean over scenes per method; and the ratios the paper reports (Residual-NeRF over
/// Dex-NeRF) with the time Residual-NeRF takes to reach Dex-NeRF's final RMSE.
pub fn table(results: &[SceneResult]) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "| scene | method | depth MAE (m) | depth RMSE (m) | holes | train (s) | test PSNR (dB) |");
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    for r in results {
        for row in rows(r) {
            let _ = writeln!(
                s,
                "| {} | {} | {:.4} | {:.4} | {:.1}% | {:.1} | {:.2} |",
                row.scene,
                row.label,
                row.errors.mae(),
                row.errors.rmse(),
                100.0 * row.errors.hole_rate(),
                row.seconds,
                row.psnr
            );
        }
    }
    if results.len() > 1 {
        let n = results.len() as f64;
        let all: Vec<Vec<Row<'_>>> = results.iter().map(rows).collect();
        for (i, row) in all[0].iter().enumerate() {
            let (mut mae, mut rmse, mut holes, mut secs, mut ps) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for r in &all {
                let x = &r[i];
                (mae, rmse, holes) = (mae + x.errors.mae(), rmse + x.errors.rmse(), holes + x.errors.hole_rate());
                (secs, ps) = (secs + x.seconds, ps + x.psnr);
            }
            let _ = writeln!(
                s,
                "| **mean** | {} | {:.4} | {:.4} | {:.1}% | {:.1} | {:.2} |",
                row.label,
                mae / n,
                rmse / n,
                100.0 * holes / n,
                secs / n,
                ps / n
            );
        }
    }
    s.push_str(&sweep_table(results));
    let dex = mean_errors(results, Method::Dex);
    for method in ALL.into_iter().skip(1) {
        if let (Some(d), Some(r)) = (dex, mean_errors(results, method)) {
            let _ = writeln!(
                s,
                "\n{} / Dex-NeRF (mean over scenes): RMSE {:.2}x, MAE {:.2}x",
                method.label(),
                r.0 / d.0,
                r.1 / d.1
            );
        }
    }
    for r in results {
        let (Some(d), Some(res)) = (
            r.methods.iter().find(|m| m.method == Method::Dex),
            r.methods.iter().find(|m| m.method == Method::RESIDUAL),
        ) else {
            continue;
        };
        let target = d.threshold.rmse();
        match seconds_to_reach(&res.curve, target) {
            Some(t) => {
                let _ = writeln!(
                    s,
                    "{}: Residual-NeRF reaches Dex-NeRF's final RMSE {target:.4} m after {t:.1} s = {:.2}x of Dex-NeRF's {:.1} s",
                    r.name,
                    t / d.seconds,
                    d.seconds
                );
            }
            None => {
                let _ = writeln!(
                    s,
                    "{}: Residual-NeRF does not reach Dex-NeRF's final RMSE {target:.4} m (its final: {:.4} m)",
                    r.name,
                    res.threshold.rmse()
                );
            }
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
    let _ = writeln!(s, "| method | threshold | depth MAE (m) | depth RMSE (m) | holes |");
    let _ = writeln!(s, "|---|---|---|---|---|");
    let n = results.len() as f64;
    for (k, m) in first.methods.iter().enumerate() {
        for (j, (th, _)) in m.sweep.iter().enumerate() {
            let (mut mae, mut rmse, mut holes) = (0.0, 0.0, 0.0);
            for r in results {
                let e = &r.methods[k].sweep[j].1;
                (mae, rmse, holes) = (mae + e.mae(), rmse + e.rmse(), holes + e.hole_rate());
            }
            let _ = writeln!(
                s,
                "| {} | {} | {:.4} | {:.4} | {:.1}% |",
                m.method.label(),
                threshold_name(*th),
                mae / n,
                rmse / n,
                100.0 * holes / n
            );
        }
    }
    s
}

/// The speed curves of one scene as CSV: `scene,method,step,seconds,mae,rmse,hole_rate`.
pub fn curves_csv(results: &[SceneResult]) -> String {
    let mut s = String::from("scene,method,step,seconds,mae,rmse,hole_rate\n");
    for r in results {
        for m in &r.methods {
            for p in &m.curve {
                let _ = writeln!(
                    s,
                    "{},{},{},{:.3},{:.6},{:.6},{:.6}",
                    r.name,
                    m.method.name(),
                    p.step,
                    p.seconds,
                    p.errors.mae(),
                    p.errors.rmse(),
                    p.errors.hole_rate()
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
    let rmse = |p: &CurvePoint| p.errors.rmse();
    let mae = |p: &CurvePoint| p.errors.mae();
    let (w, h) = (480, 300);
    let panels = [
        plot(&format!("{}: depth RMSE (m)", r.name), "steps", &series(step, rmse), w, h),
        plot(&format!("{}: depth RMSE (m)", r.name), "seconds", &series(secs, rmse), w, h),
        plot(&format!("{}: depth MAE (m)", r.name), "steps", &series(step, mae), w, h),
        plot(&format!("{}: depth MAE (m)", r.name), "seconds", &series(secs, mae), w, h),
    ];
    crate::io::export::png_bytes(figures::grid(&panels, 2))
}

/// Test view `i` of a scene side by side: ground truth, then each method's depth (NeRF's
/// expected depth beside Dex-NeRF's threshold depth), then Residual-NeRF's β map; one colour
/// scale (the ground truth's 2nd–98th percentile); the crop outlined.
pub fn depth_sheet_png(r: &SceneResult, test: &EvalSet, i: usize) -> Result<Vec<u8>, String> {
    use figures::Panel;
    let k = &test.views[i].intrinsics;
    let gt = &test.depth[i];
    let (near, far) = crate::io::export::depth_range(gt);
    let mut panels: Vec<(&str, Panel<'_>)> = vec![("truth", Panel::Depth(gt))];
    for m in &r.methods {
        let v = &m.renders[i];
        if m.method == Method::Dex {
            panels.push(("NeRF", Panel::Depth(&v.expected_z)));
        }
        panels.push((m.method.name(), Panel::Depth(&v.threshold_z)));
    }
    let with_beta = |m: &&MethodResult| matches!(m.method, Method::Residual { kind: MixKind::Mixnet(_), .. });
    if let Some(m) = r.methods.iter().find(with_beta) {
        panels.push(("beta", Panel::Gray(&m.renders[i].beta)));
    }
    crate::io::export::png_bytes(figures::depth_sheet(&panels, k.width, k.height, test.crops[i], near, far))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn method_names_round_trip() {
        for m in ALL {
            assert_eq!(Method::parse(m.name()), Some(m));
        }
        assert_eq!(Method::parse("nerf"), None);
    }

    #[test]
    fn crop_intrinsics_give_the_same_rays() {
        use crate::render::{pixel_ray, Pose};
        let k = Intrinsics::from_fov_x(40, 30, 0.8);
        let pose = Pose::from_rows([[1.0, 0.0, 0.0, 0.3], [0.0, 1.0, 0.0, -0.2], [0.0, 0.0, 1.0, 2.0]]);
        let crop = [5, 7, 19, 25];
        let kc = crop_intrinsics(&k, crop);
        for (x, y) in [(0, 0), (13, 17), (3, 9)] {
            let a = pixel_ray(&k, &pose, crop[0] + x, crop[1] + y);
            let b = pixel_ray(&kc, &pose, x, y);
            assert!((a.dir - b.dir).length() < 1e-6 && (a.origin - b.origin).length() < 1e-6);
        }
    }

    #[test]
    fn time_to_reach_is_the_first_point_at_or_below_the_target() {
        let pt = |step, seconds, err: f64| CurvePoint {
            step,
            seconds,
            errors: DepthErrors { abs_sum: err, sq_sum: err * err, pixels: 1, holes: 0 },
        };
        let curve = [pt(10, 1.0, 0.5), pt(20, 2.0, 0.3), pt(30, 3.0, 0.35), pt(40, 4.0, 0.1)];
        assert_eq!(seconds_to_reach(&curve, 0.3), Some(2.0));
        assert_eq!(seconds_to_reach(&curve, 0.05), None);
    }
}
