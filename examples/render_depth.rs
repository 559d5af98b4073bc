//! Onboard depth rendering end to end, as a robot's perception node would do it: load a model
//! once, then for each camera pose render threshold depth into a buffer it owns (no
//! allocation per frame), and hand it on — here written as the files a robot stack reads:
//! 32-bit float EXR (metres, NaN holes: ROS 32FC1), 16-bit PNG millimetres (0 = hole: ROS
//! 16UC1), `.npy` float32 metres + intrinsics JSON (Dex-Net / GQ-CNN) and a world-frame PLY.
//!
//! `cargo run --release --example render_depth -- [MODEL] [OUT_DIR]`
//!
//! Without MODEL it first trains a small workspace NeRF on a synthesised scene (≈ 30 s on two
//! cores) and saves it, so the example needs no files.

use residual_nerf::app::demo_config;
use residual_nerf::data::workspace;
use residual_nerf::io::{export, save_nerf};
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
    std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    let model = match model {
        Some(m) => m,
        None => train_small_model(&out)?,
    };

    // Once, at start-up: load the model and size the renderer's thread pool.
    let mut camera = DepthRenderer::load(&model)?.with_threads(2)?;
    let b = camera.scene_box();
    println!("loaded {} (scene box {:?}..{:?})", model.display(), b.min.to_array(), b.max.to_array());

    // Per frame: a pose from the robot's kinematics, the wrist camera's intrinsics, and a
    // depth buffer the node owns.
    let k = Intrinsics::from_fov_x(200, 200, 1.0);
    let mut depth = vec![0.0f32; 200 * 200];
    let request = DepthRequest { method: DepthMethod::default(), kind: DepthKind::Z };
    // Cameras 45° above the box's centre, a third of its diagonal away, all around.
    let (centre, distance) = ((b.min + b.max) * 0.5, (b.max - b.min).length() / 3.0);
    for (i, azimuth) in [0.3f32, 1.4, 2.6].into_iter().enumerate() {
        let dir = glam::Vec3::new(azimuth.cos(), azimuth.sin(), 1.0).normalize();
        let pose = Pose::look_at(centre + distance * dir, centre);
        let t = Instant::now();
        camera.depth(&k, &pose, request, &mut depth)?;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        let hits: Vec<f32> = depth.iter().copied().filter(|z| z.is_finite()).collect();
        let mean = hits.iter().sum::<f32>() / hits.len().max(1) as f32;
        println!("view {i}: {ms:.1} ms, {} of {} pixels hit, mean z {mean:.3} m", hits.len(), depth.len());
        write_view(&out, i, &depth, &k, &pose)?;
    }
    println!("wrote {}", out.display());
    Ok(())
}

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
