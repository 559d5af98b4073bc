//! Dataset loading (DESIGN §3): the NeRF-synthetic layout and its variants load to the right
//! cameras and pixels; bad input gives one-line errors naming the file, frame and field.

use residual_nerf::data::{AabbSource, Dataset, DepthKind, FrameType, LoadOptions};
use residual_nerf::files::export::depth_exr_bytes;
use residual_nerf::render::pixel_ray;
use serde_json::json;
use std::path::{Path, PathBuf};

/// A fresh empty directory under the target dir.
fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("data_loading").join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("train")).unwrap();
    dir
}

fn png_rgb8(path: &Path, w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 3]) {
    image::RgbImage::from_fn(w, h, |x, y| image::Rgb(f(x, y))).save(path).unwrap();
}

fn pose(tz: f64) -> serde_json::Value {
    json!([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, tz], [0, 0, 0, 1]])
}

fn write_json(dir: &Path, name: &str, v: &serde_json::Value) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, serde_json::to_vec_pretty(v).unwrap()).unwrap();
    p
}

#[test]
fn nerf_synthetic_layout_loads_cameras_pixels_and_ground_truth() {
    let dir = scratch("synthetic");
    png_rgb8(&dir.join("train/r_0.png"), 8, 6, |x, y| [x as u8 * 30, y as u8 * 40, 7]);
    // 3×4 pose, extension given, per-frame intrinsics overriding the top level.
    png_rgb8(&dir.join("train/r_1.png"), 8, 6, |_, _| [255, 0, 0]);
    let depth: Vec<f32> = (0..48).map(|i| 1.0 + i as f32 * 0.01).collect();
    std::fs::write(dir.join("train/d_0.exr"), depth_exr_bytes(&depth, 8, 6).unwrap()).unwrap();
    image::GrayImage::from_fn(8, 6, |x, _| image::Luma([if x < 4 { 255 } else { 0 }]))
        .save(dir.join("train/m_0.png"))
        .unwrap();
    write_json(
        &dir,
        "transforms_train.json",
        &json!({
            "camera_angle_x": 0.8, "aabb": [[-1, -1, -1], [1, 1, 1]], "depth_kind": "range", "unknown_key": 5,
            "frames": [
                {"file_path": "./train/r_0", "transform_matrix": pose(2.0), "depth_file_path": "train/d_0.exr",
                 "mask_path": "train/m_0.png", "crop": [1, 1, 7, 5]},
                {"file_path": "train/r_1.png", "transform_matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 3]],
                 "fl_x": 10.0, "cx": 4.5},
            ]
        }),
    );
    let d = Dataset::load(&dir, "train", &LoadOptions::default()).unwrap();
    assert_eq!(d.views.len(), 2);
    assert_eq!(d.aabb_source, AabbSource::File);
    assert_eq!(d.depth_kind, DepthKind::Range);
    let k0 = d.views[0].intrinsics;
    assert_eq!((k0.width, k0.height, k0.cx, k0.cy), (8, 6, 4.0, 3.0));
    assert!((k0.fx - 4.0 / (0.4f32).tan()).abs() < 1e-4 && k0.fy == k0.fx);
    let k1 = d.views[1].intrinsics;
    assert_eq!((k1.fx, k1.fy, k1.cx, k1.cy), (10.0, 10.0, 4.5, 3.0));
    assert_eq!(d.views[1].pose.translation.z, 3.0);
    assert_eq!(d.views[0].rgb[8 + 3], [90.0 / 255.0, 40.0 / 255.0, 7.0 / 255.0]);
    // Range in the file → z in memory: z = t · (d · forward).
    let gt = d.frames[0].depth.as_ref().unwrap();
    let ray = pixel_ray(&k0, &d.views[0].pose, 5, 2);
    assert!((gt[2 * 8 + 5] - depth[2 * 8 + 5] * ray.z_per_t).abs() < 1e-6);
    let mask = d.frames[0].mask.as_ref().unwrap();
    assert!(mask[3] && !mask[4]);
    assert_eq!(d.frames[0].crop, Some([1, 1, 7, 5]));
}

