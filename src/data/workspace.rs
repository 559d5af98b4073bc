//! The synthetic robot workspace (the scene synthesiser): a small analytic ray tracer of a
//! wooden table in an open-top room with three opaque objects and, in the scene version, glass
//! ([`Glass`]: a solid glass sphere, a tall cylinder in clear or amber glass, or one to four
//! small spheres) with Fresnel reflection and refraction. It writes background and scene
//! image sets in the dataset layout (poses, z-depth ground truth, masks, crops), so the crate's
//! tests and demo need no files.
//!
//! World: metres, +Z up, table top at z = 0 (1.6 m square), floor at z = −0.7, walls at
//! x, y = ±1.5 up to z = 1.2, sky above. Cameras 1.6 m from (0, 0, 0.1), elevation 25°–65°,
//! 50° horizontal field of view, looking at that point. Depth ground truth is the **first**
//! surface hit by the pixel-centre ray — on glass, the glass's outer surface — as planar z.
//! The mask marks pixels whose first hit is glass; the crop is the mask's bounding box grown
//! by 10% of its larger side (the full image when there is no glass), as in `shared/data/dev`.

use super::synth::SynthScene;
use crate::data::View;
use crate::geometry::Pose;
use crate::geometry::{pixel_ray, Aabb, Distortion, Intrinsics, Ray};
use glam::Vec3;
use rayon::prelude::*;

/// Sky colour (rays leaving through the open top).
pub const SKY: [f32; 3] = [0.7, 0.78, 0.9];
/// Glass sphere: centre, radius (resting on the table).
pub const GLASS: (Vec3, f32) = (Vec3::new(0.05, -0.08, 0.16), 0.16);
/// Tall glass: a solid vertical glass cylinder standing on the table where the sphere rests:
/// axis (x, y), radius, height. It reaches 0.1 m above the sphere's top, into air that is
/// empty in the background.
pub const TALL_GLASS: (f32, f32, f32, f32) = (0.05, -0.08, 0.05, 0.42);

/// The glass object a scene holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Glass {
    /// None: the empty workspace (the background).
    None,
    /// The glass sphere [`GLASS`].
    Sphere,
    /// The tall thin glass [`TALL_GLASS`].
    Tall,
    /// The same cylinder in amber glass (a beer bottle's: each pass through its surface keeps
    /// [`AMBER_TINT`] of the light), dark enough that every method's density can find it where
    /// the clear one is seen through at the test scenes' sizes: a tall object standing in
    /// what was empty air, for the occupancy and change-region paths.
    TallAmber,
    /// `n` small clear glass spheres ([`SMALL_GLASS`], the first `n` of its spots, 1 to 4):
    /// scenes whose change grows by whole objects (the cost of an update against the number
    /// of objects, `examples/update_cost.rs`).
    Spheres(u8),
}

/// Small glass spheres resting on the table, apart from each other and the opaque objects:
/// centres (radius [`SMALL_GLASS_RADIUS`]); [`Glass::Spheres`] takes the first `n`.
pub const SMALL_GLASS: [Vec3; 4] = [
    Vec3::new(0.05, -0.08, SMALL_GLASS_RADIUS),
    Vec3::new(0.4, -0.35, SMALL_GLASS_RADIUS),
    Vec3::new(-0.1, 0.4, SMALL_GLASS_RADIUS),
    Vec3::new(0.1, -0.55, SMALL_GLASS_RADIUS),
];
/// Radius of each of [`SMALL_GLASS`].
pub const SMALL_GLASS_RADIUS: f32 = 0.08;

/// Light kept per transmission through clear glass (a faint green, as thick glass has).
pub const CLEAR_TINT: [f32; 3] = [0.96, 0.99, 0.97];
/// Light kept per transmission through amber glass.
pub const AMBER_TINT: [f32; 3] = [0.6, 0.4, 0.15];

impl Glass {
    /// Light the object's glass keeps per transmission.
    pub fn tint(self) -> [f32; 3] {
        match self {
            Glass::TallAmber => AMBER_TINT,
            Glass::None | Glass::Sphere | Glass::Tall | Glass::Spheres(_) => CLEAR_TINT,
        }
    }
}
/// Index of refraction of the glass.
pub const GLASS_IOR: f32 = 1.5;
/// Point every camera looks at.
pub const TARGET: Vec3 = Vec3::new(0.0, 0.0, 0.1);
/// Camera distance from [`TARGET`].
pub const CAMERA_DISTANCE: f32 = 1.6;

