//! Depth and image exports a robot stack or a person reads (DESIGN §3), each written
//! atomically. Depth is z-depth in metres, NaN for holes in memory:
//! - EXR float32, one channel `Y`, metres, NaN holes (lossless; ROS 32FC1 convention);
//! - 16-bit PNG millimetres, 0 for holes and for depth beyond 65.535 m (ROS 16UC1);
//! - `.npy` float32 metres, shape `(height, width)`, NaN holes (Dex-Net / GQ-CNN);
//! - a colourised 8-bit PNG for people (near = dark purple, far = yellow, holes black);
//! - RGB as 8-bit sRGB-encoded PNG (values as trained, clamped to [0, 1]);
//! - a point cloud as binary PLY in the world frame (metres; float x, y, z and, with colour,
//!   uchar red, green, blue), holes left out;
//! - the camera as JSON (intrinsics, pose, depth convention).

use super::atomic::write_atomic;
use crate::geometry::{pixel_ray, Intrinsics, Pose};
use std::io::Cursor;
use std::path::Path;

/// An image as PNG bytes.
pub fn png_bytes<P: image::PixelWithColorType>(img: image::ImageBuffer<P, Vec<P::Subpixel>>) -> Result<Vec<u8>, String>
where
    [P::Subpixel]: image::EncodableLayout,
{
    let mut out = Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).map_err(|e| format!("PNG encoding failed: {e}"))?;
    Ok(out.into_inner())
}

fn check(len: usize, width: u32, height: u32) {
    assert_eq!(len, width as usize * height as usize, "export: buffer is not width × height");
}

/// Depth as single-channel float32 EXR (metres, NaN holes).
pub fn depth_exr_bytes(depth: &[f32], width: u32, height: u32) -> Result<Vec<u8>, String> {
    use exr::prelude::*;
    check(depth.len(), width, height);
    let channel = AnyChannel::new("Y", FlatSamples::F32(depth.to_vec()));
    let layer = Layer::new(
        (width as usize, height as usize),
        LayerAttributes::default(),
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(vec![channel])),
    );
    let mut out = Cursor::new(Vec::new());
    Image::from_layer(layer)
        .write()
        .non_parallel()
        .to_buffered(&mut out)
        .map_err(|e| format!("EXR encoding failed: {e}"))?;
    Ok(out.into_inner())
}

/// Depth as 16-bit PNG millimetres (0 = hole or out of range).
pub fn depth_png_mm_bytes(depth: &[f32], width: u32, height: u32) -> Result<Vec<u8>, String> {
    check(depth.len(), width, height);
    let mm: Vec<u16> = depth
        .iter()
        .map(|&z| {
            let v = (z * 1000.0).round();
            if v.is_finite() && v >= 1.0 && v <= u16::MAX as f32 {
                v as u16
            } else {
                0
            }
        })
        .collect();
    png_bytes(image::ImageBuffer::<image::Luma<u16>, _>::from_raw(width, height, mm).expect("sized above"))
}

/// Depth as `.npy` float32, shape `(height, width)`.
pub fn depth_npy_bytes(depth: &[f32], width: u32, height: u32) -> Vec<u8> {
    check(depth.len(), width, height);
    let mut header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': ({height}, {width}), }}");
    // Magic (6) + version (2) + length (2) + header + '\n' is a multiple of 64.
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len() + 4 * depth.len());
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for z in depth {
        out.extend_from_slice(&z.to_le_bytes());
    }
    out
}

/// A colour map from 0 (near) to 1 (far): dark purple → blue → teal → green → yellow.
fn colour_map(x: f32) -> [u8; 3] {
    const STOPS: [[f32; 3]; 5] =
        [[0.27, 0.0, 0.33], [0.23, 0.32, 0.55], [0.13, 0.57, 0.55], [0.37, 0.79, 0.38], [0.99, 0.91, 0.14]];
    let x = x.clamp(0.0, 1.0) * 4.0;
    let i = (x.floor() as usize).min(3);
    let f = x - i as f32;
    std::array::from_fn(|k| ((STOPS[i][k] * (1.0 - f) + STOPS[i + 1][k] * f) * 255.0).round() as u8)
}

/// The colour of z-depth `z` on a `[near, far]` scale (viridis, near dark), black for a hole.
pub fn depth_colour(z: f32, near: f32, far: f32) -> [u8; 3] {
    if z.is_finite() {
        colour_map((z - near) / (far - near).max(1e-6))
    } else {
        [0, 0, 0]
    }
}

