//! `rnerf train` as a robot runs it: SIGINT finishes the step, writes a checkpoint and exits
//! 130 without touching `--out`; `--resume` then ends with the same tensors as a run never
//! interrupted (tensors and metadata), and removes the checkpoint. A checkpoint resumes only on
//! its own data.

use residual_nerf::app::checkpoint_path;
use residual_nerf::data::{workspace, Dataset, LoadOptions};
use residual_nerf::encoding::HashGridConfig;
use residual_nerf::field::{NerfConfig, NerfField};
use residual_nerf::io::{save_checkpoint, views_fingerprint};
use residual_nerf::simd::Isa;
use residual_nerf::train::trainer::{TrainConfig, Trainer};
use safetensors::SafeTensors;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli_train").join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn rnerf(args: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_rnerf"));
    c.args(args).stdout(Stdio::null()).stderr(Stdio::piped());
    c
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The tensors of a model file, by name (metadata, e.g. seconds, may differ).
fn tensors(path: &Path) -> Vec<(String, Vec<u8>)> {
    let bytes = std::fs::read(path).unwrap();
    let st = SafeTensors::deserialize(&bytes).unwrap();
    let mut v: Vec<(String, Vec<u8>)> =
        st.tensors().into_iter().map(|(n, t)| (n.to_string(), t.data().to_vec())).collect();
    v.sort();
    v
}

/// A model file's metadata without the entries that differ between an uninterrupted and a
/// resumed run by nature (training seconds, where it resumed from).
fn run_metadata(path: &Path) -> Vec<(String, String)> {
    let bytes = std::fs::read(path).unwrap();
    let (_, meta) = SafeTensors::read_metadata(&bytes).unwrap();
    let mut v: Vec<(String, String)> = meta
        .metadata()
        .clone()
        .unwrap_or_default()
        .into_iter()
        .filter(|(k, _)| k != "train_seconds" && k != "train_resumed_from")
        .collect();
    v.sort();
    v
}

const SETTINGS: [&str; 6] = ["--steps", "30", "--rays", "128", "--log2t", "12"];

/// Runs `rnerf ARGS` (with `--checkpoint-every`), sends SIGINT once its first checkpoint
/// `ckpt` appears (the run is under way), and returns its output.
fn interrupted_at_first_checkpoint(args: &[&str], ckpt: &Path) -> Output {
    let mut child = rnerf(args).spawn().unwrap();
    let t0 = Instant::now();
    while !ckpt.exists() {
        assert!(t0.elapsed() < Duration::from_secs(120), "no checkpoint appeared");
        assert!(child.try_wait().unwrap().is_none(), "the run ended before its first checkpoint");
        std::thread::sleep(Duration::from_millis(5));
    }
    let kill = Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(kill.success());
    child.wait_with_output().unwrap()
}

#[test]
fn an_interrupted_run_resumes_to_the_same_model() {
    let dir = scratch("resume");
    let data = dir.join("data");
    workspace::workspace(16, 8, 0.0, false).write_split(&data, "train").unwrap();
    let data_s = data.to_str().unwrap();

    let straight = dir.join("straight.safetensors");
    let o = rnerf(&[&["train", "--data", data_s, "--out", straight.to_str().unwrap()], &SETTINGS[..]].concat())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));

    let out = dir.join("m.safetensors");
    let out_s = out.to_str().unwrap();
    let ckpt = checkpoint_path(&out);
    assert_eq!(ckpt, dir.join("m.ckpt.safetensors"));
    let args = [&["train", "--data", data_s, "--out", out_s, "--checkpoint-every", "5"], &SETTINGS[..]].concat();
    let o = interrupted_at_first_checkpoint(&args, &ckpt);
    let msg = stderr(&o);
    assert_eq!(o.status.code(), Some(130), "SIGINT must exit 130: {msg}");
    assert!(msg.contains("interrupted") && msg.contains("--resume"), "{msg}");
    assert!(!out.exists(), "an interrupted run must not write --out");
    assert!(ckpt.exists());

    let o = rnerf(&["train", "--resume", ckpt.to_str().unwrap(), "--data", data_s, "--out", out_s]).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("resuming"), "{}", stderr(&o));
    assert!(!ckpt.exists(), "a finished run removes its checkpoint");
    let (a, b) = (tensors(&straight), tensors(&out));
    assert_eq!(a.len(), b.len());
    for ((na, ta), (nb, tb)) in a.iter().zip(&b) {
        assert_eq!(na, nb);
        assert!(ta == tb, "tensor {na} differs between the resumed and the uninterrupted run");
    }
    assert!(!a.iter().any(|(n, _)| n.starts_with("train.")), "a finished model carries no training state");
    let (ma, mb) = (run_metadata(&straight), run_metadata(&out));
    assert!(ma.iter().any(|(k, _)| k == "train_lr") && ma.iter().any(|(k, _)| k == "train_random_background"));
    assert_eq!(ma, mb, "the resumed model's metadata differs from the uninterrupted one's");
    assert!(SafeTensors::read_metadata(&std::fs::read(&out).unwrap())
        .unwrap()
        .1
        .metadata()
        .as_ref()
        .unwrap()
        .contains_key("train_resumed_from"));
}

