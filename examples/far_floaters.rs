//! Where a residual model's near crop loses to its background beyond the glass's 1–2 px ring.
//! Takes the near crop's pixels at least 3 px (chessboard) from the object mask, renders the
//! residual model's and the background's threshold depth (σ ≥ 10/m) there, and splits the
//! pixels into those where the residual is worse than the background by more than 2 cm and the
//! rest: each group's pixels, its share of the residual's squared error in these bands, the
//! share of its pixels whose colour differs from the background's test image at the same pose
//! by more than the change maps' tolerance (where one exists), and for the worse pixels whether
//! the residual's hit lies in the change region, and in the region as voted before its one-cell
//! dilation (the vote's core, recomputed from the training images at VOTE, the share of the
//! seeing views that must see a change: the vote the model trained with, by default
//! [`PriorConfig::vote`]'s default), and how far in front of the
//! truth it lies; then the whole near crop's RMSE, the worse pixels' share of its squared error,
//! and its RMSE had those pixels the background's depth.
//!
//! ```text
//! cargo run --release --example far_floaters -- RESIDUAL_MODEL SCENE_DIR BACKGROUND_MODEL BACKGROUND_DIR [VOTE]
//! ```

use residual_nerf::data::dataset::{Dataset, LoadOptions};
use residual_nerf::eval::{mask_distance, GROSS_ERROR, NEAR_LIMIT};
use residual_nerf::geometry::camera::pixel_ray;
use residual_nerf::io::{load_model, LoadedModel};
use residual_nerf::render::view::Scene;
use residual_nerf::render::{DensityThreshold, ViewRenderer};
use residual_nerf::simd::Isa;
use residual_nerf::train::prior::{scene_prior, PriorConfig, CHANGE_TOLERANCE};
use residual_nerf::train::trainer::TrainConfig;
use std::path::Path;

/// The nearest band scored: pixels this far from the mask or farther.
const FROM_PX: u32 = 3;

/// A group of pixels: count, the residual's and the background's squared error, pixels with a
/// background image at their pose and those of them whose colour changed.
#[derive(Default)]
struct Group {
    pixels: usize,
    sq_residual: f64,
    sq_background: f64,
    with_image: usize,
    changed: usize,
}

