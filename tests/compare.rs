//! `rnerf compare` end to end on tiny synthesised datasets: a background and a scene captured
//! with different camera poses and counts (the paper's real-world set-up), every method, every
//! output file; and a scene whose box differs from the background's is refused before any work.

use residual_nerf::app;
use residual_nerf::cli::parse;
use residual_nerf::data::workspace;
use std::ffi::OsString;
use std::path::{Path, PathBuf};

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("compare").join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn run(args: &[&str]) -> Result<(), String> {
    let command = parse(args.iter().map(OsString::from)).map_err(|e| e.to_string())?;
    app::run(command).map_err(|f| f.message)
}

/// Background: 12 views; scene: 6 training views on other poses, 2 test views.
fn datasets(dir: &Path) -> (PathBuf, PathBuf) {
    let (bg, scene) = (dir.join("background"), dir.join("glass"));
    workspace::workspace(16, 12, 0.0, false).write_split(&bg, "train").unwrap();
    workspace::workspace(16, 6, 0.5, true).write_split(&scene, "train").unwrap();
    workspace::workspace(16, 2, 0.37, true).write_split(&scene, "test").unwrap();
    (bg, scene)
}

#[test]
fn compare_writes_the_table_curves_and_depth_sheets() {
    let dir = scratch("full");
    let (bg, scene) = datasets(&dir);
    let out = dir.join("out");
    let (bg_s, scene_s, out_s) = (bg.to_str().unwrap(), scene.to_str().unwrap(), out.to_str().unwrap());
    run(&[
        "compare",
        "--background",
        bg_s,
        "--scene",
        scene_s,
        "--out",
        out_s,
        "--methods",
        "dex,residual-paper-shared,residual-s",
        "--steps",
        "20",
        "--rays",
        "128",
        "--log2t",
        "12",
        "--eval-every",
        "10",
    ])
    .unwrap();
    let table = std::fs::read_to_string(out.join("table.md")).unwrap();
    for label in ["NeRF (expected depth)", "Dex-NeRF", "Residual-NeRF (paper, shared encoding)", "Residual-NeRF-S"] {
        assert!(table.contains(label), "table lacks {label}:\n{table}");
    }
    let doc: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("table.json")).unwrap()).unwrap();
    let rows = doc["rows"].as_array().unwrap();
    assert_eq!(doc["rays_per_step"], 128, "--rays fixes every run's count");
    assert!(rows.iter().all(|r| r["rays_per_step"] == 128), "{rows:?}");
    let (sweep, main): (Vec<_>, Vec<_>) = rows.iter().partition(|r| r.get("threshold").is_some());
    assert_eq!(main.len(), 4, "nerf-expected, dex, residual-paper-shared, residual-s");
    assert_eq!(sweep.len(), 3 * 4, "each trained method at the 4 thresholds of the default sweep");
    for r in rows {
        for region in ["crop", "near_crop", "object", "crop_without_object"] {
            assert!(r[region]["mae"].as_f64().is_some_and(|v| v.is_finite() && v >= 0.0), "{region}: {r}");
            assert!(r[region]["see_through"].as_f64().is_some_and(|v| (0.0..=1.0).contains(&v)), "{region}: {r}");
        }
        assert_eq!(r["scene"], "glass");
    }
    let csv = std::fs::read_to_string(out.join("curves.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 3 * 2, "two curve points per method:\n{csv}");
    assert!(csv.lines().skip(1).all(|l| l.starts_with("glass,")));
    // One sheet per test view: truth, NeRF, 3 methods, β, error — 7 panels side by side
    // (magnified).
    for i in 0..2 {
        let sheet = image::open(out.join(format!("glass/depth_{i}.png"))).unwrap();
        assert_eq!(sheet.width(), 7 * (160 + 4), "sheet {i}");
    }
    assert!(image::open(out.join("glass/curves.png")).is_ok());
    // The trained background is kept for later runs (--background-model), trained for three
    // times the scenes' steps (it is trained once, offline).
    let model = out.join("background.safetensors");
    let bytes = std::fs::read(&model).unwrap();
    let (_, meta) = safetensors::SafeTensors::read_metadata(&bytes).unwrap();
    let steps = meta.metadata().as_ref().and_then(|m| m.get("train_steps").cloned());
    assert_eq!(steps.as_deref(), Some("60"), "the background's steps: 3 × --steps 20");
    let out2 = dir.join("out2");
    run(&[
        "compare",
        "--background",
        bg_s,
        "--background-model",
        model.to_str().unwrap(),
        "--scene",
        scene_s,
        "--out",
        out2.to_str().unwrap(),
        "--methods",
        "residual",
        "--steps",
        "10",
        "--log2t",
        "12",
    ])
    .unwrap();
    assert!(!out2.join("background.safetensors").exists(), "a given background is not retrained");
    let given = run(&[
        "compare",
        "--background",
        bg_s,
        "--background-model",
        model.to_str().unwrap(),
        "--background-steps",
        "30",
        "--scene",
        scene_s,
        "--out",
        dir.join("out3").to_str().unwrap(),
    ]);
    assert_eq!(given.unwrap_err(), "--background-steps: the background is loaded from --background-model, not trained");
    // Without --rays each run draws its capture's count: 6 views of 16×16 take the floor, half
    // of the default.
    let doc: serde_json::Value = serde_json::from_slice(&std::fs::read(out2.join("table.json")).unwrap()).unwrap();
    assert!(doc["rays_per_step"].is_null(), "{doc}");
    let rows = doc["rows"].as_array().unwrap();
    let half = residual_nerf::train::trainer::TRAIN_RAYS / 2;
    assert!(!rows.is_empty() && rows.iter().all(|r| r["rays_per_step"] == half), "{rows:?}");
    // The background-aware method on a scene captured from other poses: change maps against the
    // rendered background (no background image at the scene's poses).
    let table = std::fs::read_to_string(out2.join("table.md")).unwrap();
    assert!(table.contains("0/6 views against a background image"), "{table}");
    assert!(table.contains("| glass | Residual-NeRF |"), "{table}");
}

#[test]
fn compare_refuses_a_scene_in_another_box_before_any_work() {
    let dir = scratch("box");
    let bg = dir.join("background");
    workspace::workspace(8, 4, 0.0, false).write_split(&bg, "train").unwrap();
    let scene = dir.join("moved");
    let mut s = workspace::workspace(8, 4, 0.5, true);
    s.aabb.max.z += 1.0;
    s.write_split(&scene, "train").unwrap();
    s.write_split(&scene, "test").unwrap();
    let out = dir.join("out");
    let e = run(&[
        "compare",
        "--background",
        bg.to_str().unwrap(),
        "--scene",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ])
    .unwrap_err();
    assert!(e.contains("transforms_train.json") && e.contains("field 'aabb'"), "{e}");
    assert!(!e.contains('\n'), "one line: {e}");
    assert!(!out.exists(), "nothing may be written");
}

/// `rnerf demo` (sized down): the datasets, the table, the sheets and the saved models, which
/// `rnerf eval` and `rnerf render` then read, as the demo's closing lines suggest.
#[test]
fn demo_writes_data_table_sheets_and_models_the_next_commands_read() {
    let dir = scratch("demo");
    let out = dir.join("demo");
    let out_s = out.to_str().unwrap();
    run(&["demo", "--out", out_s, "--size", "16", "--steps", "20"]).unwrap();
    for f in ["table.md", "table.json", "curves.csv", "glass/curves.png", "glass/depth_0.png"] {
        assert!(out.join(f).is_file(), "demo did not write {f}");
    }
    let table = std::fs::read_to_string(out.join("table.md")).unwrap();
    assert!(table.contains("Dex-NeRF") && table.contains("Residual-NeRF"), "{table}");
    let models = out.join("models");
    for f in ["background.safetensors", "glass_dex.safetensors", "glass_residual.safetensors"] {
        assert!(models.join(f).is_file(), "demo did not save models/{f}");
    }
    let (model, data) = (models.join("glass_residual.safetensors"), out.join("data/glass"));
    let (model_s, data_s) = (model.to_str().unwrap(), data.to_str().unwrap());
    run(&["eval", "--model", model_s, "--data", data_s]).unwrap();
    run(&["eval", "--model", model_s, "--data", data_s, "--depth-only", "--json"]).unwrap();
    let render = dir.join("render");
    run(&["render", "--model", model_s, "--data", data_s, "--split", "test", "--out", render.to_str().unwrap()])
        .unwrap();
    assert!(render.read_dir().unwrap().count() > 0, "render wrote nothing");
    let depth_only = dir.join("render_depth_only");
    run(&["render", "--model", model_s, "--data", data_s, "--out", depth_only.to_str().unwrap(), "--depth-only"])
        .unwrap();
    let names: Vec<String> =
        depth_only.read_dir().unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    assert!(names.iter().any(|n| n.ends_with("_depth.exr")) && names.iter().any(|n| n.ends_with("_points.ply")));
    assert!(!names.iter().any(|n| n.ends_with("_rgb.png") || n.ends_with("_beta.png")), "{names:?}");
    // The depth-only evaluation scores the same threshold depth as the full pass, without PSNR.
    let model = residual_nerf::io::load_model(&model).unwrap();
    let opts = residual_nerf::data::LoadOptions::default();
    let data = residual_nerf::data::Dataset::load(&data, "test", &opts).unwrap();
    let isa = residual_nerf::simd::Isa::detect();
    let residual_nerf::io::LoadedModel::Residual(r) = &model else { panic!("the demo saves a residual model") };
    let scene = residual_nerf::render::view::Scene::from(&**r);
    // A low threshold: the sized-down demo's 20-step model is still foggy and nothing in it
    // reaches the default σ ≥ 10, which would make the comparison empty.
    let m = residual_nerf::render::DensityThreshold::Sigma(1.0);
    let depth = residual_nerf::render::DepthMethod::Threshold(m);
    let crop = residual_nerf::eval::CropRule::Frame;
    let eval_tail = |depth_only, solid_fraction, coarse_start, colour_tail| {
        let (background, limit) = (opts.background, None);
        let eval =
            app::EvalOptions { depth, crop, limit, background, depth_only, solid_fraction, coarse_start, colour_tail };
        app::evaluate(isa, &scene, &data, &eval, |_| {})
    };
    let eval = |depth_only, solid_fraction, coarse_start| eval_tail(depth_only, solid_fraction, coarse_start, 0.0);
    let (full, fast) = (eval(false, 0.0, None), eval(true, 0.0, None));
    assert!(full.depth.pixels > 0 && full.psnr.is_finite() && fast.psnr.is_nan());
    assert!(full.depth.holes < full.depth.pixels, "the demo model hits nothing: the comparison would be empty");
    assert_eq!((fast.depth, fast.regions), (full.depth, full.regions));
    // The colour tail moves the colour by its quadrature error and no threshold depth.
    let tailed = eval_tail(false, 0.0, None, residual_nerf::render::view::COLOUR_TAIL);
    assert_eq!((tailed.depth, tailed.regions), (full.depth, full.regions));
    assert!((tailed.psnr - full.psnr).abs() < 0.5, "PSNR {} with the colour tail, {} without", tailed.psnr, full.psnr);
    // With a solid fraction and the coarse start it scores what the onboard renderer returns
    // at that fraction (4: the demo model is faint, and a smaller one drops none of the cells
    // its rays stop in) and its default start.
    use residual_nerf::onboard::{DepthKind, DepthRenderer, DepthRequest};
    let mut camera =
        DepthRenderer::load(&models.join("glass_residual.safetensors")).unwrap().solid_fraction(4.0).unwrap();
    let request = DepthRequest { method: depth, kind: DepthKind::Z };
    let mut robot = residual_nerf::eval::DepthErrors::default();
    for (v, f) in data.views.iter().zip(&data.frames) {
        let k = &v.intrinsics;
        let mut z = vec![0.0; (k.width * k.height) as usize];
        camera.depth(k, &v.pose, request, &mut z).unwrap();
        let gt = f.depth.as_ref().expect("the demo's test views have depth");
        robot.add_frame(&z, gt, k.width, residual_nerf::eval::crop_box(crop, k.width, k.height, f.crop), None);
    }
    let thinned = eval(true, 4.0, Some(residual_nerf::onboard::COARSE_MARGIN));
    assert_eq!(thinned.depth, robot);
    assert!(thinned.depth != fast.depth, "the demo model's grid has no cell the fraction drops");
}
