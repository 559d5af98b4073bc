//! `rnerf compare` (the paper's protocol on a dataset) and `rnerf demo` (the same on a
//! synthesised workspace): both end in [`compare_and_write`].

use super::train::{adopt_background_box, background_steps_note, load_background, trainer_settings};
use super::Progress;
use crate::compare::{self, CompareConfig, EvalSet, Method, SceneResult};
use crate::data::workspace::{self, SKY};
use crate::data::View;
use crate::data::{Dataset, FrameType, LoadOptions};
use crate::encoding::HashGridConfig;
use crate::field::{Nerf, NerfConfig};
use crate::files::{export, write_atomic};
use crate::io::save_nerf;
use crate::render::{Aabb, OccupancyConfig};
use crate::simd::Isa;
use crate::train::trainer::{train_nerf, StepStats, TrainConfig};
use serde_json::json;
use std::path::Path;

/// One scene ready to compare.
pub struct SceneData {
    /// Name (folder name).
    pub name: String,
    /// Training views.
    pub train: Vec<View>,
    /// Test views with ground truth.
    pub test: EvalSet,
}

/// The background's own training images, for change maps against images at the same pose (none
/// when the background dataset cannot be read: the prior then renders the background model).
fn background_views(dir: &Path) -> Vec<View> {
    let opts = LoadOptions { ground_truth: false, frame_type: Some(FrameType::Background), ..Default::default() };
    match crate::app::load_data(dir, "train", &opts) {
        Ok(d) => d.views,
        Err(e) => {
            eprintln!("rnerf compare: background images not read ({e}); change maps use the rendered background");
            Vec::new()
        }
    }
}

/// A scene's training views (in the background's box) and its test views with ground truth.
fn load_scene(dir: &Path, bg_box: Aabb, bg_path: &Path) -> Result<(Dataset, EvalSet), String> {
    let train_opts = LoadOptions { ground_truth: false, frame_type: Some(FrameType::Scene), ..Default::default() };
    let mut train = crate::app::load_data(dir, "train", &train_opts)?;
    adopt_background_box(&mut train, bg_box, bg_path)?;
    let test_opts = LoadOptions { frame_type: Some(FrameType::Scene), ..Default::default() };
    let test = crate::app::load_data(dir, "test", &test_opts)?;
    Ok((train, EvalSet::from_dataset(&test)?))
}

/// The background of a comparison: a given model, or the dataset to train it on.
enum Background {
    /// Loaded, with the steps its file says it trained for.
    Model(Box<Nerf>, Option<u32>),
    Data(Dataset),
}

fn scene_name(dir: &Path) -> String {
    let name = dir.canonicalize().ok().and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()));
    name.unwrap_or_else(|| "scene".into())
}

