//! `rnerf train`: dataset → NeRF (or residual model) → model file, with checkpoints, resume
//! and graceful interruption.

use super::{check_output_file, Failure, Progress};
use crate::cli::TrainArgs;
use crate::data::{AabbSource, Dataset, LoadOptions};
use crate::encoding::HashGridConfig;
use crate::field::mix::{DensityMix, MixKind};
use crate::field::mixnet::MixnetEncoding;
use crate::field::residual::{ResidualConfig, ResidualModel};
use crate::field::{Nerf, NerfConfig, NerfField};
use crate::files::write_atomic;
use crate::io::model::{model_from_reader, read_model_bytes, ModelReader};
use crate::io::{load_checkpoint, save_checkpoint, save_model, views_fingerprint, LoadedModel, ModelFile};
use crate::render::{Aabb, Pose};
use crate::simd::Isa;
use crate::train::prior::{residual_start, scene_prior, ColourCorrection, Prior};
use crate::train::register::{registration_passes, Registration};
use crate::train::sizing;
use crate::train::trainer::{NearGradient, TrainConfig, Trainer, BACKGROUND_STEP_FACTOR};
use signal_hook::consts::{SIGINT, SIGTERM};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// The grid and trainer settings of `rnerf train` and `rnerf compare`: the defaults
/// ([`TrainConfig::default`], log2T = 17) with the command line's steps, rays, table size and
/// seed, the march step and the finest grid cell sized for the scene box `aabb`
/// ([`crate::train::sizing`]); images without alpha (every pixel shows a surface) train over
/// random background colours, others over white (what their alpha was composited over).
pub(super) fn trainer_settings(
    steps: Option<u32>,
    rays: Option<usize>,
    log2t: Option<u32>,
    seed: Option<u64>,
    had_alpha: bool,
    aabb: &Aabb,
) -> (HashGridConfig, TrainConfig) {
    let grid = HashGridConfig {
        log2_table_size: log2t.unwrap_or(HashGridConfig::default().log2_table_size),
        ..Default::default()
    };
    let grid = sizing::grid_for_box(grid, aabb, sizing::FIELD_CELL);
    let mut cfg = steps.map_or_else(TrainConfig::default, TrainConfig::with_steps);
    cfg.occupancy = sizing::occupancy_for_box(cfg.occupancy, aabb);
    cfg.rays_per_step = rays.unwrap_or(cfg.rays_per_step);
    cfg.seed = seed.unwrap_or(cfg.seed);
    cfg.random_background = !had_alpha;
    (grid, cfg)
}

/// A frozen background model as `rnerf train --background` and `rnerf compare
/// --background-model` load it.
pub(super) struct LoadedBackground {
    pub nerf: Nerf,
    /// The steps it trained for, when its file records them (`train_steps`, which `rnerf
    /// train` and `rnerf compare` write).
    pub train_steps: Option<u32>,
}

/// Loads the frozen background model at `path` (given with `flag`): a plain NeRF.
pub(super) fn load_background(path: &Path, flag: &str) -> Result<LoadedBackground, String> {
    let bytes = read_model_bytes(path).map_err(|e| format!("{flag}: {e}"))?;
    let in_file = |e: crate::error::Error| format!("{flag}: {}", e.context(path.display()));
    let reader = ModelReader::parse(&bytes).map_err(in_file)?;
    let train_steps = reader.metadata().get("train_steps").and_then(|s| s.parse().ok());
    match model_from_reader(&reader).map_err(in_file)? {
        LoadedModel::Nerf(n) => Ok(LoadedBackground { nerf: *n, train_steps }),
        LoadedModel::Residual(_) => {
            Err(format!("{}: {flag}: a residual model; expected a plain NeRF of the empty workspace", path.display()))
        }
    }
}

/// A one-line note when the background at `path` trained for fewer than
/// [`BACKGROUND_STEP_FACTOR`] × `scene_steps` steps (the protocol of docs/DECISIONS.md, "The
/// background trains for three times a scene's steps"): a sharper background gives better
/// depth of the glass. None when it did, or when its file does not say.
pub(super) fn background_steps_note(path: &Path, trained: Option<u32>, scene_steps: u32) -> Option<String> {
    let wanted = BACKGROUND_STEP_FACTOR.saturating_mul(scene_steps);
    let trained = trained.filter(|&t| t < wanted)?;
    Some(format!(
        "note: the background {} trained {trained} steps, fewer than {BACKGROUND_STEP_FACTOR} x this scene phase's \
         {scene_steps}; one trained {wanted} steps (rnerf train --steps {wanted}) gives better depth of the glass",
        path.display()
    ))
}

