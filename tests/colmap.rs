//! `rnerf import colmap`: a synthesised background and scene capture through a lens, registered
//! in one "COLMAP" frame (the true world under a similarity: COLMAP's frame and unit are
//! arbitrary), written as a sparse model in text and in binary, imports back to two datasets
//! whose cameras see every surface point at the pixel they saw it at, in metres once one known
//! distance fixes the scale.

use glam::{Mat3, Vec3};
use residual_nerf::data::colmap::{self, ImportOptions};
use residual_nerf::data::workspace::{self, Capture, Glass};
use residual_nerf::data::{Dataset, LoadOptions, View};
use residual_nerf::geometry::{pixel_ray, Distortion, Pose};
use std::path::{Path, PathBuf};
use std::process::Command;

/// COLMAP's frame: `x_colmap = S·R0·x_world + T0`.
const S: f32 = 0.37;
fn r0() -> Mat3 {
    Mat3::from_axis_angle(Vec3::new(0.3, -0.5, 0.8).normalize(), 1.1)
}
const T0: Vec3 = Vec3::new(0.4, -2.0, 1.3);

fn to_colmap(p: Vec3) -> Vec3 {
    S * (r0() * p) + T0
}

struct Capture2 {
    dir: PathBuf,
    /// Metric truth: the views (world frame), with the names they carry in the model.
    truth: Vec<(String, View, Vec<f32>)>,
}

/// Writes the images and the model (text or binary) of a 4-view background and a 4-view scene.
fn capture(name: &str, binary: bool) -> Capture2 {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("colmap").join(name);
    let _ = std::fs::remove_dir_all(&dir);
    let lens = Capture {
        distortion: Distortion::Radial { k: [-0.1, 0.02, 0.0, 0.0], p: [0.001, -0.002] },
        ..Default::default()
    };
    let bg = workspace::workspace_capture(24, 4, 0.0, Glass::None, &lens);
    let scene = workspace::workspace_capture(24, 4, 0.9, Glass::Sphere, &lens);
    let mut truth = Vec::new();
    for (folder, s) in [("bg", &bg), ("scene", &scene)] {
        std::fs::create_dir_all(dir.join("images").join(folder)).unwrap();
        for (i, v) in s.views.iter().enumerate() {
            let name = format!("{folder}/r_{i}.png");
            let bytes = residual_nerf::files::export::rgb_png_bytes(&v.rgb, 24, 24).unwrap();
            std::fs::write(dir.join("images").join(&name), bytes).unwrap();
            truth.push((name, v.clone(), s.depth[i].clone()));
        }
    }
    // The views in COLMAP's frame, and sparse points: surface points seen at every 3rd pixel.
    let mut points = Vec::new();
    let views: Vec<View> = truth
        .iter()
        .map(|(_, v, z)| {
            for p in (0..z.len()).step_by(3).filter(|&p| z[p].is_finite()) {
                let ray = pixel_ray(&v.intrinsics, &v.pose, p as u32 % 24, p as u32 / 24);
                points.push(to_colmap(ray.at(ray.z_to_range(z[p]))));
            }
            let pose = Pose { rotation: r0() * v.pose.rotation, translation: to_colmap(v.pose.translation) };
            View { pose, ..v.clone() }
        })
        .collect();
    let names: Vec<String> = truth.iter().map(|t| t.0.clone()).collect();
    let model = colmap::model_of_views(&views, &names, points);
    colmap::write_model(&model, &dir.join("sparse"), binary).unwrap();
    Capture2 { dir, truth }
}

