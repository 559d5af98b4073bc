//! COLMAP sparse models (`cameras`, `images`, `points3D`, text `.txt` or binary `.bin`) → our
//! `transforms_train.json` (`rnerf import colmap`): the paper's real-world workflow registers the
//! background and the scene images in one COLMAP run, so they share one frame; the import splits
//! them into two datasets by image name.
//!
//! Conventions: COLMAP stores world-to-camera `x_c = R(q)·x_w + t` with the camera looking down
//! +z, y down (OpenCV); our poses are camera-to-world with the camera looking down −Z, +Y up
//! (OpenGL), so a pose is `[Rᵀ | −Rᵀt]` with its second and third columns negated. The world
//! frame and its unit are COLMAP's; `metres_per_unit` (from one known distance between two camera
//! centres) makes depth metric. The scene box is the sparse points' 1st–99th percentile box per
//! axis, grown by a quarter of its size on each side.
//!
//! Camera models: `SIMPLE_PINHOLE`, `PINHOLE`, `SIMPLE_RADIAL`, `RADIAL`, `OPENCV` (→ our
//! `OPENCV`), `OPENCV_FISHEYE`, `SIMPLE_RADIAL_FISHEYE`, `RADIAL_FISHEYE` (→ `OPENCV_FISHEYE`);
//! the others (`FULL_OPENCV`, `FOV`, `THIN_PRISM_FISHEYE`, …) are refused by name.

use crate::geometry::{Distortion, Intrinsics, Pose};
use glam::{DMat3, DQuat, DVec3, Vec3};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Largest accepted model file (bytes).
const MAX_FILE_BYTES: u64 = 1 << 30;

/// One COLMAP camera (intrinsics shared by images).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ColmapCamera {
    /// `CAMERA_ID`.
    pub id: u32,
    /// The intrinsics with the lens.
    pub intrinsics: Intrinsics,
}

/// One registered image.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapImage {
    /// `IMAGE_ID`.
    pub id: u32,
    /// `NAME` (relative to the images folder).
    pub name: String,
    /// `CAMERA_ID`.
    pub camera: u32,
    /// Camera-to-world, OpenGL camera axes, COLMAP's world frame and unit.
    pub pose: Pose,
}

/// A sparse model.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ColmapModel {
    /// Cameras by id.
    pub cameras: BTreeMap<u32, ColmapCamera>,
    /// Images in id order.
    pub images: Vec<ColmapImage>,
    /// Sparse points (world).
    pub points: Vec<Vec3>,
}

/// COLMAP's camera model ids and names, with their parameter counts.
const MODELS: [(i32, &str, usize); 11] = [
    (0, "SIMPLE_PINHOLE", 3),
    (1, "PINHOLE", 4),
    (2, "SIMPLE_RADIAL", 4),
    (3, "RADIAL", 5),
    (4, "OPENCV", 8),
    (5, "OPENCV_FISHEYE", 8),
    (6, "FULL_OPENCV", 12),
    (7, "FOV", 5),
    (8, "SIMPLE_RADIAL_FISHEYE", 4),
    (9, "RADIAL_FISHEYE", 5),
    (10, "THIN_PRISM_FISHEYE", 12),
];

