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
use crate::data::View;
use crate::encoding::HashGridConfig;
use crate::eval::{mse, psnr, DepthReport, NEAR_LIMIT};
use crate::field::mix::{DensityMix, MixKind};
use crate::field::mixnet::MixnetEncoding;
use crate::field::model::Model;
use crate::field::residual::ResidualConfig;
use crate::field::{Nerf, NerfConfig, NerfField};
use crate::io::{save_model, ModelFile};
use crate::render::view::{RenderedView, Scene};
use crate::render::{DensityThreshold, Intrinsics, OccupancyGrid, ViewRenderer};
use crate::simd::Isa;
pub use crate::train::prior::Prior;
use crate::train::prior::{residual_start, scene_prior, PriorConfig, ScenePrior};
use crate::train::trainer::{train_model_from, StepStats, TrainConfig, TrainError};
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
    /// Object mask per view (`None`: the frame has none; then nothing is scored as object).
    pub masks: Vec<Option<Vec<bool>>>,
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
        let masks = d.frames.iter().map(|f| f.mask.clone()).collect();
        Ok(EvalSet { views: d.views.clone(), depth, crops, masks })
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
        let masks = (0..s.views.len()).map(|i| s.masks.get(i).cloned()).collect();
        EvalSet { views: s.views.clone(), depth: depth.collect(), crops, masks }
    }
}

/// A method of the comparison.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Method {
    /// A plain NeRF on the scene: "NeRF" (expected depth) and "Dex-NeRF" (threshold depth).
    Dex,
    /// The background NeRF fine-tuned on the scene (its weights and occupancy grid as the start;
    /// a continual update, as Evo-NeRF evolves one NeRF), threshold depth.
    FineTune,
    /// Residual NeRF over the frozen background, mixed by `kind`; with `shared`, the Mixnet reads
    /// the residual's encoding instead of its own grid; `prior` says which background hints it
    /// uses ([`Prior::NONE`]: the paper's and the authors' method).
    Residual {
        /// Mixing rule.
        kind: MixKind,
        /// Mixnet encoding shared with the residual.
        shared: bool,
        /// Background hints used.
        prior: Prior,
    },
}

const fn residual(kind: MixKind, shared: bool, prior: Prior) -> Method {
    Method::Residual { kind, shared, prior }
}

const RAW: MixKind = MixKind::Mixnet(DensityMix::Raw);
const ACTIVATED: MixKind = MixKind::Mixnet(DensityMix::Activated);

/// Every method with its name (file names, json, `--methods`) and label (tables, plots), in
/// table order.
const ALL: [(Method, &str, &str); 15] = [
    (Method::Dex, "dex", "Dex-NeRF"),
    (Method::FineTune, "finetune", "Fine-tuned background"),
    (Method::RESIDUAL, "residual", "Residual-NeRF"),
    (
        residual(RAW, false, Prior { warm_start: false, ..Prior::ALL }),
        "residual-no-warm-start",
        "Residual-NeRF (no warm start)",
    ),
    (residual(RAW, false, Prior { region: false, ..Prior::ALL }), "residual-no-region", "Residual-NeRF (no region)"),
    (residual(RAW, false, Prior { focus: false, ..Prior::ALL }), "residual-no-focus", "Residual-NeRF (no focus)"),
    (residual(RAW, false, Prior { reach: false, ..Prior::ALL }), "residual-no-reach", "Residual-NeRF (no reach)"),
    (residual(RAW, false, Prior { beta: false, ..Prior::ALL }), "residual-no-beta", "Residual-NeRF (no β terms)"),
    (residual(ACTIVATED, false, Prior::ALL), "residual-activated", "Residual-NeRF (activated mix)"),
    (
        residual(ACTIVATED, false, Prior { warm_start: false, ..Prior::ALL }),
        "residual-activated-no-warm-start",
        "Residual-NeRF (activated, no warm start)",
    ),
    (Method::RESIDUAL_PAPER, "residual-paper", "Residual-NeRF (paper)"),
    (residual(ACTIVATED, false, Prior::NONE), "residual-paper-activated", "Residual-NeRF (paper, activated mix)"),
    (residual(RAW, true, Prior::NONE), "residual-paper-shared", "Residual-NeRF (paper, shared encoding)"),
    (
        residual(ACTIVATED, true, Prior::NONE),
        "residual-paper-activated-shared",
        "Residual-NeRF (paper, activated, shared)",
    ),
    (Method::RESIDUAL_S, "residual-s", "Residual-NeRF-S"),
];

