//! `transforms*.json` (DESIGN §3): the NeRF-synthetic layout with Instant-NGP's intrinsics
//! keys, our optional depth / mask / crop / aabb keys, and the authors' single-json layout with
//! per-frame `"type": "bg" | "wrap"`. Parsing is pure (bytes in, a [`Transforms`] or every
//! problem found out) so it is fuzzed and tested without files. Unknown keys are ignored.
//!
//! Intrinsics: `fl_x` (and `fl_y`, else `fl_x`), else `camera_angle_x` (and `camera_angle_y`
//! for `fl_y`, else square pixels); `cx`, `cy` default to the image centre; `w`, `h` are checked
//! against the image when given. Lens distortion: `camera_model` (`PINHOLE`, `OPENCV`,
//! `OPENCV_FISHEYE`; Instant-NGP's `is_fisheye: true` means `OPENCV_FISHEYE`) with `k1 k2 k3 k4
//! p1 p2` (missing ones are 0; coefficients without a `camera_model` mean `OPENCV`, as in
//! Instant-NGP). Every one of these keys may also appear per frame, where it overrides the top
//! level.
//!
//! Scale: the json's units are taken as metres unless a top-level `metres_per_unit` says
//! otherwise (camera positions and the `aabb` are multiplied by it at load, so threshold
//! density and depth are per metre). Instant-NGP's `scale` and `offset` (its unit cube in the
//! json's frame, axes permuted as Instant-NGP does) give the scene box when there is no `aabb`,
//! enlarged by `aabb_scale` about the cube's centre.

use super::error::DataError;
use crate::geometry::{Aabb, Distortion, Pose};
use glam::{Mat3, Vec3};
use serde_json::{Map, Value};
use std::path::{Path, PathBuf};

/// Largest accepted camera translation (metres of the dataset): anything further is a broken pose.
pub const MAX_TRANSLATION: f32 = 1e6;
/// Largest accepted image side (pixels), for `w`/`h` here and for image headers.
pub const MAX_SIDE: u32 = 16384;

pub use crate::geometry::DepthKind;

/// The authors' per-frame role (`"type"`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameType {
    /// `"bg"`: a view of the empty workspace.
    Background,
    /// `"wrap"`: a view of the workspace with the new objects.
    Scene,
}

/// Camera intrinsics as the json gives them (resolved once the image size is known).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CameraSpec {
    /// `camera_angle_x` (radians).
    pub angle_x: Option<f32>,
    /// `camera_angle_y` (radians).
    pub angle_y: Option<f32>,
    /// `fl_x` (pixels).
    pub fl_x: Option<f32>,
    /// `fl_y` (pixels).
    pub fl_y: Option<f32>,
    /// `cx` (pixels).
    pub cx: Option<f32>,
    /// `cy` (pixels).
    pub cy: Option<f32>,
    /// `w` (pixels).
    pub w: Option<u32>,
    /// `h` (pixels).
    pub h: Option<u32>,
    /// `camera_model` (or `is_fisheye`).
    pub model: Option<LensModel>,
    /// `k1 k2 k3 k4 p1 p2`, each when given.
    pub coefficients: [Option<f32>; 6],
}

/// The lens model a json names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LensModel {
    /// `PINHOLE` (also `SIMPLE_PINHOLE`).
    Pinhole,
    /// `OPENCV`.
    OpenCv,
    /// `OPENCV_FISHEYE`.
    Fisheye,
}

/// The distortion coefficients' json keys, in [`CameraSpec::coefficients`]' order.
pub const COEFFICIENT_KEYS: [&str; 6] = ["k1", "k2", "k3", "k4", "p1", "p2"];

