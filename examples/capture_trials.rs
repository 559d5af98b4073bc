//! Real-capture trials on the synthesised workspace: the capture departs from a perfect pinhole
//! camera at exact poses in one way at a time (a lens, an exposure and white-balance change
//! between the background and the scene, poses off by a robot's kinematic error), and Dex-NeRF
//! and Residual-NeRF train on it at the demo's settings; both are scored on exact pinhole test
//! views of the glass (the depth a robot asks for), on the glass's mask.
//!
//! ```text
//! cargo run --release --example capture_trials [SIZE [STEPS [TRIALS [SEED]]]]
//! cargo run --release --example capture_trials 96 600 none,radial,radial-ignored,fisheye,exposure,exposure-uncorrected
//! cargo run --release --example capture_trials 96 600 pose2,pose2-scene-registered,pose2-unregistered,pose5,pose5-scene-registered,pose5-unregistered,pose5-scene-noise,pose5-scene-noise-unregistered
//! ```
//!
//! Trials: `none`; `radial` (OpenCV k1 = −0.15, k2 = 0.03, p1 = 0.002, p2 = −0.001, both
//! captures); `radial-ignored` (the same images, the cameras taken as pinholes: what the lens
//! model buys); `fisheye` (OPENCV_FISHEYE k1 = 0.05, k2 = −0.01, both captures); `exposure` (the
//! scene's images × (1.2, 1.1, 0.9) per channel, saturating at 1, the background's as
//! rendered; Residual-NeRF corrects it to the background's appearance, the prior's default);
//! `exposure-uncorrected` (the same with `--exposure-correction off`); `pose2` / `pose5` (every
//! training pose of both captures off by 2 mm and 0.2°, or 5 mm and 0.5°, in a random
//! direction, the images rendered at the true poses; compensated as a user would: the
//! background trained after a registration pass, `rnerf train --pose-registration on`, and
//! Residual-NeRF registering the scene's images against it, the prior's default);
//! `pose5-two-passes` (the background's registration pass run twice);
//! `pose2-scene-registered` / `pose5-scene-registered` (the scene's registration only);
//! `pose2-unregistered` / `pose5-unregistered` (neither, `--pose-registration off`);
//! `pose5-scene-noise` / `pose5-scene-noise-unregistered` (exact background poses, the scene's
//! off by 5 mm and 0.5°, with and without the scene's registration); `exposure-jitter` (every
//! image of both captures through its own gain per channel, uniform in 1 ± 0.15: auto-exposure
//! and white balance moving from shot to shot; the scene's images corrected to the background's
//! appearance one by one, the prior's default; the background's trained as they are);
//! `exposure-jitter-gains` (the same, every run, the background's and both methods' on the
//! scene, learning a gain per image with the field: `rnerf train --image-gains on`);
//! `exposure-jitter-gains-background` (gains learned by the background's run only);
//! `none-gains` (one exposure, every run learning gains: what they cost where nothing moves).
//! Any trial with `-floor` appended runs the same with the residual's density floor on
//! (`--region-floor 0`, `train::lift`; docs/DECISIONS.md, "The density floor with the raw mix"),
//! and with `-tolT` appended last (e.g. `none-tol0.05`) with the change maps' tolerance T against
//! background images and rendered background alike (`--change-tolerance T,T`; docs/DECISIONS.md,
//! "The change maps' tolerance").
//! SEED (default 0) seeds every run's initialisation and sampling, not the captures.

use residual_nerf::app::{demo_config, train_background};
use residual_nerf::compare::{run_scene, EvalSet, Method};
use residual_nerf::data::workspace::{self, Capture, Glass};
use residual_nerf::geometry::Distortion;
use residual_nerf::simd::Isa;
use residual_nerf::train::lift::LiftConfig;
use residual_nerf::train::register::registration_passes;
use residual_nerf::train::trainer::GAIN_PRIOR;

