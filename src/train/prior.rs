//! What the background tells a residual model before it trains (the background-aware
//! Residual-NeRF): where each scene image changed, where in 3-D the scene changed, and which
//! pixels to train on more often.
//!
//! 1. **Background colours** per scene training view: the background capture's image at the
//!    same pose when there is one (same intrinsics, pose within [`SAME_POSE`]), else the
//!    background model rendered at that pose.
//! 2. **Registration** ([`crate::train::register`]): per scene view whose pose is not a
//!    background view's, the pose corrected so the image agrees with the background rendered
//!    there where the workspace did not change (a robot arm's poses are millimetres off); the
//!    background is rendered again at the registered pose for what follows, and the residual
//!    trains from it ([`PriorConfig::register`] turns it off).
//! 3. **Exposure and white balance** ([`fit_correction`]): per scene view, a per-channel gain
//!    fitted robustly (trimmed least squares) from the scene image to the background's colours, so a global brightness or white-balance change between the two
//!    captures is not a change; the change maps are computed after it and the residual trains
//!    on the corrected images ([`ScenePrior::corrected_views`]), in the frozen background's
//!    appearance. A fit within [`IDENTITY_GAIN`] of the identity is not applied ([`PriorConfig::exposure`] turns the correction off).
//! 4. **Change maps** ([`change_map`]): a pixel changed when the 3×3 box-filtered colours differ
//!    by more than [`PriorConfig::tolerance`] in some channel (against the rendered background,
//!    [`PriorConfig::rendered_tolerance`]); single specks are removed (a
//!    changed pixel needs [`MIN_NEIGHBOURS`] changed 8-neighbours) and the map is dilated by
//!    [`PriorConfig::dilate_px`] pixels, so the edges of a faint glass are kept.
//! 5. **Change region** ([`vote_region`]): every occupancy cell is projected into every view; a
//!    view *sees* the cell when it lies in front of the background's threshold-depth surface at
//!    that pixel (within a cell diagonal; at a hole in the background's depth per
//!    [`PriorConfig::holes_see`]). A cell is changed when at least [`PriorConfig::min_seen`] of
//!    the views (and 3) see it and at least [`PriorConfig::vote`] of them see a
//!    changed pixel there: a visual hull of the change maps, carved by the background's own
//!    geometry, so a view whose line of sight is blocked by an opaque object does not vote. The
//!    region is then voted again on cells [`PriorConfig::region_subdivide`] times finer
//!    (inside the coarse vote's cells and their neighbours) and dilated by
//!    [`PriorConfig::region_dilate`] of those cells; the occupancy grid pins every cell
//!    holding one.
//! 6. **Focus pixels**: the changed pixels of every view, from which the trainer draws
//!    [`PriorConfig::change_share`] of each step's rays ([`crate::train::trainer::Focus`]).
//! 7. **Reach pixels** ([`reach_pixels`]): the pixels whose ray crosses the region in front of
//!    the background's surface. Outside the region the field is the frozen background, so a ray
//!    that misses it carries no gradient; with the region the trainer draws the rest of each
//!    step's rays from these pixels (changed or not: the unchanged ones carve the region's
//!    floaters) instead of from the whole image.

use crate::data::View;
use crate::field::model::Model;
use crate::field::residual::{ResidualConfig, ResidualField, ResidualParams};
use crate::field::Nerf;
use crate::geometry::ChangeRegion;
use crate::render::view::Scene;
use crate::render::OccupancyGrid;
use crate::render::{DensityThreshold, RenderedView, StopFill, ViewRenderer};
use crate::rng::Rng;
use crate::simd::Isa;
use crate::train::beta::BetaRegulariser;
use crate::train::lift::{lift_region, LiftConfig, LiftReport};
use crate::train::register::{register_at, Registration};
use crate::train::trainer::{Focus, TrainConfig};
use glam::Vec3;
use rayon::prelude::*;

/// Transmittance at which the prior's colour renders of the background (registration and
/// change maps, for scene views without a background image at their pose) stop compositing
/// ([`ViewRenderer::set_early_stop`]), the rest of the ray's light taken to look like what it
/// gathered so far ([`PRIOR_STOP_FILL`]). The background's surfaces leak: a ray's transmittance
/// falls below 0.99 at its first surface, after 2.5 samples on average, but below 0.1 only after
/// 56 and below 0.01 after 106. Their threshold depth does not move (docs/DECISIONS.md, "The
/// background at other poses").
pub const PRIOR_EARLY_STOP: f32 = 0.1;

/// What stands for the light after [`PRIOR_EARLY_STOP`]: the ray's own colour, which a leaky
/// surface's rest shares, where the background colour would make up to a tenth of every
/// stopped pixel.
pub const PRIOR_STOP_FILL: StopFill = StopFill::RayColour;

/// Two poses within this (rotation entries and translation, scene units) are the same pose.
pub const SAME_POSE: f32 = 1e-4;

/// Changed 8-neighbours a changed pixel needs to stay changed (speck removal).
pub const MIN_NEIGHBOURS: u32 = 2;