#[test]
fn a_checkpoint_resumes_only_on_its_own_data() {
    let dir = scratch("other_data");
    let (data, other) = (dir.join("data"), dir.join("other"));
    workspace::workspace(16, 4, 0.0, false).write_split(&data, "train").unwrap();
    workspace::workspace(16, 4, 0.3, false).write_split(&other, "train").unwrap();
    let out = dir.join("m.safetensors");
    let x = dir.join("x.safetensors");
    let (data_s, other_s, out_s, x_s) =
        (data.to_str().unwrap(), other.to_str().unwrap(), out.to_str().unwrap(), x.to_str().unwrap());
    let o = rnerf(&["train", "--data", data_s, "--out", out_s, "--steps", "3", "--log2t", "10"]).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    // Without --rays a capture this small trains at the floor of `rays_for_capture`.
    let half = (residual_nerf::train::trainer::TRAIN_RAYS / 2).to_string();
    assert!(run_metadata(&out).contains(&("train_rays_per_step".to_string(), half)), "{:?}", run_metadata(&out));
    // A finished model is not a checkpoint.
    let o = rnerf(&["train", "--resume", out_s, "--data", data_s, "--out", x_s]).output().unwrap();
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("not a checkpoint"), "{}", stderr(&o));
    // A checkpoint of 2 steps of 6 on `data`, written through the library from the dataset
    // as `rnerf train` loads it.
    let ds = Dataset::load(&data, "train", &LoadOptions { ground_truth: false, ..Default::default() }).unwrap();
    let field = NerfField::new(NerfConfig {
        grid: HashGridConfig { log2_table_size: 10, ..Default::default() },
        aabb: ds.aabb,
    });
    let mut cfg = TrainConfig::with_steps(6);
    cfg.rays_per_step = 64;
    let mut t = Trainer::new(Isa::detect(), &field, ds.aabb, &ds.views, &cfg);
    t.step().unwrap();
    t.step().unwrap();
    let ckpt = dir.join("c.ckpt.safetensors");
    save_checkpoint(&ckpt, &field, t.state(), &cfg, views_fingerprint(&ds.views), &[]).unwrap();
    let ckpt_s = ckpt.to_str().unwrap();
    let o = rnerf(&["train", "--resume", ckpt_s, "--data", other_s, "--out", x_s]).output().unwrap();
    let msg = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{msg}");
    assert!(msg.contains("transforms_train.json") && msg.contains("not the data"), "{msg}");
    assert!(!x.exists());
    let o = rnerf(&["train", "--resume", ckpt_s, "--data", data_s, "--out", x_s]).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("at step 2 of 6"), "{}", stderr(&o));
    assert!(x.exists());
}

