//! What a parsed command line is: the [`Command`] and the arguments of the larger commands.

use crate::render::DepthMethod;
use crate::train::prior::PriorConfig;
use std::path::PathBuf;

/// Scoring crop of `rnerf eval`.
pub use crate::eval::CropRule;

/// What `rnerf render` and `rnerf eval` render, and how: the depth, the depth-only path and its
/// onboard trades, the colour pass's colour tail.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rendering {
    /// Depth method (`--depth`, `--m`, `--m-raw`).
    pub depth: DepthMethod,
    /// Threshold depth alone: no colour pass, β, expected depth or PSNR (`--depth-only`).
    pub depth_only: bool,
    /// The depth-only path's solid fraction, as the onboard renderer's (`--solid-fraction F`,
    /// with `--depth-only`; default 0: every occupied cell).
    pub solid_fraction: f32,
    /// The depth-only path's coarse start, as the onboard renderer's: lattice steps of slack
    /// before the neighbours' depth (`--coarse-start N|off`, with `--depth-only`; default off).
    pub coarse_start: Option<u32>,
    /// The colour pass's colour tail: behind each ray's threshold hit, one sample for up to
    /// `⌊R / T⌋` lattice steps (`--colour-tail R|off`; default
    /// [`crate::render::view::COLOUR_TAIL`], 0 with `--depth expected`; 0: off).
    pub colour_tail: f32,
}

/// A parsed command line.
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    /// `rnerf train`.
    Train(TrainArgs),
    /// `rnerf import colmap`.
    ImportColmap(crate::data::colmap::ImportOptions),
    /// `rnerf render`.
    Render {
        /// Model file (`--model`).
        model: PathBuf,
        /// Dataset folder (`--data`).
        data: PathBuf,
        /// Output folder (`--out`).
        out: PathBuf,
        /// Split (`--split`, default `test`).
        split: String,
        /// What is rendered and how.
        rendering: Rendering,
        /// Worker threads (`--threads`).
        threads: Option<usize>,
    },
    /// `rnerf eval`.
    Eval {
        /// Model file (`--model`).
        model: PathBuf,
        /// Dataset folder (`--data`).
        data: PathBuf,
        /// Split (`--split`, default `test`).
        split: String,
        /// Scoring crop (`--crop`, default the frames' own).
        crop: CropRule,
        /// Score only ground truth nearer than this (`--limit`, metres).
        limit: Option<f32>,
        /// One JSON object on stdout (`--json`).
        json: bool,
        /// What is rendered and how.
        rendering: Rendering,
        /// Worker threads (`--threads`).
        threads: Option<usize>,
    },
    /// `rnerf compare`.
    Compare(CompareArgs),
    /// `rnerf demo`.
    Demo {
        /// Output folder (`--out`, default `rnerf-demo`).
        out: Option<PathBuf>,
        /// Training steps (`--steps`).
        steps: Option<u32>,
        /// Image size in pixels (`--size`, square images).
        size: Option<u32>,
        /// Seed (`--seed`).
        seed: Option<u64>,
        /// Worker threads (`--threads`); all cores when absent.
        threads: Option<usize>,
    },
    /// `rnerf bench`.
    Bench {
        /// One JSON object instead of a table (`--json`).
        json: bool,
        /// Repetitions per figure (`--reps`).
        reps: Option<usize>,
        /// Hash-grid table size (`--log2t`).
        log2t: Option<u32>,
        /// Worker threads (`--threads`).
        threads: Option<usize>,
        /// Trained models whose depth rendering is timed instead of the bench's own (`--model`,
        /// repeatable: one NeRF, one residual model).
        models: Vec<PathBuf>,
        /// Their camera: the first test view of this dataset (`--data`, needed with `--model`).
        data: Option<PathBuf>,
        /// Time to quality: the background's dataset (`--background-data`, with `--scene`).
        background_data: Option<PathBuf>,
        /// Time to quality: the scene's dataset (`--scene`, with `--background-data`).
        scene: Option<PathBuf>,
    },
    /// `rnerf help`, `-h`, `--help` or no arguments.
    Help,
}