/// Settings of the background prior (defaults measured on the dev scenes: docs/DECISIONS.md).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PriorConfig {
    /// Colour difference (max over channels, of 3×3 box-filtered [0, 1] colours) above which a
    /// pixel changed. Defaults to [`CHANGE_TOLERANCE`].
    pub tolerance: f32,
    /// [`PriorConfig::tolerance`] of a view compared with the rendered background (no
    /// background image at its pose). Defaults to [`RENDERED_TOLERANCE`].
    pub rendered_tolerance: f32,
    /// Dilation of the change maps (pixels). Defaults to 2.
    pub dilate_px: u32,
    /// Dilation (pixels) of the changed pixels the β penalty on unchanged rays spares (after
    /// their closing, [`PriorConfig::beta_close_px`]): a pixel farther than this from every
    /// spared one shows the background, and its ray is penalised for β. Defaults to
    /// [`BETA_DILATE_PX`].
    pub beta_dilate_px: u32,
    /// Closing radius (pixels) of the changed pixels the β penalty spares, before their
    /// dilation by [`PriorConfig::beta_dilate_px`]: the changed pixels are closed by a square of
    /// this radius and the holes they then enclose are filled ([`close_and_fill`]), so a faint
    /// glass's unchanged-looking inside is spared with its changed outline. 0: no closing and no
    /// fill. Defaults to [`BETA_CLOSE_PX`].
    pub beta_close_px: u32,
    /// Share of the views that see a cell which must see a change there. Defaults to
    /// [`REGION_VOTE`].
    pub vote: f32,
    /// Share of all views that must see a cell before it can be changed (and at least 3
    /// views). Defaults to 0.25: cells seen by a few views only (near a wall, in front of a
    /// camera) are carved out of the region (docs/DECISIONS.md, "A tight change region").
    pub min_seen: f32,
    /// Whether a view whose background depth has a hole at the cell's pixel sees the cell (the
    /// hole read as "no surface up to infinity"). Defaults to true (as measured on the dev set,
    /// whose background has no holes); false leaves such views out of the vote, which a weak
    /// background with holes needs.
    pub holes_see: bool,
    /// Dilation of the voted region (cells of the voted grid). Defaults to 1.
    pub region_dilate: u32,
    /// The region is voted on a grid this many times finer than the occupancy grid, inside
    /// the coarse vote's cells and their neighbours ([`vote_region`]); the occupancy grid pins
    /// every cell holding a fine one. 1: the occupancy grid's cells; never finer than
    /// [`crate::geometry::region::MAX_RESOLUTION`] (what a model file holds). Defaults to
    /// [`REGION_SUBDIVIDE`].
    pub region_subdivide: u32,
    /// Share of each step's rays drawn from changed pixels. Defaults to 0.5.
    pub change_share: f32,
    /// The β regularisers ([`crate::train::beta`]); the unchanged-ray penalty reads the change
    /// maps. Defaults to [`DEFAULT_BETA`].
    pub beta: BetaRegulariser,
    /// The density floor a warm-started residual gets inside the region before training
    /// ([`crate::train::lift`]); `None`: none. Defaults to [`DEFAULT_LIFT`].
    pub lift: Option<LiftConfig>,
    /// Correct each scene image's exposure and white balance to the background's before the
    /// change maps and training ([`fit_correction`]). Defaults to true.
    pub exposure: bool,
    /// Register each scene image's pose against the background before everything else
    /// ([`crate::train::register`]). Defaults to true.
    pub register: bool,
    /// The background's threshold depth at a scene view's pose (what the vote and the reach
    /// pixels read as its surface), when only depth is rendered, is rendered on its occupancy
    /// grid kept to the cells whose value reached this fraction of `m·δ`
    /// ([`OccupancyGrid::keep_solid`], the onboard renderer's trade): the rays cross the
    /// cells that never showed a density near the threshold without evaluating it. 0: the whole
    /// grid. Defaults to [`DEPTH_SOLID_FRACTION`].
    pub depth_solid_fraction: f32,
}

/// Default of [`PriorConfig::depth_solid_fraction`]: on the dev scenes the prior takes 4.7–5.5 s
/// instead of 10.6–13.4 s on the whole grid, and the region is the same within a cell
/// (docs/DECISIONS.md, "The prior's depth renders on the thinned grid").
pub const DEPTH_SOLID_FRACTION: f32 = 1.0;

/// Default of [`PriorConfig::tolerance`]: 0.03 (7.7/255), above a renderer's differences
/// where nothing changed (the dev set's mean 1.1–2.7/255 beside the object) and low enough to
/// mark more of a clear tumbler's faint walls changed than 0.05 did; measured on the dev scenes
/// against 0.02 and 0.05 (docs/DECISIONS.md, "The change maps' tolerance"). A capture whose
/// unchanged pixels differ by more (a noisy sensor, a saturating exposure change) wants 0.05.
pub const CHANGE_TOLERANCE: f32 = 0.03;

/// Default of [`PriorConfig::rendered_tolerance`]: 0.05, the tolerance measured for maps
/// against the rendered background, whose renders carry the model's own error; at 0.03 they
/// marked twice the pixels changed and lost more of glass_up's tumbler (docs/DECISIONS.md, "The
/// change maps' tolerance").
pub const RENDERED_TOLERANCE: f32 = 0.05;

/// Default of [`PriorConfig::beta_dilate_px`]: the maps' own dilation, measured on the dev
/// scenes against 0 and 1 (docs/DECISIONS.md, "β regularisers", "The penalty's margin"), and with
/// the changed pixels closed and filled against 0 and 1 ("The β penalty sparing what the
/// changed pixels enclose").
pub const BETA_DILATE_PX: u32 = 2;

/// Default of [`PriorConfig::beta_close_px`]: 0, no closing and no fill. At 4 with margin 0 or 1
/// the dev scenes' near crops gain 5% or 2.4%, but the demo's faint sphere loses 6–26% of its
/// object MAE at every seed, and at margin 0 glass_up's tumbler 6–11% (docs/DECISIONS.md, "The
/// β penalty sparing what the changed pixels enclose (measured, off)").
pub const BETA_CLOSE_PX: u32 = 0;

/// Default density floor: none. At [`LiftConfig::DEFAULT`] (`--region-floor 0`) the dev scenes
/// gain (object MAE −11%, near-crop RMSE −6% over three seeds) but scene poses off like a robot
/// arm's lose the glass (`tests/capture_e2e.rs`): docs/DECISIONS.md, "The density floor with the raw
/// mix".
pub const DEFAULT_LIFT: Option<LiftConfig> = None;

/// Default of [`PriorConfig::vote`]: three quarters of the views that see a cell must see a
/// change there (0.5 until 2026-12-07). Over the 3000-step background the dev scenes' objects
/// gain 20% at 25 views (every scene at every seed) and their near crops 5% at 25 views and 2%
/// at 100; the region holds fewer cells, so a training ray fewer samples (docs/DECISIONS.md,
/// "The region's vote over the 3000-step background").
pub const REGION_VOTE: f32 = 0.75;

/// Default of [`PriorConfig::region_subdivide`]: the region is voted on cells half the
/// occupancy grid's (1.3 cm across, 0.85 cm high on the dev box; 1 until 2026-12-07). On the dev scenes the region
/// holds 55–60% of the volume it did, a training ray keeps 7–20% fewer samples (a step takes
/// 0.78× the time), and the objects at 100 views and the near crops at 25 gain 5–6%
/// (docs/DECISIONS.md, "The change region voted on cells half the grid's").
pub const REGION_SUBDIVIDE: u32 = 2;