pub(super) fn run(a: &crate::cli::CompareArgs) -> Result<(), String> {
    // Every input is read and checked before any training.
    if a.background_model.is_some() && a.background_steps.is_some() {
        return Err("--background-steps: the background is loaded from --background-model, not trained".into());
    }
    let background = match &a.background_model {
        Some(p) => {
            let b = load_background(p, "--background-model")?;
            Background::Model(Box::new(b.nerf), b.train_steps)
        }
        None => {
            let opts =
                LoadOptions { ground_truth: false, frame_type: Some(FrameType::Background), ..Default::default() };
            Background::Data(crate::app::load_data(&a.background, "train", &opts)?)
        }
    };
    let aabb = match &background {
        Background::Model(m, _) => m.field.config().aabb,
        Background::Data(d) => d.aabb,
    };
    let bg_views = match &background {
        Background::Model(..) => background_views(&a.background),
        Background::Data(d) => d.views.clone(),
    };
    let mut scenes = Vec::new();
    let mut names = std::collections::HashSet::new();
    let mut any_alpha = matches!(&background, Background::Data(d) if d.had_alpha);
    for dir in &a.scenes {
        let bg_path = a.background_model.as_deref().unwrap_or(&a.background);
        let (train, test) = load_scene(dir, aabb, bg_path)?;
        any_alpha |= train.had_alpha;
        let mut name = scene_name(dir);
        while !names.insert(name.clone()) {
            name.push('_');
        }
        let views = match a.scene_views {
            Some(n) => crate::data::evenly_spaced(&train.views, n),
            None => train.views,
        };
        scenes.push(SceneData { name, train: views, test });
    }
    std::fs::create_dir_all(&a.out).map_err(|e| format!("{}: --out: cannot create: {e}", a.out.display()))?;
    let (grid, mut train) = trainer_settings(a.steps, a.rays, a.log2t, a.seed, any_alpha, &aabb);
    train.frozen_stride = a.frozen_stride.unwrap_or(train.frozen_stride);
    train.frozen_tail = a.frozen_tail.unwrap_or(train.frozen_tail);
    (train.frozen_coarse, train.frozen_coarse_stride) =
        a.frozen_coarse.unwrap_or((train.frozen_coarse, train.frozen_coarse_stride));
    train.ray_pool = a.ray_pool.unwrap_or(train.ray_pool);
    train.image_gains = a.image_gains;
    train.pixel_jitter = a.pixel_jitter.unwrap_or(train.pixel_jitter);
    train.photo_tail = a.photo_tail.unwrap_or(train.photo_tail);
    train.pixel_rays = a.pixel_rays.unwrap_or(train.pixel_rays);
    train.near_gradient = crate::train::trainer::NearGradient::from_flag(a.near_grad, train.near_gradient);
    let mut cfg = CompareConfig::new(train, NerfConfig { grid, aabb });
    cfg.eval_every = a.eval_every.unwrap_or(cfg.eval_every);
    cfg.background_steps = a.background_steps.unwrap_or(cfg.background_steps);
    cfg.m = a.m;
    cfg.m_sweep = a.m_sweep.clone();
    cfg.prior = a.prior_settings.config();
    cfg.capture_rays = a.rays.is_none();
    let isa = Isa::detect();
    let rays = match cfg.capture_rays {
        false => cfg.train.rays_per_step.to_string(),
        true => {
            let each: Vec<String> = scenes.iter().map(|s| cfg.train.rays_for_views(&s.train).to_string()).collect();
            format!("{} (by each scene's capture)", each.join(","))
        }
    };
    eprintln!(
        "rnerf compare: {} scene(s), methods {}, {} steps x {rays} rays, log2 T = {}, cpu level {isa}, {} threads",
        scenes.len(),
        a.methods.iter().map(|m| m.name()).collect::<Vec<_>>().join(","),
        cfg.train.steps,
        cfg.field.grid.log2_table_size,
        rayon::current_num_threads()
    );
    let background = match background {
        Background::Model(m, trained) => {
            let path = a.background_model.as_deref().expect("a loaded background has its path");
            if let Some(note) = background_steps_note(path, trained, cfg.train.steps) {
                eprintln!("rnerf compare: {note}");
            }
            *m
        }
        Background::Data(data) => {
            let nerf = train_background(isa, &data.views, &cfg)?;
            let path = a.out.join("background.safetensors");
            let steps = cfg.background_steps.to_string();
            save_nerf(&path, &nerf, &[("train_data", a.background.display().to_string()), ("train_steps", steps)])?;
            eprintln!("rnerf compare: wrote {}", path.display());
            nerf
        }
    };
    compare_and_write(isa, &background, &bg_views, &scenes, &a.methods, &cfg, &a.out)?;
    Ok(())
}

/// Trains the background NeRF with the comparison's settings, showing progress.
pub fn train_background(isa: Isa, views: &[View], cfg: &CompareConfig) -> Result<Nerf, String> {
    let mut progress = Progress::new("background", cfg.background_steps as u64);
    let train = cfg.train_for(views).rescheduled(cfg.background_steps);
    train_nerf(isa, views, cfg.field.clone(), &train, 10, |s| {
        progress.update(s.step as u64 + 1, &format!("PSNR {:.2} dB", -10.0 * (s.loss as f64).log10()))
    })
    .map_err(|e| format!("background: {e}"))
}

/// Runs every method on every scene and writes the results into `out`: `table.md` (also
/// printed), `table.json`, `curves.csv`, and per scene `curves.png` and `depth_<i>.png`.
pub fn compare_and_write(
    isa: Isa,
    background: &Nerf,
    bg_views: &[View],
    scenes: &[SceneData],
    methods: &[Method],
    cfg: &CompareConfig,
    out: &Path,
) -> Result<Vec<SceneResult>, String> {
    let mut results = Vec::new();
    for s in scenes {
        let mut current: Option<(Method, Progress)> = None;
        let mut log = |m: Method, st: &StepStats| {
            if current.as_ref().is_none_or(|c| c.0 != m) {
                current = Some((m, Progress::new(&format!("{} {}", s.name, m.name()), cfg.train.steps as u64)));
            }
            let p = &mut current.as_mut().expect("set above").1;
            p.update(
                st.step as u64 + 1,
                &format!("PSNR {:.2} dB  {:.0} samples/ray", -10.0 * (st.loss as f64).log10(), st.samples_per_ray),
            );
        };
        let r = compare::run_scene(isa, &s.name, background, bg_views, &s.train, &s.test, methods, cfg, &mut log)?;
        let dir = out.join(&r.name);
        std::fs::create_dir_all(&dir).map_err(|e| format!("{}: cannot create: {e}", dir.display()))?;
        export::write(&dir.join("curves.png"), compare::curves_png(&r))?;
        for i in 0..s.test.views.len() {
            export::write(&dir.join(format!("depth_{i}.png")), compare::depth_sheet_png(&r, &s.test, i))?;
        }
        results.push(r);
        // Tables so far after every scene: a long run's finished scenes are never lost.
        write_tables(&results, cfg, out)?;
    }
    let table = compare::table(&results);
    println!("{table}");
    eprintln!(
        "rnerf: wrote {} (table.md, table.json, curves.csv, <scene>/curves.png, <scene>/depth_<i>.png)",
        out.display()
    );
    Ok(results)
}