/// Our intrinsics from a COLMAP model name and its parameters.
fn intrinsics(model: &str, width: u64, height: u64, p: &[f64]) -> Result<Intrinsics, String> {
    let want = MODELS.iter().find(|m| m.1 == model).map(|m| m.2);
    if want.is_some_and(|n| n != p.len()) {
        return Err(format!("{model} takes {} parameters, found {}", want.unwrap(), p.len()));
    }
    let f = |i: usize| p[i] as f32;
    let (fx, fy, cx, cy, distortion) = match model {
        "SIMPLE_PINHOLE" => (f(0), f(0), f(1), f(2), Distortion::None),
        "PINHOLE" => (f(0), f(1), f(2), f(3), Distortion::None),
        "SIMPLE_RADIAL" => (f(0), f(0), f(1), f(2), Distortion::Radial { k: [f(3), 0.0, 0.0, 0.0], p: [0.0; 2] }),
        "RADIAL" => (f(0), f(0), f(1), f(2), Distortion::Radial { k: [f(3), f(4), 0.0, 0.0], p: [0.0; 2] }),
        "OPENCV" => (f(0), f(1), f(2), f(3), Distortion::Radial { k: [f(4), f(5), 0.0, 0.0], p: [f(6), f(7)] }),
        "OPENCV_FISHEYE" => (f(0), f(1), f(2), f(3), Distortion::Fisheye { k: [f(4), f(5), f(6), f(7)] }),
        "SIMPLE_RADIAL_FISHEYE" => (f(0), f(0), f(1), f(2), Distortion::Fisheye { k: [f(3), 0.0, 0.0, 0.0] }),
        "RADIAL_FISHEYE" => (f(0), f(0), f(1), f(2), Distortion::Fisheye { k: [f(3), f(4), 0.0, 0.0] }),
        other => {
            return Err(format!(
                "unsupported camera model {other} (supported: SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, OPENCV_FISHEYE, SIMPLE_RADIAL_FISHEYE, RADIAL_FISHEYE)"
            ))
        }
    };
    let side = super::transforms::MAX_SIDE as u64;
    if !(1..=side).contains(&width) || !(1..=side).contains(&height) {
        return Err(format!("image size {width}x{height} is outside 1..={side}"));
    }
    let (width, height) = (width as u32, height as u32);
    let k = Intrinsics { width, height, fx, fy, cx, cy, distortion };
    k.check_pinhole()?;
    distortion.check(width, height, fx, fy, cx, cy)?;
    Ok(k)
}

/// Camera-to-world (OpenGL axes) from COLMAP's world-to-camera quaternion `(w, x, y, z)` and
/// translation.
pub fn pose_from_colmap(q: [f64; 4], t: [f64; 3]) -> Result<Pose, String> {
    let quat = DQuat::from_xyzw(q[1], q[2], q[3], q[0]);
    let n = quat.length();
    if !(n.is_finite() && (n - 1.0).abs() < 1e-2 && t.iter().all(|v| v.is_finite())) {
        return Err(format!("pose q={q:?} t={t:?} is not a rigid transform"));
    }
    let r = DMat3::from_quat(quat / n);
    let c2w = r.transpose();
    let centre = -(c2w * DVec3::from(t));
    let rotation = DMat3::from_cols(c2w.x_axis, -c2w.y_axis, -c2w.z_axis).as_mat3();
    if centre.abs().max_element() > super::transforms::MAX_TRANSLATION as f64 {
        return Err(format!("camera centre {centre:?} is absurd"));
    }
    Ok(Pose { rotation, translation: centre.as_vec3() })
}

/// COLMAP's world-to-camera quaternion `(w, x, y, z)` and translation of a camera-to-world pose
/// (the inverse of [`pose_from_colmap`]).
pub fn pose_to_colmap(pose: &Pose) -> ([f64; 4], [f64; 3]) {
    let m = pose.rotation.as_dmat3();
    let c2w_cv = DMat3::from_cols(m.x_axis, -m.y_axis, -m.z_axis);
    let r = c2w_cv.transpose();
    let q = DQuat::from_mat3(&r).normalize();
    let t = -(r * pose.translation.as_dvec3());
    ([q.w, q.x, q.y, q.z], t.to_array())
}

/// Reads the model in `dir`: `cameras`, `images` and `points3D`, each `.bin` if present, else
/// `.txt`. Errors name the file and, where they apply, the line (text) or record (binary).
pub fn read_model(dir: &Path) -> Result<ColmapModel, String> {
    if !dir.is_dir() {
        return Err(format!("{}: COLMAP model directory not found", dir.display()));
    }
    let pick = |stem: &str| -> Result<(PathBuf, bool), String> {
        let (bin, txt) = (dir.join(format!("{stem}.bin")), dir.join(format!("{stem}.txt")));
        if bin.is_file() {
            Ok((bin, true))
        } else if txt.is_file() {
            Ok((txt, false))
        } else {
            Err(format!("{}: no {stem}.bin or {stem}.txt", dir.display()))
        }
    };
    let read = |p: &Path| crate::files::read_limited(p, MAX_FILE_BYTES).map_err(|e| format!("{}: {e}", p.display()));
    let mut model = ColmapModel::default();
    let (path, bin) = pick("cameras")?;
    let bytes = read(&path)?;
    let at = |e: String| format!("{}: {e}", path.display());
    let cameras = if bin { cameras_bin(&bytes) } else { cameras_txt(&bytes) }.map_err(at)?;
    for c in cameras {
        if model.cameras.insert(c.id, c).is_some() {
            return Err(format!("{}: camera {} appears twice", path.display(), c.id));
        }
    }
    let (path, bin) = pick("images")?;
    let bytes = read(&path)?;
    let at = |e: String| format!("{}: {e}", path.display());
    model.images = if bin { images_bin(&bytes) } else { images_txt(&bytes) }.map_err(at)?;
    if model.images.is_empty() {
        return Err(format!("{}: no registered images", path.display()));
    }
    for im in &model.images {
        if !model.cameras.contains_key(&im.camera) {
            return Err(format!(
                "{}: image {} ({}) names camera {}, which cameras does not hold",
                path.display(),
                im.id,
                im.name,
                im.camera
            ));
        }
    }
    // points3D only give the scene box; a model without them is still usable.
    if let Ok((path, bin)) = pick("points3D") {
        let bytes = read(&path)?;
        model.points = if bin { points_bin(&bytes) } else { points_txt(&bytes) }
            .map_err(|e| format!("{}: {e}", path.display()))?;
    }
    Ok(model)
}