/// Default β regularisers: the penalty on unchanged rays at 0.02, the entropy at 0.005 from half
/// the run on (measured on the dev scenes: docs/DECISIONS.md, "β regularisers"; the entropy at
/// 0.02 and above loses glass_up's tumbler, and the penalty at 0.05 loses it at 25 views:
/// "The region's vote over the 3000-step background").
pub const DEFAULT_BETA: BetaRegulariser = BetaRegulariser { unchanged: 0.02, entropy: 0.005, entropy_from: 0.5 };

impl Default for PriorConfig {
    fn default() -> Self {
        PriorConfig {
            tolerance: CHANGE_TOLERANCE,
            rendered_tolerance: RENDERED_TOLERANCE,
            dilate_px: 2,
            beta_dilate_px: BETA_DILATE_PX,
            beta_close_px: BETA_CLOSE_PX,
            vote: REGION_VOTE,
            min_seen: 0.25,
            holes_see: true,
            region_dilate: 1,
            region_subdivide: REGION_SUBDIVIDE,
            change_share: 0.5,
            beta: DEFAULT_BETA,
            lift: DEFAULT_LIFT,
            exposure: true,
            register: true,
            depth_solid_fraction: DEPTH_SOLID_FRACTION,
        }
    }
}

/// Each training view's background colours at its pose, 16 bits a channel: lossless for 8- and
/// 16-bit images (`k/255 = 257k/65535`), within 1/131070 for rendered ones.
#[derive(Clone, Debug, PartialEq)]
pub struct BackgroundColours {
    views: Vec<Vec<[u16; 3]>>,
}

impl BackgroundColours {
    /// The colours of each view (row-major pixels, channels in [0, 1]; clamped into it).
    pub fn new(views: &[Vec<[f32; 3]>]) -> BackgroundColours {
        let q = |v: f32| (v.clamp(0.0, 1.0) * 65535.0).round() as u16;
        BackgroundColours { views: views.iter().map(|v| v.iter().map(|c| c.map(q)).collect()).collect() }
    }

    /// Views held.
    pub fn len(&self) -> usize {
        self.views.len()
    }

    /// Whether no view is held.
    pub fn is_empty(&self) -> bool {
        self.views.is_empty()
    }

    /// Pixels of view `v`.
    pub fn pixels(&self, v: usize) -> usize {
        self.views[v].len()
    }

    /// The colour of pixel `p` of view `v`.
    pub fn get(&self, v: usize, p: usize) -> [f32; 3] {
        self.views[v][p].map(|q| q as f32 / 65535.0)
    }
}

/// The prior of one scene.
#[derive(Clone, Debug)]
pub struct ScenePrior {
    /// Change map per training view (`width × height`, row-major).
    pub maps: Vec<Vec<bool>>,
    /// Views whose background colours came from a background image (the rest were rendered).
    pub matched_views: usize,
    /// The voted 3-D change region.
    pub region: ChangeRegion,
    /// `(view, pixel)` of every changed pixel.
    pub focus: Vec<(u32, u32)>,
    /// `(view, pixel)` of every pixel the β penalty spares (the changed pixels before the
    /// maps' dilation, closed and filled by [`PriorConfig::beta_close_px`] ([`close_and_fill`]),
    /// then dilated by [`PriorConfig::beta_dilate_px`]); the same as [`Self::focus`] with no
    /// closing and both dilations equal.
    pub spared: Vec<(u32, u32)>,
    /// `(view, pixel)` of every pixel whose ray crosses the region ([`reach_pixels`]).
    pub reach: Vec<(u32, u32)>,
    /// The colour correction applied to each training view (identity when off or negligible).
    pub corrections: Vec<ColourCorrection>,
    /// Each training view's background colours at its pose (`width × height`): the background
    /// image at the same pose, else the background rendered there; what the photo tail reads
    /// ([`crate::train::trainer::TrainConfig::photo_tail`]).
    pub behind: std::sync::Arc<BackgroundColours>,
    /// Each training view's registration against the background (`None`: not registered — off,
    /// or the view is a background view's pose); its pose is the view's pose for the prior and
    /// for training, the given one when not applied.
    pub registrations: Vec<Option<Registration>>,
}

/// A fitted gain within this of 1 in every channel is not applied: below that the fit is
/// within a rendered background's noise, and the change maps' tolerance ([`CHANGE_TOLERANCE`])
/// absorbs it.
pub const IDENTITY_GAIN: f32 = 0.02;

/// A per-channel gain `c ↦ gain·c`, clamped to [0, 1]: an exposure and white-balance change.
/// Both act on the captured colours as a per-channel factor (in linear light, and through a
/// power-law encoding, `(g·L)^γ = g^γ·L^γ`), so no offset is fitted: with one, a large shadow
/// trades gain for offset (docs/DECISIONS.md, "Real captures").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ColourCorrection {
    /// Per-channel gain.
    pub gain: [f32; 3],
}

impl ColourCorrection {
    /// No correction.
    pub const IDENTITY: ColourCorrection = ColourCorrection { gain: [1.0; 3] };

    /// `c` corrected.
    pub fn apply(&self, c: [f32; 3]) -> [f32; 3] {
        std::array::from_fn(|k| (self.gain[k] * c[k]).clamp(0.0, 1.0))
    }

    /// `rgb` corrected.
    pub fn image(&self, rgb: &[[f32; 3]]) -> Vec<[f32; 3]> {
        rgb.iter().map(|&x| self.apply(x)).collect()
    }

    /// `v` with its image corrected (a copy of `v` for the identity).
    pub fn view(&self, v: &View) -> View {
        match *self == ColourCorrection::IDENTITY {
            true => v.clone(),
            false => View { rgb: self.image(&v.rgb), intrinsics: v.intrinsics, pose: v.pose },
        }
    }

    /// Whether it is within [`IDENTITY_GAIN`] of the identity.
    pub fn is_negligible(&self) -> bool {
        self.gain.iter().all(|g| (g - 1.0).abs() <= IDENTITY_GAIN)
    }
}

/// Trimmed least-squares rounds of [`fit_correction`].
const FIT_ROUNDS: usize = 5;

