//! The NeRF trainer: each step draws random rays from all training views, marches them
//! through the occupancy grid, runs the field, composites (Eq. 2), takes the MSE (Eq. 4),
//! back-propagates through compositing, activations, field and grid, and steps Adam. Every
//! [`TrainConfig::occupancy_interval`] steps the occupancy grid is refreshed through the
//! field's density-only path.
//!
//! The step is fused: the rays are cut into [`SLOTS`] fixed groups; a thread takes a group
//! (its worker is `super::step::Worker`) and walks it in chunks of whole rays (at least [`CHUNK_SAMPLES`] marched samples), each
//! chunk marched, run through the densities, cut at each ray's opaque point, run through the
//! colours, composited, and back-propagated to its feature gradients before the next chunk
//! starts — so a sample's activations never leave L1/L2 ([`crate::field::model`]). The grids'
//! gradients are scattered once per step from the gathered feature gradients.
//!
//! A run is a [`Trainer`] stepped by its caller, who decides between steps what to log,
//! evaluate or checkpoint; [`train_model`] is the plain loop. A step whose loss or gradients are
//! not finite is skipped (nothing changes); too many in a row, or too many steps in which no
//! ray reaches an occupied cell, end the run with a [`TrainError`].
//!
//! Determinism: ray sampling draws from `Rng::stream(seed, step)`; a slot's rays, its chunks
//! and the order it accumulates in depend only on the data; slots reduce in slot order —
//! same seed, same bits on any thread count. All that carries over between steps is the
//! [`TrainState`] (parameters, occupancy grid, Adam moments, step, and the images' learned
//! gains when [`TrainConfig::image_gains`] is on, whose gradients the slots also reduce in slot
//! order), so a run resumed from a saved state continues bit-exactly.

use super::pool::{PoolInputs, RayPool};
pub use super::step::{scale_near_gradients, CHUNK_SAMPLES, RAY_SEGMENT};
use super::step::{slot_rays, StepInputs, StepRays, Worker};
use crate::data::View;
use crate::field::model::Model;
use crate::field::residual::{ResidualConfig, ResidualField, ResidualModel};
pub use crate::field::Nerf;
use crate::field::{NerfConfig, NerfField};
use crate::geometry::camera;
use crate::render::{image_ray, pixel_ray, Aabb, OccupancyConfig, OccupancyGrid};
use crate::rng::Rng;
use crate::simd::Isa;
use crate::slots::SLOTS;
use crate::train::beta::BetaRegulariser;
use crate::train::error_map::{self, ErrorSampler, TileLayout};
use crate::train::gains::ImageGains;
pub use crate::train::gains::GAIN_PRIOR;
use crate::train::pixel_filter;
use crate::train::{Adam, AdamConfig, LrSchedule};
use rayon::prelude::*;
use std::time::Instant;

/// Trainer settings.
#[derive(Clone, Debug)]
pub struct TrainConfig {
    /// Optimiser steps. Defaults to [`TRAIN_STEPS`].
    pub steps: u32,
    /// Rays per step. Defaults to [`TRAIN_RAYS`]; the command line takes
    /// [`Self::rays_for_views`] of the training set unless `--rays` says otherwise.
    pub rays_per_step: usize,
    /// Learning rate against step. Defaults to 1e-2, decaying ×0.33 from 60% of the steps every 15%.
    pub schedule: LrSchedule,
    /// Steps between occupancy-grid updates. Defaults to 16.
    pub occupancy_interval: u32,
    /// Occupancy grid and marching. Defaults to [`OccupancyConfig::default`].
    pub occupancy: OccupancyConfig,
    /// Colour behind the scene where rays leave the box (C's background term). Defaults to white
    /// (what a dataset's images with alpha are composited over when loaded).
    pub background: [f32; 3],
    /// Draw each training ray's background colour uniformly at random instead (targets
    /// unchanged): transmittance left at the end of a ray then costs loss, so the field must
    /// make every surface opaque. Right for images without alpha (every pixel shows a surface);
    /// `rnerf train` turns it off for images with alpha. Defaults to true.
    pub random_background: bool,
    /// Seed of initialisation and sampling. Defaults to 0.
    pub seed: u64,
    /// Weight λ of the distortion loss (per ray, scene units; [`crate::render::distortion`]).
    /// Defaults to [`DISTORTION`].
    pub distortion: f32,
    /// Where each sample's gradients are scaled down by `(t / d)²` (Philip & Deschaintre 2023,
    /// "Floaters No More"): density right in front of a training camera, which only that camera
    /// sees, learns slower than the scene. Defaults to [`NEAR_GRADIENT`] (off).
    pub near_gradient: NearGradient,
    /// Pixels to draw a share of each step's rays from (a residual model's changed pixels,
    /// [`crate::train::prior`]). Defaults to none: every ray uniform over all pixels.
    pub focus: Option<Focus>,
    /// The β regularisers of a residual model (the unchanged-ray penalty needs [`Self::focus`]:
    /// a pixel outside its list is unchanged). Defaults to off.
    pub beta: BetaRegulariser,
    /// Lattice steps one training sample stands for where the field is known to be the frozen
    /// background: outside the cells the occupancy grid pins (a residual model's change
    /// region; [`OccupancyGrid::march_segment`]). 1: every step. Models without pinned cells
    /// sample every step whatever this says. Defaults to [`FROZEN_STRIDE`].
    pub frozen_stride: u32,
    /// The frozen tail `τ`: with a model frozen outside a region (a residual model's change
    /// region, [`crate::field::model::FrozenOutside`]), a training ray stops at its first sample
    /// beyond the region's bounding box whose transmittance is below `τ`, and that sample's
    /// colour stands for the light the frozen field would still add behind it (instead of
    /// marching on to `T < 1e-4`). 0: off, every ray marched to its opaque point. Rendering and
    /// evaluation always march to the opaque point. Defaults to [`FROZEN_TAIL`].
    pub frozen_tail: f32,
    /// The frozen tail's coarse part: past the same start (the region's bounding box), once a
    /// training ray's transmittance has fallen below this, the rest of the ray (up to the
    /// frozen tail's stop) is marched [`Self::frozen_coarse_stride`] lattice steps a sample:
    /// behind the region the field is the frozen background, and what those samples give the
    /// step is the light they add behind the region, of which less than this is left. 0: off.
    /// Needs the frozen tail on. Rendering and evaluation always march every step. Defaults to
    /// [`FROZEN_COARSE`].
    pub frozen_coarse: f32,
    /// Lattice steps one sample of the frozen tail's coarse part stands for (1: off). Defaults
    /// to [`FROZEN_COARSE_STRIDE`].
    pub frozen_coarse_stride: u32,
    /// `Some(λ)`: learn a gain per training image and colour channel with the field, with an
    /// identity prior of weight λ ([`crate::train::gains`]; [`GAIN_PRIOR`] is the usual λ), for
    /// captures whose exposure or white balance moves from shot to shot. `None`: every image
    /// is taken as it is. Defaults to `None`.
    pub image_gains: Option<f32>,
    /// `Some(share)`: draw that share of each step's rays by the training error
    /// ([`crate::train::error_map`]: per tile of [`crate::train::error_map::TILE`]² pixels, a
    /// running estimate of the squared error; a tile drawn in proportion to it), after the focus
    /// share and before the uniform rest. `None`: no error map. Defaults to `None`.
    pub error_map: Option<f32>,
    /// Shoot each training ray through a point drawn uniformly over its pixel's square instead
    /// of the pixel's centre: a pixel's colour is the light over its whole area (a camera's
    /// sensor, a renderer's pixel filter), so at a silhouette it blends the object and what is
    /// behind it. On the dev scenes it does not change the depth (docs/DECISIONS.md, "Most of
    /// it is a one-pixel ring around the glass"). Defaults to [`PIXEL_JITTER`].
    pub pixel_jitter: bool,
    /// Rays per training pixel. 1: one ray (through the centre, or jittered with
    /// [`Self::pixel_jitter`]). `K > 1`: the pixel's colour is scored against the mean of `K`
    /// rays through points drawn from the pixel filter ([`crate::train::pixel_filter`], stratified),
    /// so a silhouette's blended pixel is explained by the edge crossing its footprint instead of
    /// by faint density on its centre ray. The step's [`Self::rays_per_step`] rays then cover
    /// `rays_per_step / K` pixels (it must be a multiple of `K`). Needs every ray fresh (no ray
    /// pool). Defaults to [`PIXEL_RAYS`].
    pub pixel_rays: u32,
    /// Times each training ray is drawn, on average, when the model is a frozen field outside
    /// a region whose occupancy grid is frozen there (the default residual method): a ray's
    /// samples outside the region are evaluated once and its rays are drawn from a pool
    /// (`train::pool`); 0 or 1 draws every ray fresh. Needs no distortion loss, one ray per pixel
    /// and no error map (otherwise every ray is fresh). Defaults
    /// to [`RAY_POOL`].
    pub ray_pool: u32,
    /// The photo tail: with a model frozen outside a region and [`Self::behind`], a training
    /// ray stops where it leaves the region's bounding box, and the light behind that point is
    /// read off the background image of its pixel: `(C_photo − C_bg)/T_bg`, where `C_bg` and
    /// `T_bg` are the frozen background's own colour and transmittance composited over the
    /// ray's samples so far (so a ray the residual leaves as the background predicts the
    /// background image exactly). Defaults to [`PHOTO_TAIL`].
    pub photo_tail: bool,
    /// Each training view's background colours at its pose (the background image, or the
    /// background rendered there; [`crate::train::prior::ScenePrior::behind`]), for the photo
    /// tail. `None`: no photo tail.
    pub behind: Option<std::sync::Arc<crate::train::prior::BackgroundColours>>,
}