/// Data lines of a text file: `(line number, fields)`, comments and blank lines skipped.
fn text_lines(bytes: &[u8]) -> Result<Vec<(usize, Vec<&str>)>, String> {
    let text = std::str::from_utf8(bytes).map_err(|_| "not UTF-8 text".to_string())?;
    Ok(text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim_start().starts_with('#'))
        .map(|(i, l)| (i + 1, l.split_whitespace().collect()))
        .collect())
}

fn num<T: std::str::FromStr>(s: &str, line: usize, what: &str) -> Result<T, String> {
    s.parse().map_err(|_| format!("line {line}: {what} '{s}' is not a number"))
}

/// `cameras.txt`'s contents → its cameras. Errors name the line or record; never panics (fuzzed).
pub fn cameras_txt(bytes: &[u8]) -> Result<Vec<ColmapCamera>, String> {
    let mut out = Vec::new();
    for (line, f) in text_lines(bytes)?.into_iter().filter(|(_, f)| !f.is_empty()) {
        if f.len() < 4 {
            return Err(format!("line {line}: expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]"));
        }
        let id = num(f[0], line, "CAMERA_ID")?;
        let (w, h) = (num(f[2], line, "WIDTH")?, num(f[3], line, "HEIGHT")?);
        let p: Vec<f64> = f[4..].iter().map(|s| num(s, line, "parameter")).collect::<Result<_, _>>()?;
        let intrinsics = intrinsics(f[1], w, h, &p).map_err(|e| format!("line {line}: camera {id}: {e}"))?;
        out.push(ColmapCamera { id, intrinsics });
    }
    Ok(out)
}

/// `images.txt`'s contents → its images (sorted by id). Errors name the line or record; never panics (fuzzed).
pub fn images_txt(bytes: &[u8]) -> Result<Vec<ColmapImage>, String> {
    // Every image takes two lines (its pose, then its 2D points, which may be empty).
    let text = std::str::from_utf8(bytes).map_err(|_| "not UTF-8 text".to_string())?;
    let lines: Vec<(usize, &str)> =
        text.lines().enumerate().filter(|(_, l)| !l.trim_start().starts_with('#')).map(|(i, l)| (i + 1, l)).collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let (line, l) = lines[i];
        let f: Vec<&str> = l.split_whitespace().collect();
        if f.is_empty() {
            i += 1;
            continue;
        }
        if f.len() < 10 {
            return Err(format!("line {line}: expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME"));
        }
        let v: Vec<f64> = f[1..8].iter().map(|s| num(s, line, "pose value")).collect::<Result<_, _>>()?;
        let pose =
            pose_from_colmap([v[0], v[1], v[2], v[3]], [v[4], v[5], v[6]]).map_err(|e| format!("line {line}: {e}"))?;
        // A name may hold spaces: it is everything after CAMERA_ID.
        let name = l.split_whitespace().skip(9).collect::<Vec<_>>().join(" ");
        out.push(ColmapImage { id: num(f[0], line, "IMAGE_ID")?, name, camera: num(f[8], line, "CAMERA_ID")?, pose });
        i += 2;
    }
    out.sort_by_key(|im| im.id);
    Ok(out)
}

