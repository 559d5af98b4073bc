//! Where a model's near-crop error lies: the near crop's pixels outside the object mask binned
//! by their distance (in pixels, chessboard) to the nearest mask pixel, each band's share of
//! the pixels and of the near crop's squared error, its RMSE and its floater and see-through
//! rates (prediction nearer / farther than the truth by 2 cm). Scored like `rnerf eval`
//! (threshold depth σ ≥ 10/m, the frames' crops, the near limit 1.5 m, holes as depth 0, each
//! band an [`eval::DepthErrors`](residual_nerf::eval::DepthErrors) as `rnerf eval`'s), and
//! the 1-px ring split by the side its mask neighbour lies on, and the deep floaters outside the
//! mask (10 cm or more in front of the truth): their share of the squared error, how far from
//! the camera they lie and in how many views. With a second model (e.g. the background), the
//! same for it.
//!
//! With `--images`, no model: how far beyond the mask the scene's images differ from the
//! background's image at the same pose. Every pixel of each test view with a background test
//! view at its pose, in the same bands, and per band the median and 90th percentile of the
//! largest channel's |scene − background| (in 1/255) and the share above the change maps'
//! tolerance (`CHANGE_TOLERANCE`, as loaded, before the maps' 3×3 box filter). The masks are the
//! pixel centre's first hit, so a band outside the mask that differs is colour the images carry
//! beyond the object's outline (the renderer's pixel filter, its denoiser, shadows and
//! reflections): what a NeRF trained on the images fits there.
//!
//! ```text
//! cargo run --release --example near_crop_bands -- MODEL SCENE_DIR [BACKGROUND_MODEL]
//! cargo run --release --example near_crop_bands -- --images BACKGROUND_DIR SCENE_DIR...
//! ```

use residual_nerf::data::dataset::{Dataset, LoadOptions};
use residual_nerf::eval::{mask_distance, DepthErrors, NEAR_LIMIT};
use residual_nerf::field::model::Model;
use residual_nerf::io::{load_model, LoadedModel};
use residual_nerf::render::view::Scene;
use residual_nerf::render::{DensityThreshold, ViewRenderer};
use residual_nerf::simd::Isa;
use residual_nerf::train::prior::CHANGE_TOLERANCE;
use std::path::Path;

/// Upper edges of the distance bands (pixels); the last band is everything farther.
const BANDS: [u32; 6] = [0, 1, 2, 4, 8, 16];

fn label(b: usize) -> String {
    match b {
        0 => "object mask".into(),
        _ if b == BANDS.len() => format!("> {} px", BANDS[b - 1]),
        _ => format!("{}–{} px", BANDS[b - 1] + 1, BANDS[b]),
    }
}

/// How far in front of the truth a deep floater lies (metres).
const DEEP: f32 = 0.1;

/// A deep floater nearer the camera than this (metres) is counted apart: nearer than any glass
/// of the dev scenes (0.375 m at the least), it is a floater in front of a camera.
const CAMERA_NEAR: f32 = 0.3;

/// Near-crop pixels outside the mask whose depth lies [`DEEP`] or more in front of the truth.
#[derive(Default)]
struct DeepFloaters {
    /// Their squared error, summed.
    sq_sum: f64,
    /// The same of those nearer the camera than [`CAMERA_NEAR`].
    near_sq_sum: f64,
    /// Their predicted z-depth (from the camera).
    depth: Vec<f32>,
    /// Test views holding at least one.
    views: usize,
}