/// Default of [`TrainConfig::photo_tail`].
pub const PHOTO_TAIL: bool = true;

/// A share of each step's rays drawn uniformly from a fixed list of pixels.
#[derive(Clone, Debug)]
pub struct Focus {
    /// Share of the rays (the first `round(share · rays)` of each step), in [0, 1].
    pub share: f32,
    /// `(view, pixel)` pairs (pixel = `y · width + x`).
    pub pixels: std::sync::Arc<Vec<(u32, u32)>>,
    /// `(view, pixel)` pairs the other rays are drawn from (a residual model's pixels whose ray
    /// crosses its change region: the only rays with a gradient); `None` or empty: all pixels
    /// of all views.
    pub reach: Option<std::sync::Arc<Vec<(u32, u32)>>>,
    /// `(view, pixel)` pairs the β penalty on unchanged rays spares; `None`: [`Self::pixels`].
    pub spared: Option<std::sync::Arc<Vec<(u32, u32)>>>,
}

/// The distance `d` within which [`TrainConfig::near_gradient`] scales each sample's gradients
/// by `min(1, (t / d)²)`, `t` its distance from the camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum NearGradient {
    /// No scaling.
    Off,
    /// `d` in scene units.
    Distance(f32),
    /// `d` this share of the training cameras' median distance to the point they look at
    /// ([`crate::geometry::camera::capture_focus`]; the scene box's centre where the cameras'
    /// axes do not meet near one point), so it follows the capture's scale.
    OfCapture(f32),
}

impl NearGradient {
    /// The setting of `--near-grad D` (0: off) when given, else `default`.
    pub fn from_flag(flag: Option<f32>, default: NearGradient) -> NearGradient {
        match flag {
            None => default,
            Some(0.0) => NearGradient::Off,
            Some(d) => NearGradient::Distance(d),
        }
    }

    /// `d` for the training set `views` in the box `aabb` (0: off).
    pub fn distance(&self, views: &[View], aabb: &Aabb) -> f32 {
        match *self {
            NearGradient::Off => 0.0,
            NearGradient::Distance(d) => d,
            NearGradient::OfCapture(share) => {
                let poses: Vec<_> = views.iter().map(|v| v.pose).collect();
                let focus = camera::capture_focus(&poses).unwrap_or((aabb.min + aabb.max) * 0.5);
                share * camera::median_distance(&poses, focus)
            }
        }
    }
}

/// Default of [`TrainConfig::near_gradient`]: off. Within half the cameras' distance to what
/// they look at (`OfCapture(0.5)`) it cleaned the dev box's backgrounds a little but left more
/// floaters in front of the cameras in a box 1.5 times wider, at every seed measured
/// (docs/DECISIONS.md, "The near-camera gradient scaling").
pub const NEAR_GRADIENT: NearGradient = NearGradient::Off;

/// Default weight of the distortion loss: off — on the dev background it did not improve depth
/// at the weights tried (docs/DECISIONS.md, "The engine").
pub const DISTORTION: f32 = 0.0;

/// Default of [`TrainConfig::frozen_stride`] (chosen by measured depth and time;
/// docs/DECISIONS.md, "Where a residual step's time goes").
pub const FROZEN_STRIDE: u32 = 1;

/// Default of [`TrainConfig::frozen_tail`] (chosen by measured depth and time;
/// docs/DECISIONS.md, "The frozen tail").
pub const FROZEN_TAIL: f32 = 0.05;