/// `points3D.txt`'s contents → its points. Errors name the line or record; never panics (fuzzed).
pub fn points_txt(bytes: &[u8]) -> Result<Vec<Vec3>, String> {
    let mut out = Vec::new();
    for (line, f) in text_lines(bytes)?.into_iter().filter(|(_, f)| !f.is_empty()) {
        if f.len() < 4 {
            return Err(format!("line {line}: expected POINT3D_ID X Y Z ..."));
        }
        let p: Vec<f32> = f[1..4].iter().map(|s| num(s, line, "coordinate")).collect::<Result<_, _>>()?;
        out.push(Vec3::new(p[0], p[1], p[2]));
    }
    Ok(out)
}

/// A little-endian reader over a binary model file; errors name the record.
struct Bin<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Bin<'_> {
    fn take(&mut self, n: usize, what: &str) -> Result<&[u8], String> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len());
        let end = end.ok_or_else(|| format!("truncated at byte {} (reading {what})", self.at))?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn u64(&mut self, what: &str) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.take(8, what)?.try_into().unwrap()))
    }
    fn i32(&mut self, what: &str) -> Result<i32, String> {
        Ok(i32::from_le_bytes(self.take(4, what)?.try_into().unwrap()))
    }
    fn f64(&mut self, what: &str) -> Result<f64, String> {
        Ok(f64::from_le_bytes(self.take(8, what)?.try_into().unwrap()))
    }
    /// A record count, checked against the bytes left (each record at least `min` bytes).
    fn count(&mut self, min: usize, what: &str) -> Result<usize, String> {
        let n = self.u64(what)?;
        let left = (self.bytes.len() - self.at) as u64;
        if n > left / min.max(1) as u64 {
            return Err(format!("truncated: {what} {n} is more than the file holds"));
        }
        Ok(n as usize)
    }
}

/// `cameras.bin`'s contents → its cameras. Errors name the line or record; never panics (fuzzed).
pub fn cameras_bin(bytes: &[u8]) -> Result<Vec<ColmapCamera>, String> {
    let mut b = Bin { bytes, at: 0 };
    let n = b.count(24, "number of cameras")?;
    let mut out = Vec::with_capacity(n);
    for r in 0..n {
        let id = b.i32("CAMERA_ID")?;
        let model = b.i32("MODEL_ID")?;
        let (w, h) = (b.u64("WIDTH")?, b.u64("HEIGHT")?);
        let (name, count) = MODELS
            .iter()
            .find(|m| m.0 == model)
            .map(|m| (m.1, m.2))
            .ok_or_else(|| format!("camera record {r}: unknown camera model id {model}"))?;
        let p: Vec<f64> = (0..count).map(|_| b.f64("camera parameter")).collect::<Result<_, _>>()?;
        let intrinsics = intrinsics(name, w, h, &p).map_err(|e| format!("camera {id}: {e}"))?;
        out.push(ColmapCamera { id: id as u32, intrinsics });
    }
    Ok(out)
}

/// `images.bin`'s contents → its images (sorted by id). Errors name the line or record; never panics (fuzzed).
pub fn images_bin(bytes: &[u8]) -> Result<Vec<ColmapImage>, String> {
    let mut b = Bin { bytes, at: 0 };
    let n = b.count(64, "number of images")?;
    let mut out = Vec::with_capacity(n);
    for r in 0..n {
        let id = b.i32("IMAGE_ID")? as u32;
        let v: Vec<f64> = (0..7).map(|_| b.f64("pose value")).collect::<Result<_, _>>()?;
        let camera = b.i32("CAMERA_ID")? as u32;
        let mut name = Vec::new();
        loop {
            match b.take(1, "NAME")?[0] {
                0 => break,
                c => name.push(c),
            }
        }
        let name = String::from_utf8(name).map_err(|_| format!("image record {r}: NAME is not UTF-8"))?;
        let points = b.count(24, "number of 2D points")?;
        b.take(points * 24, "2D points")?;
        let pose = pose_from_colmap([v[0], v[1], v[2], v[3]], [v[4], v[5], v[6]])
            .map_err(|e| format!("image {id} ({name}): {e}"))?;
        out.push(ColmapImage { id, name, camera, pose });
    }
    out.sort_by_key(|im| im.id);
    Ok(out)
}

