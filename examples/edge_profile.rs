//! How far beyond the object's mask a scene image differs from the background image at the
//! same pose: the test views' pixels binned by their distance (chessboard, in pixels) to the
//! object mask, and per band the median and 90th percentile of the largest channel's
//! difference |scene − background| (in 1/255) and the share of pixels above the change maps'
//! tolerance ([`CHANGE_TOLERANCE`], as loaded, before the maps' 3×3 box filter). The masks are
//! the pixel centre's first hit, so a band outside the mask that differs is colour the images
//! carry beyond the object's outline (the renderer's pixel filter, its denoiser, shadows and
//! reflections): what a NeRF trained on the images fits there.
//!
//! ```text
//! cargo run --release --example edge_profile -- BACKGROUND_DIR SCENE_DIR...
//! ```
//!
//! Uses each scene's `test` split views whose pose is one of the background's `test` views
//! (the dev set's first 10).

use residual_nerf::data::{Dataset, LoadOptions};
use residual_nerf::train::prior::{dilate, CHANGE_TOLERANCE};
use std::path::Path;

/// Upper edges of the distance bands (pixels); the last band is everything farther.
const BANDS: [u32; 6] = [0, 1, 2, 4, 8, 16];

fn label(b: usize) -> String {
    match b {
        0 => "object mask".into(),
        _ if b == BANDS.len() => format!("> {} px", BANDS[b - 1]),
        _ if BANDS[b - 1] + 1 == BANDS[b] => format!("{} px", BANDS[b]),
        _ => format!("{}–{} px", BANDS[b - 1] + 1, BANDS[b]),
    }
}

/// Value at quantile `q` of `v` (sorted in place).
fn quantile(v: &mut [f32], q: f64) -> f32 {
    v.sort_by(f32::total_cmp);
    v.get(((v.len().max(1) - 1) as f64 * q).round() as usize).copied().unwrap_or(f32::NAN)
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [bg_dir, scenes @ ..] = &args[..] else {
        return Err("usage: edge_profile BACKGROUND_DIR SCENE_DIR...".into());
    };
    let opts = LoadOptions::default();
    let load = |d: &str| Dataset::load(Path::new(d), "test", &opts).map_err(|e| e.to_string());
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
            let (w, h) = (v.intrinsics.width, v.intrinsics.height);
            // Each pixel's band: the first whose dilation of the mask reaches it.
            let grown: Vec<Vec<bool>> = BANDS.iter().map(|&r| dilate(mask, w, h, r)).collect();
            for (p, (s, c)) in v.rgb.iter().zip(&b.rgb).enumerate() {
                let band = grown.iter().position(|g| g[p]).unwrap_or(BANDS.len());
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