const TABLE: f32 = 0.8;
const FLOOR: f32 = -0.7;
const WALL: f32 = 1.5;
const WALL_TOP: f32 = 1.2;
const BALL: (Vec3, f32) = (Vec3::new(0.42, 0.3, 0.13), 0.13);
const BOX_MIN: Vec3 = Vec3::new(-0.6, 0.12, 0.0);
const BOX_MAX: Vec3 = Vec3::new(-0.3, 0.42, 0.22);
/// Vertical cylinder: base centre (z = 0), radius, height.
const CAN: (Vec3, f32, f32) = (Vec3::new(-0.32, -0.42, 0.0), 0.11, 0.3);
/// Bounces through glass before a ray gives up (and returns the sky).
const MAX_DEPTH: u32 = 6;
const EPS: f32 = 1e-4;

/// The scene box: the room with a margin, so walls and floor are strictly inside.
pub fn aabb() -> Aabb {
    Aabb {
        min: Vec3::new(-WALL - 0.05, -WALL - 0.05, FLOOR - 0.05),
        max: Vec3::new(WALL + 0.05, WALL + 0.05, WALL_TOP + 0.05),
    }
}

#[derive(Clone, Copy)]
enum Surface {
    Diffuse([f32; 3]),
    Glass,
}

#[derive(Clone, Copy)]
struct Hit {
    t: f32,
    normal: Vec3,
    surface: Surface,
}

fn light() -> Vec3 {
    Vec3::new(0.35, -0.45, 1.0).normalize()
}

fn stripes(x: f32, k: f32) -> f32 {
    0.5 + 0.5 * (x * k).sin()
}

fn checker(u: f32, v: f32, k: f32) -> f32 {
    (((u * k).floor() + (v * k).floor()) as i32).rem_euclid(2) as f32
}

/// Nearest root `t > EPS` of a sphere (works from inside too), with the outward normal.
fn sphere(ray: &Ray, (c, r): (Vec3, f32)) -> Option<(f32, Vec3)> {
    let oc = ray.origin - c;
    let b = oc.dot(ray.dir);
    let disc = b * b - (oc.length_squared() - r * r);
    if disc <= 0.0 {
        return None;
    }
    let s = disc.sqrt();
    let t = if -b - s > EPS { -b - s } else { -b + s };
    (t > EPS).then(|| (t, (ray.at(t) - c) / r))
}

/// Nearest hit `t > EPS` of the solid glass cylinder [`TALL_GLASS`] (side and both caps; works
/// from inside), with the outward normal.
fn tall_glass(ray: &Ray) -> Option<(f32, Vec3)> {
    let (cx, cy, r, h) = TALL_GLASS;
    let (z0, z1) = (1e-3, h);
    let (o, d) = (ray.origin, ray.dir);
    let mut best: Option<(f32, Vec3)> = None;
    let mut take = |t: f32, n: Vec3| {
        if t > EPS && best.is_none_or(|b| t < b.0) {
            best = Some((t, n));
        }
    };
    let (ox, oy) = (o.x - cx, o.y - cy);
    let qa = d.x * d.x + d.y * d.y;
    if qa > 0.0 {
        let qb = ox * d.x + oy * d.y;
        let disc = qb * qb - qa * (ox * ox + oy * oy - r * r);
        if disc > 0.0 {
            for t in [(-qb - disc.sqrt()) / qa, (-qb + disc.sqrt()) / qa] {
                let p = ray.at(t);
                if p.z >= z0 && p.z <= z1 {
                    take(t, Vec3::new(p.x - cx, p.y - cy, 0.0) / r);
                }
            }
        }
    }
    if d.z != 0.0 {
        for (z, n) in [(z0, -Vec3::Z), (z1, Vec3::Z)] {
            let t = (z - o.z) / d.z;
            let p = ray.at(t);
            if (p.x - cx).powi(2) + (p.y - cy).powi(2) <= r * r {
                take(t, n);
            }
        }
    }
    best
}

fn keep(best: &mut Option<Hit>, t: f32, normal: Vec3, surface: Surface) {
    if t > EPS && best.is_none_or(|b| t < b.t) {
        *best = Some(Hit { t, normal, surface });
    }
}