/// `--pose-registration on` for a NeRF: a registration pass, then the run proper at the
/// registered poses, which the model's metadata records; interrupted and resumed, the run
/// trains at the same poses (its data's fingerprint matches) and ends with the same model.
#[test]
fn a_registered_run_resumes_at_its_registered_poses() {
    let dir = scratch("registered");
    let data = dir.join("data");
    let noisy = workspace::Capture { pose_noise: Some((0.005, 0.5, 1)), ..Default::default() };
    workspace::workspace_capture(40, 10, 0.0, workspace::Glass::None, &noisy).write_split(&data, "train").unwrap();
    let data_s = data.to_str().unwrap();
    // Enough steps for a first NeRF that registration can use.
    let register = ["--pose-registration", "on", "--steps", "100", "--rays", "256", "--log2t", "12"];
    let straight = dir.join("straight.safetensors");
    let o = rnerf(&[&["train", "--data", data_s, "--out", straight.to_str().unwrap()], &register[..]].concat())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("registration:"), "{}", stderr(&o));
    let meta = run_metadata(&straight);
    let poses = meta.iter().find(|(k, _)| k == "train_registered_poses").map(|(_, v)| v.clone());
    assert!(poses.is_some_and(|p| p.contains("[[")), "no registered pose recorded: {}", stderr(&o));

    let out = dir.join("m.safetensors");
    let out_s = out.to_str().unwrap();
    let ckpt = checkpoint_path(&out);
    let args = [&["train", "--data", data_s, "--out", out_s, "--checkpoint-every", "5"], &register[..]].concat();
    let o = interrupted_at_first_checkpoint(&args, &ckpt);
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    let o = rnerf(&["train", "--resume", ckpt.to_str().unwrap(), "--data", data_s, "--out", out_s]).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(tensors(&straight), tensors(&out), "the resumed model differs from the uninterrupted one");
    assert_eq!(run_metadata(&straight), run_metadata(&out));
}

