//! The scene phase as a robot runs it, in memory: the empty workspace's background trained once,
//! then, when a glass appears, [`train_scene`] from the new images (at the background's poses)
//! and the onboard renderer's depth from poses the scene was not photographed from, scored on
//! the glass against the synthesiser's truth; then, when the glass is replaced by two small
//! ones, a second scene phase over the same [`SceneBackground`], whose prior reads the
//! background's depth at its images' poses from the first instead of rendering it again.
//!
//! ```text
//! cargo run --release --example scene_phase [-- SIZE VIEWS STEPS]
//! ```
//!
//! Defaults: 64-pixel views, 32 of them, 400 steps (the background's and the scene's; the
//! demo's settings, `rnerf demo`).

use residual_nerf::data::workspace;
use residual_nerf::io::LoadedModel;
use residual_nerf::onboard::{DepthRenderer, DepthRequest};
use residual_nerf::simd::Isa;
use residual_nerf::train::prior::PriorConfig;
use residual_nerf::train::scene::{train_scene, SceneBackground};
use residual_nerf::train::trainer::train_nerf;
use std::ops::ControlFlow;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let arg = |i: usize, default: u32| -> Result<u32, String> {
        std::env::args()
            .nth(i)
            .map_or(Ok(default), |a| a.parse().map_err(|_| format!("argument {i}: '{a}' is not a count")))
    };
    let (size, views, steps) = (arg(1, 64)?, arg(2, 32)? as usize, arg(3, 400)?);
    let isa = Isa::detect();
    let demo = residual_nerf::app::demo_config(steps, 0);

    // Once, offline: the empty workspace.
    let t = Instant::now();
    let empty = workspace::workspace(size, views, 0.0, false);
    let background = train_nerf(isa, &empty.views, demo.field.clone(), &demo.train, 0, |_| {})?;
    println!("background: {views} views of {size}x{size}, {steps} steps, {:.1} s", t.elapsed().as_secs_f64());

    // On board, kept for every scene phase: the background and its own images.
    let mut kept = SceneBackground::new(&background, &empty.views)?;
    // When the glass appears: the scene's images at the background's poses.
    let scene = workspace::workspace(size, views, 0.0, true);
    let t = Instant::now();
    let trained =
        train_scene(isa, &mut kept, &scene.views, &demo.train, &PriorConfig::default(), |_| ControlFlow::Continue(()))?;
    let report = |what: &str, trained: &residual_nerf::train::scene::SceneModel, seconds: f64| {
        println!(
            "{what}: {:.1}% of the pixels changed, change region {} cells, {steps} steps, {seconds:.1} s (prior {:.2} s)",
            100.0 * trained.prior.changed_share(),
            trained.prior.region.count(),
            trained.prior_seconds
        )
    };
    report("scene phase", &trained, t.elapsed().as_secs_f64());

    // Depth for the grasp planner from new poses, scored on the glass.
    let mut camera = DepthRenderer::new(LoadedModel::Residual(Box::new(trained.model))).with_threads(2)?;
    let test = workspace::workspace(size, 4, 0.37, true);
    let (mut sum, mut n, mut holes) = (0.0f64, 0usize, 0usize);
    for (i, v) in test.views.iter().enumerate() {
        let mut z = vec![0.0f32; (size * size) as usize];
        camera.depth(&v.intrinsics, &v.pose, DepthRequest::default(), &mut z)?;
        for (p, _) in test.masks[i].iter().enumerate().filter(|(_, &m)| m) {
            n += 1;
            match z[p].is_nan() {
                true => holes += 1,
                false => sum += (z[p] - test.depth[i][p]).abs() as f64,
            }
        }
    }
    println!(
        "depth of the glass from {} new poses: MAE {:.4} m over {} pixels, {:.1}% holes",
        test.views.len(),
        sum / (n - holes).max(1) as f64,
        n - holes,
        100.0 * holes as f64 / n.max(1) as f64
    );

    // Later, two small glasses instead: the prior reads the background's depth it rendered above.
    let again = workspace::workspace_with(size, views, 0.0, workspace::Glass::Spheres(2));
    let t = Instant::now();
    let retrained =
        train_scene(isa, &mut kept, &again.views, &demo.train, &PriorConfig::default(), |_| ControlFlow::Continue(()))?;
    report("second scene phase", &retrained, t.elapsed().as_secs_f64());
    Ok(())
}
