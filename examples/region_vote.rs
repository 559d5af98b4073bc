//! How tight the change region of a background and a scene capture is under each vote rule:
//! its cells and volume, the share of the training pixels whose ray crosses it (the pixels the
//! trainer draws from), and the share of the test views' object-mask pixels it covers (a
//! region that misses part of the glass cuts it off).
//!
//! ```text
//! cargo run --release --example region_vote -- BG_MODEL BG_DIR SCENE_DIR [V,S ...]
//! cargo run --release --example region_vote -- bg.safetensors DEV/background DEV/glass_up 0.5,0 0.75,0.25
//! ```
//!
//! Each `V,S[,D]` is a vote rule (`rnerf train --region-vote V,S --region-dilate D`): a cell is
//! changed when at least S of all views see it and at least V of those see a change there, and
//! the voted cells are grown by D cells (default 1). Default rules: 0.5,0 0.75,0 0.5,0.25
//! 0.75,0.25 0.9,0.25. The scene's test split must carry object masks.

use residual_nerf::data::dataset::{Dataset, LoadOptions};
use residual_nerf::render::DensityThreshold;
use residual_nerf::train::prior::{reach_pixels, scene_prior, PriorConfig};
use std::collections::HashSet;
use std::path::Path;

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [model, bg_dir, scene_dir, rules @ ..] = &args[..] else {
        return Err("usage: region_vote BG_MODEL BG_DIR SCENE_DIR [V,S[,D] ...]".into());
    };
    let dilate = PriorConfig::default().region_dilate;
    let mut votes = Vec::new();
    for r in rules {
        let v: Vec<f32> = r.split(',').filter_map(|x| x.parse().ok()).collect();
        match v[..] {
            [vote, seen] => votes.push((vote, seen, dilate)),
            [vote, seen, d] if d >= 0.0 && d.fract() == 0.0 => votes.push((vote, seen, d as u32)),
            _ => return Err(format!("rule '{r}' is not V,S or V,S,D")),
        }
    }
    if votes.is_empty() {
        votes = [(0.5, 0.0), (0.75, 0.0), (0.5, 0.25), (0.75, 0.25), (0.9, 0.25)].map(|(v, s)| (v, s, dilate)).to_vec();
    }
    let isa = residual_nerf::simd::Isa::detect();
    let background = residual_nerf::io::model::load_nerf(Path::new(model))?;
    let no_truth = LoadOptions { ground_truth: false, ..Default::default() };
    let load = |dir: &str, split: &str, opts: &LoadOptions| {
        Dataset::load(Path::new(dir), split, opts).map_err(|e| format!("{dir}: {e}"))
    };
    let bg = load(bg_dir, "train", &no_truth)?;
    let scene = load(scene_dir, "train", &no_truth)?;
    let test = load(scene_dir, "test", &LoadOptions::default())?;
    // No surface in the test views: a region cell anywhere along a pixel's ray covers it.
    let open: Vec<Vec<f32>> = test.views.iter().map(|v| vec![f32::INFINITY; v.rgb.len()]).collect();
    let test_pixels: usize = test.views.iter().map(|v| v.rgb.len()).sum();
    println!("| vote V,S, dilation | cells | volume (m³) | training pixels changed | crossing the region | test pixels crossing | test object pixels covered |");
    println!("|---|---|---|---|---|---|---|");
    for (vote, min_seen, region_dilate) in votes {
        let cfg = PriorConfig { vote, min_seen, region_dilate, ..Default::default() };
        let p = scene_prior(isa, &background, &bg.views, &scene.views, [0.5; 3], DensityThreshold::Sigma(10.0), &cfg);
        let reach = reach_pixels(&p.region, &test.views, &open);
        let mut hit = vec![HashSet::new(); test.views.len()];
        for &(v, px) in &reach {
            hit[v as usize].insert(px as usize);
        }
        let (mut object, mut covered) = (0usize, 0usize);
        for (f, hit) in test.frames.iter().zip(&hit) {
            for (px, _) in f.mask.iter().flatten().enumerate().filter(|(_, &m)| m) {
                object += 1;
                covered += hit.contains(&px) as usize;
            }
        }
        println!(
            "| {vote},{min_seen}, {region_dilate} | {} | {:.4} | {:.1}% | {:.1}% | {:.1}% | {:.1}% |",
            p.region.count(),
            p.region.volume(),
            100.0 * p.changed_share(),
            100.0 * p.reach_share(),
            100.0 * reach.len() as f64 / test_pixels.max(1) as f64,
            100.0 * covered as f64 / object.max(1) as f64
        );
    }
    Ok(())
}