/// Default of [`TrainConfig::frozen_coarse`]: off. At 0.5 with a stride of 4 the dev scenes'
/// scene phase trains 9–20% faster and the glass's object MAE gains, but the near crop loses
/// 1–5% on every scene and seed (docs/DECISIONS.md, "The frozen tail"): the switch is a robot's
/// trade of depth for time, not a default.
pub const FROZEN_COARSE: f32 = 0.0;
/// Default of [`TrainConfig::frozen_coarse_stride`]: the stride `--frozen-coarse` was measured at.
pub const FROZEN_COARSE_STRIDE: u32 = 4;

/// Default of [`TrainConfig::pixel_jitter`]: off, measured on the dev scenes (docs/DECISIONS.md,
/// "Most of it is a one-pixel ring around the glass").
pub const PIXEL_JITTER: bool = false;

/// Default of [`TrainConfig::pixel_rays`].
pub const PIXEL_RAYS: u32 = 1;

/// The largest [`TrainConfig::pixel_rays`] the command line and checkpoints accept.
pub const MAX_PIXEL_RAYS: u32 = 64;

/// Default of [`TrainConfig::ray_pool`]: every ray fresh. Reusing rays costs more depth than
/// drawing fewer fresh ones (`--rays 512`) at the same time (docs/DECISIONS.md, "The ray pool").
pub const RAY_POOL: u32 = 0;

/// The largest [`TrainConfig::ray_pool`] the command line and checkpoints accept.
pub const MAX_RAY_POOL: u32 = 1024;

/// Default training steps: with [`TRAIN_RAYS`], about 2–3 minutes for 100 views of 200×200 on
/// a 2-core machine (BENCHMARKS.md; docs/DECISIONS.md, "The engine").
pub const TRAIN_STEPS: u32 = 1000;

/// A background's training steps against a scene's: the empty workspace is trained once,
/// offline, before any scene phase, and the residual inherits its depth wherever nothing
/// changed. At three times a scene's steps ([`BACKGROUND_STEPS`] at the defaults) the dev
/// background's test PSNR rises from 31.7 to 33.9 dB and the default Residual-NeRF's near-crop
/// RMSE falls by 8% over three seeds (docs/DECISIONS.md, "The background trains for three times
/// a scene's steps"). `rnerf compare` and `rnerf demo` train their backgrounds so.
pub const BACKGROUND_STEP_FACTOR: u32 = 3;

/// The background's training steps at the defaults (`rnerf train --data BG_DIR --steps 3000`;
/// [`TrainConfig::with_steps`] for the library): [`BACKGROUND_STEP_FACTOR`] × [`TRAIN_STEPS`].
pub const BACKGROUND_STEPS: u32 = BACKGROUND_STEP_FACTOR * TRAIN_STEPS;

/// Default rays per step (fixed per-step costs — Adam over the 16 M grid parameters — are
/// small beside 1024 rays, and more, smaller steps learn faster per second than 4096-ray ones
/// here; measured in docs/DECISIONS.md). A small capture takes fewer: [`rays_for_capture`].
pub const TRAIN_RAYS: usize = 1024;

/// Training pixels from which a step draws all of [`TRAIN_RAYS`] (50 views of 200×200):
/// [`rays_for_capture`].
pub const CAPTURE_FULL_PIXELS: u64 = 2_000_000;

/// The rays per step the command line trains with when `--rays` is not given, from the
/// training set's pixel count: [`TRAIN_RAYS`] from [`CAPTURE_FULL_PIXELS`] up, in proportion
/// below it down to half of [`TRAIN_RAYS`] (reached at half as many pixels), rounded down to
/// a multiple of 64 and of `pixel_rays` ([`TrainConfig::pixel_rays`]). A capture with fewer
/// pixels has fewer distinct rays to learn from: at 25 views of 200×200 half the rays a step
/// give the same depth in about half the time, at 50 and 100 views they lose the faint glass
/// (docs/DECISIONS.md, "Rays per step from the capture's size").
pub fn rays_for_capture(pixels: u64, pixel_rays: u32) -> usize {
    let full = TRAIN_RAYS as u64;
    let rays = (full * pixels / CAPTURE_FULL_PIXELS).clamp(full / 2, full) as usize;
    let k = pixel_rays.max(1) as usize;
    let rays = rays - rays % 64;
    rays - rays % k
}

/// The default learning-rate schedule of a `steps`-step run from `base`: step decay ×0.33 from
/// 60% of the steps, every 15% of them ([`TrainConfig::with_steps`], [`TrainConfig::rescheduled`]).
fn schedule_for(steps: u32, base: f32) -> LrSchedule {
    LrSchedule {
        base,
        warmup_steps: 0,
        decay_start: steps * 3 / 5,
        decay_interval: (steps * 3 / 20).max(1),
        decay_factor: 0.33,
    }
}

impl TrainConfig {
    /// [`rays_for_capture`] of the training set `views` (their width × height summed) at this
    /// config's [`Self::pixel_rays`]: what the command line sets [`Self::rays_per_step`] to
    /// without `--rays`.
    pub fn rays_for_views(&self, views: &[View]) -> usize {
        let pixels = views.iter().map(|v| v.intrinsics.width as u64 * v.intrinsics.height as u64).sum();
        rays_for_capture(pixels, self.pixel_rays)
    }

    /// Rays per training pixel ([`Self::pixel_rays`], at least 1): the step's rays come in
    /// groups of this many per pixel, and slots and chunks take whole groups.
    pub fn rays_per_pixel(&self) -> usize {
        self.pixel_rays.max(1) as usize
    }

    /// This config for `steps` steps: the learning-rate schedule rescaled as
    /// [`Self::with_steps`] scales it (its base rate kept), everything else as it is.
    pub fn rescheduled(&self, steps: u32) -> TrainConfig {
        TrainConfig { steps, schedule: schedule_for(steps, self.schedule.base), ..self.clone() }
    }

    /// The defaults (what `rnerf train` does for images without alpha) for `steps` steps: the
    /// learning-rate schedule scales with it.
    pub fn with_steps(steps: u32) -> TrainConfig {
        TrainConfig {
            steps,
            rays_per_step: TRAIN_RAYS,
            schedule: schedule_for(steps, 1e-2),
            occupancy_interval: 16,
            occupancy: OccupancyConfig::default(),
            background: [1.0; 3],
            random_background: true,
            seed: 0,
            distortion: DISTORTION,
            near_gradient: NEAR_GRADIENT,
            focus: None,
            beta: BetaRegulariser::default(),
            frozen_stride: FROZEN_STRIDE,
            frozen_tail: FROZEN_TAIL,
            frozen_coarse: FROZEN_COARSE,
            frozen_coarse_stride: FROZEN_COARSE_STRIDE,
            image_gains: None,
            error_map: None,
            pixel_jitter: PIXEL_JITTER,
            pixel_rays: PIXEL_RAYS,
            ray_pool: RAY_POOL,
            photo_tail: PHOTO_TAIL,
            behind: None,
        }
    }
}