#[test]
fn sixteen_bit_gray_rgba_and_jpeg_images_load() {
    let dir = scratch("formats");
    image::ImageBuffer::<image::Luma<u16>, _>::from_fn(4, 4, |x, _| image::Luma([x as u16 * 1000 + 1]))
        .save(dir.join("train/g16.png"))
        .unwrap();
    image::RgbaImage::from_fn(4, 4, |_, _| image::Rgba([255, 0, 0, 51])).save(dir.join("train/rgba.png")).unwrap();
    image::RgbImage::from_fn(8, 8, |_, _| image::Rgb([200, 100, 50])).save(dir.join("train/photo.jpg")).unwrap();
    let frames: Vec<_> = ["train/g16", "train/rgba", "train/photo"]
        .iter()
        .map(|f| json!({"file_path": f, "transform_matrix": pose(1.0)}))
        .collect();
    write_json(&dir, "transforms_train.json", &json!({"fl_x": 5, "frames": frames}));
    let opts = LoadOptions { background: [0.0, 0.0, 1.0], ..Default::default() };
    let d = Dataset::load(&dir, "train", &opts).unwrap();
    // 16-bit: 3001/65535 is not representable in 8 bits.
    assert!((d.views[0].rgb[3][1] - 3001.0 / 65535.0).abs() < 1e-6);
    // Alpha 0.2 over blue.
    let c = d.views[1].rgb[0];
    assert!((c[0] - 0.2).abs() < 1e-6 && c[1] == 0.0 && (c[2] - 0.8).abs() < 1e-6, "{c:?}");
    assert!(d.had_alpha);
    // JPEG, found without an extension in file_path; lossy, so within a few levels.
    let j = d.views[2].rgb[0];
    assert!((j[0] - 200.0 / 255.0).abs() < 0.03 && (j[2] - 50.0 / 255.0).abs() < 0.03, "{j:?}");
    assert_eq!(d.aabb_source, AabbSource::Cameras);
}

#[test]
fn authors_single_json_layout_filters_frames_by_type() {
    let dir = scratch("authors");
    for i in 0..3 {
        png_rgb8(&dir.join(format!("train/{i}.png")), 4, 4, |_, _| [i as u8, 0, 0]);
    }
    let types = ["bg", "wrap", "bg"];
    let frames: Vec<_> = types
        .iter()
        .enumerate()
        .map(|(i, t)| json!({"file_path": format!("train/{i}.png"), "transform_matrix": pose(1.0), "type": t}))
        .collect();
    write_json(&dir, "transforms.json", &json!({"camera_angle_x": 1.0, "frames": frames}));
    let scene = Dataset::load(&dir, "train", &LoadOptions::default()).unwrap();
    assert_eq!(scene.frames.iter().map(|f| f.index).collect::<Vec<_>>(), [1]);
    let opts = LoadOptions { frame_type: Some(FrameType::Background), ..Default::default() };
    let bg = Dataset::load(&dir, "test", &opts).unwrap();
    assert_eq!(bg.frames.iter().map(|f| f.index).collect::<Vec<_>>(), [0, 2]);
}