/// Gives `data` the background model's scene box `bg_box`; a dataset whose own `aabb` differs
/// is refused (a residual field lives in its background's box).
pub(super) fn adopt_background_box(data: &mut Dataset, bg_box: Aabb, bg_path: &Path) -> Result<(), String> {
    let same = (data.aabb.min - bg_box.min).abs().max_element() <= 1e-5
        && (data.aabb.max - bg_box.max).abs().max_element() <= 1e-5;
    if data.aabb_source == AabbSource::File && !same {
        return Err(format!(
            "{}: field 'aabb' {:?}..{:?} differs from the background {}'s scene box {:?}..{:?}",
            data.json.display(),
            data.aabb.min.to_array(),
            data.aabb.max.to_array(),
            bg_path.display(),
            bg_box.min.to_array(),
            bg_box.max.to_array()
        ));
    }
    data.aabb = bg_box;
    Ok(())
}

/// Where `rnerf train --out MODEL` keeps its checkpoint: MODEL with `.ckpt` before the
/// extension (`bg.safetensors` → `bg.ckpt.safetensors`).
pub fn checkpoint_path(out: &Path) -> PathBuf {
    let stem = out.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let name = match out.extension() {
        Some(ext) => format!("{stem}.ckpt.{}", ext.to_string_lossy()),
        None => format!("{stem}.ckpt"),
    };
    out.with_file_name(name)
}

pub(super) fn run(a: &TrainArgs) -> Result<(), Failure> {
    // `--budget` counts from here: loading and the background prior spend it too.
    let deadline = a.budget.map(|s| (s, Instant::now() + Duration::from_secs_f64(s)));
    check_output_file(&a.out, "--out")?;
    if let Some(csv) = &a.csv {
        check_output_file(csv, "--csv")?;
    }
    match &a.resume {
        None => fresh(a, deadline),
        Some(path) => resume(a, path, deadline),
    }
}

/// Loads the dataset of `a` (errors name it).
fn load_data(a: &TrainArgs) -> Result<Dataset, String> {
    let opts = LoadOptions { ground_truth: false, ..Default::default() };
    crate::app::load_data(&a.data, &a.split, &opts)
}

fn describe_data(data: &Dataset) {
    let (w, h) = (data.views[0].intrinsics.width, data.views[0].intrinsics.height);
    let source = match data.aabb_source {
        AabbSource::File => "from the json's 'aabb'",
        AabbSource::Cameras => "derived from the cameras (no 'aabb' in the json)",
    };
    eprintln!(
        "rnerf train: {} views ({w}x{h}) from {}; scene box {:?}..{:?} {source}",
        data.views.len(),
        data.json.display(),
        data.aabb.min.to_array(),
        data.aabb.max.to_array()
    );
    let lens: Vec<&str> = data.views.iter().map(|v| v.intrinsics.distortion.model_name()).collect();
    let distorted = lens.iter().filter(|&&m| m != "PINHOLE").count();
    let scale = match data.metres_per_unit {
        1.0 => "the json's unit is a metre".to_string(),
        m => format!("1 json unit = {m} m (metres_per_unit), positions converted to metres"),
    };
    eprintln!("rnerf train: scale: {scale}; lens: {distorted} of {} views distorted", lens.len());
}

/// `--budget`: its seconds and the instant they run out.
type Deadline = Option<(f64, Instant)>;

/// The step after which a budgeted run says, from its pace so far, whether the budget holds it.
const BUDGET_FORECAST_STEP: u32 = 20;