/// Depth coloured over `[near, far]` (holes black), 8-bit RGB PNG.
pub fn depth_vis_png_bytes(depth: &[f32], width: u32, height: u32, near: f32, far: f32) -> Result<Vec<u8>, String> {
    check(depth.len(), width, height);
    let px: Vec<u8> = depth.iter().flat_map(|&z| depth_colour(z, near, far)).collect();
    png_bytes(image::RgbImage::from_raw(width, height, px).expect("sized above"))
}

/// The 2nd and 98th percentiles of the finite values (a robust colour range), or (0, 1).
pub fn depth_range(depth: &[f32]) -> (f32, f32) {
    let mut v: Vec<f32> = depth.iter().copied().filter(|z| z.is_finite()).collect();
    if v.is_empty() {
        return (0.0, 1.0);
    }
    v.sort_by(f32::total_cmp);
    let at = |q: f32| v[((v.len() - 1) as f32 * q) as usize];
    (at(0.02), at(0.98))
}

/// A mask as an 8-bit gray PNG (255 set, 0 clear).
pub fn mask_png_bytes(mask: &[bool], width: u32, height: u32) -> Result<Vec<u8>, String> {
    check(mask.len(), width, height);
    let px: Vec<u8> = mask.iter().map(|&b| if b { 255 } else { 0 }).collect();
    png_bytes(image::GrayImage::from_raw(width, height, px).expect("sized above"))
}

/// Colours in [0, 1] as an 8-bit RGB PNG.
pub fn rgb_png_bytes(rgb: &[[f32; 3]], width: u32, height: u32) -> Result<Vec<u8>, String> {
    check(rgb.len(), width, height);
    let px: Vec<u8> = rgb.iter().flat_map(|c| c.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)).collect();
    png_bytes(image::RgbImage::from_raw(width, height, px).expect("sized above"))
}

/// The z-depth image `depth` of camera `k` at `pose` as a binary little-endian PLY point
/// cloud in the world frame (holes left out), coloured by `rgb` when given.
pub fn depth_ply_bytes(depth: &[f32], k: &Intrinsics, pose: &Pose, rgb: Option<&[[f32; 3]]>) -> Vec<u8> {
    check(depth.len(), k.width, k.height);
    if let Some(c) = rgb {
        check(c.len(), k.width, k.height);
    }
    let points: Vec<usize> = (0..depth.len()).filter(|&p| depth[p].is_finite()).collect();
    let mut out = format!(
        "ply\nformat binary_little_endian 1.0\ncomment residual-nerf depth, world frame, metres\n\
         element vertex {}\nproperty float x\nproperty float y\nproperty float z\n{}end_header\n",
        points.len(),
        if rgb.is_some() { "property uchar red\nproperty uchar green\nproperty uchar blue\n" } else { "" }
    )
    .into_bytes();
    for p in points {
        let ray = pixel_ray(k, pose, p as u32 % k.width, p as u32 / k.width);
        let x = ray.at(ray.z_to_range(depth[p]));
        for v in x.to_array() {
            out.extend_from_slice(&v.to_le_bytes());
        }
        if let Some(c) = rgb {
            out.extend(c[p].map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8));
        }
    }
    out
}

/// The camera of a depth image as JSON: intrinsics, camera-to-world pose (OpenGL camera) and
/// the depth convention.
pub fn camera_json(k: &Intrinsics, pose: &Pose) -> String {
    let mut j = serde_json::json!({
        "width": k.width, "height": k.height, "fx": k.fx, "fy": k.fy, "cx": k.cx, "cy": k.cy,
        "camera_model": k.distortion.model_name(),
        "transform_matrix": pose.to_matrix(),
        "camera_convention": "OpenGL camera-to-world (camera looks down -Z, +Y up)",
        "depth_kind": "z", "depth_unit": "m", "holes": "NaN in .exr/.npy, 0 in the 16-bit mm PNG",
    });
    if !k.distortion.is_none() {
        for (name, c) in k.distortion.coefficients() {
            j[name] = c.into();
        }
    }
    j.to_string()
}

/// Writes `bytes` atomically, naming the file on error.
pub fn write(path: &Path, bytes: Result<Vec<u8>, String>) -> Result<(), String> {
    let bytes = bytes.map_err(|e| format!("{}: {e}", path.display()))?;
    write_atomic(path, &bytes)
}