#[test]
fn images_of_different_sizes_without_w_h_load_with_one_warning_naming_the_frame() {
    let dir = scratch("mixed_sizes");
    png_rgb8(&dir.join("train/0.png"), 4, 4, |_, _| [9, 9, 9]);
    png_rgb8(&dir.join("train/1.png"), 4, 4, |_, _| [9, 9, 9]);
    png_rgb8(&dir.join("train/2.png"), 6, 4, |_, _| [9, 9, 9]);
    let frames: Vec<_> =
        (0..3).map(|i| json!({"file_path": format!("train/{i}.png"), "transform_matrix": pose(1.0)})).collect();
    write_json(&dir, "transforms_train.json", &json!({"camera_angle_x": 1.0, "frames": frames}));
    let data = Dataset::load(&dir, "train", &LoadOptions::default()).unwrap();
    assert_eq!(data.views[2].intrinsics.width, 6, "each frame keeps its own size");
    assert_eq!(data.warnings.len(), 1, "{:?}", data.warnings);
    let w = &data.warnings[0];
    assert!(
        w.contains("transforms_train.json") && w.contains("frame 2") && w.contains("6x4") && !w.contains('\n'),
        "{w}"
    );
    // The same sizes (or sizes the json states per frame) give no warning.
    png_rgb8(&dir.join("train/2.png"), 4, 4, |_, _| [9, 9, 9]);
    assert!(Dataset::load(&dir, "train", &LoadOptions::default()).unwrap().warnings.is_empty());
    png_rgb8(&dir.join("train/2.png"), 6, 4, |_, _| [9, 9, 9]);
    let frames: Vec<_> = (0..3)
        .map(|i| {
            let w = if i == 2 { 6 } else { 4 };
            json!({"file_path": format!("train/{i}.png"), "transform_matrix": pose(1.0), "w": w, "h": 4})
        })
        .collect();
    write_json(&dir, "transforms_train.json", &json!({"camera_angle_x": 1.0, "frames": frames}));
    assert!(Dataset::load(&dir, "train", &LoadOptions::default()).unwrap().warnings.is_empty());
}

#[test]
fn scene_box_from_inward_looking_cameras_holds_cameras_and_target() {
    use residual_nerf::data::synth;
    let s = synth::tabletop(4, 12, 0.0);
    let b = residual_nerf::data::aabb_from_cameras(&s.views);
    for v in &s.views {
        let p = v.pose.translation;
        assert!(p.cmpge(b.min).all() && p.cmple(b.max).all());
    }
    let c = (b.min + b.max) * 0.5;
    assert!((c - synth::TABLE_SPHERE.0).length() < 1e-3, "centre {c:?} should be the point every camera looks at");
}

/// Writes a one-frame dataset whose json is `frames_json` (or raw `json_text`), loads it and
/// returns the one-line error.
fn load_error(name: &str, setup: impl FnOnce(&Path)) -> String {
    let dir = scratch(name);
    setup(&dir);
    let e = Dataset::load(&dir, "train", &LoadOptions::default()).expect_err("bad input must be refused").to_string();
    assert!(!e.contains('\n'), "{name}: error is not one line: {e}");
    e
}

fn one_frame(dir: &Path, frame: serde_json::Value) {
    png_rgb8(&dir.join("train/a.png"), 4, 4, |_, _| [1, 2, 3]);
    write_json(dir, "transforms_train.json", &json!({"camera_angle_x": 0.7, "frames": [frame]}));
}

/// Writes a broken dataset into a folder.
type Setup<'a> = Box<dyn FnOnce(&Path) + 'a>;

fn good() -> serde_json::Value {
    json!({"file_path": "train/a", "transform_matrix": pose(1.0)})
}