impl CameraSpec {
    /// `self` with every key `over` sets replaced.
    fn overridden(self, over: CameraSpec) -> CameraSpec {
        CameraSpec {
            angle_x: over.angle_x.or(self.angle_x),
            angle_y: over.angle_y.or(self.angle_y),
            fl_x: over.fl_x.or(self.fl_x),
            fl_y: over.fl_y.or(self.fl_y),
            cx: over.cx.or(self.cx),
            cy: over.cy.or(self.cy),
            w: over.w.or(self.w),
            h: over.h.or(self.h),
            model: over.model.or(self.model),
            coefficients: std::array::from_fn(|i| over.coefficients[i].or(self.coefficients[i])),
        }
    }

    /// The lens distortion these keys describe, or the key at fault and why.
    pub fn distortion(&self) -> Result<Distortion, (&'static str, String)> {
        let c = self.coefficients.map(|c| c.unwrap_or(0.0));
        let any = self.coefficients.iter().any(Option::is_some);
        match self.model {
            Some(LensModel::Pinhole) if c.iter().any(|&v| v != 0.0) => {
                Err(("camera_model", "PINHOLE with distortion coefficients (use OPENCV or OPENCV_FISHEYE)".into()))
            }
            Some(LensModel::Pinhole) => Ok(Distortion::None),
            None if !any => Ok(Distortion::None),
            None | Some(LensModel::OpenCv) => Ok(Distortion::Radial { k: [c[0], c[1], c[2], c[3]], p: [c[4], c[5]] }),
            Some(LensModel::Fisheye) if c[4] != 0.0 || c[5] != 0.0 => {
                Err(("p1", "OPENCV_FISHEYE has no tangential terms (p1, p2)".into()))
            }
            Some(LensModel::Fisheye) => Ok(Distortion::Fisheye { k: [c[0], c[1], c[2], c[3]] }),
        }
    }

    /// `(fx, fy, cx, cy)` for an image of `width × height`, or what is missing.
    pub fn resolve(&self, width: u32, height: u32) -> Result<(f32, f32, f32, f32), String> {
        let from_angle = |angle: f32, side: u32| 0.5 * side as f32 / (0.5 * angle).tan();
        let fx = match (self.fl_x, self.angle_x) {
            (Some(f), _) => f,
            (None, Some(a)) => from_angle(a, width),
            (None, None) => return Err("no focal length: give 'camera_angle_x' or 'fl_x'".into()),
        };
        let fy = match (self.fl_y, self.angle_y) {
            (Some(f), _) => f,
            (None, Some(a)) => from_angle(a, height),
            (None, None) => fx,
        };
        let (cx, cy) = (self.cx.unwrap_or(0.5 * width as f32), self.cy.unwrap_or(0.5 * height as f32));
        Ok((fx, fy, cx, cy))
    }
}

/// One frame of a transforms json (paths resolved against the json's folder).
#[derive(Clone, Debug, PartialEq)]
pub struct FrameSpec {
    /// Index in the json's `frames` array.
    pub index: usize,
    /// `file_path` as written (before an extension is looked for).
    pub file_path: PathBuf,
    /// `depth_file_path`.
    pub depth_path: Option<PathBuf>,
    /// `mask_path`.
    pub mask_path: Option<PathBuf>,
    /// `crop` `[x0, y0, x1, y1]`, inclusive-exclusive (checked against the image later).
    pub crop: Option<[u32; 4]>,
    /// Camera-to-world `transform_matrix`.
    pub pose: Pose,
    /// Intrinsics (top level overridden by the frame's own keys).
    pub camera: CameraSpec,
    /// `type` (authors' layout), when present.
    pub frame_type: Option<FrameType>,
}

/// A parsed transforms json.
#[derive(Clone, Debug, PartialEq)]
pub struct Transforms {
    /// Frames in file order.
    pub frames: Vec<FrameSpec>,
    /// Top-level `aabb`.
    pub aabb: Option<Aabb>,
    /// Top-level `depth_kind` (default `z`).
    pub depth_kind: DepthKind,
    /// Metres per depth-file unit from `depth_unit` (`m` → 1, `mm` → 0.001; default 1).
    pub depth_scale: f32,
    /// Metres per json unit (`metres_per_unit`, default 1), already applied to the frames'
    /// camera positions and to `aabb`.
    pub metres_per_unit: f32,
}