/// Writes `table.md`, `table.json` and `curves.csv` of `results` into `out`.
fn write_tables(results: &[SceneResult], cfg: &CompareConfig, out: &Path) -> Result<(), String> {
    let table = compare::table(results);
    write_atomic(&out.join("table.md"), table.as_bytes())?;
    write_atomic(&out.join("curves.csv"), compare::curves_csv(results).as_bytes())?;
    let rows: Vec<serde_json::Value> = results
        .iter()
        .flat_map(|r| {
            r.methods.iter().flat_map(move |m| {
                let row = |method: &str, e: &crate::eval::DepthReport| {
                    let mut x = e.to_json();
                    x["scene"] = r.name.clone().into();
                    x["method"] = method.into();
                    x["train_seconds"] = m.seconds.into();
                    x["rays_per_step"] = m.rays_per_step.into();
                    x["psnr"] = m.psnr.into();
                    x
                };
                let mut v = vec![row(m.method.name(), &m.threshold)];
                for (th, e) in &m.sweep {
                    let mut x = row(m.method.name(), e);
                    x["threshold"] = format!("{th:?}").into();
                    v.push(x);
                }
                if m.method == Method::Dex {
                    v.insert(0, row("nerf-expected", &m.expected));
                }
                v
            })
        })
        .collect();
    let priors: Vec<serde_json::Value> = results
        .iter()
        .filter_map(|r| {
            r.prior.map(|p| {
                json!({"scene": r.name, "changed_pixels": p.changed_pixels, "reach_pixels": p.reach_pixels,
            "matched_views": p.matched_views, "registered_views": p.registered_views, "views": p.views, "region_cells": p.region_cells,
            "region_volume": p.region_volume, "seconds": p.seconds})
            })
        })
        .collect();
    // Without --rays each run's own count is on its row (`CompareConfig::capture_rays`).
    let rays = if cfg.capture_rays { serde_json::Value::Null } else { cfg.train.rays_per_step.into() };
    let doc = json!({"steps": cfg.train.steps, "rays_per_step": rays, "seed": cfg.train.seed,
                     "log2_table_size": cfg.field.grid.log2_table_size, "threshold": format!("{:?}", cfg.m),
                     "near_limit": crate::eval::NEAR_LIMIT, "prior": format!("{:?}", cfg.prior), "priors": priors, "rows": rows});
    write_atomic(&out.join("table.json"), serde_json::to_string_pretty(&doc).expect("plain JSON").as_bytes())
}

/// Settings of `rnerf demo`: a small workspace sized to finish in about two minutes on two
/// cores (measured in BENCHMARKS.md; the choice in docs/DECISIONS.md, "The demo").
pub struct DemoSize {
    /// Image side (pixels).
    pub size: u32,
    /// Training views (background and scene each).
    pub views: usize,
    /// Test views.
    pub test_views: usize,
    /// Steps per training run.
    pub steps: u32,
}

/// The methods the demo trains on its scene.
pub const DEMO_METHODS: &[Method] = &[Method::Dex, Method::RESIDUAL];

/// The demo's default size.
pub const DEMO: DemoSize = DemoSize { size: 96, views: 32, test_views: 4, steps: 600 };

/// The demo's trainer and field: a small table and a coarse occupancy grid for a tiny scene.
pub fn demo_config(steps: u32, seed: u64) -> CompareConfig {
    let mut train = TrainConfig::with_steps(steps);
    train.rays_per_step = 512;
    train.background = SKY;
    // Every synthesised pixel shows a surface (no alpha): train over random background
    // colours, as `rnerf train` does for such data, so the field turns opaque at surfaces.
    train.random_background = true;
    train.seed = seed;
    train.occupancy = OccupancyConfig {
        resolution: 32,
        steps_per_diagonal: 192,
        max_samples: 192,
        warmup_steps: 64,
        ..Default::default()
    };
    let grid = HashGridConfig { levels: 12, log2_table_size: 15, base_resolution: 16, finest_resolution: 512 };
    CompareConfig::new(train, NerfConfig { grid, aabb: workspace::aabb() })
}

