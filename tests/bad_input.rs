//! The bad-input catalogue, through the `rnerf` binary as a robot's supervisor sees it: every
//! case exits 1 (never 101, a panic) with exactly one line on stderr naming the file, frame
//! and field, and leaves nothing at the output path (no model, no temporary file).

use glam::Vec3;
use residual_nerf::encoding::HashGridConfig;
use residual_nerf::field::mix::{DensityMix, MixKind};
use residual_nerf::field::mixnet::MixnetEncoding;
use residual_nerf::field::residual::{ResidualConfig, ResidualField, ResidualModel};
use residual_nerf::field::{Nerf, NerfConfig, NerfField};
use residual_nerf::io::{save_nerf, save_residual};
use residual_nerf::render::{Aabb, OccupancyConfig, OccupancyGrid};
use residual_nerf::rng::Rng;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::process::Command;

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("bad_input").join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn pose(tz: f64) -> Value {
    json!([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, tz], [0, 0, 0, 1]])
}

fn frame() -> Value {
    json!({"file_path": "train/a", "transform_matrix": pose(1.0)})
}

/// A one-frame dataset in `dir` (4×4 PNG) whose json is `json`.
fn dataset(dir: &Path, json: &Value) {
    std::fs::create_dir_all(dir.join("train")).unwrap();
    image::RgbImage::from_fn(4, 4, |_, _| image::Rgb([10, 20, 30])).save(dir.join("train/a.png")).unwrap();
    std::fs::write(dir.join("transforms_train.json"), json.to_string()).unwrap();
}

fn good_json() -> Value {
    json!({"camera_angle_x": 0.7, "frames": [frame()]})
}

const BOX: Aabb = Aabb { min: Vec3::splat(-1.0), max: Vec3::splat(1.0) };

fn small_nerf(aabb: Aabb) -> Nerf {
    let field = NerfField::new(NerfConfig { grid: HashGridConfig { log2_table_size: 8, ..Default::default() }, aabb });
    let params = field.init_params(&mut Rng::new(1));
    let occupancy = OccupancyGrid::new(aabb, OccupancyConfig { resolution: 8, ..Default::default() });
    Nerf { field, params, occupancy }
}

/// A PNG header claiming `w × h` (a decompression bomb: no pixel data).
fn png_header(w: u32, h: u32) -> Vec<u8> {
    let crc32 = |data: &[u8]| {
        let mut c = !0u32;
        for &b in data {
            c ^= b as u32;
            for _ in 0..8 {
                c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
            }
        }
        !c
    };
    let mut ihdr = b"IHDR".to_vec();
    ihdr.extend_from_slice(&w.to_be_bytes());
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[8, 2, 0, 0, 0]);
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    out.extend_from_slice(&13u32.to_be_bytes());
    out.extend_from_slice(&ihdr);
    out.extend_from_slice(&crc32(&ihdr).to_be_bytes());
    for name in [b"IDAT", b"IEND"] {
        out.extend_from_slice(&0u32.to_be_bytes());
        out.extend_from_slice(name);
        out.extend_from_slice(&crc32(name).to_be_bytes());
    }
    out
}

/// One catalogue entry: prepares the case's folder, the arguments (`{d}` stands for the
/// folder) and what the error must mention. The folder must be unchanged afterwards.
struct Case {
    name: &'static str,
    setup: Box<dyn Fn(&Path)>,
    args: &'static str,
    needles: &'static [&'static str],
}

fn case(
    name: &'static str,
    setup: impl Fn(&Path) + 'static,
    args: &'static str,
    needles: &'static [&'static str],
) -> Case {
    Case { name, setup: Box::new(setup), args, needles }
}

const TRAIN: &str = "train --data {d}/data --out {d}/m.safetensors --steps 2 --rays 16 --log2t 8";
const RENDER: &str = "render --model {d}/m.safetensors --data {d}/data --out {d}";
const TRAIN_BG: &str = "train --data {d}/data --background {d}/bg.safetensors --out {d}/m.safetensors --steps 2";