fn fresh(a: &TrainArgs, deadline: Deadline) -> Result<(), Failure> {
    // The background first: a wrong one must stop us before any work.
    let background = a.background.as_deref().map(|p| load_background(p, "--background")).transpose()?;
    let mut data = load_data(a)?;
    if let (Some(bg), Some(p)) = (&background, &a.background) {
        adopt_background_box(&mut data, bg.nerf.field.config().aabb, p)?;
    }
    if let Some(n) = a.scene_views {
        data.views = crate::data::evenly_spaced(&data.views, n);
    }
    describe_data(&data);
    let (grid, mut cfg) = trainer_settings(a.steps, a.rays, a.log2t, a.seed, data.had_alpha, &data.aabb);
    let field = NerfConfig { grid, aabb: data.aabb };
    cfg.distortion = a.distortion.unwrap_or(cfg.distortion);
    cfg.schedule.base = a.lr.unwrap_or(cfg.schedule.base);
    cfg.near_gradient = NearGradient::from_flag(a.near_grad, cfg.near_gradient);
    cfg.random_background &= a.random_bg.unwrap_or(true);
    cfg.frozen_stride = a.frozen_stride.unwrap_or(cfg.frozen_stride);
    cfg.frozen_tail = a.frozen_tail.unwrap_or(cfg.frozen_tail);
    (cfg.frozen_coarse, cfg.frozen_coarse_stride) =
        a.frozen_coarse.unwrap_or((cfg.frozen_coarse, cfg.frozen_coarse_stride));
    cfg.ray_pool = a.ray_pool.unwrap_or(cfg.ray_pool);
    cfg.image_gains = a.image_gains;
    cfg.error_map = a.error_map;
    cfg.pixel_jitter = a.pixel_jitter.unwrap_or(cfg.pixel_jitter);
    cfg.photo_tail = a.photo_tail.unwrap_or(cfg.photo_tail);
    cfg.pixel_rays = a.pixel_rays.unwrap_or(cfg.pixel_rays);
    if a.rays.is_none() {
        cfg.rays_per_step = cfg.rays_for_views(&data.views);
    }
    let isa = Isa::detect();
    describe_run(&cfg, field.grid.log2_table_size, isa);
    match (background, &a.background) {
        (Some(bg), Some(bg_path)) => {
            if let Some(note) = background_steps_note(bg_path, bg.train_steps, cfg.steps) {
                eprintln!("rnerf train: {note}");
            }
            let bg = bg.nerf;
            let kind = a.mix.unwrap_or(MixKind::Mixnet(DensityMix::Raw));
            let mixnet = match a.mixnet.unwrap_or_default() {
                MixnetEncoding::Own(_) => MixnetEncoding::Own(sizing::mixnet_grid_for_box(&data.aabb)),
                shared => shared,
            };
            let hints = a.prior.unwrap_or(match kind {
                MixKind::Mixnet(_) => Prior::ALL,
                MixKind::Sum => Prior::NONE,
            });
            eprintln!(
                "rnerf train: residual model over {} ({kind:?}, Mixnet encoding {mixnet:?}, background hints {hints:?})",
                bg_path.display()
            );
            let pcfg = a.prior_settings.config();
            let prior = (hints != Prior::NONE).then(|| {
                let bg_views = match &a.background_data {
                    Some(dir) => {
                        let opts = LoadOptions { ground_truth: false, ..Default::default() };
                        crate::app::load_data(dir, "train", &opts).map(|d| d.views)
                    }
                    None => Ok(Vec::new()),
                }?;
                let m = crate::render::DensityThreshold::DEFAULT;
                let p = scene_prior(isa, &bg, &bg_views, &data.views, cfg.background, m, &pcfg);
                eprintln!(
                    "rnerf train: background prior: {:.1}% of the pixels changed ({}/{} views against background \
                     images), change region {} cells ({:.4} m³), crossed by the rays of {:.1}% of the pixels",
                    100.0 * p.changed_share(),
                    p.matched_views,
                    data.views.len(),
                    p.region.count(),
                    p.region.volume(),
                    100.0 * p.reach_share()
                );
                Ok::<_, String>(p)
            });
            let prior = prior.transpose()?;
            if let Some(p) = prior.as_ref().filter(|p| p.registrations.iter().any(Option::is_some)) {
                let tried = p.registrations.iter().flatten().count();
                describe_registration(
                    "scene images' poses corrected against the background",
                    p.registrations.iter().flatten(),
                    tried,
                );
            }
            let (mut corrections, mut poses) = (None, None);
            if let Some(p) = prior.as_ref().filter(|p| p.corrects_views()) {
                let given: Vec<Pose> = data.views.iter().map(|v| v.pose).collect();
                data.views = p.corrected_views(&data.views);
                if p.registered_count() > 0 {
                    poses = Some(poses_json(&given, &data.views));
                }
                if p.corrected_count() > 0 {
                    corrections = Some(corrections_json(&p.corrections));
                    let c = p.corrections.iter().filter(|c| **c != ColourCorrection::IDENTITY);
                    let g = c.flat_map(|c| c.gain).fold((f32::MAX, f32::MIN), |(lo, hi), v| (lo.min(v), hi.max(v)));
                    eprintln!(
                        "rnerf train: exposure: {} of {} scene images corrected to the background's exposure and white balance \
                         (gains {:.3}..{:.3})",
                        p.corrected_count(),
                        data.views.len(),
                        g.0,
                        g.1
                    );
                }
            }
            let config = ResidualConfig { residual: field, kind, mixnet };
            let mut start = residual_start(isa, &bg, config, hints, prior.as_ref(), &cfg, &pcfg);
            let cfg = start.train_config(&cfg);
            if let Some(l) = start.lift {
                eprintln!("rnerf train: {l}");
            }
            let model = start.field;
            let residual = ResidualRun {
                background_file: bg_path.display().to_string(),
                prior: format!("{hints:?}"),
                corrections,
            };
            let extra = run_metadata(&cfg, a, Some(&residual), poses.as_deref());
            let trainer = Trainer::starting_at(isa, &model, &data.views, &cfg, start.params, start.occupancy);
            drive(a, &model, trainer, &extra, deadline)
        }
        _ => {
            // With registration: passes of a NeRF, every image registered against it, then the
            // run proper at the registered poses (docs/DECISIONS.md, "Registration against the
            // background"). The passes are not checkpointed: interrupted, they start again.
            let passes = match a.prior_settings.pose_registration {
                Some(true) => a.registration_passes.unwrap_or(1),
                _ => 0,
            };
            let given: Vec<Pose> = data.views.iter().map(|v| v.pose).collect();
            let mut progress: Option<(u32, Progress)> = None;
            let n = data.views.len();
            registration_passes(
                isa,
                &mut data.views,
                field.clone(),
                &cfg,
                passes,
                |pass, s| {
                    if progress.as_ref().is_none_or(|p| p.0 != pass) {
                        let name = format!("registration pass {pass}/{passes}");
                        progress = Some((pass, Progress::new(&name, cfg.steps as u64)));
                    }
                    let psnr = -10.0 * (s.loss as f64).log10();
                    progress.as_mut().expect("set above").1.update(s.step as u64 + 1, &format!("PSNR {psnr:.2} dB"));
                },
                |pass, regs| {
                    let what = format!("images' poses corrected against a NeRF of them (pass {pass}/{passes})");
                    describe_registration(&what, regs, n);
                },
            )
            .map_err(|e| format!("registration pass: {e}"))?;
            let poses = (passes > 0).then(|| poses_json(&given, &data.views));
            let model = NerfField::new(field);
            let extra = run_metadata(&cfg, a, None, poses.as_deref());
            let trainer = Trainer::new(isa, &model, data.aabb, &data.views, &cfg);
            drive(a, &model, trainer, &extra, deadline)
        }
    }
}

