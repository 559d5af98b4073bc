//! `rnerf render`: depth (EXR metres, 16-bit PNG mm, .npy metres, colourised PNG), a coloured
//! world-frame point cloud (PLY), RGB and the camera of every view of a split, into an output
//! folder; with `--depth-only`, threshold depth through the depth-only path (no colour pass):
//! the depth files, an uncoloured point cloud and the camera, marched as evaluation marches
//! unless `--solid-fraction` and `--coarse-start` ask for the onboard renderer's trades (as
//! `rnerf eval --depth-only` takes them).

use super::Progress;
use crate::cli::Rendering;
use crate::data::{Dataset, LoadOptions};
use crate::field::model::Model;
use crate::files::export;
use crate::io::{load_model, LoadedModel};
use crate::render::view::Scene;
use crate::render::DepthMethod;
use crate::render::{FullOutputs, ViewRenderer};
use crate::simd::Isa;
use std::path::Path;

pub(super) fn run(model: &Path, data_dir: &Path, split: &str, how: &Rendering, out: &Path) -> Result<(), String> {
    if out.exists() && !out.is_dir() {
        return Err(format!("{}: --out: not a directory", out.display()));
    }
    let model = load_model(model)?;
    let opts = LoadOptions { ground_truth: false, ..Default::default() };
    let data = crate::app::load_data(data_dir, split, &opts)?;
    // Created once the inputs have been read and checked, so a bad input leaves nothing behind.
    std::fs::create_dir_all(out).map_err(|e| format!("{}: --out: cannot create: {e}", out.display()))?;
    let background = opts.background;
    match &model {
        LoadedModel::Nerf(n) => render_all(&Scene::from(&**n), &data, how, background, out, false),
        LoadedModel::Residual(r) => render_all(&Scene::from(&**r), &data, how, background, out, true),
    }
}

/// Renders and writes every view; `beta`: also `<name>_beta.png` (where the scene changed);
/// `depth_only`: threshold depth alone (no RGB, β or point colours).
fn render_all<M: Model>(
    scene: &Scene<'_, M>,
    data: &Dataset,
    how: &Rendering,
    background: [f32; 3],
    out: &Path,
    beta: bool,
) -> Result<(), String> {
    let Rendering { depth, depth_only, solid_fraction, coarse_start, colour_tail } = *how;
    let isa = Isa::detect();
    let m = depth.threshold();
    let beta = beta && !depth_only;
    let mut renderer = ViewRenderer::<M>::new();
    let thinned = super::onboard_trades(scene, m, depth_only, solid_fraction, coarse_start, colour_tail, &mut renderer);
    let depth_scene = scene.with_grid(thinned.as_ref());
    let mut progress = Progress::new("render", data.views.len() as u64);
    for (i, (v, f)) in data.views.iter().zip(&data.frames).enumerate() {
        let k = &v.intrinsics;
        let n = (k.width * k.height) as usize;
        let mut threshold = vec![0.0; n];
        let (mut rgb, mut expected, mut b) = (Vec::new(), Vec::new(), Vec::new());
        if depth_only {
            renderer.depth(isa, &depth_scene, k, &v.pose, m, &mut threshold);
        } else {
            (rgb, expected) = (vec![[0.0; 3]; n], vec![0.0; n]);
            if beta {
                b = vec![0.0; n];
            }
            let outputs =
                FullOutputs { rgb: &mut rgb, expected_z: &mut expected, threshold_z: &mut threshold, beta: &mut b };
            renderer.full(isa, scene, k, &v.pose, background, m, outputs);
        }
        let z = if depth == DepthMethod::Expected { &expected } else { &threshold };
        let stem =
            f.image_path.file_stem().map_or_else(|| format!("frame_{}", f.index), |s| s.to_string_lossy().into_owned());
        let (w, h) = (k.width, k.height);
        let (near, far) = export::depth_range(z);
        let file = |suffix: &str| out.join(format!("{stem}{suffix}"));
        export::write(&file("_depth.exr"), export::depth_exr_bytes(z, w, h))?;
        export::write(&file("_depth_mm.png"), export::depth_png_mm_bytes(z, w, h))?;
        export::write(&file("_depth.npy"), Ok(export::depth_npy_bytes(z, w, h)))?;
        export::write(&file("_depth_vis.png"), export::depth_vis_png_bytes(z, w, h, near, far))?;
        let colours = (!depth_only).then_some(&rgb[..]);
        if let Some(rgb) = colours {
            export::write(&file("_rgb.png"), export::rgb_png_bytes(rgb, w, h))?;
        }
        export::write(&file("_points.ply"), Ok(export::depth_ply_bytes(z, k, &v.pose, colours)))?;
        if beta {
            let grey: Vec<[f32; 3]> = b.iter().map(|&x| [x; 3]).collect();
            export::write(&file("_beta.png"), export::rgb_png_bytes(&grey, w, h))?;
        }
        export::write(&file("_camera.json"), Ok(export::camera_json(k, &v.pose).into_bytes()))?;
        progress.update(i as u64 + 1, &format!("{stem}: {near:.2}..{far:.2} m"));
    }
    Ok(())
}