/// The per-channel gain taking `scene`'s colours to `background`'s (same pixels), robust to the
/// pixels that really changed: least squares per channel (`g = Σxy / Σx²`) over the inlier
/// pixels, refitted `FIT_ROUNDS` times, a pixel an inlier while its worst channel's residual
/// is within 3 robust standard deviations (1.4826 × the median absolute residual, at least
/// 0.01). Starts from every pixel; the changed ones (a glass, its shadow: a minority) drop out
/// as the fit settles. Saturated pixels (a channel at 0 or 1 in either image) are left out: they
/// carry no gain.
pub fn fit_correction(scene: &[[f32; 3]], background: &[[f32; 3]]) -> ColourCorrection {
    let usable: Vec<usize> = (0..scene.len())
        .filter(|&p| (0..3).all(|k| scene[p][k] > 0.002 && scene[p][k] < 0.998 && background[p][k] < 0.998))
        .collect();
    if usable.len() < 16 {
        return ColourCorrection::IDENTITY;
    }
    let mut c = ColourCorrection::IDENTITY;
    let mut inliers = usable.clone();
    for _ in 0..FIT_ROUNDS {
        for k in 0..3 {
            let (mut sxx, mut sxy) = (0.0f64, 0.0f64);
            for &p in &inliers {
                let (x, y) = (scene[p][k] as f64, background[p][k] as f64);
                (sxx, sxy) = (sxx + x * x, sxy + x * y);
            }
            c.gain[k] = if sxx > 0.0 { (sxy / sxx) as f32 } else { 1.0 };
        }
        let worst = |p: usize| (0..3).map(|k| (c.gain[k] * scene[p][k] - background[p][k]).abs()).fold(0f32, f32::max);
        let r: Vec<f32> = usable.iter().map(|&p| worst(p)).collect();
        let mut sorted = r.clone();
        sorted.sort_by(f32::total_cmp);
        let limit = (3.0 * 1.4826 * sorted[sorted.len() / 2]).max(0.01);
        let kept: Vec<usize> = usable.iter().zip(&r).filter(|(_, &e)| e <= limit).map(|(&p, _)| p).collect();
        if kept.len() < 16 {
            break;
        }
        inliers = kept;
    }
    c
}

impl ScenePrior {
    /// `views` (the ones the prior was computed from) in the background's frame and
    /// appearance: each at its registered pose and its image through its [`ColourCorrection`]
    /// (views with neither are returned as they are).
    pub fn corrected_views(&self, views: &[View]) -> Vec<View> {
        let each = views.iter().zip(&self.registrations).zip(&self.corrections);
        each.map(|((v, r), c)| View { pose: registered_pose(v, r), ..c.view(v) }).collect()
    }

    /// Whether [`Self::corrected_views`] differ from the views given (a pose registered or an
    /// image corrected).
    pub fn corrects_views(&self) -> bool {
        self.registered_count() > 0 || self.corrected_count() > 0
    }

    /// How many views' poses were corrected.
    pub fn registered_count(&self) -> usize {
        self.registrations.iter().flatten().filter(|r| r.applied).count()
    }

    /// How many views' images are corrected.
    pub fn corrected_count(&self) -> usize {
        self.corrections.iter().filter(|c| **c != ColourCorrection::IDENTITY).count()
    }

    /// Share of the training pixels marked changed.
    pub fn changed_share(&self) -> f64 {
        self.focus.len() as f64 / self.maps.iter().map(Vec::len).sum::<usize>().max(1) as f64
    }

    /// Share of the training pixels whose ray crosses the region.
    pub fn reach_share(&self) -> f64 {
        self.reach.len() as f64 / self.maps.iter().map(Vec::len).sum::<usize>().max(1) as f64
    }
}

/// `v`'s pose after registration `r` (its own when none was applied).
fn registered_pose(v: &View, r: &Option<Registration>) -> crate::geometry::Pose {
    r.filter(|r| r.applied).map_or(v.pose, |r| r.pose)
}

/// Registers every view without a background image at its pose (`matched[i]` is `None`)
/// against `background` rendered at its pose (one render each; [`register_at`]). Returns the
/// registrations, and the renders of the views whose pose stays (the background there for
/// [`background_at`]).
#[allow(clippy::type_complexity)]
fn register_views(
    isa: Isa,
    background: &Nerf,
    views: &[View],
    matched: &[Option<usize>],
    sky: [f32; 3],
    m: DensityThreshold,
) -> (Vec<Option<Registration>>, Vec<Option<RenderedView>>) {
    let mut renderer = ViewRenderer::new();
    renderer.set_early_stop(PRIOR_EARLY_STOP, PRIOR_STOP_FILL);
    let scene = Scene::from(background);
    let each = views.iter().zip(matched);
    each.map(|(v, matched)| match matched {
        Some(_) => (None, None),
        None => {
            let (reg, r) = register_at(isa, &mut renderer, &scene, v, sky, m);
            (Some(reg), (!reg.applied).then_some(r))
        }
    })
    .unzip()
}

fn same_pose(a: &View, b: &View) -> bool {
    let (ka, kb) = (&a.intrinsics, &b.intrinsics);
    let same_k = ka.width == kb.width
        && ka.height == kb.height
        && ka.fx == kb.fx
        && ka.fy == kb.fy
        && ka.distortion == kb.distortion;
    let dr = (a.pose.rotation - b.pose.rotation).to_cols_array().iter().fold(0f32, |m, v| m.max(v.abs()));
    same_k && dr <= SAME_POSE && (a.pose.translation - b.pose.translation).abs().max_element() <= SAME_POSE
}

/// The background's threshold depth at its own images' poses, each rendered the first time a
/// scene view is matched to that image and held after: a robot trains its background once and
/// runs a scene phase each time objects appear, and the depth of the background where its own
/// images were taken is the same every time ([`crate::train::scene::SceneBackground`] keeps
/// one). For one background model and one list of its views; a threshold or solid fraction
/// other than the held depths' starts afresh.
#[derive(Clone, Debug, Default)]
pub(crate) struct BackgroundDepths {
    /// The threshold and the solid fraction the held depths were rendered with.
    key: Option<(DensityThreshold, f32)>,
    /// Per background view, its threshold z-depth once rendered (NaN at holes).
    depth: Vec<Option<Vec<f32>>>,
}

