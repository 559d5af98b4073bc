//! What a [`SceneBackground`] kept between scene phases saves: the prior of each scene computed
//! fresh ([`scene_prior`], what `rnerf train` does) and over one kept background, whose depth at
//! the background images' poses is rendered by the first scene that matches them and read back
//! by the rest. Checks that both give the same region, change maps and reach pixels.
//!
//! ```text
//! cargo run --release --example prior_held -- BG_MODEL BACKGROUND_DIR SCENE_DIR... [-- ROUNDS]
//! ```
//!
//! `BG_MODEL` is the background's model file, `BACKGROUND_DIR` its capture (`train` split), each
//! `SCENE_DIR` a scene photographed at the background's poses. Each round runs every scene
//! fresh, then every scene over the kept background (kept across rounds, so only the first
//! round's first scene renders); wall seconds per scene.

use residual_nerf::data::{Dataset, LoadOptions};
use residual_nerf::io::load_nerf;
use residual_nerf::render::DensityThreshold;
use residual_nerf::simd::Isa;
use residual_nerf::train::prior::{scene_prior, PriorConfig, ScenePrior};
use residual_nerf::train::scene::SceneBackground;
use residual_nerf::train::trainer::TrainConfig;
use std::path::Path;
use std::time::Instant;

fn same(a: &ScenePrior, b: &ScenePrior) -> bool {
    a.maps == b.maps && a.focus == b.focus && a.reach == b.reach && a.region.cells() == b.region.cells()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (paths, rounds) = match args.iter().position(|a| a == "--") {
        Some(i) => (&args[..i], args.get(i + 1).map_or(Ok(2), |r| r.parse::<usize>())?),
        None => (&args[..], 2),
    };
    let [model, bg_dir, scenes @ ..] = paths else {
        return Err("usage: prior_held BG_MODEL BACKGROUND_DIR SCENE_DIR... [-- ROUNDS]".into());
    };
    if scenes.is_empty() {
        return Err("no scene directory".into());
    }
    let isa = Isa::detect();
    let background = load_nerf(Path::new(model))?;
    let opts = LoadOptions { ground_truth: false, ..Default::default() };
    let bg = Dataset::load(Path::new(bg_dir), "train", &opts)?;
    let scenes: Vec<(String, Dataset)> = scenes
        .iter()
        .map(|d| Ok((d.clone(), Dataset::load(Path::new(d), "train", &opts)?)))
        .collect::<Result<_, residual_nerf::data::DataReport>>()?;
    let (sky, m, pcfg) = (TrainConfig::default().background, DensityThreshold::DEFAULT, PriorConfig::default());
    let mut kept = SceneBackground::new(&background, &bg.views)?;
    println!("| round | scene | fresh (s) | kept background (s) | background depths held after | same prior |");
    println!("|---|---|---|---|---|---|");
    for round in 1..=rounds {
        let mut fresh = Vec::new();
        for (_, scene) in &scenes {
            let t = Instant::now();
            let p = scene_prior(isa, &background, &bg.views, &scene.views, sky, m, &pcfg);
            fresh.push((p, t.elapsed().as_secs_f64()));
        }
        for ((name, scene), (p, fresh_s)) in scenes.iter().zip(&fresh) {
            let t = Instant::now();
            let q = kept.prior(isa, &scene.views, sky, m, &pcfg);
            let held_s = t.elapsed().as_secs_f64();
            let held = kept.depths_held();
            println!("| {round} | {name} | {fresh_s:.2} | {held_s:.2} | {held} | {} |", same(p, &q));
        }
    }
    Ok(())
}