/// Parses `bytes`, the contents of the json at `path` (used for error messages and to resolve
/// relative paths). Returns every problem found, not just the first.
pub fn parse_transforms(bytes: &[u8], path: &Path) -> Result<Transforms, Vec<DataError>> {
    let root: Value = serde_json::from_slice(bytes).map_err(|e| {
        let what = if e.is_eof() { "truncated JSON" } else { "malformed JSON" };
        vec![DataError::file(path, format!("{what}: {e}"))]
    })?;
    let Some(root) = root.as_object() else {
        return Err(vec![DataError::file(path, "expected a JSON object at the top level")]);
    };
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut errors = Vec::new();
    let top_camera = camera_spec(root, path, None, &mut errors);
    let metres_per_unit = match root.get("metres_per_unit").map(number) {
        None => 1.0,
        Some(Ok(x)) if x > 0.0 && x <= 1e6 => x as f32,
        Some(Ok(x)) => {
            errors.push(field(path, None, "metres_per_unit", format!("{x} is outside (0, 1e6]")));
            1.0
        }
        Some(Err(m)) => {
            errors.push(field(path, None, "metres_per_unit", m));
            1.0
        }
    };
    let aabb = match root.get("aabb") {
        Some(v) => parse_aabb(v).map_err(|m| errors.push(field(path, None, "aabb", m))).ok(),
        None => ngp_aabb(root).map_err(|(name, m)| errors.push(field(path, None, name, m))).ok().flatten(),
    }
    .map(|b| Aabb { min: b.min * metres_per_unit, max: b.max * metres_per_unit });
    let depth_kind = match root.get("depth_kind").map(|v| v.as_str()) {
        None | Some(Some("z")) => DepthKind::Z,
        Some(Some("range")) => DepthKind::Range,
        Some(other) => {
            errors.push(field(path, None, "depth_kind", format!("expected \"z\" or \"range\", found {other:?}")));
            DepthKind::Z
        }
    };
    let depth_scale = match root.get("depth_unit").map(|v| v.as_str()) {
        None | Some(Some("m")) => 1.0,
        Some(Some("mm")) => 1e-3,
        Some(other) => {
            errors.push(field(path, None, "depth_unit", format!("expected \"m\" or \"mm\", found {other:?}")));
            1.0
        }
    };
    let frames = match root.get("frames") {
        None => {
            errors.push(field(path, None, "frames", "missing"));
            Vec::new()
        }
        Some(Value::Array(a)) if a.is_empty() => {
            errors.push(field(path, None, "frames", "no frames"));
            Vec::new()
        }
        Some(Value::Array(a)) => {
            let mut frames: Vec<FrameSpec> = a
                .iter()
                .enumerate()
                .filter_map(|(i, f)| parse_frame(f, i, dir, path, top_camera, &mut errors))
                .collect();
            for f in &mut frames {
                f.pose.translation *= metres_per_unit;
            }
            frames
        }
        Some(_) => {
            errors.push(field(path, None, "frames", "expected an array"));
            Vec::new()
        }
    };
    if errors.is_empty() {
        Ok(Transforms { frames, aabb, depth_kind, depth_scale, metres_per_unit })
    } else {
        Err(errors)
    }
}

fn field(path: &Path, frame: Option<usize>, name: &str, message: impl Into<String>) -> DataError {
    DataError::field(path, frame, name, message)
}

/// A finite number (json numbers only; strings are refused).
fn number(v: &Value) -> Result<f64, String> {
    match v.as_f64() {
        Some(x) if x.is_finite() => Ok(x),
        Some(x) => Err(format!("not finite ({x})")),
        None => Err(format!("expected a number, found {}", kind(v))),
    }
}

