//! A dataset split on disk → posed views (and, where the json has them, ground-truth z-depth,
//! masks and crops). Every problem of the split is collected into one [`DataReport`]; nothing
//! is written.

use super::error::{DataError, DataReport};
use super::images::{decode_depth_exr, decode_mask, decode_rgb, dimensions};
use super::transforms::{parse_transforms, DepthKind, FrameSpec, FrameType, Transforms, COEFFICIENT_KEYS};
use crate::data::View;
use crate::files::read_limited;
use crate::geometry::{pixel_ray, Aabb, Intrinsics};
use glam::Vec3;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Largest accepted json file (bytes).
const MAX_JSON_BYTES: u64 = 256 << 20;
/// Largest accepted image or depth file (bytes).
const MAX_IMAGE_BYTES: u64 = 512 << 20;

/// How a split is loaded.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadOptions {
    /// Colour that alpha is composited over. Defaults to white (the NeRF-synthetic convention).
    pub background: [f32; 3],
    /// In the authors' layout (frames with `"type"`), keep only frames of this type; frames
    /// without a type are always kept; `None` keeps all. Defaults to `Some(FrameType::Scene)`.
    pub frame_type: Option<FrameType>,
    /// Read `depth_file_path`, `mask_path`, `crop` (evaluation needs them; training does not).
    /// Defaults to true.
    pub ground_truth: bool,
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions { background: [1.0; 3], frame_type: Some(FrameType::Scene), ground_truth: true }
    }
}

/// Where the scene box came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AabbSource {
    /// The json's top-level `aabb`.
    File,
    /// Derived from the cameras (see [`aabb_from_cameras`]).
    Cameras,
}

/// Ground truth and bookkeeping of one loaded frame (its image is the matching [`View`]).
#[derive(Clone, Debug, PartialEq)]
pub struct FrameInfo {
    /// Index in the json's `frames`.
    pub index: usize,
    /// The image file read.
    pub image_path: PathBuf,
    /// `type` in the authors' layout.
    pub frame_type: Option<FrameType>,
    /// Ground-truth **z-depth** in metres per pixel (converted from range when the dataset
    /// stores range); NaN where the file holds no valid depth.
    pub depth: Option<Vec<f32>>,
    /// Mask per pixel (the transparent object).
    pub mask: Option<Vec<bool>>,
    /// `[x0, y0, x1, y1]` scoring crop, inclusive-exclusive, inside the image.
    pub crop: Option<[u32; 4]>,
}

/// One split of a dataset.
#[derive(Clone, Debug)]
pub struct Dataset {
    /// The json read.
    pub json: PathBuf,
    /// Posed images (same order as `frames`).
    pub views: Vec<View>,
    /// Per-frame ground truth.
    pub frames: Vec<FrameInfo>,
    /// The scene box.
    pub aabb: Aabb,
    /// Where `aabb` came from.
    pub aabb_source: AabbSource,
    /// What the depth files measured (in memory depth is always z).
    pub depth_kind: DepthKind,
    /// Metres per json unit (`metres_per_unit`; poses and the box are already in metres).
    pub metres_per_unit: f32,
    /// Whether any image had alpha (composited over [`LoadOptions::background`]).
    pub had_alpha: bool,
    /// One-line notes about input that was accepted but may not be what the author meant
    /// (e.g. images of different sizes while the json states no `w`/`h`); the commands print
    /// them as warnings.
    pub warnings: Vec<String>,
}

/// The json of `split` in `dir`: `transforms_{split}.json`, else the single `transforms.json`
/// (Instant-NGP and the authors' layout).
pub fn split_json(dir: &Path, split: &str) -> Result<PathBuf, DataError> {
    if !dir.is_dir() {
        return Err(DataError::file(dir, "data directory not found"));
    }
    let named = dir.join(format!("transforms_{split}.json"));
    if named.is_file() {
        return Ok(named);
    }
    let single = dir.join("transforms.json");
    if single.is_file() {
        return Ok(single);
    }
    Err(DataError::file(&named, format!("split '{split}' not found (no transforms_{split}.json or transforms.json)")))
}

/// `path` if it exists, else `path` with a common image extension appended (NeRF-synthetic
/// `file_path`s have none).
fn find_image(path: &Path) -> Option<PathBuf> {
    if path.is_file() {
        return Some(path.to_path_buf());
    }
    ["png", "jpg", "jpeg", "PNG", "JPG"]
        .iter()
        .map(|e| PathBuf::from(format!("{}.{e}", path.display())))
        .find(|p| p.is_file())
}