/// The nearest surface along `ray` (with the `glass` object).
fn intersect(ray: &Ray, glass: Glass) -> Option<Hit> {
    let mut best = None;
    let (o, d) = (ray.origin, ray.dir);
    // Table top (z = 0) and floor.
    if d.z != 0.0 {
        let t = -o.z / d.z;
        let p = ray.at(t);
        if p.x.abs() <= TABLE && p.y.abs() <= TABLE {
            let grain = stripes(p.x * 0.3 + 0.05 * (p.y * 9.0).sin() + (p.x * p.x + p.y * p.y).sqrt(), 25.0);
            let c = [0.55 + 0.2 * grain, 0.36 + 0.12 * grain, 0.2 + 0.06 * grain];
            keep(&mut best, t, Vec3::new(0.0, 0.0, -d.z.signum()), Surface::Diffuse(c));
        }
        let t = (FLOOR - o.z) / d.z;
        let p = ray.at(t);
        if p.x.abs() <= WALL && p.y.abs() <= WALL {
            let c = checker(p.x, p.y, 4.0);
            keep(&mut best, t, Vec3::Z, Surface::Diffuse([0.35 + 0.3 * c, 0.3 + 0.2 * c, 0.28 + 0.1 * c]));
        }
    }
    // Walls (inside faces), each with its own texture.
    for axis in 0..2 {
        if d[axis] == 0.0 {
            continue;
        }
        for sign in [-1.0f32, 1.0] {
            let t = (sign * WALL - o[axis]) / d[axis];
            let p = ray.at(t);
            let u = p[1 - axis];
            if p.z >= FLOOR && p.z <= WALL_TOP && u.abs() <= WALL {
                let c = match (axis, sign > 0.0) {
                    (0, false) => [0.75, 0.55 + 0.3 * stripes(u, 12.0), 0.4],
                    (0, true) => [0.4, 0.5 + 0.3 * checker(u, p.z, 5.0), 0.7],
                    (_, false) => [0.5 + 0.35 * stripes(p.z, 15.0), 0.65, 0.5],
                    _ => [0.8, 0.78, 0.55 + 0.35 * stripes(u + p.z, 9.0)],
                };
                let mut n = Vec3::ZERO;
                n[axis] = -sign;
                keep(&mut best, t, n, Surface::Diffuse(c));
            }
        }
    }
    // Ball (banded).
    if let Some((t, n)) = sphere(ray, BALL) {
        let band = (n.z * 5.0).floor() as i32 % 2 == 0;
        keep(&mut best, t, n, Surface::Diffuse(if band { [0.85, 0.25, 0.15] } else { [0.95, 0.8, 0.2] }));
    }
    // Box (checker).
    let inv = d.recip();
    let (a, b) = ((BOX_MIN - o) * inv, (BOX_MAX - o) * inv);
    let (lo, hi) = (a.min(b), a.max(b));
    let (near, far) = (lo.max_element(), hi.min_element());
    if near < far && near > EPS {
        let p = ray.at(near);
        let axis = if lo.x == near {
            0
        } else if lo.y == near {
            1
        } else {
            2
        };
        let mut n = Vec3::ZERO;
        n[axis] = -d[axis].signum();
        let c = checker(p.x + p.z, p.y - p.z, 20.0);
        keep(&mut best, near, n, Surface::Diffuse([0.2 + 0.6 * c, 0.3 + 0.5 * c, 0.75]));
    }
    // Can: vertical cylinder with a top cap.
    let (base, r, h) = CAN;
    let (ox, oy) = (o.x - base.x, o.y - base.y);
    let qa = d.x * d.x + d.y * d.y;
    if qa > 0.0 {
        let qb = ox * d.x + oy * d.y;
        let disc = qb * qb - qa * (ox * ox + oy * oy - r * r);
        if disc > 0.0 {
            let t = (-qb - disc.sqrt()) / qa;
            let p = ray.at(t);
            if p.z >= 0.0 && p.z <= h {
                let n = Vec3::new(p.x - base.x, p.y - base.y, 0.0) / r;
                let c = stripes(p.z, 60.0);
                keep(&mut best, t, n, Surface::Diffuse([0.25 + 0.5 * c, 0.6, 0.3 + 0.3 * c]));
            }
        }
    }
    if d.z != 0.0 {
        let t = (h - o.z) / d.z;
        let p = ray.at(t);
        if (p.x - base.x).powi(2) + (p.y - base.y).powi(2) <= r * r {
            keep(&mut best, t, Vec3::Z, Surface::Diffuse([0.85, 0.85, 0.8]));
        }
    }
    let spheres = match glass {
        Glass::Spheres(n) => &SMALL_GLASS[..n as usize],
        _ => &[],
    };
    let objects = match glass {
        Glass::None | Glass::Spheres(_) => None,
        Glass::Sphere => sphere(ray, GLASS),
        Glass::Tall | Glass::TallAmber => tall_glass(ray),
    }
    .into_iter()
    .chain(spheres.iter().filter_map(|&c| sphere(ray, (c, SMALL_GLASS_RADIUS))));
    for (t, n) in objects {
        keep(&mut best, t, n, Surface::Glass);
    }
    best
}