/// `points3D.bin`'s contents → its points. Errors name the line or record; never panics (fuzzed).
pub fn points_bin(bytes: &[u8]) -> Result<Vec<Vec3>, String> {
    let mut b = Bin { bytes, at: 0 };
    let n = b.count(43, "number of points")?;
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        b.u64("POINT3D_ID")?;
        let p: Vec<f64> = (0..3).map(|_| b.f64("coordinate")).collect::<Result<_, _>>()?;
        b.take(3 + 8, "colour and error")?;
        let track = b.count(8, "track length")?;
        b.take(track * 8, "track")?;
        out.push(DVec3::new(p[0], p[1], p[2]).as_vec3());
    }
    Ok(out)
}

/// Writes `model` in COLMAP's text (`binary: false`) or binary format into `dir` (created):
/// `cameras`, `images` (without 2D points) and `points3D` (without tracks). The crate's
/// synthesised captures use it to test the import; it is also a way to hand our poses to COLMAP.
pub fn write_model(model: &ColmapModel, dir: &Path, binary: bool) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: cannot create: {e}", dir.display()))?;
    let params = |k: &Intrinsics| -> (i32, Vec<f64>) {
        let (fx, fy, cx, cy) = (k.fx as f64, k.fy as f64, k.cx as f64, k.cy as f64);
        match k.distortion {
            Distortion::None => (1, vec![fx, fy, cx, cy]),
            Distortion::Radial { k: c, p } => {
                assert!(c[2] == 0.0 && c[3] == 0.0, "COLMAP's OPENCV has no k3, k4");
                (4, vec![fx, fy, cx, cy, c[0] as f64, c[1] as f64, p[0] as f64, p[1] as f64])
            }
            Distortion::Fisheye { k: c } => {
                (5, vec![fx, fy, cx, cy, c[0] as f64, c[1] as f64, c[2] as f64, c[3] as f64])
            }
        }
    };
    let (mut cams, mut ims, mut pts) = (Vec::new(), Vec::new(), Vec::new());
    if binary {
        cams.extend((model.cameras.len() as u64).to_le_bytes());
        for c in model.cameras.values() {
            let (id, p) = params(&c.intrinsics);
            cams.extend((c.id as i32).to_le_bytes());
            cams.extend(id.to_le_bytes());
            cams.extend((c.intrinsics.width as u64).to_le_bytes());
            cams.extend((c.intrinsics.height as u64).to_le_bytes());
            p.iter().for_each(|v| cams.extend(v.to_le_bytes()));
        }
        ims.extend((model.images.len() as u64).to_le_bytes());
        for im in &model.images {
            let (q, t) = pose_to_colmap(&im.pose);
            ims.extend((im.id as i32).to_le_bytes());
            q.iter().chain(&t).for_each(|v| ims.extend(v.to_le_bytes()));
            ims.extend((im.camera as i32).to_le_bytes());
            ims.extend(im.name.as_bytes());
            ims.push(0);
            ims.extend(0u64.to_le_bytes());
        }
        pts.extend((model.points.len() as u64).to_le_bytes());
        for (i, p) in model.points.iter().enumerate() {
            pts.extend((i as u64 + 1).to_le_bytes());
            p.as_dvec3().to_array().iter().for_each(|v| pts.extend(v.to_le_bytes()));
            pts.extend([128u8, 128, 128]);
            pts.extend(0f64.to_le_bytes());
            pts.extend(0u64.to_le_bytes());
        }
    } else {
        let mut c = String::from("# Camera list: CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n");
        for cam in model.cameras.values() {
            let (id, p) = params(&cam.intrinsics);
            let name = MODELS.iter().find(|m| m.0 == id).unwrap().1;
            let p: Vec<String> = p.iter().map(|v| format!("{v:?}")).collect();
            c += &format!("{} {name} {} {} {}\n", cam.id, cam.intrinsics.width, cam.intrinsics.height, p.join(" "));
        }
        cams = c.into_bytes();
        let mut s = String::from(
            "# IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n# POINTS2D[] as (X, Y, POINT3D_ID)\n",
        );
        for im in &model.images {
            let (q, t) = pose_to_colmap(&im.pose);
            let v: Vec<String> = q.iter().chain(&t).map(|v| format!("{v:?}")).collect();
            s += &format!("{} {} {} {}\n\n", im.id, v.join(" "), im.camera, im.name);
        }
        ims = s.into_bytes();
        let mut s = String::from("# POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[]\n");
        for (i, p) in model.points.iter().enumerate() {
            s += &format!("{} {:?} {:?} {:?} 128 128 128 0\n", i + 1, p.x as f64, p.y as f64, p.z as f64);
        }
        pts = s.into_bytes();
    }
    let ext = if binary { "bin" } else { "txt" };
    for (stem, bytes) in [("cameras", cams), ("images", ims), ("points3D", pts)] {
        crate::files::write_atomic(&dir.join(format!("{stem}.{ext}")), &bytes)?;
    }
    Ok(())
}

