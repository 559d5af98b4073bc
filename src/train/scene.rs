//! The scene phase in one call: what a robot runs on board when objects appear in its
//! workspace. From the frozen background model, the background's images (at the poses the
//! scene is photographed from, where there are any) and the scene's posed images, all in
//! memory, to a trained residual model the onboard renderer takes
//! ([`crate::onboard::DepthRenderer::new`]) or [`crate::io::save_residual`] writes.
//!
//! The background side is a [`SceneBackground`], made once when the background is trained and
//! passed to every scene phase: it holds the background's depth at its images' poses, which
//! the prior needs and which is the same for every scene, so only the first scene phase renders
//! it (on the dev captures the prior then takes about a third of its time; docs/DECISIONS.md,
//! "The background's depths held between scene phases").
//!
//! It is the default background-aware Residual-NeRF, the same steps as `rnerf train --data SCENE
//! --background BG --background-data BACKGROUND` with the same settings, and the same bits
//! (test `the_librarys_scene_phase_trains_the_command_lines_model` in `tests/cli_train.rs`):
//! 1. the background's prior ([`crate::train::prior::scene_prior`]'s bits): change maps, the
//!    change region, the focus and reach pixels, each scene image's pose registered and
//!    exposure corrected against the background where that applies;
//! 2. the start at the background ([`residual_start`] with [`Prior::ALL`]): the residual a copy
//!    of the background, the Mixnet's β 0 outside the region, the background's occupancy grid;
//! 3. the residual's training ([`Trainer`]) on the corrected images, whose last step settles the
//!    region's occupancy for the onboard renderer.
//!
//! Views that are not usable (colours not one finite triple per pixel, intrinsics that are not
//! a camera, a non-finite pose) are refused with a one-line error naming the view and the field
//! ([`SceneError::Input`]) before anything runs.
//!
//! The caller owns the settings: `cfg` as for `rnerf train` (its steps, rays per step — the
//! command line takes [`TrainConfig::rays_for_views`] of the scene's views — seed and
//! background colour for images without alpha: [`TrainConfig::random_background`]), `pcfg`
//! the prior's ([`PriorConfig::default`] is the command line's).

use crate::data::View;
use crate::error::Error;
use crate::field::mix::{DensityMix, MixKind};
use crate::field::mixnet::MixnetEncoding;
use crate::field::residual::{ResidualConfig, ResidualModel};
use crate::field::Nerf;
use crate::render::DensityThreshold;
use crate::simd::Isa;
use crate::train::prior::{residual_start, scene_prior_held, BackgroundDepths, Prior, PriorConfig, ScenePrior};
use crate::train::trainer::{StepStats, TrainConfig, TrainError, Trainer};
use std::ops::ControlFlow;

/// A trained scene: the model and what the background's prior found.
pub struct SceneModel {
    /// Background, residual, Mixnet and the mixed field's occupancy grid.
    pub model: ResidualModel,
    /// The change maps, the region and the pixels the training drew from, the registered poses
    /// and the exposure corrections ([`ScenePrior::changed_share`], [`ScenePrior::region`], …).
    pub prior: ScenePrior,
    /// Wall seconds of the prior.
    pub prior_seconds: f64,
    /// Steps trained: the config's, or fewer when `log` stopped the run ([`train_scene`]).
    pub steps: u32,
    /// Seconds of training (the steps' own, as [`StepStats::seconds`]).
    pub train_seconds: f64,
}

/// Why [`train_scene`] stopped.
#[derive(Clone, Debug, PartialEq)]
pub enum SceneError {
    /// The views are not usable ([`crate::error::ErrorKind::BadInput`]; the message names the
    /// view and the field): no scene view, colours not one finite triple per pixel, intrinsics
    /// that are not a camera, a non-finite pose. Nothing was trained.
    Input(Error),
    /// The training stopped ([`TrainError`]): non-finite steps in a row, or rays that reach no
    /// occupied cell.
    Train(TrainError),
}