/// Unpolarised Fresnel reflectance for `cos_i` (incidence cosine) from index `n1` into `n2`;
/// 1 under total internal reflection.
fn fresnel(cos_i: f32, n1: f32, n2: f32) -> f32 {
    let sin_t = n1 / n2 * (1.0 - cos_i * cos_i).max(0.0).sqrt();
    if sin_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin_t * sin_t).sqrt();
    let rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t);
    let rp = (n1 * cos_t - n2 * cos_i) / (n1 * cos_t + n2 * cos_i);
    0.5 * (rs * rs + rp * rp)
}

/// Colour seen along `ray` (with the `glass` object).
fn shade(ray: &Ray, glass: Glass, depth: u32) -> [f32; 3] {
    let Some(hit) = intersect(ray, glass) else {
        return SKY;
    };
    match hit.surface {
        Surface::Diffuse(albedo) => {
            let lambert = hit.normal.dot(light()).max(0.0);
            albedo.map(|a| a * (0.4 + 0.6 * lambert))
        }
        Surface::Glass if depth >= MAX_DEPTH => SKY,
        Surface::Glass => {
            let p = ray.at(hit.t);
            let entering = ray.dir.dot(hit.normal) < 0.0;
            let n = if entering { hit.normal } else { -hit.normal };
            let (n1, n2) = if entering { (1.0, GLASS_IOR) } else { (GLASS_IOR, 1.0) };
            let cos_i = -ray.dir.dot(n);
            let f = fresnel(cos_i, n1, n2);
            let reflect = ray.dir + 2.0 * cos_i * n;
            let bounce = |dir: Vec3, side: Vec3| {
                let r = Ray { origin: p + side * 1e-3, dir: dir.normalize(), z_per_t: 1.0 };
                shade(&r, glass, depth + 1)
            };
            let refl = bounce(reflect, n);
            if f >= 1.0 {
                return refl;
            }
            let eta = n1 / n2;
            let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
            let refract = eta * ray.dir + (eta * cos_i - k.sqrt()) * n;
            let refr = bounce(refract, -n);
            let tint = glass.tint();
            std::array::from_fn(|c| f * refl[c] + (1.0 - f) * refr[c] * tint[c])
        }
    }
}

/// Renders `n_views` views of `size × size` of the workspace, with the glass sphere when
/// `glass`, cameras at azimuths offset by `phase` (radians). Deterministic; parallel over views.
pub fn workspace(size: u32, n_views: usize, phase: f32, glass: bool) -> SynthScene {
    workspace_with(size, n_views, phase, if glass { Glass::Sphere } else { Glass::None })
}

/// [`workspace`] with any [`Glass`] object.
pub fn workspace_with(size: u32, n_views: usize, phase: f32, glass: Glass) -> SynthScene {
    workspace_capture(size, n_views, phase, glass, &Capture::default())
}

/// How a synthesised capture departs from a perfect pinhole camera at exact poses (the trials of
/// real captures: a lens, an exposure change, poses from a robot's kinematics).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Capture {
    /// The lens the images are rendered through (and the views' intrinsics carry).
    pub distortion: Distortion,
    /// Per-channel gain applied to the rendered colours, then clamped to [0, 1] as a sensor
    /// saturates (an exposure and white-balance change; `[1; 3]` for none).
    pub gain: [f32; 3],
    /// Pose noise: the views carry poses off the true ones by a random translation of this
    /// length (metres) and a rotation of this angle (degrees) about a random axis, drawn
    /// from the seed (the images are rendered at the true poses).
    pub pose_noise: Option<(f32, f32, u64)>,
    /// Exposure moving from shot to shot (auto-exposure and auto white balance): each view's
    /// gain is [`Capture::gain`] times a factor per channel drawn uniformly in `1 ± spread` from
    /// the seed and the view's index.
    pub gain_jitter: Option<(f32, u64)>,
}

impl Default for Capture {
    fn default() -> Self {
        Capture { distortion: Distortion::None, gain: [1.0; 3], pose_noise: None, gain_jitter: None }
    }
}

