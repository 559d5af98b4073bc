//! `rnerf train`: dataset → NeRF → model file.

use super::{check_output_file, Progress};
use crate::data::{AabbSource, Dataset, LoadOptions};
use crate::encoding::HashGridConfig;
use crate::field::mix::{DensityMix, MixKind};
use crate::field::residual::ResidualConfig;
use crate::field::{Nerf, NerfConfig};
use crate::io::{load_model, save_nerf, save_residual, write_atomic, LoadedModel};
use crate::render::Aabb;
use crate::simd::Isa;
use crate::train::trainer::{train_nerf, train_residual, StepStats, TrainConfig};
use std::fmt::Write as _;
use std::path::Path;

/// Default training steps: with [`TRAIN_RAYS`], about 6.5 minutes for 100 views of 200×200 on
/// this project's 2-core machine (see README).
pub const TRAIN_STEPS: u32 = 1000;
/// Default rays per step (fixed per-step costs — Adam over the 16 M grid parameters — are
/// small beside 1024 rays, and more, smaller steps learn faster per second than 4096-ray ones
/// here; measured in README).
pub const TRAIN_RAYS: usize = 1024;

/// The trainer settings `rnerf train` uses for `steps` steps (its defaults, documented in the
/// README): [`TRAIN_RAYS`] rays per step, Adam at 1e-2 with step decay from 60% of the steps,
/// occupancy every 16 steps (all cells for the first 256).
pub fn default_train_config(steps: u32) -> TrainConfig {
    TrainConfig { rays_per_step: TRAIN_RAYS, ..TrainConfig::with_steps(steps) }
}

/// The grid and trainer settings of `rnerf train` and `rnerf compare`: the defaults
/// ([`default_train_config`], log2T = 19) with the command line's steps, rays, table size and
/// seed; images without alpha (every pixel shows a surface) train over random background
/// colours, others over white (what their alpha was composited over).
pub(super) fn trainer_settings(
    steps: Option<u32>,
    rays: Option<usize>,
    log2t: Option<u32>,
    seed: Option<u64>,
    had_alpha: bool,
) -> (HashGridConfig, TrainConfig) {
    let grid = HashGridConfig {
        log2_table_size: log2t.unwrap_or(HashGridConfig::default().log2_table_size),
        ..Default::default()
    };
    let mut cfg = default_train_config(steps.unwrap_or(TRAIN_STEPS));
    cfg.rays_per_step = rays.unwrap_or(cfg.rays_per_step);
    cfg.seed = seed.unwrap_or(cfg.seed);
    cfg.background = LoadOptions::default().background;
    cfg.random_background = !had_alpha;
    (grid, cfg)
}

/// Loads the frozen background model at `path` (given with `flag`): a plain NeRF.
pub(super) fn load_background(path: &Path, flag: &str) -> Result<Nerf, String> {
    match load_model(path).map_err(|e| format!("{flag}: {e}"))? {
        LoadedModel::Nerf(n) => Ok(*n),
        LoadedModel::Residual(_) => {
            Err(format!("{}: {flag}: a residual model; expected a plain NeRF of the empty workspace", path.display()))
        }
    }
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

pub(super) fn run(a: &crate::cli::TrainArgs) -> Result<(), String> {
    check_output_file(&a.out, "--out")?;
    if let Some(csv) = &a.csv {
        check_output_file(csv, "--csv")?;
    }
    // The background first: a wrong one must stop us before any work.
    let background = a.background.as_deref().map(|p| load_background(p, "--background")).transpose()?;
    let opts = LoadOptions { ground_truth: false, ..Default::default() };
    let mut data = Dataset::load(&a.data, &a.split, &opts).map_err(|e| e.to_string())?;
    if let (Some(bg), Some(p)) = (&background, &a.background) {
        adopt_background_box(&mut data, bg.field.config().aabb, p)?;
    }
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
    let (grid, mut cfg) = trainer_settings(a.steps, a.rays, a.log2t, a.seed, data.had_alpha);
    let field = NerfConfig { grid, aabb: data.aabb };
    cfg.distortion = a.distortion.unwrap_or(cfg.distortion);
    cfg.schedule.base = a.lr.unwrap_or(cfg.schedule.base);
    cfg.near_gradient_distance = a.near_grad.unwrap_or(cfg.near_gradient_distance);
    cfg.random_background &= a.random_bg.unwrap_or(true);
    let isa = Isa::detect();
    eprintln!(
        "rnerf train: {} steps x {} rays, log2 T = {}, distortion {}, seed {}, cpu level {isa}, {} threads",
        cfg.steps,
        cfg.rays_per_step,
        field.grid.log2_table_size,
        cfg.distortion,
        cfg.seed,
        rayon::current_num_threads()
    );
    let mut progress = Progress::new("train", cfg.steps as u64);
    let mut csv = String::from("step,seconds,loss,psnr,samples_per_ray,marched_per_ray,occupancy,lr\n");
    let log = |s: StepStats| {
        let psnr = -10.0 * (s.loss as f64).log10();
        let rays_per_s = (s.step + 1) as f64 * cfg.rays_per_step as f64 / s.seconds;
        let _ = writeln!(
            csv,
            "{},{:.3},{:.6},{psnr:.3},{:.2},{:.2},{:.4},{:.3e}",
            s.step + 1,
            s.seconds,
            s.loss,
            s.samples_per_ray,
            s.marched_per_ray,
            s.occupancy,
            cfg.schedule.lr(s.step)
        );
        progress.update(
            (s.step + 1) as u64,
            &format!(
                "{:.1} k rays/s  loss {:.5}  PSNR {psnr:.2} dB  {:.0}/{:.0} samples/ray",
                rays_per_s / 1e3,
                s.loss,
                s.samples_per_ray,
                s.marched_per_ray
            ),
        );
    };
    let mut extra = vec![
        ("train_steps", cfg.steps.to_string()),
        ("train_rays_per_step", cfg.rays_per_step.to_string()),
        ("train_seed", cfg.seed.to_string()),
        ("train_distortion", cfg.distortion.to_string()),
        ("train_lr", cfg.schedule.base.to_string()),
        ("train_random_background", cfg.random_background.to_string()),
        ("train_near_gradient_distance", cfg.near_gradient_distance.to_string()),
        ("train_data", a.data.display().to_string()),
        ("train_split", a.split.clone()),
    ];
    match background {
        None => {
            let nerf = train_nerf(isa, &data.views, field, &cfg, 10, log);
            extra.push(("train_seconds", format!("{:.1}", progress.seconds())));
            save_nerf(&a.out, &nerf, &extra)?;
        }
        Some(bg) => {
            let kind = a.mix.unwrap_or(MixKind::Mixnet(DensityMix::Raw));
            let mixnet = a.mixnet.unwrap_or_default();
            eprintln!(
                "rnerf train: residual model over {} ({kind:?}, Mixnet encoding {mixnet:?})",
                a.background.as_ref().unwrap().display()
            );
            let config = ResidualConfig { residual: field, kind, mixnet };
            let model = train_residual(isa, bg, &data.views, config, &cfg, 10, log);
            extra.push(("train_seconds", format!("{:.1}", progress.seconds())));
            extra.push(("background_file", a.background.as_ref().unwrap().display().to_string()));
            save_residual(&a.out, &model, &extra)?;
        }
    }
    if let Some(path) = &a.csv {
        write_atomic(path, csv.as_bytes())?;
    }
    eprintln!("rnerf train: wrote {} ({:.1} s)", a.out.display(), progress.seconds());
    Ok(())
}