/// The scene phase through the library (`train::scene::train_scene`: what a robot calls with
/// its images in memory) is `rnerf train --data SCENE --background BG --background-data
/// BACKGROUND`: the same prior, start and training, so the same model tensor for tensor.
#[test]
fn the_librarys_scene_phase_trains_the_command_lines_model() {
    use residual_nerf::field::mix::{DensityMix, MixKind};
    use residual_nerf::field::mixnet::MixnetEncoding;
    use residual_nerf::field::residual::{ResidualConfig, ResidualModel};
    use residual_nerf::io::{save_nerf, save_residual};
    use residual_nerf::render::DensityThreshold;
    use residual_nerf::train::prior::PriorConfig;
    use residual_nerf::train::prior::{residual_start, scene_prior, Prior};
    use residual_nerf::train::scene::{train_scene, SceneBackground};
    use residual_nerf::train::trainer::{train_nerf, StepStats};
    use std::ops::ControlFlow;
    let dir = scratch("scene_phase");
    let isa = Isa::detect();
    let (bg_dir, scene_dir) = (dir.join("background"), dir.join("scene"));
    let bg = workspace::workspace(32, 16, 0.0, false);
    let demo = residual_nerf::app::demo_config(150, 0);
    let background = train_nerf(isa, &bg.views, demo.field.clone(), &demo.train, 0, |_| {}).unwrap();
    let bg_model = dir.join("bg.safetensors");
    // Its file says it trained 100 steps, fewer than 3 x the scene phase's 40: the run notes it.
    save_nerf(&bg_model, &background, &[("train_steps", "100".into())]).unwrap();
    bg.write_split(&bg_dir, "train").unwrap();
    workspace::workspace(32, 16, 0.0, true).write_split(&scene_dir, "train").unwrap();
    let out = dir.join("cli.safetensors");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let args = [
        "train",
        "--data",
        &s(&scene_dir),
        "--background",
        &s(&bg_model),
        "--background-data",
        &s(&bg_dir),
        "--steps",
        "40",
        "--seed",
        "3",
        "--out",
        &s(&out),
    ];
    let o = rnerf(&args).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let note = "trained 100 steps, fewer than 3 x this scene phase's 40; one trained 120 steps";
    assert!(stderr(&o).contains(note), "no note on the short background: {}", stderr(&o));
    // The images as `rnerf train` reads them, and its settings for this capture.
    let opts = LoadOptions { ground_truth: false, ..Default::default() };
    let (bg_data, scene) =
        (Dataset::load(&bg_dir, "train", &opts).unwrap(), Dataset::load(&scene_dir, "train", &opts).unwrap());
    let mut cfg = TrainConfig::with_steps(40);
    cfg.seed = 3;
    cfg.random_background = !scene.had_alpha;
    cfg.rays_per_step = cfg.rays_for_views(&scene.views);
    let (mut steps, pcfg) = (0, PriorConfig::default());
    let mut bg = SceneBackground::new(&background, &bg_data.views).unwrap();
    let lib = train_scene(isa, &mut bg, &scene.views, &cfg, &pcfg, |_| {
        steps += 1;
        ControlFlow::Continue(())
    })
    .unwrap();
    assert_eq!((steps, lib.steps), (40, 40));
    assert_eq!(lib.prior.matched_views, 16, "every scene view has a background image at its pose");
    assert!(lib.model.field.region().is_some_and(|r| r.count() > 0), "no change region");
    let lib_file = dir.join("lib.safetensors");
    save_residual(&lib_file, &lib.model, &[]).unwrap();
    assert_eq!(tensors(&lib_file), tensors(&out));

    // Stopped by its log after 15 of the 40 steps: the run's first 15 steps, its change region
    // settled as a finished run's is; by hand, the same start stepped 15 times and finished.
    let stop = |s: &StepStats| if s.step + 1 == 15 { ControlFlow::Break(()) } else { ControlFlow::Continue(()) };
    let stopped = train_scene(isa, &mut bg, &scene.views, &cfg, &pcfg, stop).unwrap();
    assert_eq!(stopped.steps, 15);
    let prior =
        scene_prior(isa, &background, &bg_data.views, &scene.views, cfg.background, DensityThreshold::DEFAULT, &pcfg);
    let config = ResidualConfig {
        residual: background.field.config().clone(),
        kind: MixKind::Mixnet(DensityMix::Raw),
        mixnet: MixnetEncoding::default(),
    };
    let mut start = residual_start(isa, &background, config, Prior::ALL, Some(&prior), &cfg, &pcfg);
    let run_cfg = start.train_config(&cfg);
    let corrected = prior.corrects_views().then(|| prior.corrected_views(&scene.views));
    let views = corrected.as_deref().unwrap_or(&scene.views);
    let by_hand = |finish: bool| {
        let (params, occupancy) = (start.params.clone(), start.occupancy.clone());
        let mut t = Trainer::starting_at(isa, &start.field, views, &run_cfg, params, occupancy);
        for _ in 0..15 {
            t.step().unwrap();
        }
        let state = if finish { t.finish() } else { t.into_state() };
        let file = dir.join(if finish { "finished.safetensors" } else { "unsettled.safetensors" });
        let model = ResidualModel { field: start.field.clone(), params: state.params, occupancy: state.occupancy };
        save_residual(&file, &model, &[]).unwrap();
        tensors(&file)
    };
    let stopped_file = dir.join("stopped.safetensors");
    save_residual(&stopped_file, &stopped.model, &[]).unwrap();
    assert_eq!(tensors(&stopped_file), by_hand(true), "a stopped scene phase is not its first steps, finished");
    assert_ne!(tensors(&stopped_file), by_hand(false), "stopping early did not settle the change region");

    // `rnerf train --budget 0`: out of time before the first step, so it stops after that step
    // and writes the library's model stopped there, saying so in its metadata.
    let first = train_scene(isa, &mut bg, &scene.views, &cfg, &pcfg, |_| ControlFlow::Break(())).unwrap();
    assert_eq!(first.steps, 1);
    let first_file = dir.join("first.safetensors");
    save_residual(&first_file, &first.model, &[]).unwrap();
    let budget_out = dir.join("budget.safetensors");
    let mut budget_args = args.to_vec();
    let out_at = budget_args.len() - 1;
    budget_args[out_at] = budget_out.to_str().unwrap();
    budget_args.extend(["--budget", "0"]);
    let o = rnerf(&budget_args).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("--budget 0 s spent"), "{}", stderr(&o));
    assert_eq!(tensors(&budget_out), tensors(&first_file), "--budget 0 is not the run stopped after its first step");
    let stopped_at = run_metadata(&budget_out).into_iter().find(|(k, _)| k == "train_stopped").map(|(_, v)| v);
    assert_eq!(stopped_at.as_deref(), Some("after step 1 of 40 (--budget 0 s)"));
    assert!(run_metadata(&out).iter().all(|(k, _)| k != "train_stopped"), "a finished run says it was stopped");
}