#[test]
fn bad_datasets_give_one_line_errors_naming_file_frame_and_field() {
    let cases: Vec<(&str, Setup, &[&str])> = vec![
        (
            "malformed",
            Box::new(|d: &Path| std::fs::write(d.join("transforms_train.json"), "{\"frames\": [}").unwrap()),
            &["transforms_train.json", "malformed JSON"],
        ),
        (
            "truncated",
            Box::new(|d: &Path| std::fs::write(d.join("transforms_train.json"), "{\"frames\": [").unwrap()),
            &["truncated JSON"],
        ),
        (
            "commented",
            Box::new(|d: &Path| std::fs::write(d.join("transforms_train.json"), "// c\n{}").unwrap()),
            &["malformed JSON"],
        ),
        (
            "no frames",
            Box::new(|d: &Path| {
                write_json(d, "transforms_train.json", &json!({"camera_angle_x": 1, "frames": []}));
            }),
            &["field 'frames'", "no frames"],
        ),
        (
            "no focal",
            Box::new(|d: &Path| {
                png_rgb8(&d.join("train/a.png"), 4, 4, |_, _| [0; 3]);
                write_json(d, "transforms_train.json", &json!({"frames": [good()]}));
            }),
            &["frame 0", "camera_angle_x", "no focal length"],
        ),
        (
            "absurd focal",
            Box::new(|d: &Path| {
                write_json(d, "transforms_train.json", &json!({"camera_angle_x": 7.0, "frames": [good()]}));
            }),
            &["field 'camera_angle_x'", "outside"],
        ),
        (
            "string pose",
            Box::new(|d: &Path| one_frame(d, json!({"file_path": "train/a", "transform_matrix": "eye"}))),
            &["frame 0", "field 'transform_matrix'"],
        ),
        (
            "absurd pose",
            Box::new(|d: &Path| one_frame(d, json!({"file_path": "train/a", "transform_matrix": pose(1e7)}))),
            &["frame 0", "transform_matrix", "absurd"],
        ),
        (
            "skewed pose",
            Box::new(|d: &Path| {
                one_frame(
                    d,
                    json!({"file_path": "train/a", "transform_matrix": [[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]]}),
                )
            }),
            &["not orthonormal"],
        ),
        (
            "short pose",
            Box::new(|d: &Path| {
                one_frame(d, json!({"file_path": "train/a", "transform_matrix": [[1, 0, 0, 0], [0, 1, 0]]}))
            }),
            &["expected 4 or 3 rows"],
        ),
        (
            "missing image",
            Box::new(|d: &Path| one_frame(d, json!({"file_path": "train/nope", "transform_matrix": pose(1.0)}))),
            &["frame 0", "field 'file_path'", "not found"],
        ),
        (
            "not an image",
            Box::new(|d: &Path| {
                one_frame(d, good());
                std::fs::write(d.join("train/a.png"), b"hello, not a png").unwrap();
            }),
            &["a.png", "frame 0", "not an image"],
        ),
        (
            "corrupt image",
            Box::new(|d: &Path| {
                one_frame(d, good());
                let mut b = std::fs::read(d.join("train/a.png")).unwrap();
                b.truncate(b.len() / 2);
                std::fs::write(d.join("train/a.png"), b).unwrap();
            }),
            &["a.png", "frame 0"],
        ),
        (
            "mis-sized image",
            Box::new(|d: &Path| {
                png_rgb8(&d.join("train/a.png"), 4, 4, |_, _| [0; 3]);
                write_json(
                    d,
                    "transforms_train.json",
                    &json!({"camera_angle_x": 1, "w": 8, "h": 4, "frames": [good()]}),
                );
            }),
            &["a.png", "frame 0", "4x4", "w=8"],
        ),
        (
            "bomb",
            Box::new(|d: &Path| {
                one_frame(d, good());
                std::fs::write(d.join("train/a.png"), png_header(100_000, 100_000)).unwrap();
            }),
            &["a.png", "100000x100000"],
        ),
        (
            "bad crop",
            Box::new(|d: &Path| {
                one_frame(d, json!({"file_path": "train/a", "transform_matrix": pose(1.0), "crop": [0, 0, 9, 9]}))
            }),
            &["frame 0", "field 'crop'", "outside"],
        ),
        (
            "bad type",
            Box::new(|d: &Path| {
                one_frame(d, json!({"file_path": "train/a", "transform_matrix": pose(1.0), "type": "fg"}))
            }),
            &["field 'type'"],
        ),
        (
            "missing depth",
            Box::new(|d: &Path| {
                one_frame(
                    d,
                    json!({"file_path": "train/a", "transform_matrix": pose(1.0), "depth_file_path": "train/d.exr"}),
                )
            }),
            &["d.exr", "frame 0", "depth_file_path"],
        ),
        (
            "missing split",
            Box::new(|d: &Path| {
                write_json(d, "transforms_test.json", &json!({}));
            }),
            &["split 'train' not found"],
        ),
    ];
    for (name, setup, needles) in cases {
        let e = load_error(&name.replace(' ', "_"), setup);
        for n in needles {
            assert!(e.contains(n), "{name}: '{e}' should mention '{n}'");
        }
    }
    let e = Dataset::load(Path::new("/nonexistent/data"), "train", &LoadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("/nonexistent/data") && e.contains("not found"), "{e}");
}