/// Logs what a registration did: how many of `n` views it moved and by how much.
fn describe_registration<'a>(what: &str, regs: impl IntoIterator<Item = &'a Registration>, n: usize) {
    let applied: Vec<&Registration> = regs.into_iter().filter(|r| r.applied).collect();
    let mut shifts: Vec<f64> = applied.iter().map(|r| r.shift_px).collect();
    shifts.sort_by(f64::total_cmp);
    let most = applied.iter().fold((0f64, 0f64), |m, r| (m.0.max(r.degrees), m.1.max(r.distance)));
    match shifts.last() {
        None => eprintln!("rnerf train: registration: none of {n} {what}"),
        Some(largest) => eprintln!(
            "rnerf train: registration: {} of {n} {what} (median {:.2} px, largest {largest:.2} px; up to {:.2} degrees \
             and {:.4} scene units)",
            shifts.len(),
            shifts[shifts.len() / 2],
            most.0,
            most.1
        ),
    }
}

/// What a residual run adds to its model file's metadata (a checkpoint carries it to the resumed run).
struct ResidualRun {
    background_file: String,
    prior: String,
    /// The scene images' colour corrections as JSON (`[[gain×3], …]` per view), when
    /// any was applied: a resumed run applies them again before checking its data.
    corrections: Option<String>,
}

/// Metadata keys of [`ResidualRun`].
const BACKGROUND_FILE: &str = "background_file";
const TRAIN_PRIOR: &str = "train_prior";
const COLOUR_CORRECTIONS: &str = "train_colour_corrections";
const REGISTERED_POSES: &str = "train_registered_poses";

/// Per view, `null` where `trained` keeps the `given` pose, else the pose it trained at.
fn poses_json(given: &[Pose], trained: &[crate::data::View]) -> String {
    let rows: Vec<Option<[[f32; 4]; 3]>> =
        given.iter().zip(trained).map(|(g, t)| (*g != t.pose).then(|| t.pose.to_rows())).collect();
    serde_json::to_string(&rows).expect("plain json")
}