impl Dataset {
    /// Loads `split` of the dataset in `dir`.
    pub fn load(dir: &Path, split: &str, opts: &LoadOptions) -> Result<Dataset, DataReport> {
        let json = split_json(dir, split)?;
        let bytes = read_limited(&json, MAX_JSON_BYTES).map_err(|m| DataError::file(&json, m))?;
        let t = parse_transforms(&bytes, &json).map_err(DataReport)?;
        Dataset::from_transforms(json, t, opts)
    }

    /// Loads the files a parsed json names.
    pub fn from_transforms(json: PathBuf, t: Transforms, opts: &LoadOptions) -> Result<Dataset, DataReport> {
        let specs: Vec<&FrameSpec> = t
            .frames
            .iter()
            .filter(|f| match (opts.frame_type, f.frame_type) {
                (Some(want), Some(have)) => want == have,
                _ => true,
            })
            .collect();
        if specs.is_empty() {
            let what =
                opts.frame_type
                    .map_or("", |t| if t == FrameType::Scene { " of type \"wrap\"" } else { " of type \"bg\"" });
            return Err(DataError::field(&json, None, "frames", format!("no frames{what}")).into());
        }
        let loaded: Vec<Result<(View, FrameInfo, bool), Vec<DataError>>> =
            specs.par_iter().map(|f| load_frame(&json, f, &t, opts)).collect();
        let mut errors = Vec::new();
        let (mut views, mut frames, mut had_alpha) = (Vec::new(), Vec::new(), false);
        for r in loaded {
            match r {
                Ok((v, f, a)) => {
                    views.push(v);
                    frames.push(f);
                    had_alpha |= a;
                }
                Err(e) => errors.extend(e),
            }
        }
        if !errors.is_empty() {
            return Err(DataReport(errors));
        }
        let (aabb, aabb_source) = match t.aabb {
            Some(b) => (b, AabbSource::File),
            None => (aabb_from_cameras(&views), AabbSource::Cameras),
        };
        let warnings = mixed_sizes_warning(&json, &specs, &views).into_iter().collect();
        Ok(Dataset {
            json,
            views,
            frames,
            aabb,
            aabb_source,
            depth_kind: t.depth_kind,
            metres_per_unit: t.metres_per_unit,
            had_alpha,
            warnings,
        })
    }
}

/// A warning when the images differ in size and the json states no `w`/`h` for the frame that
/// differs from the first: each frame then keeps its own size and intrinsics derived from it,
/// which is right for mixed cameras but usually means a mis-exported image.
fn mixed_sizes_warning(json: &Path, specs: &[&FrameSpec], views: &[View]) -> Option<String> {
    let first = views.first()?;
    let (w0, h0) = (first.intrinsics.width, first.intrinsics.height);
    let differ = specs.iter().zip(views).find(|(f, v)| {
        (v.intrinsics.width, v.intrinsics.height) != (w0, h0) && (f.camera.w.is_none() || f.camera.h.is_none())
    })?;
    let (f, v) = differ;
    Some(format!(
        "{}: frame {}: image is {}x{} but frame {}'s is {w0}x{h0} and the json states no w/h; each frame keeps its own size",
        json.display(),
        f.index,
        v.intrinsics.width,
        v.intrinsics.height,
        specs[0].index
    ))
}