impl Default for TrainConfig {
    /// What `rnerf train` does: [`TRAIN_STEPS`] steps of [`TRAIN_RAYS`] rays, Adam at 1e-2 with
    /// step decay from 60% of the steps, occupancy every 16 steps (all cells for the first 256),
    /// random background colours (the CLI turns them off for images with alpha).
    fn default() -> Self {
        TrainConfig::with_steps(TRAIN_STEPS)
    }
}

/// Progress of one logged step.
#[derive(Clone, Copy, Debug)]
pub struct StepStats {
    /// Step index (0-based).
    pub step: u32,
    /// MSE over the step's rays.
    pub loss: f32,
    /// Mean samples per ray that reached the field's full forward and backward.
    pub samples_per_ray: f32,
    /// Mean samples per ray whose density was evaluated: those the occupancy grid let through,
    /// up to the end of the segment ([`RAY_SEGMENT`]) in which the ray stopped.
    pub marched_per_ray: f32,
    /// Seconds of training so far (time spent in the observer excluded).
    pub seconds: f64,
    /// Fraction of occupied cells.
    pub occupancy: f64,
    /// Steps skipped so far for a non-finite loss or gradient.
    pub skipped: u32,
}

/// Trains a NeRF of `field_config` on `views`; `log` receives stats every `log_every` steps
/// (0: never).
pub fn train_nerf(
    isa: Isa,
    views: &[View],
    field_config: NerfConfig,
    cfg: &TrainConfig,
    log_every: u32,
    log: impl FnMut(StepStats),
) -> Result<Nerf, TrainError> {
    let aabb = field_config.aabb;
    let field = NerfField::new(field_config);
    let mut log = log;
    let (params, occupancy) = train_model(isa, &field, aabb, views, cfg, log_every, |s, _, _| log(s))?;
    Ok(Nerf { field, params, occupancy })
}

/// Trains a residual model (residual NeRF + Mixnet over the frozen `background`) on the scene
/// `views`; the occupancy grid covers the mixed field.
pub fn train_residual(
    isa: Isa,
    background: Nerf,
    views: &[View],
    config: ResidualConfig,
    cfg: &TrainConfig,
    log_every: u32,
    log: impl FnMut(StepStats),
) -> Result<ResidualModel, TrainError> {
    let aabb = config.residual.aabb;
    let field = ResidualField::new(background, config);
    let mut log = log;
    let (params, occupancy) = train_model(isa, &field, aabb, views, cfg, log_every, |s, _, _| log(s))?;
    Ok(ResidualModel { field, params, occupancy })
}

/// Points per cell edge of the lattice that settles a residual model's change-region cell
/// values after its last step ([`OccupancyGrid::settle_pinned`]; docs/DECISIONS.md, "The
/// onboard renderer's solid fraction").
pub const SETTLE_LATTICE: u32 = 4;

/// Consecutive skipped (non-finite) steps after which training gives up
/// ([`TrainError::NonFinite`]); the parameters are then those of the last good step.
pub const MAX_BAD_STEPS_IN_A_ROW: u32 = 16;

/// Consecutive steps in which no ray reached an occupied cell after which training gives up
/// ([`TrainError::NoLiveSamples`]): more than one occupancy refresh, so a grid that empties
/// for a moment can recover.
pub const MAX_EMPTY_STEPS_IN_A_ROW: u32 = 64;

/// Why training stopped before its last step. The trainer's state stays that of the last good
/// step (skipped steps change nothing), so a caller can still save it.
#[derive(Clone, Debug, PartialEq)]
pub enum TrainError {
    /// [`MAX_BAD_STEPS_IN_A_ROW`] steps in a row had a non-finite loss or gradient.
    NonFinite {
        /// The last step tried (0-based).
        step: u32,
        /// Steps skipped in the whole run.
        skipped: u32,
    },
    /// [`MAX_EMPTY_STEPS_IN_A_ROW`] steps in a row marched no sample: the rays miss the
    /// occupied part of the scene box.
    NoLiveSamples {
        /// The last step tried (0-based).
        step: u32,
        /// The scene box.
        aabb: Aabb,
        /// Fraction of occupied cells.
        occupancy: f64,
    },
}

impl std::fmt::Display for TrainError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            TrainError::NonFinite { step, skipped } => write!(
                f,
                "training diverged: {MAX_BAD_STEPS_IN_A_ROW} steps in a row up to step {} had a non-finite loss or \
                 gradient ({skipped} skipped in all); the parameters are those of the last good step \
                 (try a lower --lr, or check the images for NaN values)",
                step + 1
            ),
            TrainError::NoLiveSamples { step, aabb, occupancy } => write!(
                f,
                "no live samples: for {MAX_EMPTY_STEPS_IN_A_ROW} steps up to step {} no training ray crossed an \
                 occupied cell ({:.1}% of the grid occupied) — check that the scene box {:?}..{:?} ('aabb') \
                 holds what the cameras look at",
                step + 1,
                occupancy * 100.0,
                aabb.min.to_array(),
                aabb.max.to_array()
            ),
        }
    }
}

impl std::error::Error for TrainError {}

/// Everything a training run carries from one step to the next: with the same views and
/// [`TrainConfig`], a run continued from a saved state produces the same bits as one never
/// stopped (sampling draws from per-step streams, never from state).
#[derive(Clone)]
pub struct TrainState<P> {
    /// Steps completed (the next step's index).
    pub step: u32,
    /// The trained parameters.
    pub params: P,
    /// The occupancy grid.
    pub occupancy: OccupancyGrid,
    /// One optimiser per parameter group, in [`Model::groups`] order.
    pub adams: Vec<Adam>,
    /// Steps skipped for non-finite values so far.
    pub skipped: u32,
    /// Seconds spent training so far (informational; not part of the bits).
    pub seconds: f64,
    /// The training images' learned gains, when [`TrainConfig::image_gains`] is on.
    pub gains: Option<ImageGains>,
    /// The error map's tile values ([`crate::train::error_map`]), when
    /// [`TrainConfig::error_map`] is on.
    pub error_map: Option<Vec<f32>>,
}