/// The scene views at the poses `json` records (the inverse of [`poses_json`]).
fn apply_poses(views: &mut [crate::data::View], json: &str) -> Result<(), String> {
    let rows: Vec<Option<[[f32; 4]; 3]>> =
        serde_json::from_str(json).map_err(|e| format!("metadata '{REGISTERED_POSES}' is not a list of poses: {e}"))?;
    if rows.len() != views.len() {
        return Err(format!("metadata '{REGISTERED_POSES}' holds {} poses for {} views", rows.len(), views.len()));
    }
    for (v, r) in views.iter_mut().zip(rows) {
        if let Some(r) = r {
            v.pose = Pose::from_rows(r);
        }
    }
    Ok(())
}

fn corrections_json(c: &[ColourCorrection]) -> String {
    let rows: Vec<[f32; 3]> = c.iter().map(|c| c.gain).collect();
    serde_json::to_string(&rows).expect("plain json")
}

/// The scene views through the corrections `json` records (the inverse of [`corrections_json`]).
fn apply_corrections(views: &mut [crate::data::View], json: &str) -> Result<(), String> {
    let rows: Vec<[f32; 3]> = serde_json::from_str(json)
        .map_err(|e| format!("metadata '{COLOUR_CORRECTIONS}' is not a list of corrections: {e}"))?;
    if rows.len() != views.len() {
        return Err(format!(
            "metadata '{COLOUR_CORRECTIONS}' holds {} corrections for {} views",
            rows.len(),
            views.len()
        ));
    }
    for (v, r) in views.iter_mut().zip(rows) {
        *v = ColourCorrection { gain: r }.view(v);
    }
    Ok(())
}

/// The metadata of a model file `rnerf train` writes (and of its checkpoints): the run's
/// settings, data and, for a residual model, its background and hints. One builder for fresh
/// and resumed runs, so a resumed model carries what an uninterrupted one does. `poses`: the
/// training images' registered poses as JSON ([`poses_json`]), when any was registered: a
/// resumed run applies them again before checking its data.
fn run_metadata(
    cfg: &TrainConfig,
    a: &TrainArgs,
    residual: Option<&ResidualRun>,
    poses: Option<&str>,
) -> Vec<(&'static str, String)> {
    let mut m = vec![
        ("train_steps", cfg.steps.to_string()),
        ("train_rays_per_step", cfg.rays_per_step.to_string()),
        ("train_seed", cfg.seed.to_string()),
        ("train_distortion", cfg.distortion.to_string()),
        ("train_lr", cfg.schedule.base.to_string()),
        ("train_random_background", cfg.random_background.to_string()),
        ("train_near_gradient", format!("{:?}", cfg.near_gradient)),
        ("train_frozen_stride", cfg.frozen_stride.to_string()),
        ("train_frozen_tail", cfg.frozen_tail.to_string()),
        ("train_frozen_coarse", format!("{},{}", cfg.frozen_coarse, cfg.frozen_coarse_stride)),
        ("train_ray_pool", cfg.ray_pool.to_string()),
        ("train_image_gains", cfg.image_gains.map_or("off".into(), |l| format!("on (prior {l})"))),
        ("train_error_map", cfg.error_map.map_or("off".into(), |s| format!("share {s}"))),
        ("train_pixel_jitter", cfg.pixel_jitter.to_string()),
        ("train_photo_tail", cfg.photo_tail.to_string()),
        ("train_pixel_rays", cfg.pixel_rays.to_string()),
        ("train_data", a.data.display().to_string()),
        ("train_split", a.split.clone()),
    ];
    if let Some(r) = residual {
        m.push((BACKGROUND_FILE, r.background_file.clone()));
        m.push((TRAIN_PRIOR, r.prior.clone()));
        if let Some(c) = &r.corrections {
            m.push((COLOUR_CORRECTIONS, c.clone()));
        }
    }
    if let Some(p) = poses {
        m.push((REGISTERED_POSES, p.to_string()));
    }
    m
}

fn describe_run(cfg: &TrainConfig, log2t: u32, isa: Isa) {
    eprintln!(
        "rnerf train: {} steps x {} rays, log2 T = {log2t}, distortion {}, seed {}, cpu level {isa}, {} threads",
        cfg.steps,
        cfg.rays_per_step,
        cfg.distortion,
        cfg.seed,
        rayon::current_num_threads()
    );
    if let Some(prior) = cfg.image_gains {
        eprintln!("rnerf train: learning a gain per image and colour channel (identity prior {prior})");
    }
}

