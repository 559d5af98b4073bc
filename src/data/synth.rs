//! Small analytic scenes for tests: (a) a closed room (procedurally textured walls, floor and
//! ceiling) with a shaded opaque sphere, seen from cameras inside it, and (b) a tabletop — a
//! textured square table top with the sphere on it under a plain sky — seen from cameras
//! around and above it; exact z-depth ground truth per pixel. [`SynthScene`] is shared with the
//! robot workspace of [`super::workspace`] and writes any of them in the dataset layout.

use crate::data::View;
use crate::geometry::{pixel_ray, Aabb, Intrinsics, Pose, Ray};
use glam::Vec3;

/// Half-size of the room (metres): the room is `[−1, 1]³`.
pub const ROOM: f32 = 1.0;
/// Sphere centre and radius.
pub const SPHERE: (Vec3, f32) = (Vec3::new(0.1, -0.05, -0.55), 0.35);

/// A synthesised scene: views with colours, their z-depth ground truth, and the scene box.
#[derive(Clone, Debug)]
pub struct SynthScene {
    /// Posed views.
    pub views: Vec<View>,
    /// z-depth (metres) per pixel of each view (first surface hit; NaN or ∞ where none).
    pub depth: Vec<Vec<f32>>,
    /// Per view, pixels whose first hit is the transparent object (empty: no such object).
    pub masks: Vec<Vec<bool>>,
    /// Per view, the scoring crop `[x0, y0, x1, y1)` (empty: the full image).
    pub crops: Vec<[u32; 4]>,
    /// The scene box.
    pub aabb: Aabb,
}

impl SynthScene {
    /// Writes the scene as split `split` of a dataset in `dir` (created if missing):
    /// `transforms_{split}.json` plus `{split}/r_{i}.png` (8-bit), `r_{i}_depth.exr` (z,
    /// metres), and `r_{i}_mask.png` with the frame's `crop` when the scene has masks. Every file
    /// is written atomically.
    pub fn write_split(&self, dir: &std::path::Path, split: &str) -> Result<(), String> {
        use crate::files::export::{depth_exr_bytes, mask_png_bytes, rgb_png_bytes, write};
        let sub = dir.join(split);
        std::fs::create_dir_all(&sub).map_err(|e| format!("{}: cannot create: {e}", sub.display()))?;
        let k = self.views.first().map(|v| v.intrinsics).ok_or("synth: no views")?;
        let mut frames = Vec::new();
        for (i, v) in self.views.iter().enumerate() {
            let (w, h) = (v.intrinsics.width, v.intrinsics.height);
            let name = format!("r_{i}");
            write(&sub.join(format!("{name}.png")), rgb_png_bytes(&v.rgb, w, h))?;
            let z: Vec<f32> = self.depth[i].iter().map(|&z| if z.is_finite() { z } else { f32::NAN }).collect();
            write(&sub.join(format!("{name}_depth.exr")), depth_exr_bytes(&z, w, h))?;
            let mut frame = serde_json::json!({
                "file_path": format!("./{split}/{name}"),
                "transform_matrix": v.pose.to_matrix(),
                "depth_file_path": format!("{split}/{name}_depth.exr"),
            });
            if let Some(mask) = self.masks.get(i) {
                write(&sub.join(format!("{name}_mask.png")), mask_png_bytes(mask, w, h))?;
                frame["mask_path"] = format!("{split}/{name}_mask.png").into();
                frame["crop"] = self.crops[i].to_vec().into();
            }
            frames.push(frame);
        }
        let mut json = serde_json::json!({
            "camera_angle_x": 2.0 * (0.5 * k.width as f32 / k.fx).atan(),
            "fl_x": k.fx, "fl_y": k.fy, "cx": k.cx, "cy": k.cy, "w": k.width, "h": k.height,
            "aabb": [self.aabb.min.to_array(), self.aabb.max.to_array()],
            "depth_unit": "m", "depth_kind": "z",
            "frames": frames,
        });
        if !k.distortion.is_none() {
            json["camera_model"] = k.distortion.model_name().into();
            for (name, c) in k.distortion.coefficients() {
                json[name] = c.into();
            }
        }
        let text = serde_json::to_string_pretty(&json).expect("plain json");
        crate::files::write_atomic(&dir.join(format!("transforms_{split}.json")), text.as_bytes())
    }
}

/// Direction towards the (distant) light of both scenes.
fn light() -> Vec3 {
    Vec3::new(0.3, -0.5, 1.0).normalize()
}

/// First hit of a banded, Lambert-shaded sphere: (range t, colour), `None` on a miss.
fn hit_sphere(ray: &Ray, (c, r): (Vec3, f32)) -> Option<(f32, [f32; 3])> {
    let oc = ray.origin - c;
    let b = oc.dot(ray.dir);
    let disc = b * b - (oc.length_squared() - r * r);
    let t = -b - disc.max(0.0).sqrt();
    if disc <= 0.0 || t <= 1e-4 {
        return None;
    }
    let n = (ray.at(t) - c) / r;
    let band = if ((n.z * 4.0).floor() as i32).rem_euclid(2) == 0 { [0.85, 0.25, 0.15] } else { [0.95, 0.8, 0.2] };
    let shade = 0.35 + 0.65 * n.dot(light()).max(0.0);
    Some((t, band.map(|v| v * shade)))
}