/// A training run, one [`Trainer::step`] at a time: the caller decides between steps whether
/// to log, evaluate, checkpoint ([`Trainer::state`]) or stop.
pub struct Trainer<'a, M: Model> {
    isa: Isa,
    model: &'a M,
    views: &'a [View],
    cfg: &'a TrainConfig,
    state: TrainState<M::Params>,
    grads: M::Grads,
    rays: StepRays,
    workers: Vec<Worker<M::Chunk>>,
    slots: Vec<M::Slot>,
    ctx: M::Context,
    /// Per view, a bitset of the pixels the β penalty spares ([`Focus::spared`], else the focus
    /// pixels), when there is a focus.
    changed: Vec<Vec<u64>>,
    /// The error map's tiles and its sampler (used when [`TrainConfig::error_map`] is on).
    error_draws: (TileLayout, ErrorSampler),
    /// The ray pool, once a step draws from it ([`TrainConfig::ray_pool`]).
    pool: Option<RayPool>,
    bad_in_a_row: u32,
    empty_in_a_row: u32,
    /// [`TrainConfig::near_gradient`]'s distance for these views (0: off).
    near_distance: f32,
}

impl<'a, M: Model> Trainer<'a, M> {
    /// A fresh run: parameters initialised from `cfg.seed`, every occupancy cell occupied.
    pub fn new(isa: Isa, model: &'a M, aabb: Aabb, views: &'a [View], cfg: &'a TrainConfig) -> Self {
        assert!(!views.is_empty(), "train: no training views");
        let mut rng = Rng::new(cfg.seed);
        let params = model.init_params(&mut rng);
        let occupancy = OccupancyGrid::new(aabb, cfg.occupancy.clone());
        Self::starting_at(isa, model, views, cfg, params, occupancy)
    }

    /// A fresh run (step 0, fresh optimisers) from given parameters and occupancy grid: a
    /// residual model started at its background, or a background NeRF fine-tuned on a scene.
    pub fn starting_at(
        isa: Isa,
        model: &'a M,
        views: &'a [View],
        cfg: &'a TrainConfig,
        mut params: M::Params,
        occupancy: OccupancyGrid,
    ) -> Self {
        assert!(!views.is_empty(), "train: no training views");
        assert!(
            cfg.pixel_rays >= 1 && cfg.rays_per_step.is_multiple_of(cfg.pixel_rays as usize),
            "train: {} rays per step are not whole pixels of {} rays",
            cfg.rays_per_step,
            cfg.pixel_rays
        );
        if let Some(b) = &cfg.behind {
            let fits = b.len() == views.len()
                && views
                    .iter()
                    .enumerate()
                    .all(|(i, v)| b.pixels(i) == (v.intrinsics.width * v.intrinsics.height) as usize);
            assert!(fits, "train: the background colours are not one per pixel of the training views");
        }
        let grads = model.zero_grads();
        let adams = model
            .groups(&mut params, &grads)
            .iter()
            .map(|g| Adam::new(g.master.len(), AdamConfig { l2: g.l2, ..Default::default() }))
            .collect();
        model.after_step(&mut params);
        let gains = cfg.image_gains.map(|prior| ImageGains::new(views.len(), prior));
        let error_map = cfg.error_map.map(|_| TileLayout::new(views).initial_values());
        let state = TrainState { step: 0, params, occupancy, adams, skipped: 0, seconds: 0.0, gains, error_map };
        Self::from_state(isa, model, views, cfg, state).expect("a fresh state fits its model")
    }

    /// Continues a run from `state` (a checkpoint); refuses a state whose optimisers do not
    /// fit the model's parameter groups.
    pub fn from_state(
        isa: Isa,
        model: &'a M,
        views: &'a [View],
        cfg: &'a TrainConfig,
        mut state: TrainState<M::Params>,
    ) -> Result<Self, String> {
        if views.is_empty() {
            return Err("train: no training views".into());
        }
        let grads = model.zero_grads();
        let sizes: Vec<usize> = model.groups(&mut state.params, &grads).iter().map(|g| g.master.len()).collect();
        model.after_step(&mut state.params); // groups() lends the weights out mutably
        let saved: Vec<usize> = state.adams.iter().map(|a| a.moments().0.len()).collect();
        if sizes != saved {
            return Err(format!("optimiser state sizes {saved:?} do not fit the model's parameter groups {sizes:?}"));
        }
        match (&state.gains, cfg.image_gains) {
            (Some(g), Some(_)) if g.log_gains.len() != views.len() => {
                return Err(format!("state has gains for {} images, the run has {}", g.log_gains.len(), views.len()))
            }
            (Some(_), None) | (None, Some(_)) => {
                return Err("state and settings disagree on learning per-image gains".into())
            }
            _ => {}
        }
        let tiles = TileLayout::new(views);
        match (&state.error_map, cfg.error_map) {
            (Some(m), Some(_)) if m.len() != tiles.len() => {
                return Err(format!(
                    "state has an error map of {} tiles, the run's views have {}",
                    m.len(),
                    tiles.len()
                ))
            }
            (Some(_), None) | (None, Some(_)) => return Err("state and settings disagree on the error map".into()),
            _ => {}
        }
        if state.step > cfg.steps {
            return Err(format!("state is at step {}, past the run's {} steps", state.step, cfg.steps));
        }
        if let Some(f) = &cfg.focus {
            let lists = std::iter::once(("focus", &f.pixels)).chain(f.reach.as_ref().map(|r| ("reach", r)));
            for (name, list) in lists {
                let bad = list.iter().find(|&&(v, p)| {
                    views
                        .get(v as usize)
                        .is_none_or(|v| p as u64 >= v.intrinsics.width as u64 * v.intrinsics.height as u64)
                });
                if let Some((v, p)) = bad {
                    return Err(format!("{name} pixel {p} of view {v} is outside the training views"));
                }
            }
        }
        let changed = match &cfg.focus {
            Some(f) => {
                let mut bits: Vec<Vec<u64>> = views
                    .iter()
                    .map(|v| vec![0u64; (v.intrinsics.width as usize * v.intrinsics.height as usize).div_ceil(64)])
                    .collect();
                for &(v, p) in f.spared.as_deref().unwrap_or(&f.pixels).iter() {
                    bits[v as usize][p as usize / 64] |= 1 << (p % 64);
                }
                bits
            }
            None => Vec::new(),
        };
        let (rays, ctx) = (StepRays::default(), M::Context::default());
        let workers = (0..SLOTS).map(|_| Worker::default()).collect();
        let slots = (0..SLOTS).map(|_| M::Slot::default()).collect();
        let near_distance = cfg.near_gradient.distance(views, state.occupancy.aabb());
        Ok(Trainer {
            isa,
            model,
            views,
            cfg,
            state,
            grads,
            rays,
            workers,
            slots,
            ctx,
            changed,
            error_draws: (tiles, ErrorSampler::default()),
            pool: None,
            bad_in_a_row: 0,
            empty_in_a_row: 0,
            near_distance,
        })
    }

