//! Training time to quality on a captured background and scene (`rnerf bench --background-data
//! BG --scene S`): the two figures a robot's update waits for, taken by the same training code
//! as `rnerf train` and `rnerf compare` at their defaults.
//!
//! - **The background** is trained from its images (every default: 1000 steps × 1024 rays,
//!   log2 T = 17); after every [`CURVE_EVERY`] steps its test PSNR is taken on
//!   [`PSNR_VIEWS`] evenly spaced views of the background's test split, and the first time it
//!   reaches [`TARGET_PSNR_DB`] gives `background_seconds_to_28db` (training seconds; the
//!   evaluations stop the clock).
//! - **The scene phase**: the default Residual-NeRF (`Method::RESIDUAL`, its prior included)
//!   over that background, curves every [`CURVE_EVERY`] steps as `rnerf compare` takes them;
//!   `scene_seconds_to_quality` is the training seconds to the first curve point whose
//!   object-mask MAE is within [`QUALITY_TOLERANCE`] of the final one (RESULTS.md's "own final
//!   within 5%"), and `scene_prior_seconds` what the prior took before it.
//!
//! Each figure is one measurement (no repetitions: a training run is minutes).

use super::report::{QualityFigures, Stat};
use crate::compare::{first_reaching, run_scene, CompareConfig, EvalSet, Method};
use crate::data::{evenly_spaced, View};
use crate::eval::{mse, psnr};
use crate::field::{Nerf, NerfField};
use crate::render::view::Scene;
use crate::render::{FullOutputs, ViewRenderer};
use crate::simd::Isa;
use crate::train::trainer::train_model_from;

/// The background's test PSNR to reach (the speed target's quality bar).
pub const TARGET_PSNR_DB: f64 = 28.0;
/// Steps between the evaluations of a curve.
pub const CURVE_EVERY: u32 = 100;
/// Test views the background's PSNR is taken on (evenly spaced over its test split; a full
/// 200×200 colour render costs ~2 s at AVX2, so the whole split at every point would take
/// longer than the training).
pub const PSNR_VIEWS: usize = 5;
/// "Its final quality": within this share of the final object-mask MAE.
pub const QUALITY_TOLERANCE: f64 = 0.05;

/// What the measurement needs: the background's training and test views, the scene's training
/// views (in the background's box) and test set with ground truth, and the settings (those of
/// `rnerf compare` at its defaults; the scene's curve every [`CURVE_EVERY`] steps).
pub struct QualityInputs<'a> {
    /// The background's training views.
    pub background_train: &'a [View],
    /// Its test views (colour only).
    pub background_test: &'a [View],
    /// The scene's training views.
    pub scene_train: &'a [View],
    /// The scene's test views with depth, masks and crops.
    pub scene_test: &'a EvalSet,
    /// Trainer, field and prior settings.
    pub cfg: &'a CompareConfig,
    /// The background's test PSNR to reach (`rnerf bench`: [`TARGET_PSNR_DB`]).
    pub target_psnr_db: f64,
}

/// Trains the background, then the default Residual-NeRF over it, and returns the figures.
pub fn measure(isa: Isa, input: &QualityInputs<'_>) -> Result<QualityFigures, String> {
    let cfg = input.cfg;
    let field = NerfField::new(cfg.field.clone());
    let psnr_views = evenly_spaced(input.background_test, PSNR_VIEWS);
    if psnr_views.is_empty() {
        return Err("bench: the background's test split has no views".into());
    }
    let mut renderer = ViewRenderer::<NerfField>::new();
    let mut rgb = Vec::new();
    let mut reached: Option<(f64, u32, f64)> = None;
    let steps = cfg.train.steps;
    let target = input.target_psnr_db;
    eprintln!("rnerf bench: background to {target} dB ({steps} steps, PSNR on {} test views)", psnr_views.len());
    let (params, occupancy) = train_model_from(
        isa,
        &field,
        cfg.field.aabb,
        input.background_train,
        &cfg.train_for(input.background_train),
        None,
        CURVE_EVERY,
        |s, params, occupancy| {
            if reached.is_some() {
                return;
            }
            let scene = Scene { model: &field, params, occupancy };
            let mut sum = 0.0;
            for v in &psnr_views {
                // Colour only, into one buffer: the other outputs are left empty, so not written.
                rgb.resize(v.rgb.len(), [0.0; 3]);
                let out = FullOutputs { rgb: &mut rgb, expected_z: &mut [], threshold_z: &mut [], beta: &mut [] };
                renderer.full(isa, &scene, &v.intrinsics, &v.pose, cfg.train.background, cfg.m, out);
                sum += psnr(mse(&rgb, &v.rgb));
            }
            let db = sum / psnr_views.len() as f64;
            eprintln!("rnerf bench: background step {}: test PSNR {db:.2} dB ({:.1} s)", s.step + 1, s.seconds);
            if db >= target {
                reached = Some((s.seconds, s.step + 1, db));
            }
        },
    )
    .map_err(|e| format!("bench: background: {e}"))?;
    let background = Nerf { field, params, occupancy };
    eprintln!("rnerf bench: the scene phase (the default Residual-NeRF, curve every {CURVE_EVERY} steps)");
    let mut scene_cfg = cfg.clone();
    scene_cfg.eval_every = CURVE_EVERY;
    let r = run_scene(
        isa,
        "scene",
        &background,
        input.background_train,
        input.scene_train,
        input.scene_test,
        &[Method::RESIDUAL],
        &scene_cfg,
        &mut |_, _| {},
    )?;
    let method = &r.methods[0];
    let prior = r.prior.ok_or("bench: the default method ran without its prior")?;
    let last = method.curve.last().ok_or("bench: the scene's curve is empty")?;
    let final_mae = last.errors.object.mae();
    let near = first_reaching(&method.curve, (1.0 + QUALITY_TOLERANCE) * final_mae).unwrap_or(last);
    if reached.is_none() {
        eprintln!("rnerf bench: the background did not reach {target} dB in {steps} steps");
    }
    let one = |v: f64| Some(Stat::exact(v));
    Ok(QualityFigures {
        background_seconds_to_28db: reached.and_then(|r| one(r.0)),
        background_steps_to_28db: reached.and_then(|r| one(r.1 as f64)),
        background_test_psnr_at_28db: reached.and_then(|r| one(r.2)),
        scene_prior_seconds: one(prior.seconds),
        scene_seconds_to_quality: one(near.seconds),
        scene_steps_to_quality: one(near.step as f64),
        scene_seconds: one(last.seconds),
        scene_final_object_mae_m: one(final_mae),
    })
}