/// The background's and the scene's capture of a trial.
fn trial(name: &str) -> Result<(Capture, Capture), String> {
    let plain = Capture::default();
    let lens = |distortion| Capture { distortion, ..plain };
    let noisy = |metres, degrees, seed| Capture { pose_noise: Some((metres, degrees, seed)), ..plain };
    Ok(match name {
        "none" | "none-gains" => (plain, plain),
        "radial" | "radial-ignored" => {
            let l = lens(Distortion::Radial { k: [-0.15, 0.03, 0.0, 0.0], p: [0.002, -0.001] });
            (l, l)
        }
        "fisheye" => {
            let l = lens(Distortion::Fisheye { k: [0.05, -0.01, 0.0, 0.0] });
            (l, l)
        }
        "exposure" | "exposure-uncorrected" => (plain, Capture { gain: [1.2, 1.1, 0.9], ..plain }),
        "pose2" | "pose2-scene-registered" | "pose2-unregistered" => (noisy(0.002, 0.2, 1), noisy(0.002, 0.2, 2)),
        "pose5" | "pose5-two-passes" | "pose5-scene-registered" | "pose5-unregistered" => {
            (noisy(0.005, 0.5, 1), noisy(0.005, 0.5, 2))
        }
        "pose5-scene-noise" | "pose5-scene-noise-unregistered" => (plain, noisy(0.005, 0.5, 2)),
        "exposure-jitter" | "exposure-jitter-gains" | "exposure-jitter-gains-background" => {
            let jitter = |seed| Capture { gain_jitter: Some((0.15, seed)), ..plain };
            (jitter(1), jitter(2))
        }
        other => {
            return Err(format!("TRIALS: unknown trial '{other}' (none, none-gains, radial, radial-ignored, fisheye, exposure, exposure-uncorrected, pose2, pose2-scene-registered, pose2-unregistered, pose5, pose5-two-passes, pose5-scene-registered, pose5-unregistered, pose5-scene-noise, pose5-scene-noise-unregistered, exposure-jitter, exposure-jitter-gains, exposure-jitter-gains-background)"))
        }
    })
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let size: u32 = args.first().map_or(Ok(96), |s| s.parse().map_err(|_| format!("SIZE: '{s}' is not a number")))?;
    let steps: u32 = args.get(1).map_or(Ok(600), |s| s.parse().map_err(|_| format!("STEPS: '{s}' is not a number")))?;
    let trials: Vec<&str> = args
        .get(2)
        .map_or("none,radial,radial-ignored,fisheye,exposure,exposure-uncorrected,pose2,pose5", String::as_str)
        .split(',')
        .collect();
    let isa = Isa::detect();
    let seed: u64 = args.get(3).map_or(Ok(0), |s| s.parse().map_err(|_| format!("SEED: '{s}' is not a number")))?;
    let cfg = demo_config(steps, seed);
    let test = EvalSet::from_synth(&workspace::workspace_with(size, 4, 0.37, Glass::Sphere));
    eprintln!("{size}x{size} images, 32 views, {steps} steps, seed {seed}, cpu level {isa}");
    println!(
        "| trial | method | object MAE (m) | holes | see-through | floaters | crop w/o object MAE (m) | PSNR (dB) |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for label in trials {
        // `TRIAL-tolT`: the trial with the change maps' tolerance T (`--change-tolerance T,T`).
        let (name, tolerance) = match label.rsplit_once("-tol").map(|(n, t)| (n, t.parse::<f32>())) {
            Some((name, Ok(t))) => (name, Some(t)),
            _ => (label, None),
        };
        // `TRIAL-floor`: the trial with the residual's density floor on (`--region-floor 0`).
        let (name, floor) = match name.strip_suffix("-floor") {
            Some(name) => (name, true),
            None => (name, false),
        };
        let (bg_capture, scene_capture) = trial(name)?;
        let mut bg = workspace::workspace_capture(size, 32, 0.0, Glass::None, &bg_capture);
        let mut scene = workspace::workspace_capture(size, 32, 0.0, Glass::Sphere, &scene_capture);
        if name == "radial-ignored" {
            // The images through the lens, the cameras taken as pinholes.
            for v in bg.views.iter_mut().chain(scene.views.iter_mut()) {
                v.intrinsics.distortion = Distortion::None;
            }
        }
        // `pose2` / `pose5`: the background's own poses registered first, as `rnerf train
        // --pose-registration on` does for a NeRF (`pose5-two-passes`: twice).
        let passes = match name {
            "pose2" | "pose5" => 1,
            "pose5-two-passes" => 2,
            _ => 0,
        };
        registration_passes(
            isa,
            &mut bg.views,
            cfg.field.clone(),
            &cfg.train,
            passes,
            |_, _| {},
            |pass, regs| {
                let applied = regs.iter().filter(|r| r.applied).count();
                eprintln!("{name}: pass {pass}: {applied} of {} background poses registered", regs.len());
            },
        )
        .map_err(|e| format!("registration pass: {e}"))?;
        let mut cfg = cfg.clone();
        if name.contains("-gains") {
            cfg.train.image_gains = Some(GAIN_PRIOR);
        }
        let background = train_background(isa, &bg.views, &cfg)?;
        if name.ends_with("-gains-background") {
            cfg.train.image_gains = None;
        }
        let methods = [Method::Dex, Method::RESIDUAL];
        cfg.prior.exposure = name != "exposure-uncorrected";
        cfg.prior.register = !name.ends_with("-unregistered");
        if floor {
            cfg.prior.lift = Some(LiftConfig::DEFAULT);
        }
        if let Some(t) = tolerance {
            (cfg.prior.tolerance, cfg.prior.rendered_tolerance) = (t, t);
        }
        let r = run_scene(isa, label, &background, &bg.views, &scene.views, &test, &methods, &cfg, &mut |_, _| {})?;
        for m in &r.methods {
            let (o, rest) = (&m.threshold.object, &m.threshold.rest);
            println!(
                "| {label} | {} | {:.4} | {:.1}% | {:.1}% | {:.1}% | {:.4} | {:.2} |",
                m.method.name(),
                o.mae(),
                100.0 * o.hole_rate(),
                100.0 * o.see_through_rate(),
                100.0 * o.floater_rate(),
                rest.mae(),
                m.psnr
            );
        }
    }
    Ok(())
}