/// Arguments of `rnerf train`.
#[derive(Clone, Debug, PartialEq)]
pub struct TrainArgs {
    /// Dataset folder (`--data`).
    pub data: PathBuf,
    /// Model file to write (`--out`).
    pub out: PathBuf,
    /// Split to train on (`--split`, default `train`).
    pub split: String,
    /// Steps (`--steps`).
    pub steps: Option<u32>,
    /// Rays per step (`--rays`).
    pub rays: Option<usize>,
    /// log2 of the hash-table size (`--log2t`).
    pub log2t: Option<u32>,
    /// Seed (`--seed`).
    pub seed: Option<u64>,
    /// Worker threads (`--threads`).
    pub threads: Option<usize>,
    /// Metrics log (`--csv`).
    pub csv: Option<PathBuf>,
    /// Frozen background model: train a residual model (`--background`).
    pub background: Option<PathBuf>,
    /// How background and residual mix (`--mix`, `--density-mix`); default Mixnet, raw.
    pub mix: Option<crate::field::mix::MixKind>,
    /// The Mixnet's encoding (`--mixnet-encoding`); default its own grid.
    pub mixnet: Option<crate::field::mixnet::MixnetEncoding>,
    /// Weight of the distortion loss (`--distortion`, 0 turns it off).
    pub distortion: Option<f32>,
    /// Base learning rate (`--lr`).
    pub lr: Option<f32>,
    /// Near-camera gradient scaling distance (`--near-grad`, 0 turns it off); `None`: the
    /// default, half the training cameras' distance to what they look at.
    pub near_grad: Option<f32>,
    /// `Some(false)`: train over the fixed background colour even for images without
    /// alpha (`--fixed-background`).
    pub random_bg: Option<bool>,
    /// Steps between checkpoints (`--checkpoint-every`); none when absent (an interrupted run
    /// still writes one).
    pub checkpoint_every: Option<u32>,
    /// Wall seconds from the command's start after which the run stops after its current step
    /// and writes the model of the steps so far (`--budget`); none when absent.
    pub budget: Option<f64>,
    /// A checkpoint to continue from with its own settings (`--resume`).
    pub resume: Option<PathBuf>,
    /// Train on this many evenly spaced views of the split (`--scene-views`); all when absent.
    pub scene_views: Option<usize>,
    /// The background hints a residual model uses (`--prior`; default all).
    pub prior: Option<crate::train::prior::Prior>,
    /// The background's dataset, whose images at the scene's poses give the change maps
    /// (`--background-data`; without it the background model is rendered at those poses).
    pub background_data: Option<PathBuf>,
    /// The background prior's settings (`--beta`, `--region-floor`, `--focus-share`,
    /// `--region-vote`, `--exposure-correction`, `--pose-registration`).
    pub prior_settings: PriorArgs,
    /// Lattice steps per training sample outside a residual model's change region
    /// (`--frozen-stride N`).
    pub frozen_stride: Option<u32>,
    /// The transmittance below which a training ray past a residual model's change region
    /// stops (`--frozen-tail T`).
    pub frozen_tail: Option<f32>,
    /// Past a residual model's change region, the transmittance below which a training ray's
    /// frozen samples go on N lattice steps each (`--frozen-coarse T,N`; `off`: (0, 1)).
    pub frozen_coarse: Option<(f32, u32)>,
    /// A residual model's training rays stop where they leave the change region, the light
    /// behind read off the background image (`--photo-tail on|off`); `None`: the default.
    pub photo_tail: Option<bool>,
    /// Times each pooled training ray of a residual model is drawn (`--ray-pool N`; 0 or 1:
    /// every ray fresh).
    pub ray_pool: Option<u32>,
    /// The identity prior's weight when a gain per training image is learned with the field
    /// (`--image-gains on`); `None`: off, the default.
    pub image_gains: Option<f32>,
    /// The share of each step's rays drawn by the training error (`--error-map S`); `None`:
    /// off, the default.
    pub error_map: Option<f32>,
    /// Rays through a random point of their pixel (`--pixel-jitter on|off`); `None`: the default.
    pub pixel_jitter: Option<bool>,
    /// Rays per training pixel, scored by their mean (`--pixel-rays K`); `None`: the default.
    pub pixel_rays: Option<u32>,
    /// Registration passes of a NeRF trained with `--pose-registration on`
    /// (`--registration-passes N`; default 1).
    pub registration_passes: Option<u32>,
}