/// `--resume`: the model, optimiser state and settings from the checkpoint; the data must be
/// the data it was trained on.
fn resume(a: &TrainArgs, path: &Path, deadline: Deadline) -> Result<(), Failure> {
    let (model, checkpoint) = load_checkpoint(path).map_err(|e| format!("--resume: {e}"))?;
    let mut data = load_data(a)?;
    let aabb = match &model {
        LoadedModel::Nerf(n) => n.field.config().aabb,
        LoadedModel::Residual(m) => m.field.residual().config().aabb,
    };
    data.aabb = aabb;
    describe_data(&data);
    if let Some(json) = checkpoint.metadata.get(REGISTERED_POSES) {
        apply_poses(&mut data.views, json).map_err(|e| format!("--resume: {}: {e}", path.display()))?;
    }
    if let Some(json) = checkpoint.metadata.get(COLOUR_CORRECTIONS) {
        apply_corrections(&mut data.views, json).map_err(|e| format!("--resume: {}: {e}", path.display()))?;
    }
    if views_fingerprint(&data.views) != checkpoint.fingerprint {
        return Err(format!(
            "{}: split '{}' is not the data the checkpoint {} was trained on (its views, poses or pixels differ)",
            data.json.display(),
            a.split,
            path.display()
        )
        .into());
    }
    let isa = Isa::detect();
    let cfg = checkpoint.config.clone();
    let residual = match (checkpoint.metadata.get(BACKGROUND_FILE), checkpoint.metadata.get(TRAIN_PRIOR)) {
        (Some(b), Some(p)) => Some(ResidualRun {
            background_file: b.clone(),
            prior: p.clone(),
            corrections: checkpoint.metadata.get(COLOUR_CORRECTIONS).cloned(),
        }),
        _ => None,
    };
    let poses = checkpoint.metadata.get(REGISTERED_POSES).map(String::as_str);
    let mut extra = run_metadata(&cfg, a, residual.as_ref(), poses);
    extra.push(("train_resumed_from", format!("{} at step {}", path.display(), checkpoint.step)));
    eprintln!("rnerf train: resuming {} at step {} of {}", path.display(), checkpoint.step, cfg.steps);
    let at = |e: String| format!("--resume: {}: {e}", path.display());
    match model {
        LoadedModel::Nerf(n) => {
            let Nerf { field, params, occupancy } = *n;
            describe_run(&cfg, field.config().grid.log2_table_size, isa);
            let state = checkpoint.into_state(&field, params, occupancy).map_err(at)?;
            let trainer = Trainer::from_state(isa, &field, &data.views, &cfg, state).map_err(at)?;
            drive(a, &field, trainer, &extra, deadline)
        }
        LoadedModel::Residual(m) => {
            let ResidualModel { field, params, occupancy } = *m;
            describe_run(&cfg, field.residual().config().grid.log2_table_size, isa);
            let state = checkpoint.into_state(&field, params, occupancy).map_err(at)?;
            let trainer = Trainer::from_state(isa, &field, &data.views, &cfg, state).map_err(at)?;
            drive(a, &field, trainer, &extra, deadline)
        }
    }
}