impl Method {
    /// The background-aware Residual-NeRF (raw density mix, the Mixnet's own grid, every
    /// background hint): the crate's default residual method.
    pub const RESIDUAL: Method = residual(RAW, false, Prior::ALL);
    /// Residual-NeRF as the paper and the authors' code define it (no background hints).
    pub const RESIDUAL_PAPER: Method = residual(RAW, false, Prior::NONE);
    /// Residual-NeRF-S (paper Eq. 6).
    pub const RESIDUAL_S: Method = residual(MixKind::Sum, false, Prior::NONE);

    fn entry(&self) -> &'static (Method, &'static str, &'static str) {
        ALL.iter().find(|e| e.0 == *self).expect("every method is listed")
    }

    /// The name used in file names, json and `--methods`.
    pub fn name(&self) -> &'static str {
        self.entry().1
    }

    /// The method called `name` (see [`Method::name`]).
    pub fn parse(name: &str) -> Option<Method> {
        ALL.iter().find(|e| e.1 == name).map(|e| e.0)
    }

    /// Every method's name, for help and errors.
    pub fn names() -> String {
        ALL.iter().map(|e| e.1).collect::<Vec<_>>().join(", ")
    }

    /// The paper's methods: Dex-NeRF (with NeRF's expected depth), Residual-NeRF as published,
    /// Residual-NeRF-S.
    pub fn paper() -> Vec<Method> {
        vec![Method::Dex, Method::RESIDUAL_PAPER, Method::RESIDUAL_S]
    }

    /// The default comparison: the baselines (Dex-NeRF, the fine-tuned background), the paper's
    /// Residual-NeRF and the background-aware one.
    pub fn defaults() -> Vec<Method> {
        vec![Method::Dex, Method::FineTune, Method::RESIDUAL_PAPER, Method::RESIDUAL]
    }

    fn label(&self) -> &'static str {
        self.entry().2
    }

    /// The background hints the method uses (none for the non-residual methods).
    pub fn prior(&self) -> Prior {
        match self {
            Method::Residual { prior, .. } => *prior,
            _ => Prior::NONE,
        }
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
    /// The background prior's settings (methods with a [`Prior`]).
    pub prior: PriorConfig,
    /// Where each trained model is saved as `<scene>_<method>.safetensors` (None: not saved).
    pub models: Option<std::path::PathBuf>,
}

/// A point of a speed curve: threshold-depth errors inside the test crops after `step` steps.
#[derive(Clone, Copy, Debug)]
pub struct CurvePoint {
    /// Steps done.
    pub step: u32,
    /// Training seconds so far (evaluation excluded).
    pub seconds: f64,
    /// Errors inside the crops (every region).
    pub errors: DepthReport,
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
    /// Final threshold-depth errors (every region).
    pub threshold: DepthReport,
    /// Final expected-depth errors (every region).
    pub expected: DepthReport,
    /// Mean test PSNR (dB) over the whole images.
    pub psnr: f64,
    /// Final renders of the test views.
    pub renders: Vec<RenderedView>,
    /// Final threshold-depth errors in the crops at each threshold of [`CompareConfig::m_sweep`].
    pub sweep: Vec<(DensityThreshold, DepthReport)>,
}

/// What the background prior found on one scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PriorSummary {
    /// Share of the training pixels marked changed.
    pub changed_pixels: f64,
    /// Share of the training pixels whose ray crosses the change region.
    pub reach_pixels: f64,
    /// Training views compared with a background image at the same pose (the rest against
    /// the rendered background).
    pub matched_views: usize,
    /// Training views.
    pub views: usize,
    /// Cells in the change region.
    pub region_cells: usize,
    /// The region's volume (scene units cubed).
    pub region_volume: f64,
    /// Seconds to compute the prior (change maps, the background's depth, the vote).
    pub seconds: f64,
}

