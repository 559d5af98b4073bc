//! The robot's threshold depth at a finer resolution than the ground truth, scored against it.
//!
//! Renders every test view of DATA_DIR at N times its width and height (N odd, the same lens:
//! focal length and principal point scaled by N) with the onboard renderer's settings (solid
//! fraction `onboard::SOLID_FRACTION`, each coarse-start setting), keeps the middle pixel of
//! every N×N block (its ray is exactly the ground-truth pixel's ray) and scores that as
//! `rnerf eval --depth-only` does: crop, near crop, object mask, crop without the object. So a
//! trade that depends on the pixel angle (the coarse start's first-pass stride,
//! `ViewRenderer::set_coarse_spacing`) is scored where the ground truth exists. A setting is
//! `off` (every ray from the box), a margin (the default spacing `COARSE_SPACING`), or
//! `MARGIN@MRAD` (`1@0`: two passes at any size).
//!
//! ```text
//! cargo run --release --example fine_depth -- MODEL DATA_DIR [N [SETTINGS]]
//! RNERF_CPU_LEVEL=avx2 cargo run --release --example fine_depth -- res.safetensors DEV/glass_up 3 off,1@0,1
//! ```

use residual_nerf::data::dataset::{Dataset, LoadOptions};
use residual_nerf::eval::{crop_box, CropRule, DepthReport, NEAR_LIMIT};
use residual_nerf::field::model::Model;
use residual_nerf::io::{load_model, LoadedModel};
use residual_nerf::render::view::Scene;
use residual_nerf::render::{DepthMethod, ViewRenderer};
use residual_nerf::simd::Isa;
use std::path::Path;
use std::time::Instant;

#[path = "shared/coarse_setting.rs"]
mod coarse_setting;

/// A coarse start's margin and first-pass spacing (radians); `None`: every ray from the box.
type Setting = Option<(u32, f32)>;

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [model, data, rest @ ..] = &args[..] else {
        return Err("usage: fine_depth MODEL DATA_DIR [N [SETTINGS]]".into());
    };
    let n: u32 = rest.first().map_or(Ok(3), |s| s.parse().map_err(|_| format!("'{s}' is not a factor")))?;
    if n.is_multiple_of(2) {
        return Err(format!("N = {n}: an odd factor keeps a pixel on each ground-truth ray"));
    }
    let settings: Vec<Setting> = rest
        .get(1)
        .map_or("off,1@0,1", String::as_str)
        .split(',')
        .map(coarse_setting::parse)
        .collect::<Result<_, _>>()?;
    let test = Dataset::load(Path::new(data), "test", &LoadOptions::default()).map_err(|e| e.to_string())?;
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().map_err(|e| e.to_string())?;
    let model = load_model(Path::new(model))?;
    pool.install(|| match &model {
        LoadedModel::Nerf(m) => run(&Scene::from(&**m), &test, n, &settings),
        LoadedModel::Residual(m) => run(&Scene::from(&**m), &test, n, &settings),
    });
    Ok(())
}

fn run<M: Model>(scene: &Scene<'_, M>, test: &Dataset, n: u32, settings: &[Setting]) {
    let isa = Isa::detect();
    let m = DepthMethod::default().threshold();
    let grid = scene.occupancy.keep_solid(residual_nerf::onboard::SOLID_FRACTION, m.min_sigma());
    let thinned = scene.with_grid(Some(&grid));
    for &setting in settings {
        let mut renderer = ViewRenderer::<M>::new();
        renderer.set_coarse_start(setting.map(|(margin, _)| margin));
        if let Some((_, spacing)) = setting {
            renderer.set_coarse_spacing(spacing);
        }
        let (mut report, mut fine, mut z, mut seconds) = (DepthReport::default(), Vec::new(), Vec::new(), 0.0);
        for (v, f) in test.views.iter().zip(&test.frames) {
            let Some(truth) = &f.depth else { continue };
            let k = v.intrinsics;
            let kn = residual_nerf::bench::resized(k, k.width * n, Some(k.height * n));
            fine.resize((kn.width * kn.height) as usize, 0.0);
            let t = Instant::now();
            renderer.depth(isa, &thinned, &kn, &v.pose, m, &mut fine);
            seconds += t.elapsed().as_secs_f64();
            let (w, h, half) = (k.width as usize, k.height as usize, (n / 2) as usize);
            let wn = kn.width as usize;
            z.clear();
            z.extend(
                (0..h)
                    .flat_map(|y| (0..w).map(move |x| (y, x)))
                    .map(|(y, x)| fine[(y * n as usize + half) * wn + x * n as usize + half]),
            );
            let crop = crop_box(CropRule::Frame, k.width, k.height, f.crop);
            report.add_frame(&z, truth, f.mask.as_deref(), k.width, crop, NEAR_LIMIT);
        }
        let name = coarse_setting::name(setting);
        let r = &report;
        println!(
            "{name}, {n}x: crop MAE {:.4} RMSE {:.4}; object MAE {:.4} holes {:.2}%; near-crop RMSE {:.4}; crop w/o object MAE {:.4}; rendering {seconds:.2} s",
            r.crop.mae(),
            r.crop.rmse(),
            r.object.mae(),
            100.0 * r.object.hole_rate(),
            r.near.rmse(),
            r.rest.mae()
        );
    }
}
