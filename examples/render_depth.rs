//! Onboard depth rendering end to end, as a robot's perception node would do it: load a model
//! once, then for each camera pose render threshold depth into a buffer it owns (no
//! allocation per frame), and hand it on — here written as the files a robot stack reads:
//! 32-bit float EXR (metres, NaN holes: ROS 32FC1), 16-bit PNG millimetres (0 = hole: ROS
//! 16UC1), `.npy` float32 metres + intrinsics JSON (Dex-Net / GQ-CNN) and a world-frame PLY.
//!
//! `cargo run --release --example render_depth -- [MODEL [OUT_DIR [DATA_DIR [SOLID_FRACTION]]]]`
//!
//! Without MODEL it first trains a small workspace NeRF on a synthesised scene (≈ 30 s on two
//! cores) and saves it, so the example needs no files. With DATA_DIR the cameras are the first
//! three of its test split (intrinsics and poses); otherwise three 200×200 cameras around the
//! scene box. Each view is rendered 9 times; the median time is printed (the first frame also
//! grows the renderer's buffers). SOLID_FRACTION sets `DepthRenderer::solid_fraction` (default
//! 0.5), beside the default two-pass start (`DepthRenderer::coarse_start`); every view is also
//! rendered exactly (`exact(true)`: every occupied cell, every ray from the box) to show what
//! they change.

use residual_nerf::app::demo_config;
use residual_nerf::data::{workspace, Dataset, LoadOptions};
use residual_nerf::files::export;
use residual_nerf::io::save_nerf;
use residual_nerf::onboard::{DepthKind, DepthMethod, DepthRenderer, DepthRequest};
use residual_nerf::render::{Intrinsics, Pose};
use residual_nerf::simd::Isa;
use residual_nerf::train::trainer::train_nerf;
use std::path::{Path, PathBuf};
use std::time::Instant;