fn load_frame(
    json: &Path,
    f: &FrameSpec,
    t: &Transforms,
    opts: &LoadOptions,
) -> Result<(View, FrameInfo, bool), Vec<DataError>> {
    let at = Some(f.index);
    let fail = |field: &str, m: String| vec![DataError::field(json, at, field, m)];
    let image_path = find_image(&f.file_path).ok_or_else(|| {
        fail("file_path", format!("image {} not found (also tried .png, .jpg)", f.file_path.display()))
    })?;
    let on_image = |m: String| vec![DataError::file(&image_path, format!("frame {}: {m}", f.index))];
    let bytes = read_limited(&image_path, MAX_IMAGE_BYTES).map_err(on_image)?;
    let (w, h) = dimensions(&bytes).map_err(on_image)?;
    if f.camera.w.is_some_and(|cw| cw != w) || f.camera.h.is_some_and(|ch| ch != h) {
        return Err(on_image(format!(
            "image is {w}x{h} but the json says w={} h={}",
            f.camera.w.unwrap_or(w),
            f.camera.h.unwrap_or(h)
        )));
    }
    let (fx, fy, cx, cy) = f.camera.resolve(w, h).map_err(|m| fail("camera_angle_x", m))?;
    let distortion = f.camera.distortion().map_err(|(name, m)| fail(name, m))?;
    // Which key to blame when the model cannot be inverted over this image: the first
    // coefficient the json gives.
    let blame = (0..6).find(|&i| f.camera.coefficients[i].is_some()).map_or("camera_model", |i| COEFFICIENT_KEYS[i]);
    distortion.check(w, h, fx, fy, cx, cy).map_err(|m| fail(blame, m))?;
    let intrinsics = Intrinsics { width: w, height: h, fx, fy, cx, cy, distortion };
    let rgb = decode_rgb(&bytes, opts.background).map_err(on_image)?;
    let mut info = FrameInfo {
        index: f.index,
        image_path: image_path.clone(),
        frame_type: f.frame_type,
        depth: None,
        mask: None,
        crop: None,
    };
    if opts.ground_truth {
        if let Some(c) = f.crop {
            if c[2] > w || c[3] > h {
                return Err(fail("crop", format!("{c:?} reaches outside the {w}x{h} image")));
            }
            info.crop = Some(c);
        }
        if let Some(p) = &f.depth_path {
            let on_depth =
                |m: String| vec![DataError::file(p, format!("frame {}: field 'depth_file_path': {m}", f.index))];
            let bytes = read_limited(p, MAX_IMAGE_BYTES).map_err(on_depth)?;
            let (dw, dh, mut d) = decode_depth_exr(&bytes).map_err(on_depth)?;
            if (dw, dh) != (w, h) {
                return Err(on_depth(format!("depth is {dw}x{dh}, the image {w}x{h}")));
            }
            for (p, z) in d.iter_mut().enumerate() {
                let v = *z * t.depth_scale;
                *z = if v.is_finite() && v > 0.0 {
                    match t.depth_kind {
                        DepthKind::Z => v,
                        DepthKind::Range => pixel_ray(&intrinsics, &f.pose, p as u32 % w, p as u32 / w).range_to_z(v),
                    }
                } else {
                    f32::NAN
                };
            }
            info.depth = Some(d);
        }
        if let Some(p) = &f.mask_path {
            let on_mask = |m: String| vec![DataError::file(p, format!("frame {}: field 'mask_path': {m}", f.index))];
            let bytes = read_limited(p, MAX_IMAGE_BYTES).map_err(on_mask)?;
            let (mw, mh, m) = decode_mask(&bytes).map_err(on_mask)?;
            if (mw, mh) != (w, h) {
                return Err(on_mask(format!("mask is {mw}x{mh}, the image {w}x{h}")));
            }
            info.mask = Some(m);
        }
    }
    Ok((View { intrinsics, pose: f.pose, rgb: rgb.pixels }, info, rgb.had_alpha))
}

/// A scene box from the cameras alone, for captures that look inwards: the centre is the point
/// nearest (least squares) to every optical axis, the half-size the largest camera distance from
/// it, so the box holds every camera and what they look at. Degenerate (parallel) axes fall
/// back to the cameras' centroid.
pub fn aabb_from_cameras(views: &[View]) -> Aabb {
    // Σ (I − d dᵀ) c = Σ (I − d dᵀ) o for the nearest point c to the lines (o, d).
    let (mut a, mut b) = (glam::DMat3::ZERO, glam::DVec3::ZERO);
    let mut centroid = glam::DVec3::ZERO;
    for v in views {
        let d = v.pose.forward().as_dvec3().normalize();
        let o = v.pose.translation.as_dvec3();
        let p = glam::DMat3::IDENTITY - glam::DMat3::from_cols(d * d.x, d * d.y, d * d.z);
        a += p;
        b += p * o;
        centroid += o / views.len() as f64;
    }
    let centre = if a.determinant().abs() > 1e-6 * views.len().pow(3) as f64 { a.inverse() * b } else { centroid };
    let radius = views.iter().map(|v| (v.pose.translation.as_dvec3() - centre).length()).fold(1e-3, f64::max);
    let (c, r) = (centre.as_vec3(), Vec3::splat(radius as f32 * 1.05));
    Aabb { min: c - r, max: c + r }
}
