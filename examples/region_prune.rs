//! Prunes a trained residual model's change region by what its training views say: renders the
//! model's and the background's threshold depth (σ ≥ 10/m) at every EVERY-th training view,
//! and for each pixel whose hit lies in a region cell counts the cell as **supported** when the
//! pixel is in its change map (the prior's, as the model trained with), and as **contradicted**
//! when it is not and the hit lies more than 2 cm in front of the background's. Cells
//! contradicted more than RATIO times as often as supported leave the region (the field there is
//! the background again; RATIO `inf`: contradicted and never supported);
//! ROUNDS times, each round rendering over the region the last one left. Writes the pruned model
//! to OUT.
//!
//! ```text
//! cargo run --release --example region_prune -- RESIDUAL_MODEL SCENE_DIR BACKGROUND_MODEL BACKGROUND_DIR OUT [EVERY] [ROUNDS] [RATIO]
//! ```

use residual_nerf::data::dataset::{Dataset, LoadOptions};
use residual_nerf::eval::GROSS_ERROR;
use residual_nerf::geometry::camera::pixel_ray;
use residual_nerf::geometry::ChangeRegion;
use residual_nerf::io::{load_model, save_residual, LoadedModel};
use residual_nerf::render::view::Scene;
use residual_nerf::render::{DensityThreshold, ViewRenderer};
use residual_nerf::simd::Isa;
use residual_nerf::train::prior::{scene_prior, PriorConfig};
use residual_nerf::train::trainer::TrainConfig;
use std::path::Path;

fn load(dir: &str, split: &str) -> Result<Dataset, String> {
    let opts = LoadOptions { ground_truth: false, ..Default::default() };
    Dataset::load(Path::new(dir), split, &opts).map_err(|e| format!("{dir}: {e}"))
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage =
        "usage: region_prune RESIDUAL_MODEL SCENE_DIR BACKGROUND_MODEL BACKGROUND_DIR OUT [EVERY] [ROUNDS] [RATIO]";
    if !(5..=8).contains(&args.len()) {
        return Err(usage.into());
    }
    let (model, scene_dir, bg_model, bg_dir, out) = (&args[0], &args[1], &args[2], &args[3], &args[4]);
    let every: usize = args.get(5).map_or(Ok(4), |s| s.parse()).map_err(|_| "EVERY is not a count")?;
    let rounds: usize = args.get(6).map_or(Ok(3), |s| s.parse()).map_err(|_| "ROUNDS is not a count")?;
    let ratio: f32 = args.get(7).map_or(Ok(f32::INFINITY), |s| s.parse()).map_err(|_| "RATIO is not a number")?;
    let isa = Isa::detect();
    let LoadedModel::Residual(mut res) = load_model(Path::new(model)).map_err(|e| e.to_string())? else {
        return Err(format!("{model}: not a residual model"));
    };
    let LoadedModel::Nerf(bg) = load_model(Path::new(bg_model)).map_err(|e| e.to_string())? else {
        return Err(format!("{bg_model}: not a plain NeRF"));
    };
    let (train, bg_train) = (load(scene_dir, "train")?, load(bg_dir, "train")?);
    let region0 = res.field.region().ok_or(format!("{model}: no change region"))?.clone();
    let region_subdivide = region0.resolution() / res.occupancy.config().resolution;
    let pcfg = PriorConfig { region_subdivide, ..Default::default() };
    let sky = TrainConfig::default().background;
    let maps = scene_prior(isa, &bg, &bg_train.views, &train.views, sky, DensityThreshold::DEFAULT, &pcfg).maps;
    let bs = Scene::from(&*bg);
    let (mut render_r, mut render_b) = (ViewRenderer::new(), ViewRenderer::new());
    // The background's depth does not change between rounds.
    let mut bg_depth: Vec<Option<Vec<f32>>> = vec![None; train.views.len()];
    let mut zr: Vec<f32> = Vec::new();
    println!("{model}: region {} cells", region0.count());
    for round in 0..rounds {
        let region = res.field.region().expect("kept").clone();
        let (mut support, mut contra) = (vec![0u32; region.n_cells()], vec![0u32; region.n_cells()]);
        let rs = Scene::from(&*res);
        for (vi, v) in train.views.iter().enumerate().step_by(every.max(1)) {
            let k = &v.intrinsics;
            let (w, h) = (k.width as usize, k.height as usize);
            zr.resize(w * h, 0.0);
            render_r.depth(isa, &rs, k, &v.pose, DensityThreshold::DEFAULT, &mut zr);
            let zb = bg_depth[vi].get_or_insert_with(|| {
                let mut z = vec![0.0; w * h];
                render_b.depth(isa, &bs, k, &v.pose, DensityThreshold::DEFAULT, &mut z);
                z
            });
            for p in 0..w * h {
                if !zr[p].is_finite() {
                    continue;
                }
                let ray = pixel_ray(k, &v.pose, (p % w) as u32, (p / w) as u32);
                let hit = ray.at(ray.z_to_range(zr[p]));
                let Some(c) = region.cell_at(hit).filter(|&c| region.has_cell(c)) else { continue };
                if maps[vi][p] {
                    support[c] += 1;
                } else if !zb[p].is_finite() || zr[p] < zb[p] - GROSS_ERROR {
                    contra[c] += 1;
                }
            }
        }
        let kept: Vec<u32> = region
            .cells()
            .into_iter()
            .filter(|&c| {
                let (s, x) = (support[c as usize], contra[c as usize]);
                !(x > 0 && (s == 0 || x as f32 > ratio * s as f32))
            })
            .collect();
        let (n_sup, n_con) = (support.iter().filter(|&&s| s > 0).count(), contra.iter().filter(|&&s| s > 0).count());
        let before = region.count();
        println!(
            "round {round}: cells hit by changed pixels {n_sup}, by unchanged pixels in front of the background {n_con}; pruned {} of {before}",
            before - kept.len()
        );
        let pruned = ChangeRegion::from_cells(*region.aabb(), region.resolution(), &kept)?;
        res.field = res.field.clone().with_region(pruned);
    }
    save_residual(Path::new(out), &res, &[]).map_err(|e| e.to_string())?;
    println!("wrote {out}: region {} cells", res.field.region().expect("kept").count());
    Ok(())
}