fn main() -> Result<(), String> {
    let mut args = std::env::args().skip(1);
    let model = args.next().map(PathBuf::from);
    let out = PathBuf::from(args.next().unwrap_or_else(|| "render-depth-out".into()));
    let data = args.next().map(PathBuf::from);
    let fraction: f32 = match args.next() {
        Some(f) => f.parse().map_err(|_| format!("SOLID_FRACTION {f:?} is not a number"))?,
        None => residual_nerf::onboard::SOLID_FRACTION,
    };
    std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    let model = match model {
        Some(m) => m,
        None => train_small_model(&out)?,
    };

    // Once, at start-up: load the model and size the renderer's thread pool. (A second,
    // exact renderer — every occupied cell of every ray marched from the box — is only here to
    // show what the default's cell skipping and two-pass start change.)
    let mut camera = DepthRenderer::load(&model)?.with_threads(2)?.solid_fraction(fraction)?;
    let mut exact = DepthRenderer::load(&model)?.with_threads(2)?.exact(true);
    let b = camera.scene_box();
    println!("loaded {} (scene box {:?}..{:?})", model.display(), b.min.to_array(), b.max.to_array());

    // Per frame: a pose from the robot's kinematics, the camera's intrinsics, and a depth
    // buffer the node owns.
    let cameras: Vec<(Intrinsics, Pose)> = match &data {
        Some(dir) => {
            let opts = LoadOptions { ground_truth: false, ..Default::default() };
            let test = Dataset::load(dir, "test", &opts).map_err(|e| e.to_string())?;
            test.views.iter().take(3).map(|v| (v.intrinsics, v.pose)).collect()
        }
        None => {
            // 45° above the box's centre, a third of its diagonal away, all around.
            let (centre, distance) = ((b.min + b.max) * 0.5, (b.max - b.min).length() / 3.0);
            [0.3f32, 1.4, 2.6]
                .into_iter()
                .map(|azimuth| {
                    let dir = glam::Vec3::new(azimuth.cos(), azimuth.sin(), 1.0).normalize();
                    (Intrinsics::from_fov_x(200, 200, 1.0), Pose::look_at(centre + distance * dir, centre))
                })
                .collect()
        }
    };
    let request = DepthRequest { method: DepthMethod::default(), kind: DepthKind::Z };
    let (mut depth, mut reference) = (Vec::new(), Vec::new());
    for (i, (k, pose)) in cameras.iter().enumerate() {
        depth.resize((k.width * k.height) as usize, 0.0);
        reference.resize(depth.len(), 0.0);
        let time = |cam: &mut DepthRenderer, out: &mut [f32]| -> Result<(f64, Vec<f64>), String> {
            let mut ms: Vec<f64> = (0..REPS)
                .map(|_| {
                    let t = Instant::now();
                    cam.depth(k, pose, request, out).map(|()| t.elapsed().as_secs_f64() * 1e3)
                })
                .collect::<Result<_, _>>()?;
            let first = ms[0];
            ms.sort_by(f64::total_cmp);
            Ok((first, ms))
        };
        let (_, exact_ms) = time(&mut exact, &mut reference)?;
        let (first, ms) = time(&mut camera, &mut depth)?;
        let same_hole = depth.iter().zip(&reference).filter(|(a, b)| a.is_nan() != b.is_nan()).count();
        let diffs: Vec<f32> = depth
            .iter()
            .zip(&reference)
            .filter(|(a, b)| a.is_finite() && b.is_finite())
            .map(|(a, b)| (a - b).abs())
            .collect();
        let over_1cm = diffs.iter().filter(|&&d| d > 0.01).count();
        let mean_diff = diffs.iter().sum::<f32>() / diffs.len().max(1) as f32;
        println!(
            "view {i}: exact marching median {:.1} ms; vs exact: {} pixels differ in hole/hit, {} by more than 1 cm, mean |dz| {:.4} m",
            exact_ms[REPS / 2],
            same_hole,
            over_1cm,
            mean_diff
        );
        let hits: Vec<f32> = depth.iter().copied().filter(|z| z.is_finite()).collect();
        let mean = hits.iter().sum::<f32>() / hits.len().max(1) as f32;
        println!(
            "view {i} ({}x{}): median {:.1} ms (first {first:.1}, range {:.1}-{:.1}), {} of {} pixels hit, mean z {mean:.3} m",
            k.width,
            k.height,
            ms[REPS / 2],
            ms[0],
            ms[REPS - 1],
            hits.len(),
            depth.len()
        );
        write_view(&out, i, &depth, k, pose)?;
    }
    println!("wrote {}", out.display());
    Ok(())
}

/// Timed renders per view (the median is reported).
const REPS: usize = 9;

/// What a perception node publishes for one view.
fn write_view(out: &Path, i: usize, depth: &[f32], k: &Intrinsics, pose: &Pose) -> Result<(), String> {
    let (w, h) = (k.width, k.height);
    let file = |suffix: &str| out.join(format!("view_{i}{suffix}"));
    export::write(&file("_depth.exr"), export::depth_exr_bytes(depth, w, h))?;
    export::write(&file("_depth_mm.png"), export::depth_png_mm_bytes(depth, w, h))?;
    export::write(&file("_depth.npy"), Ok(export::depth_npy_bytes(depth, w, h)))?;
    export::write(&file("_camera.json"), Ok(export::camera_json(k, pose).into_bytes()))?;
    export::write(&file("_points.ply"), Ok(export::depth_ply_bytes(depth, k, pose, None)))
}

/// Trains the demo's background NeRF on a synthesised workspace and saves it.
fn train_small_model(out: &Path) -> Result<PathBuf, String> {
    let cfg = demo_config(300, 0);
    let scene = workspace::workspace(40, 32, 0.0, false);
    println!("no model given: training a small workspace NeRF ({} steps)", cfg.train.steps);
    let t = Instant::now();
    let nerf =
        train_nerf(Isa::detect(), &scene.views, cfg.field.clone(), &cfg.train, 0, |_| {}).map_err(|e| e.to_string())?;
    let path = out.join("workspace.safetensors");
    save_nerf(&path, &nerf, &[])?;
    println!("trained in {:.1} s, saved {}", t.elapsed().as_secs_f64(), path.display());
    Ok(path)
}