/// [`workspace_with`] through a [`Capture`].
pub fn workspace_capture(size: u32, n_views: usize, phase: f32, glass: Glass, capture: &Capture) -> SynthScene {
    let k = Intrinsics { distortion: capture.distortion, ..Intrinsics::from_fov_x(size, size, 50f32.to_radians()) };
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    let rendered: Vec<(View, Vec<f32>, Vec<bool>)> = (0..n_views)
        .into_par_iter()
        .map(|v| {
            let a = phase + v as f32 * golden;
            // Elevation uniform in sin over 25°–65° (a low-discrepancy sequence, not random).
            let s = (25f32.to_radians().sin())
                + (65f32.to_radians().sin() - 25f32.to_radians().sin()) * ((v as f32 * 0.618_034 + 0.31).fract());
            let elev = s.asin();
            let eye = TARGET + CAMERA_DISTANCE * Vec3::new(elev.cos() * a.cos(), elev.cos() * a.sin(), elev.sin());
            let pose = Pose::look_at(eye, TARGET);
            let gain = match capture.gain_jitter {
                Some((spread, seed)) => {
                    // A stream apart from the pose noise's (which uses the view's index).
                    let mut rng = crate::rng::Rng::stream(seed, (1 << 32) + v as u64);
                    capture.gain.map(|g| g * rng.uniform(1.0 - spread, 1.0 + spread))
                }
                None => capture.gain,
            };
            let (rgb, z, mask) = render_view(&k, &pose, glass, gain);
            let pose = match capture.pose_noise {
                Some((metres, degrees, seed)) => jitter(pose, metres, degrees, crate::rng::Rng::stream(seed, v as u64)),
                None => pose,
            };
            (View { intrinsics: k, pose, rgb }, z, mask)
        })
        .collect();
    let mut scene =
        SynthScene { views: Vec::new(), depth: Vec::new(), masks: Vec::new(), crops: Vec::new(), aabb: aabb() };
    for (view, z, mask) in rendered {
        scene.crops.push(crop_of(&mask, size, size));
        scene.views.push(view);
        scene.depth.push(z);
        scene.masks.push(mask);
    }
    scene
}

/// One view of the workspace from any camera: colours (through a per-channel `gain`, clamped
/// as a sensor saturates), z-depth of the first surface (NaN where none) and the glass mask.
pub fn render_view(k: &Intrinsics, pose: &Pose, glass: Glass, gain: [f32; 3]) -> (Vec<[f32; 3]>, Vec<f32>, Vec<bool>) {
    if let Glass::Spheres(s) = glass {
        assert!((1..=SMALL_GLASS.len()).contains(&(s as usize)), "workspace: Glass::Spheres takes 1 to 4 spheres");
    }
    let n = (k.width * k.height) as usize;
    let (mut rgb, mut z, mut mask) = (Vec::with_capacity(n), Vec::with_capacity(n), Vec::with_capacity(n));
    for j in 0..k.height {
        for i in 0..k.width {
            let ray = pixel_ray(k, pose, i, j);
            let first = intersect(&ray, glass);
            let c = shade(&ray, glass, 0);
            rgb.push(match gain == [1.0; 3] {
                true => c,
                // A camera's exposure: the sensor saturates.
                false => std::array::from_fn(|ch| (c[ch] * gain[ch]).clamp(0.0, 1.0)),
            });
            z.push(first.map_or(f32::NAN, |h| ray.range_to_z(h.t)));
            mask.push(first.is_some_and(|h| matches!(h.surface, Surface::Glass)));
        }
    }
    (rgb, z, mask)
}

/// `pose` moved by `metres` in a random direction and turned by `degrees` about a random axis
/// (the directions drawn from `rng`).
pub fn jitter(pose: Pose, metres: f32, degrees: f32, mut rng: crate::rng::Rng) -> Pose {
    let mut unit = || {
        let z = rng.uniform(-1.0, 1.0);
        let a = std::f32::consts::TAU * rng.f32();
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(r * a.cos(), r * a.sin(), z)
    };
    let (shift, axis) = (unit(), unit());
    let turn = glam::Mat3::from_axis_angle(axis, degrees.to_radians());
    Pose { rotation: turn * pose.rotation, translation: pose.translation + metres * shift }
}

/// The mask's bounding box grown by ⌈10%⌉ of its larger side, clamped; the full image when
/// the mask is empty.
pub fn crop_of(mask: &[bool], w: u32, h: u32) -> [u32; 4] {
    let (mut x0, mut y0, mut x1, mut y1) = (w, h, 0, 0);
    for (p, _) in mask.iter().enumerate().filter(|(_, m)| **m) {
        let (x, y) = (p as u32 % w, p as u32 / w);
        (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x + 1), y1.max(y + 1));
    }
    if x1 == 0 {
        return [0, 0, w, h];
    }
    let grow = ((x1 - x0).max(y1 - y0) as f32 * 0.1).ceil() as u32;
    [x0.saturating_sub(grow), y0.saturating_sub(grow), (x1 + grow).min(w), (y1 + grow).min(h)]
}