fn kind(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}

/// The intrinsics keys of `obj` (a frame or the top level), each validated.
fn camera_spec(obj: &Map<String, Value>, path: &Path, frame: Option<usize>, errors: &mut Vec<DataError>) -> CameraSpec {
    let mut get = |name: &str, lo: f64, hi: f64| -> Option<f64> {
        let v = obj.get(name)?;
        match number(v) {
            Ok(x) if x > lo && x < hi => Some(x),
            Ok(x) => {
                errors.push(field(path, frame, name, format!("{x} is outside ({lo}, {hi})")));
                None
            }
            Err(m) => {
                errors.push(field(path, frame, name, m));
                None
            }
        }
    };
    let pi = std::f64::consts::PI;
    let side = MAX_SIDE as f64 + 1.0;
    // Distortion coefficients beyond these are not a lens (real ones are within ±2 for k, ±0.1
    // for p); whether a model can be inverted over the image is checked once its size is known.
    let coefficients = COEFFICIENT_KEYS.map(|name| {
        let bound = if name.starts_with('p') { 1.0 } else { 10.0 };
        get(name, -bound, bound).map(|x| x as f32)
    });
    let spec = CameraSpec {
        model: None,
        coefficients,
        angle_x: get("camera_angle_x", 0.0, pi).map(|x| x as f32),
        angle_y: get("camera_angle_y", 0.0, pi).map(|x| x as f32),
        fl_x: get("fl_x", 0.0, 1e7).map(|x| x as f32),
        fl_y: get("fl_y", 0.0, 1e7).map(|x| x as f32),
        cx: get("cx", -1e6, 1e6).map(|x| x as f32),
        cy: get("cy", -1e6, 1e6).map(|x| x as f32),
        w: get("w", 0.5, side).map(|x| x.round() as u32),
        h: get("h", 0.5, side).map(|x| x.round() as u32),
    };
    let model = match (obj.get("camera_model"), obj.get("is_fisheye")) {
        (Some(v), _) => match v.as_str() {
            Some("PINHOLE" | "SIMPLE_PINHOLE") => Some(LensModel::Pinhole),
            Some("OPENCV") => Some(LensModel::OpenCv),
            Some("OPENCV_FISHEYE") => Some(LensModel::Fisheye),
            _ => {
                errors.push(field(
                    path,
                    frame,
                    "camera_model",
                    format!("expected \"PINHOLE\", \"OPENCV\" or \"OPENCV_FISHEYE\", found {v}"),
                ));
                None
            }
        },
        (None, Some(Value::Bool(true))) => Some(LensModel::Fisheye),
        (None, Some(Value::Bool(false))) => None,
        (None, Some(v)) => {
            errors.push(field(path, frame, "is_fisheye", format!("expected a boolean, found {}", kind(v))));
            None
        }
        (None, None) => None,
    };
    CameraSpec { model, ..spec }
}