impl BackgroundDepths {
    /// How many background views' depths are held.
    pub(crate) fn held(&self) -> usize {
        self.depth.iter().flatten().count()
    }
}

/// The background at each of `views`' poses: its colours — the background image at the same
/// pose (`bg_views[matched[i]]`), else `background` rendered there (over `sky`) — and its
/// threshold z-depth at `m` (NaN at holes). A matched view's depth is the background's at its
/// image's pose, taken from `held` or rendered depth-only on the grid kept to the cells whose
/// value reached `solid_fraction · m · δ` ([`PriorConfig::depth_solid_fraction`]) and held; an
/// unmatched view's comes from its colour render (`rendered[i]` when given: view `i` rendered
/// at its pose already).
#[allow(clippy::too_many_arguments)]
fn background_at(
    isa: Isa,
    background: &Nerf,
    bg_views: &[View],
    held: &mut BackgroundDepths,
    views: &[View],
    matched: &[Option<usize>],
    rendered: Vec<Option<RenderedView>>,
    sky: [f32; 3],
    m: DensityThreshold,
    solid_fraction: f32,
) -> Vec<(Vec<[f32; 3]>, Vec<f32>)> {
    let key = Some((m, solid_fraction));
    if held.key != key || held.depth.len() != bg_views.len() {
        *held = BackgroundDepths { key, depth: vec![None; bg_views.len()] };
    }
    let mut renderer = ViewRenderer::new();
    renderer.set_early_stop(PRIOR_EARLY_STOP, PRIOR_STOP_FILL);
    let scene = Scene::from(background);
    // The thinned grid only when some matched view's depth is still to render.
    let grid = &background.occupancy;
    let depth_only = matched.iter().flatten().any(|&b| held.depth[b].is_none());
    let solid = depth_only.then(|| grid.keep_solid(solid_fraction, m.min_sigma()));
    let depth_scene = scene.with_grid(solid.as_ref());
    let each = views.iter().zip(matched).zip(rendered);
    each.map(|((v, matched), done)| match (done, *matched) {
        (Some(r), _) => (r.rgb, r.threshold_z),
        (None, Some(b)) => {
            let image = &bg_views[b];
            let z = held.depth[b].get_or_insert_with(|| {
                let k = &image.intrinsics;
                let mut z = vec![0.0; (k.width * k.height) as usize];
                renderer.depth(isa, &depth_scene, k, &image.pose, m, &mut z);
                z
            });
            (image.rgb.clone(), z.clone())
        }
        (None, None) => {
            let r = renderer.render(isa, &scene, &v.intrinsics, &v.pose, sky, m);
            (r.rgb, r.threshold_z)
        }
    })
    .collect()
}

/// 3×3 box filter (edges clamped).
pub(super) fn box3(img: &[[f32; 3]], w: usize, h: usize) -> Vec<[f32; 3]> {
    let mut out = vec![[0.0; 3]; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut acc = [0.0f32; 3];
            for dy in -1i64..=1 {
                for dx in -1i64..=1 {
                    let xx = (x as i64 + dx).clamp(0, w as i64 - 1) as usize;
                    let yy = (y as i64 + dy).clamp(0, h as i64 - 1) as usize;
                    let c = img[yy * w + xx];
                    (0..3).for_each(|k| acc[k] += c[k]);
                }
            }
            out[y * w + x] = acc.map(|v| v / 9.0);
        }
    }
    out
}

/// The change map of a scene image against the background's colours at the same pose (see the
/// module docs).
pub fn change_map(scene: &[[f32; 3]], background: &[[f32; 3]], w: u32, h: u32, cfg: &PriorConfig) -> Vec<bool> {
    dilate(&changed_pixels(scene, background, w, h, cfg), w, h, cfg.dilate_px)
}

/// The changed pixels of [`change_map`] before its dilation.
pub fn changed_pixels(scene: &[[f32; 3]], background: &[[f32; 3]], w: u32, h: u32, cfg: &PriorConfig) -> Vec<bool> {
    let (w, h) = (w as usize, h as usize);
    assert!(scene.len() == w * h && background.len() == w * h, "prior: images differ from width × height");
    let (a, b) = (box3(scene, w, h), box3(background, w, h));
    let raw: Vec<bool> = a.iter().zip(&b).map(|(p, q)| (0..3).any(|k| (p[k] - q[k]).abs() > cfg.tolerance)).collect();
    let at = |m: &[bool], x: i64, y: i64| {
        x >= 0 && y >= 0 && (x as usize) < w && (y as usize) < h && m[y as usize * w + x as usize]
    };
    let mut kept = vec![false; w * h];
    for y in 0..h as i64 {
        for x in 0..w as i64 {
            if at(&raw, x, y) {
                let n = (-1..=1).flat_map(|dy| (-1..=1).map(move |dx| (dx, dy))).filter(|&(dx, dy)| (dx, dy) != (0, 0));
                let count = n.filter(|&(dx, dy)| at(&raw, x + dx, y + dy)).count() as u32;
                kept[y as usize * w + x as usize] = count >= MIN_NEIGHBOURS;
            }
        }
    }
    kept
}

/// `map` (`w × h`, row-major) grown by `r` pixels (a square neighbourhood, clipped to the
/// image): along each row, then each column, a pixel is set when any pixel within `r` of it is,
/// from running counts of set pixels.
pub fn dilate(map: &[bool], w: u32, h: u32, r: u32) -> Vec<bool> {
    let (w, h, r) = (w as usize, h as usize, r as usize);
    assert_eq!(map.len(), w * h, "prior: map differs from width × height");
    let pass = |m: &[bool], along_rows: bool| -> Vec<bool> {
        let (lines, len) = if along_rows { (h, w) } else { (w, h) };
        let at = |line: usize, i: usize| if along_rows { line * w + i } else { i * w + line };
        let mut out = vec![false; w * h];
        let mut prefix = vec![0u32; len + 1];
        for line in 0..lines {
            for i in 0..len {
                prefix[i + 1] = prefix[i] + m[at(line, i)] as u32;
            }
            for i in 0..len {
                out[at(line, i)] = prefix[(i + r + 1).min(len)] > prefix[i.saturating_sub(r)];
            }
        }
        out
    };
    pass(&pass(map, true), false)
}