/// What `rnerf import colmap` does.
#[derive(Clone, Debug, PartialEq)]
pub struct ImportOptions {
    /// The sparse model's folder (`sparse/0`).
    pub model: PathBuf,
    /// The folder the images' names are relative to.
    pub images: PathBuf,
    /// Where the dataset(s) go.
    pub out: PathBuf,
    /// Images whose name contains this go to `OUT/background`, the others to `OUT/scene`;
    /// `None` writes one dataset in `OUT`.
    pub background_match: Option<String>,
    /// `(image A, image B, metres)`: the distance between the two camera centres, fixing the scale.
    pub known_distance: Option<(String, String, f64)>,
}

/// What an import wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct ImportReport {
    /// Each written json and its number of frames.
    pub written: Vec<(PathBuf, usize)>,
    /// Metres per COLMAP unit (1 when no distance was given).
    pub metres_per_unit: f64,
    /// The scene box written (COLMAP units), if the model has points.
    pub aabb: Option<crate::geometry::Aabb>,
}

/// Imports a COLMAP model as our dataset(s) (see the module documentation). Nothing is written
/// until the model, the images and the options have been checked; each json is written
/// atomically.
pub fn import(o: &ImportOptions) -> Result<ImportReport, String> {
    let model = read_model(&o.model)?;
    if !o.images.is_dir() {
        return Err(format!("{}: images directory not found", o.images.display()));
    }
    let images = std::fs::canonicalize(&o.images).map_err(|e| format!("{}: {e}", o.images.display()))?;
    for im in &model.images {
        if !images.join(&im.name).is_file() {
            return Err(format!(
                "{}: image {} ({}) is not in {}",
                o.model.display(),
                im.id,
                im.name,
                o.images.display()
            ));
        }
    }
    let metres_per_unit = match &o.known_distance {
        None => 1.0,
        Some((a, b, metres)) => {
            let find = |n: &str| {
                model.images.iter().find(|im| im.name == n).ok_or_else(|| {
                    format!("--known-distance: no registered image named '{n}' in {}", o.model.display())
                })
            };
            let (pa, pb) = (find(a)?.pose.translation, find(b)?.pose.translation);
            let d = (pa - pb).length() as f64;
            if !(d.is_finite() && d > 0.0 && *metres > 0.0 && metres.is_finite()) {
                return Err(format!("--known-distance: cannot scale {d} COLMAP units to {metres} m"));
            }
            metres / d
        }
    };
    let aabb = points_box(&model.points);
    let groups: Vec<(PathBuf, Vec<&ColmapImage>)> = match &o.background_match {
        None => vec![(o.out.clone(), model.images.iter().collect())],
        Some(m) => {
            let (bg, scene): (Vec<&ColmapImage>, Vec<&ColmapImage>) =
                model.images.iter().partition(|im| im.name.contains(m.as_str()));
            if bg.is_empty() || scene.is_empty() {
                return Err(format!(
                    "--background-match '{m}': {} of {} image names match; both the background and the scene need images",
                    bg.len(),
                    model.images.len()
                ));
            }
            vec![(o.out.join("background"), bg), (o.out.join("scene"), scene)]
        }
    };
    let mut jsons = Vec::new();
    for (dir, ims) in &groups {
        // Image paths relative to the json's folder, so the images and the datasets move
        // together (as the loader reads them: relative to the json).
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: cannot create: {e}", dir.display()))?;
        let here = std::fs::canonicalize(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        let from_json = relative_to(&images, &here);
        let frames: Vec<serde_json::Value> = ims
            .iter()
            .map(|im| {
                let k = model.cameras[&im.camera].intrinsics;
                let mut f = serde_json::json!({
                    "file_path": from_json.join(&im.name).to_string_lossy(),
                    "transform_matrix": im.pose.to_matrix(),
                    "colmap_image_id": im.id,
                    "fl_x": k.fx, "fl_y": k.fy, "cx": k.cx, "cy": k.cy, "w": k.width, "h": k.height,
                    "camera_model": k.distortion.model_name(),
                });
                if !k.distortion.is_none() {
                    for (name, c) in k.distortion.coefficients() {
                        f[name] = c.into();
                    }
                }
                f
            })
            .collect();
        let mut json = serde_json::json!({ "frames": frames, "metres_per_unit": metres_per_unit });
        if let Some(b) = aabb {
            json["aabb"] = serde_json::json!([b.min.to_array(), b.max.to_array()]);
        }
        jsons.push((dir.clone(), ims.len(), serde_json::to_string_pretty(&json).expect("plain json")));
    }
    let mut written = Vec::new();
    for (dir, n, text) in jsons {
        std::fs::create_dir_all(&dir).map_err(|e| format!("{}: cannot create: {e}", dir.display()))?;
        let path = dir.join("transforms_train.json");
        crate::files::write_atomic(&path, text.as_bytes())?;
        written.push((path, n));
    }
    Ok(ImportReport { written, metres_per_unit, aabb })
}

/// `path` relative to the folder `base` (both absolute and canonical): `..` up to their common
/// ancestor, then down to `path`. `path` itself when they share no root (another drive).
fn relative_to(path: &Path, base: &Path) -> PathBuf {
    let (p, b): (Vec<_>, Vec<_>) = (path.components().collect(), base.components().collect());
    let common = p.iter().zip(&b).take_while(|(x, y)| x == y).count();
    if common == 0 {
        return path.to_path_buf();
    }
    let mut out: PathBuf = b[common..].iter().map(|_| std::path::Component::ParentDir).collect();
    out.extend(&p[common..]);
    out
}

/// The sparse points' 1st–99th percentile box per axis, grown by a quarter of its size on each
/// side (`None` with fewer than 8 points or a flat box).
fn points_box(points: &[Vec3]) -> Option<crate::geometry::Aabb> {
    let finite: Vec<Vec3> = points.iter().copied().filter(|p| p.is_finite()).collect();
    if finite.len() < 8 {
        return None;
    }
    let mut lo = [0f32; 3];
    let mut hi = [0f32; 3];
    for a in 0..3 {
        let mut v: Vec<f32> = finite.iter().map(|p| p[a]).collect();
        v.sort_by(f32::total_cmp);
        let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
        let (l, h) = (at(0.01), at(0.99));
        let grow = 0.25 * (h - l);
        (lo[a], hi[a]) = (l - grow, h + grow);
    }
    let b = crate::geometry::Aabb { min: Vec3::from(lo), max: Vec3::from(hi) };
    b.min.cmplt(b.max).all().then_some(b)
}

/// A capture's views as a COLMAP model: one camera per distinct intrinsics, images named by
/// `names`, and `points` as the sparse points (used by the crate's tests to make a model with
/// a known answer).
pub fn model_of_views(views: &[crate::data::View], names: &[String], points: Vec<Vec3>) -> ColmapModel {
    let mut model = ColmapModel { points, ..Default::default() };
    for (i, (v, name)) in views.iter().zip(names).enumerate() {
        let id = match model.cameras.values().find(|c| c.intrinsics == v.intrinsics) {
            Some(c) => c.id,
            None => {
                let id = model.cameras.len() as u32 + 1;
                model.cameras.insert(id, ColmapCamera { id, intrinsics: v.intrinsics });
                id
            }
        };
        model.images.push(ColmapImage { id: i as u32 + 1, name: name.clone(), camera: id, pose: v.pose });
    }
    model
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pose_survives_colmap_and_back() {
        let pose = Pose::look_at(Vec3::new(0.4, -1.3, 0.9), Vec3::new(0.0, 0.1, 0.0));
        let (q, t) = pose_to_colmap(&pose);
        let back = pose_from_colmap(q, t).unwrap();
        assert!((back.translation - pose.translation).length() < 1e-5);
        assert!((back.rotation - pose.rotation).to_cols_array().iter().all(|v| v.abs() < 1e-5));
        // The camera centre maps to COLMAP's camera origin; a point ahead has z > 0 there.
        let r = DMat3::from_quat(DQuat::from_xyzw(q[1], q[2], q[3], q[0]));
        let ahead = (pose.translation + pose.forward()).as_dvec3();
        assert!((r * ahead + DVec3::from(t)).z > 0.99);
    }
}