    /// The run's settings.
    pub fn config(&self) -> &'a TrainConfig {
        self.cfg
    }

    /// The training views.
    pub fn views(&self) -> &'a [View] {
        self.views
    }

    /// The distance within which the run scales gradients down ([`TrainConfig::near_gradient`]
    /// resolved for its views; 0: off).
    pub fn near_distance(&self) -> f32 {
        self.near_distance
    }

    /// Whether every step of the run is done.
    pub fn is_done(&self) -> bool {
        self.state.step >= self.cfg.steps
    }

    /// The run's state after the last step.
    pub fn state(&self) -> &TrainState<M::Params> {
        &self.state
    }

    /// Ends the run, returning its state.
    pub fn into_state(self) -> TrainState<M::Params> {
        self.state
    }

    /// Ends the run after the steps taken so far as its last step would have: a grid frozen
    /// outside its pinned cells (a residual model's change region) has those cells' values
    /// settled from a lattice in each ([`OccupancyGrid::settle_pinned`]), for the renderers
    /// that skip cells by value. The same as [`Self::into_state`] once every step is done (the
    /// last step settled them) or on a grid without that freeze. For a run stopped early: a
    /// robot's scene phase out of time ([`crate::train::scene::train_scene`]).
    pub fn finish(mut self) -> TrainState<M::Params> {
        if !self.is_done() {
            crate::simd::fpmode::flushed_on_pool(|| self.settle_region());
        }
        self.state
    }

    /// The change region's cell values from a lattice in each cell, not the refreshes' single
    /// points (what the renderers that skip cells by value read): the end of a run whose grid is
    /// frozen outside its pinned cells; nothing on other grids.
    fn settle_region(&mut self) {
        if self.state.occupancy.is_frozen_outside_pins() {
            let (isa, model, state, ctx) = (self.isa, self.model, &mut self.state, &mut self.ctx);
            let params = &state.params;
            state.occupancy.settle_pinned(SETTLE_LATTICE, |pts, sigma| model.density(isa, params, pts, sigma, ctx));
        }
    }

    /// Runs the next step. A step whose loss or gradients are not finite changes nothing and
    /// is counted ([`TrainState::skipped`]); too many in a row, or too many steps without a
    /// live sample, end the run with an error (the state stays the last good one).
    pub fn step(&mut self) -> Result<StepStats, TrainError> {
        assert!(!self.is_done(), "train: step past the end of the run");
        let start = Instant::now();
        let result = crate::simd::fpmode::flushed_on_pool(|| {
            let result = self.step_inner();
            // The run's last step (counted, whether or not it was finite) ends it.
            if self.is_done() {
                self.settle_region();
            }
            result
        });
        self.state.seconds += start.elapsed().as_secs_f64();
        let mut stats = result?;
        stats.seconds = self.state.seconds;
        Ok(stats)
    }

    fn step_inner(&mut self) -> Result<StepStats, TrainError> {
        let (isa, model, views, cfg) = (self.isa, self.model, self.views, self.cfg);
        let Trainer {
            state,
            grads,
            rays,
            workers,
            slots,
            ctx,
            changed,
            error_draws,
            pool,
            bad_in_a_row,
            empty_in_a_row,
            ..
        } = self;
        let (tiles, sampler) = error_draws;
        let step = state.step;
        let params = &mut state.params;
        let occupancy = &mut state.occupancy;
        if step % cfg.occupancy_interval.max(1) == 0 {
            let mut orng = Rng::stream(cfg.seed ^ 0x0CC, step as u64);
            occupancy.update(step, &mut orng, |pts, sigma| model.density(isa, params, pts, sigma, ctx));
        }
        // 1. Rays: the focus share from the focus pixels, then the error map's share by the
        //    training error, the rest uniform over the reach pixels when there are some, else
        //    over all pixels of all views; or, with the ray pool, drawn from the pool (whose
        //    fresh rays are drawn the same way).
        let mut srng = Rng::stream(cfg.seed, step as u64);
        rays.clear();
        let focused = match &cfg.focus {
            Some(f) if !f.pixels.is_empty() => (f.share.clamp(0.0, 1.0) * cfg.rays_per_step as f32).round() as usize,
            _ => 0,
        };
        let errored = match (&state.error_map, cfg.error_map) {
            (Some(values), Some(share)) => {
                sampler.rebuild(values);
                ((share.clamp(0.0, 1.0) * cfg.rays_per_step as f32).round() as usize).min(cfg.rays_per_step - focused)
            }
            _ => 0,
        };
        let split = model.frozen_outside().filter(|_| {
            cfg.ray_pool > 1
                && cfg.pixel_rays == 1
                && occupancy.is_frozen_outside_pins()
                && cfg.distortion == 0.0
                && cfg.error_map.is_none()
        });
        match split {
            Some(split) => {
                let pool = pool.get_or_insert_with(|| RayPool::new(cfg.rays_per_step, focused, cfg.ray_pool));
                let occupancy = &*occupancy;
                pool.refresh(step, &PoolInputs { isa, split, occupancy, views, cfg, changed });
                pool.take(step, cfg.rays_per_step, &mut srng, rays, |rng| background_colour(cfg, rng));
            }
            None => {
                let per_pixel = cfg.rays_per_pixel();
                let mut offsets = Vec::with_capacity(per_pixel);
                for r in (0..cfg.rays_per_step).step_by(per_pixel) {
                    let errors = Some((&*tiles, &*sampler));
                    let (vi, p) = draw_pixel(views, cfg.focus.as_ref(), focused, errored, r, &mut srng, errors);
                    let v = &views[vi as usize];
                    let (unchanged, target) = (is_unchanged(changed, vi, p), v.rgb[p as usize]);
                    if per_pixel > 1 {
                        pixel_filter::offsets(per_pixel, &mut srng, &mut offsets);
                    }
                    for k in 0..per_pixel {
                        rays.view.push(vi);
                        rays.pixel.push(p);
                        rays.unchanged.push(unchanged);
                        rays.rays.push(match per_pixel {
                            1 => ray_through(v, p, cfg.pixel_jitter, &mut srng),
                            _ => pixel_filter::ray(v, p, offsets[k]),
                        });
                        rays.targets.push(target);
                        rays.backgrounds.push(background_colour(cfg, &mut srng));
                        rays.behind.push(match (&cfg.behind, cfg.photo_tail) {
                            (Some(b), true) => b.get(vi as usize, p as usize),
                            _ => [f32::NAN; 3],
                        });
                    }
                }
            }
        }
        // 2. The fused pass: each slot's rays, chunk by chunk, marched, evaluated, composited
        //    and back-propagated to the networks' and the grids' feature gradients.
        let entropy = match step as f32 >= cfg.beta.entropy_from * cfg.steps as f32 {
            true => cfg.beta.entropy,
            false => 0.0,
        };
        let gains = state.gains.as_ref().map(ImageGains::gains).unwrap_or_default();
        let near_distance = self.near_distance;
        let inputs = StepInputs {
            isa,
            model,
            params: &*params,
            occupancy: &*occupancy,
            cfg,
            entropy,
            gains: &gains,
            near_distance,
        };
        let rays = &*rays;
        workers.par_iter_mut().zip(slots.par_iter_mut()).enumerate().for_each(|(s, (w, slot))| {
            let range = slot_rays(rays.rays.len(), cfg.rays_per_pixel(), s);
            match (split, pool.as_ref()) {
                (Some(split), Some(pool)) => w.run_pooled(&inputs, split, pool, rays, range, slot),
                _ => w.run(&inputs, rays, range, slot),
            }
        });
        let loss: f64 = workers.iter().map(|w| w.loss).sum();
        let marched: usize = workers.iter().map(|w| w.n_marched).sum();
        let n: usize = workers.iter().map(|w| w.n_kept).sum();
        *empty_in_a_row = if marched == 0 { *empty_in_a_row + 1 } else { 0 };
        if *empty_in_a_row >= MAX_EMPTY_STEPS_IN_A_ROW {
            return Err(TrainError::NoLiveSamples { step, aabb: *occupancy.aabb(), occupancy: occupancy.occupancy() });
        }
        // 3. The step's gradients: the slots' network gradients in slot order, the grids'
        //    scattered from the gathered feature gradients. A non-finite loss or gradient skips
        //    the step (the parameters, moments and step count of Adam stay as they were).
        model.finish_step(isa, slots, grads);
        let gain_grads: Vec<[f32; 3]> = (0..gains.len())
            .map(|v| workers.iter().fold([0.0; 3], |acc, w| std::array::from_fn(|c| acc[c] + w.d_gain[v][c])))
            .collect();
        let finite = loss.is_finite()
            && model.groups(params, grads).iter().all(|g| all_finite(g.grad))
            && gain_grads.iter().flatten().all(|g| g.is_finite());
        if finite {
            // 4. Adam on every parameter group, and on the images' gains.
            let lr = cfg.schedule.lr(step);
            for (adam, g) in state.adams.iter_mut().zip(model.groups(params, grads)) {
                adam.step(isa, lr, g.master, g.grad, g.mirror);
            }
            if let Some(g) = &mut state.gains {
                g.step(isa, lr, &gain_grads);
            }
            // The error map learns each ray's error, in ray order (the slots hold consecutive rays).
            if let Some(values) = &mut state.error_map {
                let errors = workers.iter().flat_map(|w| w.ray_errors.iter());
                for ((&v, &p), &e) in rays.view.iter().zip(&rays.pixel).zip(errors) {
                    error_map::record(values, tiles.tile_of(v, p), e);
                }
            }
            *bad_in_a_row = 0;
        } else {
            state.skipped += 1;
            *bad_in_a_row += 1;
        }
        // Re-derive the MLPs' transposed copies: Adam changed the weights, or (skipped step)
        // groups() lent them out mutably.
        model.after_step(params);
        state.step += 1;
        if *bad_in_a_row >= MAX_BAD_STEPS_IN_A_ROW {
            return Err(TrainError::NonFinite { step, skipped: state.skipped });
        }
        Ok(StepStats {
            step,
            loss: (loss / (3 * cfg.rays_per_step) as f64) as f32,
            samples_per_ray: n as f32 / cfg.rays_per_step as f32,
            marched_per_ray: marched as f32 / cfg.rays_per_step as f32,
            seconds: 0.0,
            occupancy: occupancy.occupancy(),
            skipped: state.skipped,
        })
    }
}