/// `map` (`w × h`, row-major) closed by a square of radius `r` (grown by `r`, then shrunk by
/// `r`, as on an image extended by unset pixels, so no set pixel is lost and nothing grows
/// towards the border), then with its holes filled: every unset pixel that no path of unset
/// pixels (4-connected) joins to the image's border is set.
pub fn close_and_fill(map: &[bool], w: u32, h: u32, r: u32) -> Vec<bool> {
    let (w, h, r) = (w as usize, h as usize, r as usize);
    assert_eq!(map.len(), w * h, "prior: map differs from width × height");
    // The closing on the image padded by `r`, where no pixel's window leaves the padded image:
    // grown, then shrunk (the pixels no unset pixel of the grown map is within `r` of).
    let (pw, ph) = (w + 2 * r, h + 2 * r);
    let mut padded = vec![false; pw * ph];
    for y in 0..h {
        padded[(y + r) * pw + r..(y + r) * pw + r + w].copy_from_slice(&map[y * w..(y + 1) * w]);
    }
    let unset: Vec<bool> = dilate(&padded, pw as u32, ph as u32, r as u32).iter().map(|&g| !g).collect();
    let near_unset = dilate(&unset, pw as u32, ph as u32, r as u32);
    let mut closed: Vec<bool> = (0..w * h).map(|i| !near_unset[(i / w + r) * pw + r + i % w]).collect();
    // The holes: unset pixels the border's unset pixels do not reach.
    let mut outside = vec![false; w * h];
    let mut stack: Vec<usize> = (0..w * h)
        .filter(|&i| {
            let (x, y) = (i % w, i / w);
            (x == 0 || y == 0 || x == w - 1 || y == h - 1) && !closed[i]
        })
        .collect();
    stack.iter().for_each(|&i| outside[i] = true);
    while let Some(i) = stack.pop() {
        let (x, y) = (i % w, i / w);
        let next =
            [(x > 0).then(|| i - 1), (x + 1 < w).then(|| i + 1), (y > 0).then(|| i - w), (y + 1 < h).then(|| i + w)];
        for j in next.into_iter().flatten() {
            if !closed[j] && !outside[j] {
                outside[j] = true;
                stack.push(j);
            }
        }
    }
    closed.iter_mut().zip(&outside).for_each(|(c, &o)| *c |= !o);
    closed
}

/// World point `p` in `v`'s image (through its lens): pixel coordinates and camera z-depth,
/// `None` when it is not in front of the camera (z ≤ 1 mm).
fn project(v: &View, p: Vec3) -> Option<(f32, f32, f32)> {
    let c = v.pose.rotation.transpose() * (p - v.pose.translation);
    v.intrinsics.project(c).map(|(u, v)| (u, v, -c.z))
}

/// Votes the change maps into a region over the cells of `grid` (the background's occupancy
/// grid), given the background's threshold z-depth per view (NaN at holes; module docs). With
/// [`PriorConfig::region_subdivide`] `k > 1` the region is voted again on a grid `k` times
/// finer, over the children of the coarse vote's cells and their neighbours (a fine cell
/// outside that shell is not voted), and dilated in fine cells.
pub fn vote_region(
    grid: &OccupancyGrid,
    views: &[View],
    maps: &[Vec<bool>],
    depth: &[Vec<f32>],
    cfg: &PriorConfig,
) -> ChangeRegion {
    assert!(views.len() == maps.len() && views.len() == depth.len(), "prior: one change map and depth per view");
    let (aabb, res) = (*grid.aabb(), grid.config().resolution);
    let min_views = ((cfg.min_seen * views.len() as f32).ceil() as u32).max(3);
    // Whether the cell at `p` (`margin` its diagonal) is changed.
    let changed = |p: Vec3, margin: f32| {
        let (mut seen, mut hit) = (0u32, 0u32);
        for ((v, map), zb) in views.iter().zip(maps).zip(depth) {
            let k = &v.intrinsics;
            let Some((px, py, zc)) = project(v, p) else { continue };
            if !(px >= 0.0 && py >= 0.0 && px < k.width as f32 && py < k.height as f32) {
                continue;
            }
            let pix = py as usize * k.width as usize + px as usize;
            let surface = zb[pix];
            // Behind the background's surface the view does not vote; at a hole in the
            // background's depth it votes when `holes_see`.
            let visible = match surface.is_finite() {
                true => zc <= surface + margin,
                false => cfg.holes_see,
            };
            if !visible {
                continue;
            }
            seen += 1;
            hit += map[pix] as u32;
        }
        seen >= min_views && hit as f32 >= cfg.vote * seen as f32
    };
    let empty = ChangeRegion::empty(aabb, res);
    let margin = (aabb.size() / res as f32).length();
    let plane = (res * res) as usize;
    let cells: Vec<u32> = (0..res as usize)
        .into_par_iter()
        .map(|z| {
            (z * plane..(z + 1) * plane)
                .filter(|&i| changed(empty.cell_centre(i), margin))
                .map(|i| i as u32)
                .collect::<Vec<_>>()
        })
        .collect::<Vec<_>>()
        .concat();
    let region = ChangeRegion::from_cells(aabb, res, &cells).expect("cells come from the grid");
    // At most as fine as a model file holds.
    let k = cfg.region_subdivide.clamp(1, (crate::geometry::region::MAX_RESOLUTION / res).max(1));
    if k == 1 {
        return region.dilated(cfg.region_dilate);
    }
    let candidates = region.dilated(1).subdivided(k);
    let fine_margin = margin / k as f32;
    let cells: Vec<u32> = candidates
        .cells()
        .into_par_iter()
        .filter(|&i| changed(candidates.cell_centre(i as usize), fine_margin))
        .collect();
    let region = ChangeRegion::from_cells(aabb, res * k, &cells).expect("cells come from the finer grid");
    region.dilated(cfg.region_dilate)
}