/// Arguments of `rnerf compare`.
#[derive(Clone, Debug, PartialEq)]
pub struct CompareArgs {
    /// Background dataset folder (`--background`).
    pub background: PathBuf,
    /// A trained background model to use instead of training one (`--background-model`).
    pub background_model: Option<PathBuf>,
    /// Scene dataset folders (`--scene`, repeatable).
    pub scenes: Vec<PathBuf>,
    /// Output folder (`--out`), created if missing.
    pub out: PathBuf,
    /// Methods (`--methods`, default [`crate::compare::Method::defaults`]: dex, finetune,
    /// residual-paper, residual).
    pub methods: Vec<crate::compare::Method>,
    /// Train every method on this many evenly spaced scene views (`--scene-views`); the
    /// background keeps all of its own.
    pub scene_views: Option<usize>,
    /// Steps per method (`--steps`).
    pub steps: Option<u32>,
    /// Rays per step (`--rays`).
    pub rays: Option<usize>,
    /// log2 of the hash-table size (`--log2t`).
    pub log2t: Option<u32>,
    /// Seed (`--seed`).
    pub seed: Option<u64>,
    /// Steps between points of the speed curves (`--eval-every`).
    pub eval_every: Option<u32>,
    /// Steps of the background's training when no `--background-model` is given
    /// (`--background-steps`, default 3 × the steps).
    pub background_steps: Option<u32>,
    /// Threshold of threshold depth (`--m`, `--m-raw`).
    pub m: crate::render::DensityThreshold,
    /// Further σ thresholds the final models are scored at (`--m-sweep`).
    pub m_sweep: Vec<crate::render::DensityThreshold>,
    /// Worker threads (`--threads`).
    pub threads: Option<usize>,
    /// The background prior's settings (`--beta`, `--region-floor`, `--focus-share`,
    /// `--region-vote`, `--exposure-correction`, `--pose-registration`).
    pub prior_settings: PriorArgs,
    /// Lattice steps per training sample outside a residual model's change region
    /// (`--frozen-stride N`).
    pub frozen_stride: Option<u32>,
    /// The transmittance below which a training ray past a residual model's change region
    /// stops (`--frozen-tail T`).
    pub frozen_tail: Option<f32>,
    /// Past a residual model's change region, the transmittance below which a training ray's
    /// frozen samples go on N lattice steps each (`--frozen-coarse T,N`; `off`: (0, 1)).
    pub frozen_coarse: Option<(f32, u32)>,
    /// A residual model's training rays stop where they leave the change region, the light
    /// behind read off the background image (`--photo-tail on|off`); `None`: the default.
    pub photo_tail: Option<bool>,
    /// Times each pooled training ray of a residual model is drawn (`--ray-pool N`; 0 or 1:
    /// every ray fresh).
    pub ray_pool: Option<u32>,
    /// The identity prior's weight when a gain per training image is learned with the field
    /// (`--image-gains on`); `None`: off, the default.
    pub image_gains: Option<f32>,
    /// Every method's rays through a random point of their pixel (`--pixel-jitter on|off`);
    /// `None`: the default.
    pub pixel_jitter: Option<bool>,
    /// Every method's rays per training pixel (`--pixel-rays K`); `None`: the default.
    pub pixel_rays: Option<u32>,
    /// Every training's near-camera gradient scaling distance (`--near-grad D`, 0 turns it
    /// off); `None`: the default (half the cameras' distance to what they look at).
    pub near_grad: Option<f32>,
}

/// The background prior's settings `rnerf train` and `rnerf compare` share; each `None` keeps
/// [`PriorConfig`]'s default.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PriorArgs {
    /// Weights of the β penalty on unchanged rays and of the β entropy (`--beta U,E`).
    pub beta: Option<(f32, f32)>,
    /// Pixels around the changed ones the β penalty spares (`--beta-margin N`).
    pub beta_margin: Option<u32>,
    /// Closing radius of the changed pixels the β penalty spares, their holes filled
    /// (`--beta-fill R`).
    pub beta_fill: Option<u32>,
    /// The residual's density floor in the change region (`--region-floor S|off`).
    pub region_floor: Option<Option<f32>>,
    /// Share of each step's rays drawn from changed pixels (`--focus-share F`).
    pub focus_share: Option<f32>,
    /// The region's vote: share of the seeing views that must see a change, share of all
    /// views that must see the cell (`--region-vote V,S`).
    pub region_vote: Option<(f32, f32)>,
    /// Cells the voted change region grows by (`--region-dilate N`).
    pub region_dilate: Option<u32>,
    /// The region voted on a grid this many times finer than the occupancy grid
    /// (`--region-subdivide K`).
    pub region_subdivide: Option<u32>,
    /// Colour difference above which a scene pixel changed, and against the rendered background
    /// (`--change-tolerance T[,R]`).
    pub change_tolerance: Option<(f32, Option<f32>)>,
    /// Whether the scene images are corrected to the background's exposure and white balance
    /// (`--exposure-correction on|off`; default on).
    pub exposure_correction: Option<bool>,
    /// Whether the scene images' poses are registered against the background
    /// (`--pose-registration on|off`; default on).
    pub pose_registration: Option<bool>,
}

impl PriorArgs {
    /// [`PriorConfig::default`] with the given settings applied.
    pub fn config(&self) -> PriorConfig {
        let mut p = PriorConfig::default();
        p.exposure = self.exposure_correction.unwrap_or(p.exposure);
        p.register = self.pose_registration.unwrap_or(p.register);
        if let Some((vote, seen)) = self.region_vote {
            (p.vote, p.min_seen) = (vote, seen);
        }
        if let Some(share) = self.focus_share {
            p.change_share = share;
        }
        if let Some((unchanged, entropy)) = self.beta {
            (p.beta.unchanged, p.beta.entropy) = (unchanged, entropy);
        }
        p.beta_dilate_px = self.beta_margin.unwrap_or(p.beta_dilate_px);
        p.beta_close_px = self.beta_fill.unwrap_or(p.beta_close_px);
        p.region_dilate = self.region_dilate.unwrap_or(p.region_dilate);
        p.region_subdivide = self.region_subdivide.unwrap_or(p.region_subdivide);
        if let Some((t, r)) = self.change_tolerance {
            p.tolerance = t;
            p.rendered_tolerance = r.unwrap_or(p.rendered_tolerance);
        }
        if let Some(floor) = self.region_floor {
            p.lift = floor.map(|floor| crate::train::lift::LiftConfig { floor, ..Default::default() });
        }
        p
    }
}