/// Renders one view per pose with `trace` (range, colour per ray) into colours and z-depth.
fn render_views(
    k: &Intrinsics,
    poses: impl Iterator<Item = Pose>,
    trace: impl Fn(&Ray) -> (f32, [f32; 3]),
) -> (Vec<View>, Vec<Vec<f32>>) {
    let (mut views, mut depth) = (Vec::new(), Vec::new());
    for pose in poses {
        let n = (k.width * k.height) as usize;
        let (mut rgb, mut z) = (Vec::with_capacity(n), Vec::with_capacity(n));
        for j in 0..k.height {
            for i in 0..k.width {
                let ray = pixel_ray(k, &pose, i, j);
                let (t, c) = trace(&ray);
                rgb.push(c);
                z.push(ray.range_to_z(t));
            }
        }
        views.push(View { intrinsics: *k, pose, rgb });
        depth.push(z);
    }
    (views, depth)
}

/// First hit of `ray` in the room: (range t, albedo·shading).
pub fn trace(ray: &Ray) -> (f32, [f32; 3]) {
    let mut best = hit_sphere(ray, SPHERE).unwrap_or((f32::INFINITY, [0.0; 3]));
    // Room walls (inside faces of the cube).
    let inv = ray.dir.recip();
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let t = (sign * ROOM - ray.origin[axis]) * inv[axis];
            if t > 1e-4 && t < best.0 {
                let p = ray.at(t);
                let (u, v) = match axis {
                    0 => (p.y, p.z),
                    1 => (p.x, p.z),
                    _ => (p.x, p.y),
                };
                let check = (((u * 4.0).floor() + (v * 4.0).floor()) as i32).rem_euclid(2) as f32;
                let base = match (axis, sign > 0.0) {
                    (2, false) => [0.55 + 0.3 * check, 0.45 + 0.25 * check, 0.3],
                    (2, true) => [0.9, 0.9, 0.85],
                    (0, _) => [0.2 + 0.5 * (0.5 + 0.5 * (u * 9.0).sin()), 0.5, 0.7],
                    _ => [0.3, 0.35 + 0.4 * check, 0.25 + 0.3 * (0.5 + 0.5 * (v * 7.0).cos())],
                };
                best = (t, base);
            }
        }
    }
    best
}

/// Renders `n_views` views of `size × size` pixels (horizontal FOV 60°) from cameras on a
/// ring inside the room, at azimuths offset by `phase` (radians).
pub fn room(size: u32, n_views: usize, phase: f32) -> SynthScene {
    let k = Intrinsics::from_fov_x(size, size, 60f32.to_radians());
    let poses = (0..n_views).map(|v| {
        let a = phase + v as f32 / n_views as f32 * std::f32::consts::TAU;
        let eye = Vec3::new(0.75 * a.cos(), 0.75 * a.sin(), 0.1 + 0.25 * (3.0 * a).sin());
        Pose::look_at(eye, SPHERE.0)
    });
    let (views, depth) = render_views(&k, poses, trace);
    // The box encloses the room with a margin, so the walls are inside it (marching ends at the
    // box; a surface on its faces would have no room for density).
    SynthScene {
        views,
        depth,
        masks: Vec::new(),
        crops: Vec::new(),
        aabb: Aabb { min: Vec3::splat(-1.1 * ROOM), max: Vec3::splat(1.1 * ROOM) },
    }
}

/// Sky colour of the tabletop scene (the compositing background `c_bg` for rays that miss).
pub const SKY: [f32; 3] = [0.62, 0.7, 0.85];
/// Half-size of the tabletop's square top (metres), at z = 0.
pub const TABLE: f32 = 0.8;
/// Sphere of the tabletop scene, resting on the table.
pub const TABLE_SPHERE: (Vec3, f32) = (Vec3::new(0.1, -0.1, 0.3), 0.3);

/// First hit of `ray` in the tabletop scene: (range t, colour), `t = ∞` with the sky colour on a miss.
pub fn trace_tabletop(ray: &Ray) -> (f32, [f32; 3]) {
    let mut best = hit_sphere(ray, TABLE_SPHERE).unwrap_or((f32::INFINITY, SKY));
    if ray.dir.z < 0.0 {
        let t = -ray.origin.z / ray.dir.z;
        let p = ray.at(t);
        if t > 1e-4 && t < best.0 && p.x.abs() <= TABLE && p.y.abs() <= TABLE {
            let check = (((p.x * 5.0).floor() + (p.y * 5.0).floor()) as i32).rem_euclid(2) as f32;
            let grain = 0.5 + 0.5 * (p.x * 23.0 + 3.0 * (p.y * 4.0).sin()).sin();
            best = (t, [0.45 + 0.25 * check + 0.1 * grain, 0.3 + 0.15 * check + 0.05 * grain, 0.2 + 0.1 * grain]);
        }
    }
    best
}

/// Renders `n_views` tabletop views of `size × size` pixels (horizontal FOV 50°) from cameras
/// 2.2 m from the sphere at elevations 25°–60°, azimuths offset by `phase`. Misses have
/// depth `∞` (no ground truth there).
pub fn tabletop(size: u32, n_views: usize, phase: f32) -> SynthScene {
    let k = Intrinsics::from_fov_x(size, size, 50f32.to_radians());
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    let poses = (0..n_views).map(|v| {
        let a = phase + v as f32 * golden;
        let elev = (25.0 + 35.0 * ((v as f32 * 0.618_034).fract())).to_radians();
        let eye = TABLE_SPHERE.0 + 2.2 * Vec3::new(elev.cos() * a.cos(), elev.cos() * a.sin(), elev.sin());
        Pose::look_at(eye, TABLE_SPHERE.0)
    });
    let (views, depth) = render_views(&k, poses, trace_tabletop);
    SynthScene {
        views,
        depth,
        masks: Vec::new(),
        crops: Vec::new(),
        aabb: Aabb { min: Vec3::new(-1.0, -1.0, -0.25), max: Vec3::new(1.0, 1.0, 1.0) },
    }
}