/// The pixel `(view, y · width + x)` of a step's ray `r`: the first `focused` rays from the
/// focus pixels, the next `errored` by the error map (`errors`, required when `errored > 0`),
/// the rest uniform over the reach pixels when there are some, else over all pixels of all
/// views.
pub(super) fn draw_pixel(
    views: &[View],
    focus: Option<&Focus>,
    focused: usize,
    errored: usize,
    r: usize,
    rng: &mut Rng,
    errors: Option<(&TileLayout, &ErrorSampler)>,
) -> (u32, u32) {
    let reach = focus.and_then(|f| f.reach.as_deref()).filter(|r| !r.is_empty());
    match (focus, reach, errors) {
        (Some(f), _, _) if r < focused => f.pixels[rng.below(f.pixels.len() as u64) as usize],
        (_, _, Some((tiles, sampler))) if r < focused + errored => tiles.draw_pixel(sampler.draw(rng), rng),
        (_, Some(reach), _) => reach[rng.below(reach.len() as u64) as usize],
        _ => {
            let vi = rng.below(views.len() as u64) as u32;
            let v = &views[vi as usize];
            (vi, rng.below(v.intrinsics.width as u64 * v.intrinsics.height as u64) as u32)
        }
    }
}

/// Whether pixel `p` of view `v` is one the β penalty takes as unchanged: not in the view's
/// bitset of spared pixels (`changed`, one per view; none without a focus).
pub(super) fn is_unchanged(changed: &[Vec<u64>], v: u32, p: u32) -> bool {
    changed.get(v as usize).is_some_and(|b| b[p as usize / 64] >> (p % 64) & 1 == 0)
}

/// The colour behind a training ray: uniform random with [`TrainConfig::random_background`],
/// else [`TrainConfig::background`].
fn background_colour(cfg: &TrainConfig, rng: &mut Rng) -> [f32; 3] {
    match cfg.random_background {
        true => std::array::from_fn(|_| rng.uniform(0.0, 1.0)),
        false => cfg.background,
    }
}