/// Runs `trainer` to the end with progress, the metrics log, checkpoints every
/// `--checkpoint-every` steps, and SIGINT / SIGTERM handling (finish the step, checkpoint,
/// exit 128 + signal); writes the model to `--out` and removes the checkpoint. A run that
/// fails ([`crate::train::trainer::TrainError`]) checkpoints its last good state and fails.
/// Past `deadline` (`--budget`) the run ends after the current step ([`Trainer::finish`]) and
/// its model is written as a finished run's, with the steps it took in its metadata.
fn drive<M: ModelFile>(
    a: &TrainArgs,
    model: &M,
    mut trainer: Trainer<'_, M>,
    extra: &[(&str, String)],
    deadline: Deadline,
) -> Result<(), Failure> {
    let signal = Arc::new(AtomicUsize::new(0));
    let seen = Arc::new(AtomicBool::new(false));
    for sig in [SIGINT, SIGTERM] {
        // Handlers run in registration order: a signal after one was already seen (e.g. while
        // the checkpoint is written) ends the process at once; the first only marks it.
        signal_hook::flag::register_conditional_shutdown(sig, 128 + sig, seen.clone())
            .and_then(|_| signal_hook::flag::register(sig, seen.clone()))
            .and_then(|_| signal_hook::flag::register_usize(sig, signal.clone(), sig as usize))
            .map_err(|e| format!("cannot install the signal handler: {e}"))?;
    }
    let cfg = trainer.config().clone();
    let near = trainer.near_distance();
    if near > 0.0 {
        eprintln!("rnerf train: gradients scaled down within {near} of each camera ({:?})", cfg.near_gradient);
    }
    let mut extra = extra.to_vec();
    extra.push(("train_near_gradient_distance", near.to_string()));
    let extra = &extra[..];
    let ckpt = checkpoint_path(&a.out);
    let fingerprint = views_fingerprint(trainer.views());
    let save_checkpoint_now = |trainer: &Trainer<'_, M>| -> Result<(), String> {
        save_checkpoint(&ckpt, model, trainer.state(), &cfg, fingerprint, extra)
    };
    let mut progress = Progress::new("train", cfg.steps as u64);
    let mut csv = String::from("step,seconds,loss,psnr,samples_per_ray,marched_per_ray,occupancy,lr,skipped\n");
    let mut stopped = None;
    while !trainer.is_done() {
        let sig = signal.load(Ordering::SeqCst);
        if sig != 0 {
            save_checkpoint_now(&trainer)?;
            let step = trainer.state().step;
            return Err(Failure {
                message: format!(
                    "interrupted (signal {sig}) after step {step}; checkpoint written to {} — continue with \
                     'rnerf train --resume {} --data {} --out {}'",
                    ckpt.display(),
                    ckpt.display(),
                    a.data.display(),
                    a.out.display()
                ),
                code: 128 + sig as u8,
            });
        }
        let s = match trainer.step() {
            Ok(s) => s,
            Err(e) => {
                let saved = match save_checkpoint_now(&trainer) {
                    Ok(()) => format!("last good state saved to {}", ckpt.display()),
                    Err(w) => format!("last good state not saved: {w}"),
                };
                return Err(format!("{e}; {saved}").into());
            }
        };
        let done = s.step + 1;
        let out_of_time = deadline.is_some_and(|(_, at)| Instant::now() >= at);
        if let Some((seconds, at)) = deadline.filter(|_| done == BUDGET_FORECAST_STEP && done < cfg.steps) {
            // Once, from the pace so far: whether the budget holds the run's steps.
            let pace = s.seconds / done as f64;
            let left = at.saturating_duration_since(Instant::now()).as_secs_f64();
            let need = pace * (cfg.steps - done) as f64;
            if need > left {
                eprintln!(
                    "rnerf train: at {:.0} ms a step the last {} steps need about {need:.0} s, and --budget {seconds} s \
                     leaves {left:.0}: the run will stop near step {}; fewer --rays a step buy more steps \
                     (RESULTS.md, \"A scene phase with a time budget\")",
                    pace * 1e3,
                    cfg.steps - done,
                    done + (left / pace) as u32
                );
            }
        }
        if done % 10 == 0 || done == cfg.steps || out_of_time {
            let psnr = -10.0 * (s.loss as f64).log10();
            let rays_per_s = done as f64 * cfg.rays_per_step as f64 / s.seconds.max(1e-9);
            let _ = writeln!(
                csv,
                "{done},{:.3},{:.6},{psnr:.3},{:.2},{:.2},{:.4},{:.3e},{}",
                s.seconds,
                s.loss,
                s.samples_per_ray,
                s.marched_per_ray,
                s.occupancy,
                cfg.schedule.lr(s.step),
                s.skipped
            );
            progress.update(
                done as u64,
                &format!(
                    "{:.1} k rays/s  loss {:.5}  PSNR {psnr:.2} dB  {:.0}/{:.0} samples/ray{}",
                    rays_per_s / 1e3,
                    s.loss,
                    s.samples_per_ray,
                    s.marched_per_ray,
                    if s.skipped > 0 { format!("  {} skipped", s.skipped) } else { String::new() }
                ),
            );
        }
        if a.checkpoint_every.is_some_and(|n| done % n == 0) && done < cfg.steps {
            save_checkpoint_now(&trainer)?;
        }
        if let Some((seconds, at)) = deadline.filter(|_| out_of_time && done < cfg.steps) {
            let late = Instant::now().duration_since(at).as_secs_f64();
            eprintln!(
                "rnerf train: --budget {seconds} s spent ({late:.2} s over) after step {done} of {}; writing the model \
                 of the steps so far",
                cfg.steps
            );
            stopped = Some(format!("after step {done} of {} (--budget {seconds} s)", cfg.steps));
            break;
        }
    }
    let state = trainer.finish();
    let mut extra = extra.to_vec();
    if let Some(s) = stopped {
        extra.push(("train_stopped", s));
    }
    if let Some(g) = &state.gains {
        // The learned gains: in the log as a range per channel, in the model as JSON rows.
        let gains = g.gains();
        let range = |c: usize| gains.iter().fold((f32::MAX, f32::MIN), |(lo, hi), g| (lo.min(g[c]), hi.max(g[c])));
        let [r, gr, b] = [range(0), range(1), range(2)];
        eprintln!(
            "rnerf train: learned image gains r {:.3}..{:.3}, g {:.3}..{:.3}, b {:.3}..{:.3} (geometric mean 1)",
            r.0, r.1, gr.0, gr.1, b.0, b.1
        );
        extra.push(("train_image_gains_learned", serde_json::to_string(&gains).expect("finite gains")));
    }
    extra.push(("train_seconds", format!("{:.1}", state.seconds)));
    extra.push(("train_skipped_steps", state.skipped.to_string()));
    save_model(&a.out, model, &state.params, &state.occupancy, &extra)?;
    if ckpt.exists() {
        std::fs::remove_file(&ckpt).map_err(|e| format!("{}: cannot remove the checkpoint: {e}", ckpt.display()))?;
    }
    if let Some(path) = &a.csv {
        write_atomic(path, csv.as_bytes())?;
    }
    eprintln!("rnerf train: wrote {} ({:.1} s)", a.out.display(), progress.seconds());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The note on a background trained for fewer than three times the scene phase's steps:
    /// there below the protocol, silent at or above it and when the file does not say.
    #[test]
    fn a_background_short_of_three_times_the_scene_steps_is_noted() {
        let p = Path::new("bg.safetensors");
        let note = background_steps_note(p, Some(1000), 1000).expect("1000 < 3 x 1000");
        assert!(note.contains("bg.safetensors trained 1000 steps") && note.contains("--steps 3000"), "{note}");
        assert_eq!(background_steps_note(p, Some(3000), 1000), None);
        assert_eq!(background_steps_note(p, Some(1800), 600), None);
        assert_eq!(background_steps_note(p, None, 1000), None);
    }

    /// A resumed run applies the corrections its checkpoint records: the same images as the
    /// fresh run trained on, so the views' fingerprint matches.
    #[test]
    fn recorded_colour_corrections_give_the_same_views_back() {
        let scene = crate::data::workspace::workspace(8, 3, 0.0, true);
        let c = [
            ColourCorrection { gain: [0.8, 1.0, 1.2] },
            ColourCorrection::IDENTITY,
            ColourCorrection { gain: [1.1; 3] },
        ];
        let fresh: Vec<crate::data::View> = scene
            .views
            .iter()
            .zip(&c)
            .map(|(v, c)| crate::data::View { rgb: v.rgb.iter().map(|&x| c.apply(x)).collect(), ..v.clone() })
            .collect();
        let mut resumed = scene.views.clone();
        apply_corrections(&mut resumed, &corrections_json(&c)).unwrap();
        assert_eq!(views_fingerprint(&resumed), views_fingerprint(&fresh));
        assert!(apply_corrections(&mut resumed, "[[1,1,1]]").unwrap_err().contains("1 corrections for 3 views"));
    }

    /// A resumed run trains at the poses its checkpoint records (registered ones moved, the
    /// rest as given), so the views' fingerprint matches the fresh run's.
    #[test]
    fn recorded_poses_give_the_same_views_back() {
        let scene = crate::data::workspace::workspace(8, 3, 0.0, true);
        let mut fresh = scene.views.clone();
        fresh[1].pose = crate::data::workspace::jitter(fresh[1].pose, 0.004, 0.3, crate::rng::Rng::new(5));
        let given: Vec<Pose> = scene.views.iter().map(|v| v.pose).collect();
        let json = poses_json(&given, &fresh);
        assert!(json.starts_with("[null,[[") && json.ends_with("]],null]"), "{json}");
        let mut resumed = scene.views.clone();
        apply_poses(&mut resumed, &json).unwrap();
        assert_eq!(views_fingerprint(&resumed), views_fingerprint(&fresh));
        assert_ne!(views_fingerprint(&resumed), views_fingerprint(&scene.views));
        assert!(apply_poses(&mut resumed, "[null]").unwrap_err().contains("1 poses for 3 views"));
    }
}