#[test]
fn every_problem_of_a_dataset_is_reported_at_once() {
    let e = load_error("many", |d| {
        let frames: Vec<_> = (0..5).map(|_| json!({"file_path": "train/a", "transform_matrix": pose(2e6)})).collect();
        write_json(d, "transforms_train.json", &json!({"camera_angle_x": 1, "frames": frames}));
    });
    assert!(e.contains("frame 0") && e.contains("frame 2") && e.contains("and 2 more problems"), "{e}");
}

/// A PNG claiming `w × h` with no image data.
fn png_header(w: u32, h: u32) -> Vec<u8> {
    let mut ihdr = b"IHDR".to_vec();
    ihdr.extend_from_slice(&w.to_be_bytes());
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[8, 2, 0, 0, 0]);
    let crc = crc32(&ihdr);
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    out.extend_from_slice(&13u32.to_be_bytes());
    out.extend_from_slice(&ihdr);
    out.extend_from_slice(&crc.to_be_bytes());
    // An empty IDAT and IEND: the header reader stops at the first IDAT.
    for name in [b"IDAT", b"IEND"] {
        out.extend_from_slice(&0u32.to_be_bytes());
        out.extend_from_slice(name);
        out.extend_from_slice(&crc32(name).to_be_bytes());
    }
    out
}

fn crc32(data: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in data {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
        }
    }
    !c
}

/// Scale: `metres_per_unit` multiplies the camera positions and the box; without an `aabb`,
/// Instant-NGP's `scale`/`offset` give its unit cube in the json's frame (axes permuted as
/// Instant-NGP does: its cube's x, y, z are the json's y, z, x), `aabb_scale` enlarging it.
#[test]
fn metres_per_unit_and_instant_ngp_scale_offset_give_the_frame_and_box() {
    let dir = scratch("scale");
    png_rgb8(&dir.join("train/a.png"), 4, 4, |_, _| [1, 2, 3]);
    let frames = json!([{"file_path": "train/a", "transform_matrix": pose(2.0)}]);
    let load = |v: serde_json::Value| {
        write_json(&dir, "transforms_train.json", &v);
        Dataset::load(&dir, "train", &LoadOptions::default()).unwrap()
    };
    let d = load(json!({"camera_angle_x": 0.7, "metres_per_unit": 0.5,
        "aabb": [[-2, -2, -2], [2, 2, 2]], "frames": frames}));
    assert_eq!(d.views[0].pose.translation.z, 1.0);
    assert_eq!((d.aabb.min.x, d.aabb.max.z), (-1.0, 1.0));
    let d = load(json!({"camera_angle_x": 0.7, "scale": 0.5, "offset": [0.5, 0.6, 0.7], "frames": frames}));
    assert_eq!(d.aabb_source, AabbSource::File);
    let (min, max) = (d.aabb.min.to_array(), d.aabb.max.to_array());
    let want_min = [-1.4f32, -1.0, -1.2];
    let want_max = [0.6f32, 1.0, 0.8];
    for a in 0..3 {
        assert!((min[a] - want_min[a]).abs() < 1e-6 && (max[a] - want_max[a]).abs() < 1e-6, "{min:?} {max:?}");
    }
    let d = load(json!({"camera_angle_x": 0.7, "scale": 0.5, "aabb_scale": 4, "frames": frames}));
    assert!((d.aabb.min.x + 4.0).abs() < 1e-6 && (d.aabb.max.y - 4.0).abs() < 1e-6, "{:?}", d.aabb);
    write_json(&dir, "transforms_train.json", &json!({"camera_angle_x": 0.7, "metres_per_unit": -1, "frames": frames}));
    let e = Dataset::load(&dir, "train", &LoadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("field 'metres_per_unit'") && !e.contains('\n'), "{e}");
}