/// All methods on one scene.
#[derive(Clone, Debug)]
pub struct SceneResult {
    /// Scene name (its folder).
    pub name: String,
    /// In the order the methods were given.
    pub methods: Vec<MethodResult>,
    /// The background prior, when a method used it.
    pub prior: Option<PriorSummary>,
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

/// Threshold-depth errors of `scene` inside the crops of `test`, every region (renders the
/// crops only).
pub fn crop_errors<M: Model>(
    isa: Isa,
    scene: &Scene<'_, M>,
    test: &EvalSet,
    m: DensityThreshold,
    renderer: &mut ViewRenderer<M>,
    z: &mut Vec<f32>,
    truth: &mut Vec<f32>,
) -> DepthReport {
    let mut e = DepthReport::default();
    let mut mask = Vec::new();
    for (((v, gt), &crop), full_mask) in test.views.iter().zip(&test.depth).zip(&test.crops).zip(&test.masks) {
        let k = crop_intrinsics(&v.intrinsics, crop);
        z.resize((k.width * k.height) as usize, 0.0);
        renderer.depth(isa, scene, &k, &v.pose, m, z);
        truth.clear();
        mask.clear();
        for y in crop[1]..crop[3] {
            let row = (y * v.intrinsics.width) as usize;
            let r = row + crop[0] as usize..row + crop[2] as usize;
            truth.extend_from_slice(&gt[r.clone()]);
            if let Some(fm) = full_mask {
                mask.extend_from_slice(&fm[r]);
            }
        }
        let mask = full_mask.as_ref().map(|_| &mask[..]);
        e.add_frame(z, truth, mask, k.width, [0, 0, k.width, k.height], NEAR_LIMIT);
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

/// The file [`CompareConfig::models`] gets for `method` trained on `scene`.
pub fn model_path(dir: &std::path::Path, scene: &str, method: Method) -> std::path::PathBuf {
    dir.join(format!("{scene}_{}.safetensors", method.name()))
}

/// Trains `model` on `train` (from `start` when given) with the curve observer, then renders
/// and scores every test view (and saves the model where [`CompareConfig::models`] says).
#[allow(clippy::too_many_arguments)]
fn run_method<M: Model + ModelFile>(
    isa: Isa,
    scene_name: &str,
    method: Method,
    model: &M,
    start: Option<(M::Params, OccupancyGrid)>,
    train: &[View],
    test: &EvalSet,
    cfg: &CompareConfig,
    log: &mut dyn FnMut(Method, &StepStats),
) -> Result<MethodResult, String> {
    let mut curve = Vec::new();
    let mut renderer = ViewRenderer::<M>::new();
    let (mut z, mut truth) = (Vec::new(), Vec::new());
    let steps = cfg.train.steps;
    let every = if cfg.eval_every == 0 { steps } else { cfg.eval_every };
    let log_every = gcd(10, every);
    let (params, occupancy) =
        train_model_from(isa, model, cfg.field.aabb, train, &cfg.train, start, log_every, |s, params, occupancy| {
            log(method, &s);
            let done = s.step + 1;
            if done % every == 0 || done == steps {
                let scene = Scene { model, params, occupancy };
                let errors = crop_errors(isa, &scene, test, cfg.m, &mut renderer, &mut z, &mut truth);
                curve.push(CurvePoint { step: done, seconds: s.seconds, errors });
            }
        })
        .map_err(|e: TrainError| e.to_string())?;
    if let Some(dir) = &cfg.models {
        save_model(
            &model_path(dir, scene_name, method),
            model,
            &params,
            &occupancy,
            &[("compare_method", method.name().to_string())],
        )?;
    }
    let seconds = curve.last().map_or(0.0, |p| p.seconds);
    let scene = Scene { model, params: &params, occupancy: &occupancy };
    let (mut threshold, mut expected) = (DepthReport::default(), DepthReport::default());
    let mut psnr_sum = 0.0;
    let mut renders = Vec::new();
    for (((v, gt), &crop), mask) in test.views.iter().zip(&test.depth).zip(&test.crops).zip(&test.masks) {
        let k = &v.intrinsics;
        let r = renderer.render(isa, &scene, k, &v.pose, cfg.train.background, cfg.m);
        threshold.add_frame(&r.threshold_z, gt, mask.as_deref(), k.width, crop, NEAR_LIMIT);
        expected.add_frame(&r.expected_z, gt, mask.as_deref(), k.width, crop, NEAR_LIMIT);
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
/// `bg_views` are the background's own training images (matched by pose for the change maps;
/// may be empty). `log` sees every method's training progress. A method whose training fails
/// ends the scene with an error naming the scene and method.
#[allow(clippy::too_many_arguments)]
pub fn run_scene(
    isa: Isa,
    name: &str,
    background: &Nerf,
    bg_views: &[View],
    train: &[View],
    test: &EvalSet,
    methods: &[Method],
    cfg: &CompareConfig,
    log: &mut dyn FnMut(Method, &StepStats),
) -> Result<SceneResult, String> {
    let mut prior: Option<(ScenePrior, PriorSummary)> = None;
    if methods.iter().any(|m| m.prior() != Prior::NONE) {
        let t0 = std::time::Instant::now();
        let p = scene_prior(isa, background, bg_views, train, cfg.train.background, cfg.m, &cfg.prior);
        let summary = PriorSummary {
            changed_pixels: p.changed_share(),
            reach_pixels: p.reach_share(),
            matched_views: p.matched_views,
            views: train.len(),
            region_cells: p.region.count(),
            region_volume: p.region.volume(),
            seconds: t0.elapsed().as_secs_f64(),
        };
        prior = Some((p, summary));
    }
    let results = methods
        .iter()
        .map(|&method| {
            match method {
                Method::Dex => {
                    run_method(isa, name, method, &NerfField::new(cfg.field.clone()), None, train, test, cfg, log)
                }
                Method::FineTune => {
                    let field = NerfField::new(background.field.config().clone());
                    let start = Some((background.params.clone(), background.occupancy.clone()));
                    run_method(isa, name, method, &field, start, train, test, cfg, log)
                }
                Method::Residual { kind, shared, prior: hints } => {
                    let mixnet = if shared { MixnetEncoding::Shared } else { MixnetEncoding::Own(cfg.mixnet_grid) };
                    let config = ResidualConfig { residual: cfg.field.clone(), kind, mixnet };
                    let p = prior.as_ref().map(|p| &p.0);
                    let start = residual_start(isa, background, config, hints, p, &cfg.train, &cfg.prior);
                    let mut mcfg = cfg.clone();
                    mcfg.train.focus = start.focus;
                    mcfg.train.beta = start.beta;
                    if let Some(l) = start.lift {
                        eprintln!("{name}: {l}");
                    }
                    let init = Some((start.params, start.occupancy));
                    // In the background's appearance when the prior corrected the exposure.
                    let corrected = p.filter(|p| p.corrected_count() > 0).map(|p| p.corrected_views(train));
                    let views = corrected.as_deref().unwrap_or(train);
                    run_method(isa, name, method, &start.field, init, views, test, &mcfg, log)
                }
            }
            .map_err(|e| format!("{name}: {}: {e}", method.name()))
        })
        .collect::<Result<_, _>>()?;
    Ok(SceneResult { name: name.to_string(), methods: results, prior: prior.map(|p| p.1) })
}

/// The first curve point whose object-mask MAE is ≤ `target` (None: never).
pub fn first_reaching(curve: &[CurvePoint], target: f64) -> Option<&CurvePoint> {
    curve.iter().find(|p| p.errors.object.mae() <= target)
}

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
                 the same pose, the rest against the rendered background); change region {} cells ({:.4} m³), crossed by the rays of {} of the pixels; {:.1} s",
                r.name,
                pct(p.changed_pixels),
                p.matched_views,
                p.views,
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
    crate::io::export::png_bytes(figures::depth_sheet(&panels, k.width, k.height, test.crops[i], mask, near, far))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::DepthErrors;

    #[test]
    fn method_names_round_trip() {
        for (m, name, _) in ALL {
            assert_eq!(Method::parse(name), Some(m));
            assert_eq!(m.name(), name);
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
        let pt = |step, seconds, err: f64| {
            let object = DepthErrors { abs_sum: err, sq_sum: err * err, pixels: 1, ..Default::default() };
            CurvePoint { step, seconds, errors: DepthReport { object, ..Default::default() } }
        };
        let curve = [pt(10, 1.0, 0.5), pt(20, 2.0, 0.3), pt(30, 3.0, 0.35), pt(40, 4.0, 0.1)];
        assert_eq!(first_reaching(&curve, 0.3).map(|p| p.step), Some(20));
        assert!(first_reaching(&curve, 0.05).is_none());
    }
}