/// `rnerf demo`: synthesise the workspace with and without a glass sphere (written as datasets
/// into `out/data`), train the background, then compare the paper's methods on the scene.
pub(super) fn demo(out: &Path, steps: Option<u32>, size: Option<u32>, seed: Option<u64>) -> Result<(), String> {
    let t0 = std::time::Instant::now();
    let size = size.unwrap_or(DEMO.size);
    let cfg = demo_config(steps.unwrap_or(DEMO.steps), seed.unwrap_or(0));
    let isa = Isa::detect();
    eprintln!(
        "rnerf demo: synthesising a {s}x{s} workspace ({} views with and without a glass sphere) into {}",
        DEMO.views,
        out.join("data").display(),
        s = size
    );
    let bg = workspace::workspace(size, DEMO.views, 0.0, false);
    let scene = workspace::workspace(size, DEMO.views, 0.0, true);
    let test = workspace::workspace(size, DEMO.test_views, 0.37, true);
    std::fs::create_dir_all(out).map_err(|e| format!("{}: --out: cannot create: {e}", out.display()))?;
    bg.write_split(&out.join("data/background"), "train")?;
    scene.write_split(&out.join("data/glass"), "train")?;
    test.write_split(&out.join("data/glass"), "test")?;
    eprintln!(
        "rnerf demo: training the background ({} steps), then Dex-NeRF and Residual-NeRF ({} steps each, cpu level {isa}, {} threads)",
        cfg.background_steps,
        cfg.train.steps,
        rayon::current_num_threads()
    );
    let background = train_background(isa, &bg.views, &cfg)?;
    let models = out.join("models");
    std::fs::create_dir_all(&models).map_err(|e| format!("{}: cannot create: {e}", models.display()))?;
    save_nerf(&models.join("background.safetensors"), &background, &[])?;
    let cfg = CompareConfig { models: Some(models.clone()), ..cfg };
    let scenes = [SceneData { name: "glass".into(), train: scene.views, test: EvalSet::from_synth(&test) }];
    compare_and_write(isa, &background, &bg.views, &scenes, DEMO_METHODS, &cfg, out)?;
    let (data, residual) = (out.join("data/glass"), compare::model_path(&models, "glass", Method::RESIDUAL));
    let (data, residual) = (data.display(), residual.display());
    eprintln!(
        "rnerf demo: done in {:.1} s; look at {}\nnext, try:\n  rnerf render --model {residual} --data {data} --split test --out {}\n  rnerf eval --model {residual} --data {data}",
        t0.elapsed().as_secs_f64(),
        out.join("glass/depth_0.png").display(),
        out.join("render").display(),
    );
    Ok(())
}

/// The datasets and settings of `rnerf bench --background-data BG --scene S`, read and checked
/// before the bench runs.
pub(super) struct QualityData {
    bg_train: Dataset,
    bg_test: Dataset,
    scene_train: Dataset,
    scene_test: EvalSet,
    cfg: CompareConfig,
}

impl QualityData {
    /// Reads both datasets; the settings are `rnerf compare`'s defaults (`log2t` as given).
    pub(super) fn load(bg_dir: &Path, scene_dir: &Path, log2t: Option<u32>) -> Result<QualityData, String> {
        let bg_opts =
            LoadOptions { ground_truth: false, frame_type: Some(FrameType::Background), ..Default::default() };
        let bg_train = crate::app::load_data(bg_dir, "train", &bg_opts)?;
        let bg_test = crate::app::load_data(bg_dir, "test", &bg_opts)?;
        let (scene_train, scene_test) = load_scene(scene_dir, bg_train.aabb, bg_dir)?;
        let (grid, train) =
            trainer_settings(None, None, log2t, None, bg_train.had_alpha || scene_train.had_alpha, &bg_train.aabb);
        // The curve's spacing is the measurement's own (`quality::CURVE_EVERY`); each run's
        // rays by its capture, as `rnerf compare` does without `--rays`.
        let cfg =
            CompareConfig { capture_rays: true, ..CompareConfig::new(train, NerfConfig { grid, aabb: bg_train.aabb }) };
        Ok(QualityData { bg_train, bg_test, scene_train, scene_test, cfg })
    }

    /// [`crate::bench::quality::measure`] on them.
    pub(super) fn measure(&self, isa: Isa) -> Result<crate::bench::QualityFigures, String> {
        let input = crate::bench::quality::QualityInputs {
            background_train: &self.bg_train.views,
            background_test: &self.bg_test.views,
            scene_train: &self.scene_train.views,
            scene_test: &self.scene_test,
            cfg: &self.cfg,
            target_psnr_db: crate::bench::quality::TARGET_PSNR_DB,
        };
        crate::bench::quality::measure(isa, &input)
    }
}