fn check_import(c: &Capture2) {
    let known = (c.truth[0].1.pose.translation - c.truth[1].1.pose.translation).length() as f64;
    let o = ImportOptions {
        model: c.dir.join("sparse"),
        images: c.dir.join("images"),
        out: c.dir.join("out"),
        background_match: Some("bg/".into()),
        known_distance: Some(("bg/r_0.png".into(), "bg/r_1.png".into(), known)),
    };
    let report = colmap::import(&o).unwrap();
    assert!((report.metres_per_unit - 1.0 / S as f64).abs() < 1e-4, "{}", report.metres_per_unit);
    let opts = LoadOptions { ground_truth: false, ..Default::default() };
    let bg = Dataset::load(&o.out.join("background"), "train", &opts).unwrap();
    let scene = Dataset::load(&o.out.join("scene"), "train", &opts).unwrap();
    assert_eq!((bg.views.len(), scene.views.len()), (4, 4));
    let imported: Vec<&View> = bg.views.iter().chain(&scene.views).collect();
    // In metres, the imported frame is the world under the rotation R0 and a shift.
    let shift = T0 / S;
    for ((name, truth, z), v) in c.truth.iter().zip(&imported) {
        assert_eq!(v.intrinsics, truth.intrinsics, "{name}");
        let off =
            v.rgb.iter().zip(&truth.rgb).flat_map(|(a, b)| (0..3).map(move |c| (a[c] - b[c].clamp(0.0, 1.0)).abs()));
        assert!(off.fold(0f32, f32::max) <= 0.5 / 255.0 + 1e-6, "{name}: pixels (8-bit)");
        let mut checked = 0;
        for p in [0usize, 300, 575] {
            if !z[p].is_finite() {
                continue;
            }
            checked += 1;
            let ray = pixel_ray(&truth.intrinsics, &truth.pose, p as u32 % 24, p as u32 / 24);
            let x = r0() * ray.at(ray.z_to_range(z[p])) + shift;
            let cam = v.pose.rotation.transpose() * (x - v.pose.translation);
            let (u, w) = v.intrinsics.project(cam).unwrap();
            let want = ((p % 24) as f32 + 0.5, (p / 24) as f32 + 0.5);
            assert!((u - want.0).abs() < 0.01 && (w - want.1).abs() < 0.01, "{name} pixel {p}: ({u}, {w}) vs {want:?}");
            assert!((-cam.z - z[p]).abs() < 1e-3 * z[p], "{name} pixel {p}: depth {} vs {}", -cam.z, z[p]);
        }
        assert!(checked > 0, "{name}: no pixel with a surface was checked");
    }
    // The scene box from the points holds the table's centre (in the imported metric frame).
    let centre = r0() * Vec3::new(0.0, 0.0, 0.05) + shift;
    assert!(centre.cmpgt(bg.aabb.min).all() && centre.cmplt(bg.aabb.max).all(), "{:?}", bg.aabb);
    // The images are named relative to the json, so the capture moves as a whole.
    let json = std::fs::read_to_string(o.out.join("scene/transforms_train.json")).unwrap();
    assert!(json.contains("\"../../images/scene/r_0.png\""), "{json}");
    let moved = c.dir.with_extension("moved");
    let _ = std::fs::remove_dir_all(&moved);
    std::fs::rename(&c.dir, &moved).unwrap();
    let scene_moved = Dataset::load(&moved.join("out/scene"), "train", &opts);
    std::fs::rename(&moved, &c.dir).unwrap();
    assert_eq!(scene_moved.unwrap().views[0].rgb, scene.views[0].rgb);
}

#[test]
fn a_text_model_imports_to_a_background_and_a_scene_in_metres() {
    check_import(&capture("text", false));
}

#[test]
fn a_binary_model_imports_the_same() {
    check_import(&capture("binary", true));
}

/// Through the binary: the command writes both datasets and says which scale it used.
#[test]
fn the_import_command_writes_both_datasets_and_states_the_scale() {
    let c = capture("cli", false);
    let d = c.dir.display();
    let args = format!(
        "import colmap --model {d}/sparse --images {d}/images --out {d}/out --background-match bg/ --known-distance bg/r_0.png,bg/r_2.png,1.5"
    );
    let o = Command::new(env!("CARGO_BIN_EXE_rnerf")).args(args.split(' ')).output().unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.contains("background/transforms_train.json (4 frames)") && out.contains("metres_per_unit"), "{out}");
    assert!(c.dir.join("out/scene/transforms_train.json").is_file());
}