fn load(dir: &str, split: &str, ground_truth: bool) -> Result<Dataset, String> {
    let opts = LoadOptions { ground_truth, ..Default::default() };
    Dataset::load(Path::new(dir), split, &opts).map_err(|e| format!("{dir}: {e}"))
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: far_floaters RESIDUAL_MODEL SCENE_DIR BACKGROUND_MODEL BACKGROUND_DIR [VOTE]";
    let (model, scene_dir, bg_model, bg_dir, vote) = match &args[..] {
        [m, s, b, d] => (m, s, b, d, PriorConfig::default().vote),
        [m, s, b, d, v] => (m, s, b, d, v.parse().map_err(|_| format!("VOTE '{v}' is not a share"))?),
        _ => return Err(usage.into()),
    };
    let isa = Isa::detect();
    let LoadedModel::Residual(res) = load_model(Path::new(model)).map_err(|e| e.to_string())? else {
        return Err(format!("{model}: not a residual model"));
    };
    let LoadedModel::Nerf(bg) = load_model(Path::new(bg_model)).map_err(|e| e.to_string())? else {
        return Err(format!("{bg_model}: not a plain NeRF"));
    };
    let region = res.field.region().ok_or(format!("{model}: no change region"))?.clone();
    let (test, bg_test) = (load(scene_dir, "test", true)?, load(bg_dir, "test", true)?);
    let (train, bg_train) = (load(scene_dir, "train", false)?, load(bg_dir, "train", false)?);
    // The core as the model's own region was voted: on the grid's cells or finer.
    let region_subdivide = region.resolution() / res.occupancy.config().resolution;
    let pcfg = PriorConfig { region_dilate: 0, vote, region_subdivide, ..Default::default() };
    let sky = TrainConfig::default().background;
    let core = scene_prior(isa, &bg, &bg_train.views, &train.views, sky, DensityThreshold::DEFAULT, &pcfg).region;
    let (rs, bs) = (Scene::from(&*res), Scene::from(&*bg));
    let (mut render_r, mut render_b) = (ViewRenderer::new(), ViewRenderer::new());
    let (mut worse, mut rest) = (Group::default(), Group::default());
    let (mut in_region, mut in_core) = (0usize, 0usize);
    let mut offsets: Vec<f32> = Vec::new();
    // The whole near crop (the mask and every band): its squared error and pixels.
    let (mut near_sq, mut near_pixels) = (0f64, 0usize);
    for (v, f) in test.views.iter().zip(&test.frames) {
        let k = &v.intrinsics;
        let (Some(truth), Some(crop), Some(mask)) = (&f.depth, f.crop, f.mask.as_deref()) else { continue };
        let (w, h) = (k.width as usize, k.height as usize);
        let image = bg_test.views.iter().find(|b| b.pose == v.pose && b.intrinsics == *k).map(|b| &b.rgb);
        let (mut zr, mut zb) = (vec![0.0; w * h], vec![0.0; w * h]);
        render_r.depth(isa, &rs, k, &v.pose, DensityThreshold::DEFAULT, &mut zr);
        render_b.depth(isa, &bs, k, &v.pose, DensityThreshold::DEFAULT, &mut zb);
        let dist = mask_distance(mask, w, h);
        for y in crop[1] as usize..crop[3] as usize {
            for x in crop[0] as usize..crop[2] as usize {
                let p = y * w + x;
                let t = truth[p];
                if !(t.is_finite() && t > 0.0 && t < NEAR_LIMIT) {
                    continue;
                }
                // Holes count as depth 0, as `rnerf eval` scores them.
                let err = |z: f32| if z.is_finite() { z - t } else { -t };
                let (er, eb) = (err(zr[p]), err(zb[p]));
                near_sq += (er * er) as f64;
                near_pixels += 1;
                if dist[p] < FROM_PX {
                    continue;
                }
                let is_worse = er.abs() > eb.abs() + GROSS_ERROR;
                let g = if is_worse { &mut worse } else { &mut rest };
                g.pixels += 1;
                g.sq_residual += (er * er) as f64;
                g.sq_background += (eb * eb) as f64;
                if let Some(img) = image {
                    g.with_image += 1;
                    let diff = (0..3).map(|i| (v.rgb[p][i] - img[p][i]).abs()).fold(0.0, f32::max);
                    g.changed += (diff > CHANGE_TOLERANCE) as usize;
                }
                if is_worse {
                    offsets.push(er);
                    if zr[p].is_finite() {
                        let ray = pixel_ray(k, &v.pose, x as u32, y as u32);
                        let hit = ray.at(ray.z_to_range(zr[p]));
                        in_region += region.contains(hit) as usize;
                        in_core += core.contains(hit) as usize;
                    }
                }
            }
        }
    }
    let total = worse.sq_residual + rest.sq_residual;
    println!("{model}: change region {} cells, its vote's core {} cells", region.count(), core.count());
    println!("| pixels ≥ {FROM_PX} px from the mask | pixels | share of the residual's squared error | residual RMSE (m) | background RMSE (m) | changed colour |");
    println!("|---|---|---|---|---|---|");
    for (name, g) in [("residual worse by > 2 cm", &worse), ("the rest", &rest)] {
        let n = g.pixels.max(1) as f64;
        println!(
            "| {name} | {} | {:.1}% | {:.4} | {:.4} | {:.0}% of {} |",
            g.pixels,
            100.0 * g.sq_residual / total,
            (g.sq_residual / n).sqrt(),
            (g.sq_background / n).sqrt(),
            100.0 * g.changed as f64 / g.with_image.max(1) as f64,
            g.with_image
        );
    }
    let kept = near_sq - worse.sq_residual + worse.sq_background;
    println!(
        "near crop: RMSE {:.4} m; the worse pixels hold {:.1}% of its squared error; with the background's depth there {:.4} m",
        (near_sq / near_pixels.max(1) as f64).sqrt(),
        100.0 * worse.sq_residual / near_sq,
        (kept / near_pixels.max(1) as f64).sqrt()
    );
    offsets.sort_by(f32::total_cmp);
    let q = |f: f64| offsets.get(((offsets.len().max(1) - 1) as f64 * f) as usize).copied().unwrap_or(f32::NAN);
    println!(
        "worse pixels: hit in the region {in_region}, in its core {in_core} ({:.1}%); residual depth − truth: 10th / 50th / 90th percentile {:.3} / {:.3} / {:.3} m",
        100.0 * in_core as f64 / worse.pixels.max(1) as f64,
        q(0.1),
        q(0.5),
        q(0.9)
    );
    Ok(())
}
