//! The best near-crop figures a residual model can reach over a given background: the depth of
//! a model that is exact on the object mask and is the background elsewhere (what the change
//! region aims at), scored like `rnerf eval` (threshold depth σ ≥ 10/m, the frames' crops, the
//! near crop < 1.5 m). Beside it the background alone and the truth on the mask only.
//!
//! ```text
//! cargo run --release --example background_floor -- BG_MODEL SCENE_DIR [SCENE_DIR ...]
//! ```

use residual_nerf::data::dataset::{Dataset, LoadOptions};
use residual_nerf::eval::{DepthReport, NEAR_LIMIT};
use residual_nerf::render::view::Scene;
use residual_nerf::render::{DensityThreshold, ViewRenderer};
use std::path::Path;

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [model, scenes @ ..] = &args[..] else {
        return Err("usage: background_floor BG_MODEL SCENE_DIR [SCENE_DIR ...]".into());
    };
    let isa = residual_nerf::simd::Isa::detect();
    let background = residual_nerf::io::model::load_nerf(Path::new(model))?;
    let scene = Scene::from(&background);
    let mut renderer = ViewRenderer::new();
    println!("| scene | background alone: near-crop RMSE | crop w/o object MAE | floor (truth on the mask): near-crop RMSE |");
    println!("|---|---|---|---|");
    for dir in scenes {
        let test = Dataset::load(Path::new(dir), "test", &LoadOptions::default()).map_err(|e| format!("{dir}: {e}"))?;
        let (mut alone, mut floor) = (DepthReport::default(), DepthReport::default());
        for (v, f) in test.views.iter().zip(&test.frames) {
            let k = &v.intrinsics;
            let (Some(truth), Some(crop)) = (&f.depth, f.crop) else { continue };
            let mut z = vec![0.0; (k.width * k.height) as usize];
            renderer.depth(isa, &scene, k, &v.pose, DensityThreshold::Sigma(10.0), &mut z);
            let mask = f.mask.as_deref();
            alone.add_frame(&z, truth, mask, k.width, crop, NEAR_LIMIT);
            let best: Vec<f32> =
                z.iter().enumerate().map(|(p, &d)| if mask.is_some_and(|m| m[p]) { truth[p] } else { d }).collect();
            floor.add_frame(&best, truth, mask, k.width, crop, NEAR_LIMIT);
        }
        println!("| {dir} | {:.4} | {:.4} | {:.4} |", alone.near.rmse(), alone.rest.mae(), floor.near.rmse());
    }
    Ok(())
}