/// Instant-NGP's unit cube in the json's frame, from `scale` and `offset` (and `aabb_scale`),
/// when either is given: Instant-NGP maps a camera position `p` to `(p.y, p.z, p.x)·scale +
/// offset` and renders the cube `[0, 1]³` enlarged by `aabb_scale` about its centre.
fn ngp_aabb(root: &Map<String, Value>) -> Result<Option<Aabb>, (&'static str, String)> {
    if root.get("scale").is_none() && root.get("offset").is_none() {
        return Ok(None);
    }
    let scale = match root.get("scale").map(number) {
        None => 0.33, // Instant-NGP's default
        Some(Ok(s)) if s > 0.0 && s < 1e6 => s,
        Some(Ok(s)) => return Err(("scale", format!("{s} is outside (0, 1e6)"))),
        Some(Err(m)) => return Err(("scale", m)),
    };
    let offset = match root.get("offset") {
        None => [0.5; 3],
        Some(v) => {
            let a = v.as_array().filter(|a| a.len() == 3).ok_or(("offset", "expected [x, y, z]".to_string()))?;
            let mut o = [0.0; 3];
            for (o, x) in o.iter_mut().zip(a) {
                *o = number(x).map_err(|m| ("offset", m))?;
            }
            o
        }
    };
    let aabb_scale = match root.get("aabb_scale").map(number) {
        None => 1.0,
        Some(Ok(s)) if (1.0..=128.0).contains(&s) => s,
        Some(Ok(s)) => return Err(("aabb_scale", format!("{s} is outside [1, 128]"))),
        Some(Err(m)) => return Err(("aabb_scale", m)),
    };
    // Cube axis a of Instant-NGP is json axis (a + 1) mod 3.
    let (lo, hi) = (0.5 - 0.5 * aabb_scale, 0.5 + 0.5 * aabb_scale);
    let mut min = [0f32; 3];
    let mut max = [0f32; 3];
    for a in 0..3 {
        let j = (a + 1) % 3;
        min[j] = ((lo - offset[a]) / scale) as f32;
        max[j] = ((hi - offset[a]) / scale) as f32;
    }
    let b = Aabb { min: Vec3::from(min), max: Vec3::from(max) };
    if !(b.size().is_finite() && b.max.abs().max(b.min.abs()).max_element() <= MAX_TRANSLATION) {
        return Err(("scale", format!("the box {:?}..{:?} is absurd", b.min, b.max)));
    }
    Ok(Some(b))
}

fn parse_aabb(v: &Value) -> Result<Aabb, String> {
    let corner = |c: &Value| -> Result<Vec3, String> {
        let a = c.as_array().filter(|a| a.len() == 3).ok_or("expected [[xmin,ymin,zmin],[xmax,ymax,zmax]]")?;
        let x: Vec<f64> = a.iter().map(number).collect::<Result<_, _>>()?;
        Ok(Vec3::new(x[0] as f32, x[1] as f32, x[2] as f32))
    };
    let a = v.as_array().filter(|a| a.len() == 2).ok_or("expected [[xmin,ymin,zmin],[xmax,ymax,zmax]]")?;
    let (min, max) = (corner(&a[0])?, corner(&a[1])?);
    if !(min.cmplt(max).all() && (max - min).is_finite() && max.abs().max(min.abs()).max_element() <= MAX_TRANSLATION) {
        return Err(format!("empty, inverted or absurd box {min:?}..{max:?}"));
    }
    Ok(Aabb { min, max })
}

/// A 4×4 or 3×4 camera-to-world matrix with an orthonormal rotation and a sane translation.
pub fn parse_pose(v: &Value) -> Result<Pose, String> {
    let rows = v.as_array().ok_or_else(|| format!("expected a 4x4 or 3x4 matrix, found {}", kind(v)))?;
    if rows.len() != 4 && rows.len() != 3 {
        return Err(format!("expected 4 or 3 rows, found {}", rows.len()));
    }
    let mut m = [[0f32; 4]; 3];
    for (r, row) in rows.iter().take(3).enumerate() {
        let row = row.as_array().filter(|x| x.len() == 4).ok_or_else(|| format!("row {r} is not 4 numbers"))?;
        for (c, x) in row.iter().enumerate() {
            m[r][c] = number(x).map_err(|e| format!("row {r}, column {c}: {e}"))? as f32;
        }
    }
    if rows.len() == 4 {
        let last = rows[3].as_array().filter(|x| x.len() == 4).ok_or("row 3 is not 4 numbers")?;
        let last: Vec<f64> = last.iter().map(number).collect::<Result<_, _>>().map_err(|e| format!("row 3: {e}"))?;
        if last.iter().zip([0.0, 0.0, 0.0, 1.0]).any(|(a, b)| (a - b).abs() > 1e-4) {
            return Err(format!("last row is {last:?}, expected [0, 0, 0, 1]"));
        }
    }
    let pose = Pose::from_rows(m);
    let r: Mat3 = pose.rotation;
    let err = (r.transpose() * r - Mat3::IDENTITY).to_cols_array().iter().fold(0f32, |a, x| a.max(x.abs()));
    if err > 1e-2 {
        return Err(format!("rotation is not orthonormal (|RᵀR − I| = {err:.3})"));
    }
    if pose.translation.abs().max_element() > MAX_TRANSLATION {
        return Err(format!("translation {:?} is beyond ±{MAX_TRANSLATION} (absurd)", pose.translation));
    }
    Ok(pose)
}