impl std::fmt::Display for SceneError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SceneError::Input(e) => write!(f, "{e}"),
            SceneError::Train(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for SceneError {}

impl From<TrainError> for SceneError {
    fn from(e: TrainError) -> SceneError {
        SceneError::Train(e)
    }
}

/// `Err` naming the first view of `views` (called `what`) that is not usable: colours not one
/// finite triple per pixel, intrinsics that are not a camera ([`crate::render::Intrinsics::check`]),
/// a non-finite pose ([`crate::render::Pose::check`]).
fn check_views(what: &str, views: &[View]) -> Result<(), Error> {
    for (i, v) in views.iter().enumerate() {
        let bad = |m: String| Error::bad_input(format!("{what} view {i}: {m}"));
        let k = &v.intrinsics;
        let n = k.width as usize * k.height as usize;
        if n == 0 || v.rgb.len() != n {
            return Err(bad(format!(
                "rgb holds {} colours, the camera has {}x{} = {n}",
                v.rgb.len(),
                k.width,
                k.height
            )));
        }
        if let Some(p) = v.rgb.iter().position(|c| !c.iter().all(|x| x.is_finite())) {
            return Err(bad(format!("rgb holds a non-finite colour at pixel {p}")));
        }
        k.check().map_err(bad)?;
        v.pose.check().map_err(bad)?;
    }
    Ok(())
}

/// The background side of the scene phase, kept from one scene phase to the next: the frozen
/// background model, its own images, and the background's depth at those images' poses, each
/// rendered the first time a scene view is matched to it and held after (the same bits as
/// rendering it again). A robot makes one when its background is trained and passes it to
/// every [`train_scene`]: a scene phase then spends nothing on the background's depth at the
/// poses it has already seen. It holds one `f32` per pixel of the matched background images (a
/// third of what their colours take in memory: 16 MB for 100 views of 200×200).
pub struct SceneBackground<'a> {
    model: &'a Nerf,
    views: &'a [View],
    depths: BackgroundDepths,
}

impl<'a> SceneBackground<'a> {
    /// The background `model` and its own images `views` (the views among them at a scene
    /// view's pose are that view's background colours; scene views at other poses are compared
    /// with the background rendered there; empty: every view is). `Err` names the first
    /// background view that is not usable ([`SceneError::Input`]).
    pub fn new(model: &'a Nerf, views: &'a [View]) -> Result<SceneBackground<'a>, SceneError> {
        check_views("background", views).map_err(SceneError::Input)?;
        Ok(SceneBackground { model, views, depths: BackgroundDepths::default() })
    }

    /// The background model.
    pub fn model(&self) -> &'a Nerf {
        self.model
    }

    /// How many of the background's images have their depth held.
    pub fn depths_held(&self) -> usize {
        self.depths.held()
    }

    /// The background's prior of the scene `views` ([`crate::train::prior::scene_prior`], the
    /// same bits), the background's depth at its images' poses read from what is held.
    pub fn prior(
        &mut self,
        isa: Isa,
        views: &[View],
        sky: [f32; 3],
        m: DensityThreshold,
        pcfg: &PriorConfig,
    ) -> ScenePrior {
        scene_prior_held(isa, self.model, self.views, &mut self.depths, views, sky, m, pcfg)
    }
}

/// Trains the default residual model of the scene `views` over `background` (its model and
/// its own images, [`SceneBackground`]). `log` sees every step and may end the run there
/// (`ControlFlow::Break`): a robot out of time, or a capture superseded. The model is then what
/// the steps so far trained, with the change region's occupancy settled as at the run's end
/// ([`Trainer::finish`]), so the onboard renderer reads it as it reads a finished one; the
/// learning rate follows the whole run's schedule up to there (docs/DECISIONS.md, "A scene
/// phase stopped early").
pub fn train_scene(
    isa: Isa,
    background: &mut SceneBackground<'_>,
    views: &[View],
    cfg: &TrainConfig,
    pcfg: &PriorConfig,
    mut log: impl FnMut(&StepStats) -> ControlFlow<()>,
) -> Result<SceneModel, SceneError> {
    if views.is_empty() {
        return Err(SceneError::Input(Error::bad_input("no scene views")));
    }
    check_views("scene", views).map_err(SceneError::Input)?;
    let clock = std::time::Instant::now();
    let prior = background.prior(isa, views, cfg.background, DensityThreshold::DEFAULT, pcfg);
    let prior_seconds = clock.elapsed().as_secs_f64();
    let background = background.model;
    let config = ResidualConfig {
        residual: background.field.config().clone(),
        kind: MixKind::Mixnet(DensityMix::Raw),
        mixnet: MixnetEncoding::Own(crate::train::sizing::mixnet_grid_for_box(&background.field.config().aabb)),
    };
    let mut start = residual_start(isa, background, config, Prior::ALL, Some(&prior), cfg, pcfg);
    let cfg = start.train_config(cfg);
    // In the background's frame and appearance when the prior registered a pose or corrected
    // the exposure.
    let corrected = prior.corrects_views().then(|| prior.corrected_views(views));
    let views = corrected.as_deref().unwrap_or(views);
    let mut trainer = Trainer::starting_at(isa, &start.field, views, &cfg, start.params, start.occupancy);
    while !trainer.is_done() {
        if log(&trainer.step()?).is_break() {
            break;
        }
    }
    let state = trainer.finish();
    Ok(SceneModel {
        model: ResidualModel { field: start.field, params: state.params, occupancy: state.occupancy },
        prior,
        prior_seconds,
        steps: state.step,
        train_seconds: state.seconds,
    })
}
