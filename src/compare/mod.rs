//! The paper's comparison protocol (Experiments; DESIGN §2.6), shared by `rnerf compare` (on a
//! dataset) and `rnerf demo` (on a synthesised workspace).
//!
//! Given a trained background NeRF and a scene (training views, test views with ground-truth
//! z-depth and crops), each [`Method`] is trained on the scene's views with the same
//! [`TrainConfig`] and seed:
//! - [`Method::Dex`]: a plain NeRF; scored twice — its expected depth ("NeRF") and its
//!   threshold depth ("Dex-NeRF"); [`Method::DexErrorMap`] the same NeRF trained with rays
//!   drawn by its own error map;
//! - [`Method::FineTune`]: the background NeRF fine-tuned on the scene;
//! - [`Method::Residual`]: residual NeRF (+ Mixnet) over the frozen background, threshold depth
//!   (Residual-NeRF; with [`MixKind::Sum`] the Residual-NeRF-S ablation of Eq. 6).
//!
//! While a method trains, its threshold depth inside the test crops is scored every
//! `eval_every` steps (the trainer's clock stops meanwhile): the training-speed curves. The
//! background's own training time is not counted (it is pre-trained, as in the paper).
//!
//! Layout: this module holds the methods, the settings and the results' types; `run.rs` trains
//! and scores, `report.rs` writes the tables, curves and depth sheets, which [`figures`] draws.

pub mod figures;
mod report;
mod run;

pub use report::{curves_csv, curves_png, depth_sheet_png, mean_errors, table};
pub use run::{crop_errors, crop_intrinsics, first_reaching, model_path, run_scene};

use crate::data::synth::SynthScene;
use crate::data::Dataset;
use crate::data::View;
use crate::encoding::HashGridConfig;
use crate::eval::DepthReport;
use crate::field::mix::{DensityMix, MixKind};
use crate::field::NerfConfig;
use crate::render::view::RenderedView;
use crate::render::DensityThreshold;
pub use crate::train::prior::Prior;
use crate::train::prior::PriorConfig;
use crate::train::trainer::TrainConfig;

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
    /// Dex-NeRF with rays drawn by its own training error ([`crate::train::error_map`], share
    /// [`crate::train::error_map::ERROR_MAP_SHARE`]): the improvement of sampling that needs no
    /// background, threshold depth.
    DexErrorMap,
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
const ALL: [(Method, &str, &str); 17] = [
    (Method::Dex, "dex", "Dex-NeRF"),
    (Method::DexErrorMap, "dex-error-map", "Dex-NeRF (error map)"),
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
    (
        residual(RAW, false, Prior { solid: true, ..Prior::ALL }),
        "residual-solid",
        "Residual-NeRF (colour-only on solid)",
    ),
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
    /// Each run (the background's, every method on every scene) draws
    /// [`TrainConfig::rays_for_views`] of its own training set a step instead of
    /// `train.rays_per_step` (what `rnerf compare` does without `--rays`): [`Self::train_for`].
    pub capture_rays: bool,
    /// Steps of the background's training when the comparison trains it
    /// ([`crate::app::train_background`]; `--background-steps`), by default
    /// [`BACKGROUND_STEP_FACTOR`](crate::train::trainer::BACKGROUND_STEP_FACTOR) × `train.steps`.
    pub background_steps: u32,
}

impl CompareConfig {
    /// `train` and `field` with every other setting at its default: the Mixnet's default grid
    /// sized for the field's box ([`crate::train::sizing::mixnet_grid_for_box`]),
    /// threshold depth at [`DensityThreshold::DEFAULT`], no `m` sweep, the prior's defaults,
    /// models not saved, curve points every 1/20 of the steps, the background trained for
    /// [`BACKGROUND_STEP_FACTOR`](crate::train::trainer::BACKGROUND_STEP_FACTOR) times the steps.
    pub fn new(train: TrainConfig, field: NerfConfig) -> CompareConfig {
        CompareConfig {
            mixnet_grid: crate::train::sizing::mixnet_grid_for_box(&field.aabb),
            eval_every: (train.steps / 20).max(1),
            background_steps: crate::train::trainer::BACKGROUND_STEP_FACTOR * train.steps,
            train,
            field,
            m: DensityThreshold::DEFAULT,
            m_sweep: Vec::new(),
            prior: Default::default(),
            models: None,
            capture_rays: false,
        }
    }

    /// The trainer settings of a run on `views`: [`Self::train`], with the rays per step taken
    /// from the views' pixels when [`Self::capture_rays`].
    pub fn train_for(&self, views: &[crate::data::View]) -> TrainConfig {
        let mut t = self.train.clone();
        if self.capture_rays {
            t.rays_per_step = t.rays_for_views(views);
        }
        t
    }
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
    /// Rays per training step ([`CompareConfig::train_for`]).
    pub rays_per_step: usize,
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
    /// Training views whose pose was registered against the background.
    pub registered_views: usize,
    /// Training views.
    pub views: usize,
    /// Cells in the change region.
    pub region_cells: usize,
    /// The region's volume (scene units cubed).
    pub region_volume: f64,
    /// Seconds to compute the prior (registration, change maps, the background's depth, the
    /// vote).
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::DepthErrors;
    use crate::render::Intrinsics;

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