/// The bands, then the 1-px ring by the side its mask neighbour lies on (left, right, above,
/// below; a pixel with several counts on each), then the deep floaters outside the mask.
fn bands<M: Model>(
    isa: Isa,
    scene: &Scene<'_, M>,
    test: &Dataset,
) -> (Vec<DepthErrors>, [DepthErrors; 4], DeepFloaters) {
    let mut out = vec![DepthErrors::default(); BANDS.len() + 1];
    let mut sides = [DepthErrors::default(); 4];
    let mut deep = DeepFloaters::default();
    let mut renderer = ViewRenderer::new();
    for (v, f) in test.views.iter().zip(&test.frames) {
        let k = &v.intrinsics;
        let (Some(truth), Some(crop), Some(mask)) = (&f.depth, f.crop, f.mask.as_deref()) else { continue };
        let (w, h) = (k.width as usize, k.height as usize);
        let mut z = vec![0.0; w * h];
        renderer.depth(isa, scene, k, &v.pose, DensityThreshold::Sigma(10.0), &mut z);
        let dist = mask_distance(mask, w, h);
        let before = deep.depth.len();
        for y in crop[1] as usize..crop[3] as usize {
            for x in crop[0] as usize..crop[2] as usize {
                let p = y * w + x;
                let t = truth[p];
                if !(t.is_finite() && t > 0.0 && t < NEAR_LIMIT) {
                    continue;
                }
                let b = BANDS.iter().position(|&e| dist[p] <= e).unwrap_or(BANDS.len());
                out[b].add_pixel(z[p], t);
                if b > 0 && z[p] <= t - DEEP {
                    let e = ((z[p] - t) as f64).powi(2);
                    deep.sq_sum += e;
                    if z[p] < CAMERA_NEAR {
                        deep.near_sq_sum += e;
                    }
                    deep.depth.push(z[p]);
                }
                if b == 1 {
                    let near = [
                        (x > 0, p.wrapping_sub(1)),
                        (x + 1 < w, p + 1),
                        (y > 0, p.wrapping_sub(w)),
                        (y + 1 < h, p + w),
                    ];
                    for (side, &(ok, q)) in sides.iter_mut().zip(&near) {
                        if ok && mask[q] {
                            side.add_pixel(z[p], t);
                        }
                    }
                }
            }
        }
        deep.views += usize::from(deep.depth.len() > before);
    }
    (out, sides, deep)
}

fn print(name: &str, b: &[DepthErrors]) {
    let all = b.iter().fold(DepthErrors::default(), |a, x| a.merged(x));
    println!("{name}: near-crop RMSE {:.4} m over {} pixels ({} holes)", all.rmse(), all.pixels, all.holes);
    println!("| band | pixels | share of squared error | RMSE (m) | floaters | see-through |");
    println!("|---|---|---|---|---|---|");
    for (i, x) in b.iter().enumerate().filter(|(_, x)| x.pixels > 0) {
        println!(
            "| {} | {:.1}% | {:.1}% | {:.4} | {:.1}% | {:.1}% |",
            label(i),
            100.0 * x.pixels as f64 / all.pixels as f64,
            100.0 * x.sq_sum / all.sq_sum,
            x.rmse(),
            100.0 * x.floater_rate(),
            100.0 * x.see_through_rate()
        );
    }
}

/// Value at quantile `q` of `v` (sorted in place).
fn quantile(v: &mut [f32], q: f64) -> f32 {
    v.sort_by(f32::total_cmp);
    v.get(((v.len().max(1) - 1) as f64 * q).round() as usize).copied().unwrap_or(f32::NAN)
}