/// The training ray of pixel `p` of `v`: through its centre, or through a uniform random point
/// of it with `jitter` ([`TrainConfig::pixel_jitter`]).
pub(super) fn ray_through(v: &View, p: u32, jitter: bool, rng: &mut Rng) -> crate::geometry::camera::Ray {
    let w = v.intrinsics.width;
    match jitter {
        true => {
            let (x, y) = ((p % w) as f32 + rng.uniform(0.0, 1.0), (p / w) as f32 + rng.uniform(0.0, 1.0));
            image_ray(&v.intrinsics, &v.pose, x, y)
        }
        false => pixel_ray(&v.intrinsics, &v.pose, p % w, p / w),
    }
}

/// Whether every value is finite (a branch-free pass over chunks, on the rayon pool).
fn all_finite(x: &[f32]) -> bool {
    const EXP: u32 = 0x7f80_0000;
    x.par_chunks(1 << 16).all(|c| c.iter().fold(0u32, |acc, v| acc | ((v.to_bits() & EXP == EXP) as u32)) == 0)
}

/// Trains `model` on `views` inside `aabb` from fresh parameters (seeded by `cfg.seed`);
/// returns the parameters and the occupancy grid. `observe` receives the stats, parameters and
/// occupancy grid after every `log_every`-th step and the last (0: never); the training clock
/// ([`StepStats::seconds`]) stops while it runs, so an observer that evaluates the model (the
/// speed curves of `rnerf compare`) does not count as training time.
pub fn train_model<M: Model>(
    isa: Isa,
    model: &M,
    aabb: Aabb,
    views: &[View],
    cfg: &TrainConfig,
    log_every: u32,
    observe: impl FnMut(StepStats, &M::Params, &OccupancyGrid),
) -> Result<(M::Params, OccupancyGrid), TrainError> {
    train_model_from(isa, model, aabb, views, cfg, None, log_every, observe)
}

/// [`train_model`] from `start` (parameters and occupancy grid, [`Trainer::starting_at`])
/// when given, else from fresh parameters.
#[allow(clippy::too_many_arguments)]
pub fn train_model_from<M: Model>(
    isa: Isa,
    model: &M,
    aabb: Aabb,
    views: &[View],
    cfg: &TrainConfig,
    start: Option<(M::Params, OccupancyGrid)>,
    log_every: u32,
    mut observe: impl FnMut(StepStats, &M::Params, &OccupancyGrid),
) -> Result<(M::Params, OccupancyGrid), TrainError> {
    let mut trainer = match start {
        Some((params, occupancy)) => Trainer::starting_at(isa, model, views, cfg, params, occupancy),
        None => Trainer::new(isa, model, aabb, views, cfg),
    };
    while !trainer.is_done() {
        let stats = trainer.step()?;
        if log_every > 0 && ((stats.step + 1) % log_every == 0 || stats.step + 1 == cfg.steps) {
            observe(stats, &trainer.state().params, &trainer.state().occupancy);
        }
    }
    let state = trainer.into_state();
    Ok((state.params, state.occupancy))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_small_capture_takes_fewer_rays_a_step() {
        let px = 200 * 200;
        // 100 and 50 views of 200×200: every ray; 35: in proportion; 25 and a tiny capture: half.
        assert_eq!(rays_for_capture(100 * px, 1), TRAIN_RAYS);
        assert_eq!(rays_for_capture(CAPTURE_FULL_PIXELS, 1), TRAIN_RAYS);
        assert_eq!(rays_for_capture(35 * px, 1), 704);
        assert_eq!(rays_for_capture(25 * px, 1), TRAIN_RAYS / 2);
        assert_eq!(rays_for_capture(32 * 96 * 96, 1), TRAIN_RAYS / 2);
        assert_eq!(rays_for_capture(0, 1), TRAIN_RAYS / 2);
        // Whole pixels of K rays, never more than the plain count.
        for k in 1..=MAX_PIXEL_RAYS {
            for views in [1, 25, 31, 35, 49, 50, 400] {
                let rays = rays_for_capture(views * px, k);
                assert_eq!(rays % k as usize, 0, "K = {k}, {views} views");
                assert!(rays <= rays_for_capture(views * px, 1) && rays >= TRAIN_RAYS / 2 - 64, "K = {k}");
            }
        }
    }

    #[test]
    fn the_near_gradient_distance_follows_the_capture() {
        use crate::geometry::camera::Pose;
        use crate::geometry::Intrinsics;
        use glam::Vec3;
        let view = |eye: Vec3, target: Vec3| View {
            intrinsics: Intrinsics::pinhole(4, 4, 4.0, 4.0, 2.0, 2.0),
            pose: Pose::look_at(eye, target),
            rgb: vec![[0.5; 3]; 16],
        };
        let target = Vec3::new(0.1, 0.0, 0.0);
        let ring: Vec<View> = (0..8)
            .map(|i| {
                let a = i as f32 * std::f32::consts::FRAC_PI_4;
                view(target + 2.0 * Vec3::new(a.cos(), a.sin(), 0.5).normalize(), target)
            })
            .collect();
        let aabb = Aabb { min: Vec3::splat(-3.0), max: Vec3::splat(3.0) };
        let d = |n: NearGradient, views: &[View]| n.distance(views, &aabb);
        assert!((d(NearGradient::OfCapture(0.5), &ring) - 1.0).abs() < 1e-5, "half the ring's radius");
        assert!((d(NearGradient::OfCapture(0.25), &ring) - 0.5).abs() < 1e-5);
        assert_eq!(d(NearGradient::Distance(0.3), &ring), 0.3);
        assert_eq!(d(NearGradient::Off, &ring), 0.0);
        // Parallel axes pin no focus: the box's centre stands in for it.
        let parallel: Vec<View> =
            (0..3).map(|i| view(Vec3::new(i as f32, -2.0, 0.0), Vec3::new(i as f32, 0.0, 0.0))).collect();
        assert!((d(NearGradient::OfCapture(0.5), &parallel) - 0.5 * Vec3::new(1.0, -2.0, 0.0).length()).abs() < 1e-5);
    }

    #[test]
    fn near_gradients_scale_quadratically_up_to_the_distance() {
        let t = [0.05, 0.1, 0.2, 0.5];
        let mut ds = [1.0, 2.0, 1.0, 1.0];
        let mut dc = [[1.0; 3], [1.0; 3], [-2.0; 3], [1.0; 3]];
        scale_near_gradients(&t, 0.2, &mut ds, &mut dc);
        assert_eq!(ds, [0.0625, 0.5, 1.0, 1.0]);
        assert_eq!(dc, [[0.0625; 3], [0.25; 3], [-2.0; 3], [1.0; 3]]);
    }
}