fn json_case(name: &'static str, text: &'static str, needles: &'static [&'static str]) -> Case {
    case(
        name,
        move |d| {
            dataset(&d.join("data"), &good_json());
            std::fs::write(d.join("data/transforms_train.json"), text).unwrap();
        },
        TRAIN,
        needles,
    )
}

fn frame_case(name: &'static str, frame: Value, needles: &'static [&'static str]) -> Case {
    case(
        name,
        move |d| dataset(&d.join("data"), &json!({"camera_angle_x": 0.7, "frames": [frame.clone()]})),
        TRAIN,
        needles,
    )
}

/// `rnerf import colmap` of a model folder holding `files` (name, contents) and an empty
/// images folder.
fn colmap_case(name: &'static str, files: &'static [(&str, &[u8])], needles: &'static [&'static str]) -> Case {
    case(
        name,
        move |d| {
            std::fs::create_dir_all(d.join("sparse")).unwrap();
            std::fs::create_dir_all(d.join("images")).unwrap();
            for (file, bytes) in files {
                std::fs::write(d.join("sparse").join(file), bytes).unwrap();
            }
        },
        "import colmap --model {d}/sparse --images {d}/images --out {d}/out",
        needles,
    )
}

fn image_case(name: &'static str, bytes: fn() -> Vec<u8>, needles: &'static [&'static str]) -> Case {
    case(
        name,
        move |d| {
            dataset(&d.join("data"), &good_json());
            std::fs::write(d.join("data/train/a.png"), bytes()).unwrap();
        },
        TRAIN,
        needles,
    )
}

fn model_case(name: &'static str, bytes: fn() -> Vec<u8>, needles: &'static [&'static str]) -> Case {
    case(
        name,
        move |d| {
            dataset(&d.join("data"), &good_json());
            std::fs::write(d.join("m.safetensors"), bytes()).unwrap();
        },
        RENDER,
        needles,
    )
}

fn background_case(name: &'static str, setup: impl Fn(&Path) + 'static, needles: &'static [&'static str]) -> Case {
    case(name, setup, TRAIN_BG, needles)
}

fn good_model_bytes() -> Vec<u8> {
    let dir = scratch("good_model");
    save_nerf(&dir.join("m.safetensors"), &small_nerf(BOX), &[]).unwrap();
    std::fs::read(dir.join("m.safetensors")).unwrap()
}

fn catalogue() -> Vec<Case> {
    vec![
        json_case("malformed json", "{\"frames\": [}", &["transforms_train.json", "malformed JSON"]),
        json_case("truncated json", "{\"frames\": [", &["transforms_train.json", "truncated JSON"]),
        json_case("commented json", "// a comment\n{}", &["transforms_train.json", "malformed JSON"]),
        json_case("no frames", "{\"camera_angle_x\": 0.7, \"frames\": []}", &["field 'frames'", "no frames"]),
        json_case(
            "no focal length",
            "{\"frames\": [{\"file_path\": \"train/a\", \"transform_matrix\": [[1,0,0,0],[0,1,0,0],[0,0,1,1],[0,0,0,1]]}]}",
            &["frame 0", "camera_angle_x"],
        ),
        json_case(
            "absurd focal length",
            "{\"camera_angle_x\": 9.0, \"frames\": [{\"file_path\": \"train/a\", \"transform_matrix\": [[1,0,0,0],[0,1,0,0],[0,0,1,1],[0,0,0,1]]}]}",
            &["camera_angle_x", "outside"],
        ),
        json_case(
            "non-finite pose",
            "{\"camera_angle_x\": 0.7, \"frames\": [{\"file_path\": \"train/a\", \"transform_matrix\": [[1,0,0,0],[0,1,0,0],[0,0,1,1e999],[0,0,0,1]]}]}",
            &["transforms_train.json"],
        ),
        frame_case(
            "absurd pose",
            json!({"file_path": "train/a", "transform_matrix": pose(2e6)}),
            &["frame 0", "transform_matrix", "absurd"],
        ),
        frame_case(
            "mis-shaped pose",
            json!({"file_path": "train/a", "transform_matrix": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}),
            &["frame 0", "transform_matrix"],
        ),
        frame_case(
            "pose not a matrix",
            json!({"file_path": "train/a", "transform_matrix": "identity"}),
            &["frame 0", "transform_matrix"],
        ),
        frame_case(
            "missing image",
            json!({"file_path": "train/missing", "transform_matrix": pose(1.0)}),
            &["frame 0", "file_path", "not found"],
        ),
        json_case(
            "unknown lens model",
            "{\"camera_angle_x\": 0.7, \"camera_model\": \"FULL_OPENCV\", \"frames\": [{\"file_path\": \"train/a\", \"transform_matrix\": [[1,0,0,0],[0,1,0,0],[0,0,1,1],[0,0,0,1]]}]}",
            &["transforms_train.json", "field 'camera_model'", "FULL_OPENCV"],
        ),
        json_case(
            "lens that folds over the image",
            "{\"camera_angle_x\": 0.7, \"k1\": -5, \"frames\": [{\"file_path\": \"train/a\", \"transform_matrix\": [[1,0,0,0],[0,1,0,0],[0,0,1,1],[0,0,0,1]]}]}",
            &["transforms_train.json", "frame 0", "field 'k1'", "cannot be inverted"],
        ),
        json_case(
            "fisheye with tangential terms",
            "{\"camera_angle_x\": 0.7, \"camera_model\": \"OPENCV_FISHEYE\", \"p1\": 0.01, \"frames\": [{\"file_path\": \"train/a\", \"transform_matrix\": [[1,0,0,0],[0,1,0,0],[0,0,1,1],[0,0,0,1]]}]}",
            &["transforms_train.json", "frame 0", "field 'p1'", "tangential"],
        ),
        json_case(
            "distortion coefficient out of range",
            "{\"camera_angle_x\": 0.7, \"k2\": 40, \"frames\": [{\"file_path\": \"train/a\", \"transform_matrix\": [[1,0,0,0],[0,1,0,0],[0,0,1,1],[0,0,0,1]]}]}",
            &["transforms_train.json", "field 'k2'", "40"],
        ),
        image_case("corrupt image", || good_png()[..40].to_vec(), &["a.png", "frame 0"]),
        image_case("not an image", || b"this is no picture".to_vec(), &["a.png", "frame 0", "not an image"]),
        image_case("decompression bomb", || png_header(100_000, 100_000), &["a.png", "100000x100000"]),
        case(
            "mis-sized image",
            |d| {
                dataset(&d.join("data"), &json!({"camera_angle_x": 0.7, "w": 8, "h": 4, "frames": [frame()]}));
            },
            TRAIN,
            &["a.png", "frame 0", "4x4", "w=8"],
        ),
        colmap_case(
            "colmap: unknown camera model",
            &[
                ("cameras.txt", b"# c\n1 FULL_OPENCV 4 4 1 1 2 2 0 0 0 0 0 0 0 0\n"),
                ("images.txt", b"1 1 0 0 0 0 0 1 1 a.png\n\n"),
            ],
            &["cameras.txt", "line 2", "FULL_OPENCV"],
        ),
        colmap_case(
            "colmap: image missing",
            &[("cameras.txt", b"1 PINHOLE 4 4 3 3 2 2\n"), ("images.txt", b"1 1 0 0 0 0 0 1 1 a.png\n\n")],
            &["a.png", "is not in"],
        ),
        colmap_case(
            "colmap: truncated binary model",
            &[("cameras.bin", &[1, 0, 0, 0, 0, 0, 0, 0, 1, 0])],
            &["cameras.bin", "truncated"],
        ),
        case("missing data directory", |_| {}, TRAIN, &["data", "not found"]),
        case(
            "missing split",
            |d| {
                dataset(&d.join("data"), &good_json());
                std::fs::remove_file(d.join("data/transforms_train.json")).unwrap();
            },
            TRAIN,
            &["split 'train' not found"],
        ),
        case(
            "missing output directory",
            |d| dataset(&d.join("data"), &good_json()),
            "train --data {d}/data --out {d}/nowhere/m.safetensors --steps 2",
            &["--out", "does not exist"],
        ),
        case(
            "unwritable output directory (a file)",
            |d| {
                dataset(&d.join("data"), &good_json());
                std::fs::write(d.join("file"), b"x").unwrap();
            },
            "train --data {d}/data --out {d}/file/m.safetensors --steps 2",
            &["--out", "does not exist"],
        ),
        case(
            "output is a directory",
            |d| {
                dataset(&d.join("data"), &good_json());
                std::fs::create_dir(d.join("m.safetensors")).unwrap();
            },
            TRAIN,
            &["--out", "is a directory"],
        ),
        model_case("empty model file", Vec::new, &["m.safetensors", "truncated or empty"]),
        model_case("truncated model file", || good_model_bytes()[..300].to_vec(), &["m.safetensors", "truncated"]),
        model_case(
            "random-bytes model file",
            || (0..4096u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 24) as u8).collect(),
            &["m.safetensors", "not a model file"],
        ),
        model_case(
            "malicious header length",
            || {
                let mut b = good_model_bytes();
                b[..8].copy_from_slice(&(u64::MAX / 2).to_le_bytes());
                b
            },
            &["m.safetensors", "not a model file"],
        ),
        model_case(
            "model with a non-finite weight",
            || {
                let mut b = good_model_bytes();
                let header = u64::from_le_bytes(b[..8].try_into().unwrap()) as usize;
                b[8 + header..8 + header + 4].copy_from_slice(&f32::NAN.to_le_bytes());
                b
            },
            &["m.safetensors", "non-finite"],
        ),
        case(
            "missing model file",
            |d| dataset(&d.join("data"), &good_json()),
            RENDER,
            &["m.safetensors", "No such file"],
        ),
        background_case(
            "background is not a model",
            |d| {
                dataset(&d.join("data"), &good_json());
                std::fs::write(d.join("bg.safetensors"), good_png()).unwrap();
            },
            &["bg.safetensors", "--background", "not a model file"],
        ),
        background_case(
            "background missing",
            |d| dataset(&d.join("data"), &good_json()),
            &["bg.safetensors", "--background"],
        ),
        background_case(
            "background of another scene box",
            |d| {
                let mut j = good_json();
                j["aabb"] = json!([[-2, -2, -2], [2, 2, 2]]);
                dataset(&d.join("data"), &j);
                save_nerf(&d.join("bg.safetensors"), &small_nerf(BOX), &[]).unwrap();
            },
            &["transforms_train.json", "field 'aabb'", "differs from the background"],
        ),
        background_case(
            "background is a residual model",
            |d| {
                dataset(&d.join("data"), &good_json());
                let bg = small_nerf(BOX);
                let config = ResidualConfig {
                    residual: bg.field.config().clone(),
                    kind: MixKind::Mixnet(DensityMix::Raw),
                    mixnet: MixnetEncoding::Shared,
                };
                let field = ResidualField::new(bg.clone(), config);
                let params = field.init_params(&mut Rng::new(2));
                let model = ResidualModel { field, params, occupancy: bg.occupancy };
                save_residual(&d.join("bg.safetensors"), &model, &[]).unwrap();
            },
            &["bg.safetensors", "residual model", "plain NeRF"],
        ),
        case("zero steps", |_| {}, "train --data {d} --out {d}/m.safetensors --steps 0", &["--steps"]),
        case("steps not a number", |_| {}, "train --data {d} --out {d}/m.safetensors --steps ten", &["--steps", "ten"]),
        case("table size out of range", |_| {}, "train --data {d} --out {d}/m.safetensors --log2t 40", &["--log2t", "40"]),
        case("zero threads", |_| {}, "train --data {d} --out {d}/m.safetensors --threads 0", &["--threads"]),
        case(
            "change tolerance out of range",
            |_| {},
            "train --data {d} --out {d}/m.safetensors --change-tolerance 0.9",
            &["--change-tolerance", "0.9"],
        ),
        case(
            "change tolerance not T or T,R",
            |_| {},
            "train --data {d} --out {d}/m.safetensors --change-tolerance 0.03,0.05,0.1",
            &["--change-tolerance", "0.03,0.05,0.1"],
        ),
        case("region dilation too large", |_| {}, "train --data {d} --out {d}/m.safetensors --region-dilate 9", &["--region-dilate", "9"]),
        case("negative threshold", |_| {}, "render --model {d}/m --data {d} --out {d}/r --m -1", &["--m"]),
        case("unknown flag", |_| {}, "train --data {d} --out {d}/m.safetensors --fast", &["--fast"]),
        case("unknown command", |_| {}, "paint --out {d}/x", &["unknown command 'paint'"]),
        case("missing required flag", |_| {}, "train --out {d}/m.safetensors", &["--data"]),
        case(
            "resume with new settings",
            |_| {},
            "train --resume {d}/c --data {d} --out {d}/m.safetensors --steps 5",
            &["--resume", "--steps"],
        ),
        case(
            "registration passes without registration",
            |_| {},
            "train --data {d} --out {d}/m.safetensors --registration-passes 2",
            &["--registration-passes", "--pose-registration on"],
        ),
        case(
            "too many registration passes",
            |_| {},
            "train --data {d} --out {d}/m.safetensors --pose-registration on --registration-passes 9",
            &["--registration-passes", "1..=4"],
        ),
        case(
            "resume with a new prior setting",
            |_| {},
            "train --resume {d}/c --data {d} --out {d}/m.safetensors --focus-share 0.3",
            &["--resume", "--focus-share"],
        ),
        case(
            "resume of a finished model",
            |d| {
                dataset(&d.join("data"), &good_json());
                save_nerf(&d.join("done.safetensors"), &small_nerf(BOX), &[]).unwrap();
            },
            "train --resume {d}/done.safetensors --data {d}/data --out {d}/m.safetensors",
            &["done.safetensors", "not a checkpoint"],
        ),
    ]
}