/// `--images`: per scene, the bands' differences from the background image at the same pose.
fn image_profile(bg_dir: &str, scenes: &[String]) -> Result<(), String> {
    let load = |d: &str| Dataset::load(Path::new(d), "test", &LoadOptions::default()).map_err(|e| format!("{d}: {e}"));
    let bg = load(bg_dir)?;
    for dir in scenes {
        let scene = load(dir)?;
        let mut diffs: Vec<Vec<f32>> = vec![Vec::new(); BANDS.len() + 1];
        let mut views = 0;
        for (v, f) in scene.views.iter().zip(&scene.frames) {
            let Some(b) = bg.views.iter().find(|b| b.pose == v.pose && b.intrinsics == v.intrinsics) else {
                continue;
            };
            let mask = f.mask.as_ref().ok_or_else(|| format!("{dir}: test frame {} has no mask", f.index))?;
            let dist = mask_distance(mask, v.intrinsics.width as usize, v.intrinsics.height as usize);
            for (p, (s, c)) in v.rgb.iter().zip(&b.rgb).enumerate() {
                let band = BANDS.iter().position(|&e| dist[p] <= e).unwrap_or(BANDS.len());
                diffs[band].push((0..3).map(|i| (s[i] - c[i]).abs()).fold(0.0, f32::max));
            }
            views += 1;
        }
        if views == 0 {
            return Err(format!("{dir}: no test view at a background test view's pose"));
        }
        let total: usize = diffs.iter().map(Vec::len).sum();
        println!("{dir}: {views} test views at the background's poses");
        println!(
            "| band (distance to the mask) | pixels | median (/255) | 90th percentile (/255) | above the tolerance |"
        );
        println!("|---|---|---|---|---|");
        for (b, d) in diffs.iter_mut().enumerate().filter(|(_, d)| !d.is_empty()) {
            let above = d.iter().filter(|&&x| x > CHANGE_TOLERANCE).count() as f64 / d.len() as f64;
            let share = d.len() as f64 / total as f64;
            let (median, p90) = (quantile(d, 0.5) * 255.0, quantile(d, 0.9) * 255.0);
            println!("| {} | {:.1}% | {median:.1} | {p90:.1} | {:.0}% |", label(b), 100.0 * share, 100.0 * above);
        }
    }
    Ok(())
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if let [flag, bg_dir, scenes @ ..] = &args[..] {
        if flag == "--images" && !scenes.is_empty() {
            return image_profile(bg_dir, scenes);
        }
    }
    let (model, dir, background) = match &args[..] {
        [m, d] => (m, d, None),
        [m, d, b] => (m, d, Some(b)),
        _ => {
            return Err(
                "usage: near_crop_bands MODEL SCENE_DIR [BACKGROUND_MODEL] | --images BACKGROUND_DIR SCENE_DIR..."
                    .into(),
            )
        }
    };
    let isa = Isa::detect();
    let test = Dataset::load(Path::new(dir), "test", &LoadOptions::default()).map_err(|e| format!("{dir}: {e}"))?;
    for path in std::iter::once(model).chain(background) {
        let (b, sides, mut deep) = match load_model(Path::new(path)).map_err(|e| e.to_string())? {
            LoadedModel::Nerf(n) => bands(isa, &Scene::from(&*n), &test),
            LoadedModel::Residual(r) => bands(isa, &Scene::from(&*r), &test),
        };
        print(path, &b);
        let side = |s: &DepthErrors| format!("{:.4} m, {:.1}% floaters", s.rmse(), 100.0 * s.floater_rate());
        println!(
            "1-px ring by the side of its mask neighbour: left {}; right {}; above {}; below {}",
            side(&sides[0]),
            side(&sides[1]),
            side(&sides[2]),
            side(&sides[3])
        );
        let all = b.iter().fold(DepthErrors::default(), |a, x| a.merged(x));
        let n = deep.depth.len();
        let near = deep.depth.iter().filter(|&&d| d < CAMERA_NEAR).count();
        println!(
            "floaters {DEEP} m or more in front of the truth outside the mask: {n} pixels ({:.2}% of the near crop), \
             {:.1}% of its squared error, in {} of {} views; their depth from the camera: median {:.3} m, \
             10th–90th percentiles {:.3}–{:.3} m; nearer than {CAMERA_NEAR} m: {near} pixels, {:.1}% of the \
             squared error",
            100.0 * n as f64 / all.pixels.max(1) as f64,
            100.0 * deep.sq_sum / all.sq_sum.max(f64::MIN_POSITIVE),
            deep.views,
            test.views.len(),
            quantile(&mut deep.depth, 0.5),
            quantile(&mut deep.depth, 0.1),
            quantile(&mut deep.depth, 0.9),
            100.0 * deep.near_sq_sum / all.sq_sum.max(f64::MIN_POSITIVE)
        );
    }
    Ok(())
}
