//! A robot's scene phase with a time budget: [`train_scene`] over a background kept from an
//! earlier scene phase ([`SceneBackground`], its depths held), stopped by its log once the
//! scene phase's wall time (prior included) reaches the budget, then scored on the scene's test
//! split as `rnerf eval --depth-only` scores it (every ray from the box) and as the onboard
//! renderer renders it (solid fraction ½, the coarse start at 1 step). Each budget is a run of
//! its own from the start; `full` runs every step.
//!
//! ```text
//! cargo run --release --example scene_budget -- [--scene-views N] BG_MODEL BACKGROUND_DIR SCENE_DIR... [-- SECONDS...]
//! ```
//!
//! Default budgets: 10, 15 and 20 s, and `full`. The scene phase takes `rnerf train`'s
//! settings for the capture (seed 0, the rays per step from its size); `--scene-views N` trains
//! on N evenly spaced views of each scene, as `rnerf train --scene-views N` does.

use residual_nerf::app::{evaluate, EvalOptions};
use residual_nerf::data::{Dataset, LoadOptions};
use residual_nerf::eval::CropRule;
use residual_nerf::io::load_nerf;
use residual_nerf::render::view::Scene;
use residual_nerf::render::{DensityThreshold, DepthMethod};
use residual_nerf::simd::Isa;
use residual_nerf::train::prior::PriorConfig;
use residual_nerf::train::scene::{train_scene, SceneBackground};
use residual_nerf::train::trainer::TrainConfig;
use std::ops::ControlFlow;
use std::path::Path;
use std::time::{Duration, Instant};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let scene_views = match args.first().map(String::as_str) {
        Some("--scene-views") => {
            let n = args.get(1).ok_or("--scene-views needs a count")?.parse::<usize>()?;
            args.drain(..2);
            Some(n)
        }
        _ => None,
    };
    let (paths, budgets) = match args.iter().position(|a| a == "--") {
        Some(i) => (&args[..i], args[i + 1..].iter().map(|b| b.parse::<f64>()).collect::<Result<Vec<_>, _>>()?),
        None => (&args[..], vec![10.0, 15.0, 20.0]),
    };
    let [model, bg_dir, scenes @ ..] = paths else {
        return Err("usage: scene_budget [--scene-views N] BG_MODEL BACKGROUND_DIR SCENE_DIR... [-- SECONDS...]".into());
    };
    let isa = Isa::detect();
    let background = load_nerf(Path::new(model))?;
    let train_opts = LoadOptions { ground_truth: false, ..Default::default() };
    let bg = Dataset::load(Path::new(bg_dir), "train", &train_opts)?;
    let mut kept = SceneBackground::new(&background, &bg.views)?;
    let pcfg = PriorConfig::default();
    let runs: Vec<Option<f64>> = budgets.iter().map(|&b| Some(b)).chain([None]).collect();
    println!("| scene | budget (s) | steps | prior (s) | training (s) | object MAE exact / onboard (m) | near-crop RMSE exact / onboard (m) | object holes onboard |");
    println!("|---|---|---|---|---|---|---|---|");
    for dir in scenes {
        let name = Path::new(dir).file_name().map_or(dir.clone(), |n| n.to_string_lossy().into_owned());
        let mut scene = Dataset::load(Path::new(dir), "train", &train_opts)?;
        if let Some(n) = scene_views {
            scene.views = residual_nerf::data::evenly_spaced(&scene.views, n);
        }
        let test = Dataset::load(Path::new(dir), "test", &LoadOptions::default())?;
        let mut cfg = TrainConfig::default();
        cfg.random_background = !scene.had_alpha;
        cfg.rays_per_step = cfg.rays_for_views(&scene.views);
        // A robot's later scene phase: the background's depths at its images' poses are held.
        kept.prior(isa, &scene.views, cfg.background, DensityThreshold::DEFAULT, &pcfg);
        for budget in &runs {
            let clock = Instant::now();
            let limit = budget.map(Duration::from_secs_f64);
            let stop = |_: &_| match limit.is_some_and(|l| clock.elapsed() >= l) {
                true => ControlFlow::Break(()),
                false => ControlFlow::Continue(()),
            };
            let trained = train_scene(isa, &mut kept, &scene.views, &cfg, &pcfg, stop)?;
            let scored = |solid_fraction: f32, coarse_start: Option<u32>| {
                let opts = EvalOptions {
                    depth: DepthMethod::default(),
                    crop: CropRule::Frame,
                    limit: None,
                    background: LoadOptions::default().background,
                    depth_only: true,
                    solid_fraction,
                    coarse_start,
                    colour_tail: 0.0,
                };
                evaluate(isa, &Scene::from(&trained.model), &test, &opts, |_| {}).regions
            };
            let (exact, onboard) = (scored(0.0, None), scored(0.5, Some(1)));
            println!(
                "| {name} | {} | {} | {:.1} | {:.1} | {:.4} / {:.4} | {:.4} / {:.4} | {:.2}% |",
                budget.map_or("full".to_string(), |b| format!("{b}")),
                trained.steps,
                trained.prior_seconds,
                trained.train_seconds,
                exact.object.mae(),
                onboard.object.mae(),
                exact.near.rmse(),
                onboard.near.rmse(),
                100.0 * onboard.object.hole_rate()
            );
        }
    }
    Ok(())
}