fn parse_crop(v: &Value) -> Result<[u32; 4], String> {
    let a = v.as_array().filter(|a| a.len() == 4).ok_or("expected [x0, y0, x1, y1]")?;
    let mut c = [0u32; 4];
    for (o, x) in c.iter_mut().zip(a) {
        let x = number(x)?;
        if !(0.0..=MAX_SIDE as f64).contains(&x) || x.fract() != 0.0 {
            return Err(format!("{x} is not a pixel index in 0..={MAX_SIDE}"));
        }
        *o = x as u32;
    }
    if c[0] >= c[2] || c[1] >= c[3] {
        return Err(format!("empty crop {c:?}"));
    }
    Ok(c)
}

fn relative_path(v: &Value, dir: &Path) -> Result<PathBuf, String> {
    match v.as_str() {
        Some("") => Err("empty path".into()),
        Some(s) if s.contains('\0') => Err("path contains a NUL byte".into()),
        Some(s) => Ok(dir.join(s)),
        None => Err(format!("expected a path string, found {}", kind(v))),
    }
}

fn parse_frame(
    v: &Value,
    index: usize,
    dir: &Path,
    path: &Path,
    top: CameraSpec,
    errors: &mut Vec<DataError>,
) -> Option<FrameSpec> {
    let Some(obj) = v.as_object() else {
        errors.push(DataError {
            file: path.into(),
            frame: Some(index),
            field: None,
            message: "expected an object".into(),
        });
        return None;
    };
    let before = errors.len();
    let at = Some(index);
    let mut need = |name: &str| {
        let v = obj.get(name);
        if v.is_none() {
            errors.push(field(path, at, name, "missing"));
        }
        v
    };
    let file_path = need("file_path");
    let matrix = need("transform_matrix");
    let file_path =
        file_path.and_then(|v| relative_path(v, dir).map_err(|m| errors.push(field(path, at, "file_path", m))).ok());
    let pose = matrix.and_then(|v| parse_pose(v).map_err(|m| errors.push(field(path, at, "transform_matrix", m))).ok());
    let mut optional_path = |name: &str| {
        obj.get(name).and_then(|v| relative_path(v, dir).map_err(|m| errors.push(field(path, at, name, m))).ok())
    };
    let depth_path = optional_path("depth_file_path");
    let mask_path = optional_path("mask_path");
    let crop = obj.get("crop").and_then(|v| parse_crop(v).map_err(|m| errors.push(field(path, at, "crop", m))).ok());
    let frame_type = match obj.get("type").map(|t| t.as_str()) {
        None => None,
        Some(Some("bg")) => Some(FrameType::Background),
        Some(Some("wrap")) => Some(FrameType::Scene),
        Some(other) => {
            errors.push(field(path, at, "type", format!("expected \"bg\" or \"wrap\", found {other:?}")));
            None
        }
    };
    let camera = top.overridden(camera_spec(obj, path, at, errors));
    if camera.fl_x.is_none() && camera.angle_x.is_none() {
        errors.push(field(path, at, "camera_angle_x", "no focal length: give 'camera_angle_x' or 'fl_x'"));
    }
    if errors.len() > before {
        return None;
    }
    Some(FrameSpec { index, file_path: file_path?, depth_path, mask_path, crop, pose: pose?, camera, frame_type })
}