/// The pixels of `views` whose ray crosses a cell of `region` in front of the background's
/// threshold z-depth there (`depth`, per view; within a cell diagonal, as the vote; a hole in
/// the depth is no surface), as `(view, pixel)` in view then pixel order. Each cell is splatted
/// as the bounding box of its projected corners, so the set is conservative (a pixel just
/// beside a cell's silhouette may be in it, one whose ray crosses the cell is).
pub fn reach_pixels(region: &ChangeRegion, views: &[View], depth: &[Vec<f32>]) -> Vec<(u32, u32)> {
    assert_eq!(views.len(), depth.len(), "prior: one depth per view");
    let cells = region.cells();
    let size = region.aabb().size() / region.resolution() as f32;
    let margin = size.length();
    let per_view: Vec<Vec<(u32, u32)>> = views
        .par_iter()
        .zip(depth)
        .enumerate()
        .map(|(vi, (v, zb))| {
            let k = &v.intrinsics;
            let (w, h) = (k.width as usize, k.height as usize);
            let mut hit = vec![false; w * h];
            for &c in &cells {
                let lo = region.cell_centre(c as usize) - 0.5 * size;
                let (mut x0, mut y0, mut x1, mut y1) = (f32::MAX, f32::MAX, f32::MIN, f32::MIN);
                let mut near = f32::MAX;
                let mut behind = false;
                for corner in 0..8 {
                    let off = Vec3::new((corner & 1) as f32, (corner >> 1 & 1) as f32, (corner >> 2) as f32);
                    let Some((px, py, zc)) = project(v, lo + off * size) else {
                        behind = true;
                        break;
                    };
                    (x0, y0, x1, y1) = (x0.min(px), y0.min(py), x1.max(px), y1.max(py));
                    near = near.min(zc);
                }
                // A cell reaching behind the camera: every pixel may see it.
                let (xa, ya, xb, yb) = match behind {
                    true => (0, 0, w as i64 - 1, h as i64 - 1),
                    false => (x0.floor() as i64, y0.floor() as i64, x1.floor() as i64, y1.floor() as i64),
                };
                let (xa, ya) = (xa.max(0), ya.max(0));
                let (xb, yb) = (xb.min(w as i64 - 1), yb.min(h as i64 - 1));
                for y in ya..=yb {
                    for x in xa..=xb {
                        let pix = y as usize * w + x as usize;
                        let surface = zb[pix];
                        if behind || !surface.is_finite() || near <= surface + margin {
                            hit[pix] = true;
                        }
                    }
                }
            }
            hit.iter().enumerate().filter(|(_, &h)| h).map(|(p, _)| (vi as u32, p as u32)).collect()
        })
        .collect();
    per_view.into_iter().flatten().collect()
}

/// The whole prior of a scene: colours, change maps, region, focus and reach pixels.
pub fn scene_prior(
    isa: Isa,
    background: &Nerf,
    bg_views: &[View],
    views: &[View],
    sky: [f32; 3],
    m: DensityThreshold,
    cfg: &PriorConfig,
) -> ScenePrior {
    let mut fresh = BackgroundDepths::default();
    scene_prior_held(isa, background, bg_views, &mut fresh, views, sky, m, cfg)
}

/// [`scene_prior`] with the background's depths at its own images' poses taken from `held`
/// where it has them, and those it renders kept there (the same bits either way).
#[allow(clippy::too_many_arguments)]
pub(crate) fn scene_prior_held(
    isa: Isa,
    background: &Nerf,
    bg_views: &[View],
    held: &mut BackgroundDepths,
    views: &[View],
    sky: [f32; 3],
    m: DensityThreshold,
    cfg: &PriorConfig,
) -> ScenePrior {
    // A view at a background image's pose is compared with that image; the rest are
    // registered (when on) and compared with the background rendered at their pose.
    let matched: Vec<Option<usize>> = views.iter().map(|v| bg_views.iter().position(|b| same_pose(b, v))).collect();
    let (registrations, rendered) = match cfg.register {
        true => register_views(isa, background, views, &matched, sky, m),
        false => (vec![None; views.len()], (0..views.len()).map(|_| None).collect()),
    };
    let registered: Vec<View>;
    let views = match registrations.iter().flatten().any(|r| r.applied) {
        true => {
            let each = views.iter().zip(&registrations);
            registered = each.map(|(v, r)| View { pose: registered_pose(v, r), ..v.clone() }).collect();
            &registered[..]
        }
        false => views,
    };
    let bg =
        background_at(isa, background, bg_views, held, views, &matched, rendered, sky, m, cfg.depth_solid_fraction);
    let matched_views = matched.iter().flatten().count();
    let corrections: Vec<ColourCorrection> = views
        .par_iter()
        .zip(&bg)
        .map(|(v, (colours, _))| match cfg.exposure {
            true => Some(fit_correction(&v.rgb, colours))
                .filter(|c| !c.is_negligible())
                .unwrap_or(ColourCorrection::IDENTITY),
            false => ColourCorrection::IDENTITY,
        })
        .collect();
    // Per view: the map (the changed pixels dilated by `dilate_px`) and, when the β penalty's
    // pixels differ from it, the changed pixels closed and filled by its radius and dilated by
    // its margin. A view compared with the rendered background takes the renders' tolerance.
    let rendered_cfg = PriorConfig { tolerance: cfg.rendered_tolerance, ..*cfg };
    let (maps, spared_maps): (Vec<Vec<bool>>, Vec<Option<Vec<bool>>>) = views
        .par_iter()
        .zip(&bg)
        .zip(&corrections)
        .zip(&matched)
        .map(|(((v, (colours, _)), c), matched)| {
            let (w, h) = (v.intrinsics.width, v.intrinsics.height);
            let cfg = if matched.is_some() { cfg } else { &rendered_cfg };
            let changed = match *c == ColourCorrection::IDENTITY {
                true => changed_pixels(&v.rgb, colours, w, h, cfg),
                false => changed_pixels(&c.image(&v.rgb), colours, w, h, cfg),
            };
            let spared = match cfg.beta_close_px {
                0 => (cfg.beta_dilate_px != cfg.dilate_px).then(|| dilate(&changed, w, h, cfg.beta_dilate_px)),
                r => Some(dilate(&close_and_fill(&changed, w, h, r), w, h, cfg.beta_dilate_px)),
            };
            (dilate(&changed, w, h, cfg.dilate_px), spared)
        })
        .unzip();
    let (behind, depth): (Vec<Vec<[f32; 3]>>, Vec<Vec<f32>>) = bg.into_iter().unzip();
    let behind = std::sync::Arc::new(BackgroundColours::new(&behind));
    let region = vote_region(&background.occupancy, views, &maps, &depth, cfg);
    let reach = reach_pixels(&region, views, &depth);
    let focus = set_pixels(&maps);
    let spared = match spared_maps.into_iter().collect::<Option<Vec<_>>>() {
        Some(spared_maps) => set_pixels(&spared_maps),
        None => focus.clone(),
    };
    ScenePrior { maps, matched_views, region, focus, spared, reach, corrections, behind, registrations }
}