fn good_png() -> Vec<u8> {
    let mut b = std::io::Cursor::new(Vec::new());
    image::RgbImage::from_fn(4, 4, |_, _| image::Rgb([1, 2, 3])).write_to(&mut b, image::ImageFormat::Png).unwrap();
    b.into_inner()
}

#[test]
fn every_bad_input_gets_one_line_a_non_zero_exit_and_no_output() {
    let cases = catalogue();
    assert!(cases.len() >= 25, "the catalogue holds {} cases", cases.len());
    let mut failures = Vec::new();
    for c in &cases {
        let dir = scratch(&c.name.replace(' ', "_"));
        (c.setup)(&dir);
        let before = listing(&dir);
        let d = dir.to_str().unwrap();
        let args: Vec<String> = c.args.split(' ').map(|a| a.replace("{d}", d)).collect();
        let o = Command::new(env!("CARGO_BIN_EXE_rnerf")).args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        let line = err.trim_end();
        let mut problems = Vec::new();
        if o.status.code() != Some(1) {
            problems.push(format!("exit {:?}", o.status.code()));
        }
        if line.lines().count() != 1 || !line.starts_with("rnerf: ") {
            problems.push("stderr is not one 'rnerf: ' line".to_string());
        }
        for n in c.needles {
            if !line.contains(n) {
                problems.push(format!("does not mention '{n}'"));
            }
        }
        let after = listing(&dir);
        if after != before {
            let new: Vec<_> = after.iter().filter(|p| !before.contains(p)).collect();
            problems.push(format!("files appeared: {new:?}"));
        }
        if !problems.is_empty() {
            failures.push(format!("{}: {} — stderr: {line}", c.name, problems.join("; ")));
        }
    }
    assert!(failures.is_empty(), "{} of {} cases failed:\n{}", failures.len(), cases.len(), failures.join("\n"));
}

/// Every path under `dir`, sorted.
fn listing(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                todo.push(p.clone());
            }
            out.push(p);
        }
    }
    out.sort();
    out
}