/// `(view, pixel)` of every set pixel of per-view maps, in view then pixel order.
fn set_pixels(maps: &[Vec<bool>]) -> Vec<(u32, u32)> {
    let each = maps.iter().enumerate();
    each.flat_map(|(i, map)| map.iter().enumerate().filter(|(_, &c)| c).map(move |(p, _)| (i as u32, p as u32)))
        .collect()
}

/// Which of the background's hints a residual model uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Prior {
    /// Start at the background: the residual NeRF a copy of the background's weights (and so
    /// of its architecture), the occupancy grid the background's.
    pub warm_start: bool,
    /// The voted change region: β = 0 outside it, its cells always marched.
    pub region: bool,
    /// Draw [`PriorConfig::change_share`] of the rays from changed pixels.
    pub focus: bool,
    /// The β regularisers of [`PriorConfig::beta`].
    pub beta: bool,
    /// With the region: draw the rays that are not focused from the pixels whose ray crosses
    /// the region ([`ScenePrior::reach`]) instead of from all pixels.
    pub reach: bool,
    /// Colour-only mixing where the background is solid (σ_bg at or above the default depth
    /// threshold, [`ResidualField::with_solid_background`]): shadows and caustics on the
    /// background's surfaces change their colour, never their depth.
    pub solid: bool,
}

impl Prior {
    /// None: the paper's Residual-NeRF.
    pub const NONE: Prior =
        Prior { warm_start: false, region: false, focus: false, beta: false, reach: false, solid: false };
    /// All: the background-aware Residual-NeRF (the default).
    pub const ALL: Prior = Prior { warm_start: true, region: true, focus: true, beta: true, reach: true, solid: false };
}

/// Where a residual model's training starts.
pub struct ResidualStart {
    /// The field (with its change region when the hints ask for one).
    pub field: ResidualField,
    /// Initial parameters.
    pub params: ResidualParams,
    /// Initial occupancy grid (the region's cells pinned).
    pub occupancy: OccupancyGrid,
    /// The focus pixels for [`TrainConfig::focus`], when the hints ask for them or for the β
    /// penalty (which reads them as the change maps; share 0 without the focus hint).
    pub focus: Option<Focus>,
    /// The β regularisers for [`TrainConfig::beta`] (off without the hint).
    pub beta: BetaRegulariser,
    /// What the density floor's fit reached, when there was one.
    pub lift: Option<LiftReport>,
    /// The background's colours at each training view's pose, with the region
    /// ([`TrainConfig::behind`]).
    pub behind: Option<std::sync::Arc<BackgroundColours>>,
}

impl ResidualStart {
    /// `cfg` with this start's focus pixels, background colours behind the region and β
    /// regularisers moved into it: the training config a [`crate::train::trainer::Trainer`]
    /// from this start reads.
    pub fn train_config(&mut self, cfg: &TrainConfig) -> TrainConfig {
        TrainConfig { focus: self.focus.take(), behind: self.behind.take(), beta: self.beta, ..cfg.clone() }
    }
}

/// The start of a residual model over `background` with `config` and `hints`, the scene's
/// `prior` (needed by every hint but none), seeded by `cfg.seed`. With `warm_start` the
/// residual takes the background's architecture (`config.residual` is replaced), so the mixed
/// field equals the background at step 0.
pub fn residual_start(
    isa: Isa,
    background: &Nerf,
    mut config: ResidualConfig,
    hints: Prior,
    prior: Option<&ScenePrior>,
    cfg: &TrainConfig,
    pcfg: &PriorConfig,
) -> ResidualStart {
    if hints.warm_start {
        config.residual = background.field.config().clone();
    }
    let aabb = config.residual.aabb;
    let mut field = ResidualField::new(background.clone(), config);
    if let (true, Some(p)) = (hints.region, prior) {
        field = field.with_region(p.region.clone());
    }
    if hints.solid && matches!(field.kind(), crate::field::mix::MixKind::Mixnet(_)) {
        field = field.with_solid_background(DensityThreshold::DEFAULT.min_sigma());
    }
    let mut rng = Rng::new(cfg.seed);
    let mut lifted = None;
    let mut params = match hints.warm_start {
        true => field.warm_params(&mut rng).expect("the residual has the background's architecture"),
        false => Model::init_params(&field, &mut rng),
    };
    if let (true, Some(region), Some(lift)) = (hints.warm_start, field.region(), &pcfg.lift) {
        let res = field.residual().clone();
        lifted = Some(lift_region(isa, &res, &mut params.residual, background, region, lift, cfg.seed));
    }
    let mut occupancy = match hints.warm_start {
        true => background.occupancy.clone(),
        false => OccupancyGrid::new(aabb, cfg.occupancy.clone()),
    };
    if let Some(region) = field.region() {
        if region.resolution().is_multiple_of(occupancy.config().resolution) {
            occupancy.pin(region);
            // Outside the region the field is the background, whose grid this is.
            if hints.warm_start {
                occupancy.freeze_outside_pins();
            }
        }
    }
    let share = if hints.focus { pcfg.change_share } else { 0.0 };
    let reach = hints.reach && hints.region;
    let focus = match (hints.focus || hints.beta || reach, prior) {
        (true, Some(p)) => Some(Focus {
            share,
            pixels: std::sync::Arc::new(p.focus.clone()),
            reach: reach.then(|| std::sync::Arc::new(p.reach.clone())),
            spared: (p.spared != p.focus).then(|| std::sync::Arc::new(p.spared.clone())),
        }),
        _ => None,
    };
    let beta = if hints.beta { pcfg.beta } else { BetaRegulariser::default() };
    let behind = prior.filter(|_| field.region().is_some()).map(|p| p.behind.clone());
    ResidualStart { field, params, occupancy, focus, beta, lift: lifted, behind }
}
