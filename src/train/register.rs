//! Registration of a scene image against the frozen background: the scene's camera pose
//! corrected so the image agrees with the background where the workspace did not change.
//!
//! A robot's poses come from its arm's kinematics, millimetres and tenths of a degree off; the
//! residual model trains in the frozen background's frame, so a scene image taken from a pose
//! that is off by that much puts the table's edges where the background has none, and the
//! residual learns the difference as a change (RESULTS.md, "Real-capture trials"). Most of a
//! scene image is the unchanged workspace, which the background knows, so each image can be
//! aligned to it directly (photometric alignment, as in direct visual odometry):
//!
//! - the background is rendered once at the given pose `P₀`: colours `C(u)` and the 3-D point
//!   `X(u)` each pixel sees (its threshold depth: the surface the depth maps report; holes are
//!   left out);
//! - the pose `P = P₀·Δ` and a per-channel gain `g` minimise `Σᵤ ρ(g ⊙ I(π(P⁻¹X(u))) − C(u))`
//!   over pixels with texture, `I` the scene image (bilinear), `π` the camera through its lens,
//!   `ρ` Huber's loss at 1.345 robust standard deviations with pixels beyond 3 left out (the
//!   changed pixels: the glass, its shadow);
//! - Gauss–Newton with Levenberg–Marquardt damping on the six pose parameters (a rotation
//!   vector and a shift in the camera frame) and the three gains, on images smoothed twice by a
//!   3×3 box and then once (coarse to fine: the smoother images reach a few pixels); the image
//!   Jacobian from central differences, the projection's by finite differences, so a lens needs
//!   no derivative of its own;
//! - the result is kept only when it lowers the robust cost and moves the selected points by
//!   at least [`MIN_SHIFT_PX`] on average (below that it is within the rendering's noise) and
//!   less than [`MAX_SHIFT_PX`] (beyond that it is not arm noise but a wrong match).
//!
//! The gain is a nuisance parameter here (an exposure change must not pull the pose); the
//! exposure correction of the registered image is fitted afterwards ([`super::prior`]).

use super::prior::box3;
use super::trainer::{train_nerf, StepStats, TrainConfig, TrainError};
use crate::data::View;
use crate::field::{Nerf, NerfConfig, NerfField};
use crate::geometry::{pixel_ray, Intrinsics, Pose};
use crate::render::view::{RenderedView, Scene};
use crate::render::{DensityThreshold, ViewRenderer};
use crate::simd::Isa;
use glam::{DMat3, DVec3, Mat3};

/// Mean image motion (pixels) of the selected points below which a registration is not
/// applied.
pub const MIN_SHIFT_PX: f64 = 0.1;
/// Mean image motion (pixels) beyond which a registration is refused.
pub const MAX_SHIFT_PX: f64 = 20.0;
/// Most pixels a registration uses (a regular subsample of the textured ones).
const MAX_PIXELS: usize = 6000;
/// Gauss–Newton iterations per smoothing stage.
const ITERATIONS: usize = 12;

/// The outcome of registering one image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Registration {
    /// The registered pose (the given one when not applied).
    pub pose: Pose,
    /// Whether the registration was applied.
    pub applied: bool,
    /// Mean image motion of the selected points (pixels) from the given pose to the found one.
    pub shift_px: f64,
    /// Rotation between the given and the found pose (degrees).
    pub degrees: f64,
    /// Distance between the camera centres (scene units).
    pub distance: f64,
    /// Pixels used.
    pub pixels: usize,
}

/// Registers `view` against the background's `colours` and threshold z-depth (NaN at holes)
/// rendered at `view.pose`.
pub fn register(view: &View, colours: &[[f32; 3]], threshold_z: &[f32]) -> Registration {
    let k = &view.intrinsics;
    let (w, h) = (k.width as usize, k.height as usize);
    let unchanged =
        Registration { pose: view.pose, applied: false, shift_px: 0.0, degrees: 0.0, distance: 0.0, pixels: 0 };
    // The points the background's pixels see, in the given camera's frame.
    let p0 = Rigid::of(&view.pose);
    let smooth1 = (box3(&view.rgb, w, h), box3(colours, w, h));
    let mut points = Vec::new();
    for j in 2..h.saturating_sub(2) {
        for i in 2..w.saturating_sub(2) {
            let p = j * w + i;
            let z = threshold_z[p];
            if !(z.is_finite() && z > 0.0) {
                continue;
            }
            // Texture: the smoothed background's gradient, largest channel.
            let c = &smooth1.1;
            let g = (0..3)
                .map(|ch| {
                    let gx = c[p + 1][ch] - c[p - 1][ch];
                    let gy = c[p + w][ch] - c[p - w][ch];
                    (gx * gx + gy * gy).sqrt() * 0.5
                })
                .fold(0f32, f32::max);
            if g < 0.005 {
                continue;
            }
            let ray = pixel_ray(k, &view.pose, i as u32, j as u32);
            let x = ray.at(ray.z_to_range(z));
            points.push((p, p0.to_camera(x.as_dvec3())));
        }
    }
    if points.len() < 64 {
        return Registration { pixels: points.len(), ..unchanged };
    }
    let stride = points.len().div_ceil(MAX_PIXELS);
    let points: Vec<(usize, DVec3)> = points.into_iter().step_by(stride).collect();
    let smooth2 = (box3(&smooth1.0, w, h), box3(&smooth1.1, w, h));

    let mut delta = Rigid::IDENTITY; // P = P₀·Δ
    let mut gain = [1.0f64; 3];
    let mut last = (f64::INFINITY, 0.0);
    for (scene, background) in [&smooth2, &smooth1] {
        let problem = Problem { k, w, h, scene, background, points: &points };
        let scale = problem.robust_scale(&delta, gain);
        let mut cost = problem.cost(&delta, gain, scale);
        let mut lambda = 1e-3;
        for _ in 0..ITERATIONS {
            let Some(step) = problem.step(&delta, gain, scale, lambda) else { break };
            let (d, g) = apply(&delta, gain, &step);
            let c = problem.cost(&d, g, scale);
            if c < cost {
                let small = step.iter().map(|s| s.abs()).fold(0.0, f64::max) < 1e-7;
                (delta, gain, cost) = (d, g, c);
                lambda = (lambda * 0.3).max(1e-7);
                if small {
                    break;
                }
            } else {
                lambda *= 10.0;
                if lambda > 1e4 {
                    break;
                }
            }
        }
        last = (cost, scale);
    }
    // The final stage's cost against the start's, at the final stage's scale.
    let (cost, scale) = last;
    let problem = Problem { k, w, h, scene: &smooth1.0, background: &smooth1.1, points: &points };
    let start = problem.cost(&Rigid::IDENTITY, [1.0; 3], scale);
    let shift_px = mean_shift(k, &points, &delta);
    let pose = p0.compose(&delta).to_pose();
    let degrees = delta.angle().to_degrees();
    let distance = delta.t.length();
    let applied = cost < start && (MIN_SHIFT_PX..MAX_SHIFT_PX).contains(&shift_px);
    Registration {
        pose: if applied { pose } else { view.pose },
        applied,
        shift_px,
        degrees,
        distance,
        pixels: points.len(),
    }
}

/// A rigid transform in f64: `x ↦ r·x + t` (camera-to-world for a pose).
#[derive(Clone, Copy, Debug)]
struct Rigid {
    r: DMat3,
    t: DVec3,
}

impl Rigid {
    const IDENTITY: Rigid = Rigid { r: DMat3::IDENTITY, t: DVec3::ZERO };

    fn of(p: &Pose) -> Rigid {
        Rigid { r: p.rotation.as_dmat3(), t: p.translation.as_dvec3() }
    }

    fn to_pose(self) -> Pose {
        // Re-orthonormalise (Gram–Schmidt on the columns) so the f32 pose stays a rotation.
        let x = self.r.x_axis.normalize();
        let y = (self.r.y_axis - x * x.dot(self.r.y_axis)).normalize();
        let z = x.cross(y);
        Pose { rotation: Mat3::from_cols(x.as_vec3(), y.as_vec3(), z.as_vec3()), translation: self.t.as_vec3() }
    }

    /// World point in this camera's frame.
    fn to_camera(self, x: DVec3) -> DVec3 {
        self.r.transpose() * (x - self.t)
    }

    /// `self·other`.
    fn compose(&self, o: &Rigid) -> Rigid {
        Rigid { r: self.r * o.r, t: self.r * o.t + self.t }
    }

    /// Rotation angle (radians).
    fn angle(&self) -> f64 {
        ((self.r.x_axis.x + self.r.y_axis.y + self.r.z_axis.z - 1.0) * 0.5).clamp(-1.0, 1.0).acos()
    }

    /// `exp` of a rotation vector and a shift.
    fn exp(v: &[f64]) -> Rigid {
        let w = DVec3::new(v[0], v[1], v[2]);
        let angle = w.length();
        let r = if angle < 1e-12 { DMat3::IDENTITY } else { DMat3::from_axis_angle(w / angle, angle) };
        Rigid { r, t: DVec3::new(v[3], v[4], v[5]) }
    }
}

/// The pose and gains after `step` (6 pose parameters, then 3 gains).
fn apply(delta: &Rigid, gain: [f64; 3], step: &[f64; 9]) -> (Rigid, [f64; 3]) {
    (delta.compose(&Rigid::exp(&step[..6])), std::array::from_fn(|c| gain[c] + step[6 + c]))
}

/// A camera-frame point (of the given pose) in the image of the pose `P₀·Δ`.
fn project(k: &Intrinsics, delta: &Rigid, x: DVec3) -> Option<(f64, f64)> {
    let c = delta.to_camera(x);
    k.project(c.as_vec3()).map(|(u, v)| (u as f64, v as f64))
}

/// Mean image motion of the points from the given pose to `P₀·Δ` (pixels).
fn mean_shift(k: &Intrinsics, points: &[(usize, DVec3)], delta: &Rigid) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for (_, x) in points {
        if let (Some(a), Some(b)) = (project(k, &Rigid::IDENTITY, *x), project(k, delta, *x)) {
            sum += ((a.0 - b.0).powi(2) + (a.1 - b.1).powi(2)).sqrt();
            n += 1;
        }
    }
    if n == 0 {
        f64::INFINITY
    } else {
        sum / n as f64
    }
}

/// The length of a colour residual.
fn norm(r: [f64; 3]) -> f64 {
    (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt()
}

/// Where a point lands in the scene image, the (bilinear) image there, and its residual.
struct Warp {
    at: (f64, f64),
    image: [f64; 3],
    residual: [f64; 3],
}

/// One smoothing stage's alignment problem.
struct Problem<'a> {
    k: &'a Intrinsics,
    w: usize,
    h: usize,
    scene: &'a [[f32; 3]],
    background: &'a [[f32; 3]],
    points: &'a [(usize, DVec3)],
}

impl Problem<'_> {
    /// The scene image at pixel coordinates `(u, v)` (pixel centres at `+½`), bilinear;
    /// `None` outside the image's centres.
    fn sample(&self, u: f64, v: f64) -> Option<[f64; 3]> {
        let (x, y) = (u - 0.5, v - 0.5);
        if !(x >= 0.0 && y >= 0.0 && x <= (self.w - 1) as f64 && y <= (self.h - 1) as f64) {
            return None;
        }
        let (x0, y0) = ((x as usize).min(self.w - 2), (y as usize).min(self.h - 2));
        let (fx, fy) = (x - x0 as f64, y - y0 as f64);
        let at = |i: usize, j: usize| self.scene[j * self.w + i];
        let (a, b, c, d) = (at(x0, y0), at(x0 + 1, y0), at(x0, y0 + 1), at(x0 + 1, y0 + 1));
        Some(std::array::from_fn(|ch| {
            let top = a[ch] as f64 * (1.0 - fx) + b[ch] as f64 * fx;
            let bottom = c[ch] as f64 * (1.0 - fx) + d[ch] as f64 * fx;
            top * (1.0 - fy) + bottom * fy
        }))
    }

    /// Point `i` at `(Δ, g)`: where it lands in the scene image, the image there, and the
    /// residual (3 channels); `None` when it leaves the image.
    fn warp(&self, i: usize, delta: &Rigid, gain: [f64; 3]) -> Option<Warp> {
        let (p, x) = self.points[i];
        let at = project(self.k, delta, x)?;
        let image = self.sample(at.0, at.1)?;
        let b = self.background[p];
        Some(Warp { at, image, residual: std::array::from_fn(|c| gain[c] * image[c] - b[c] as f64) })
    }

    /// Residual of point `i` (3 channels) at `(Δ, g)`, `None` when it leaves the image.
    fn residual(&self, i: usize, delta: &Rigid, gain: [f64; 3]) -> Option<[f64; 3]> {
        self.warp(i, delta, gain).map(|w| w.residual)
    }

    /// 1.4826 × the median residual norm at `(Δ, g)` (at least 0.01).
    fn robust_scale(&self, delta: &Rigid, gain: [f64; 3]) -> f64 {
        let mut norms: Vec<f64> =
            (0..self.points.len()).filter_map(|i| self.residual(i, delta, gain)).map(norm).collect();
        if norms.is_empty() {
            return 0.01;
        }
        let mid = norms.len() / 2;
        let (_, m, _) = norms.select_nth_unstable_by(mid, f64::total_cmp);
        (1.4826 * *m).max(0.01)
    }

    /// Huber weight of a residual norm at `scale` (0 beyond 3 scales: an outlier).
    fn weight(norm: f64, scale: f64) -> f64 {
        let k = 1.345 * scale;
        match norm {
            n if n > 3.0 * scale => 0.0,
            n if n > k => k / n,
            _ => 1.0,
        }
    }

    /// The robust cost: Huber's loss of each point's residual norm, outliers (and points
    /// outside the image) at the cap `3·scale`'s loss, so leaving the image is not a gain.
    fn cost(&self, delta: &Rigid, gain: [f64; 3], scale: f64) -> f64 {
        let k = 1.345 * scale;
        let huber = |n: f64| if n <= k { 0.5 * n * n } else { k * (n - 0.5 * k) };
        let cap = huber(3.0 * scale);
        (0..self.points.len())
            .map(|i| match self.residual(i, delta, gain) {
                Some(r) => huber(norm(r)).min(cap),
                None => cap,
            })
            .sum()
    }

    /// One damped Gauss–Newton step in (rotation vector, shift, gains), `None` when the
    /// normal equations are singular.
    fn step(&self, delta: &Rigid, gain: [f64; 3], scale: f64, lambda: f64) -> Option<[f64; 9]> {
        const EPS: f64 = 1e-5;
        let mut a = [[0.0f64; 9]; 9];
        let mut b = [0.0f64; 9];
        for (i, &(_, x)) in self.points.iter().enumerate() {
            let Some(Warp { at: (u, v), image: s, residual: r }) = self.warp(i, delta, gain) else { continue };
            let wgt = Self::weight(norm(r), scale);
            if wgt == 0.0 {
                continue;
            }
            let (Some(sx0), Some(sx1), Some(sy0), Some(sy1)) =
                (self.sample(u - 0.5, v), self.sample(u + 0.5, v), self.sample(u, v - 0.5), self.sample(u, v + 0.5))
            else {
                continue;
            };
            // d(u, v)/d(pose parameter) by central differences of the projection.
            let mut duv = [[0.0f64; 2]; 6];
            for (q, d) in duv.iter_mut().enumerate() {
                let mut e = [0.0f64; 6];
                e[q] = EPS;
                let plus = project(self.k, &delta.compose(&Rigid::exp(&e)), x);
                e[q] = -EPS;
                let minus = project(self.k, &delta.compose(&Rigid::exp(&e)), x);
                let (Some(p), Some(m)) = (plus, minus) else { return None };
                *d = [(p.0 - m.0) / (2.0 * EPS), (p.1 - m.1) / (2.0 * EPS)];
            }
            for c in 0..3 {
                let (gx, gy) = (sx1[c] - sx0[c], sy1[c] - sy0[c]);
                let mut row = [0.0f64; 9];
                for q in 0..6 {
                    row[q] = gain[c] * (gx * duv[q][0] + gy * duv[q][1]);
                }
                row[6 + c] = s[c];
                for m in 0..9 {
                    b[m] -= wgt * row[m] * r[c];
                    for n in 0..9 {
                        a[m][n] += wgt * row[m] * row[n];
                    }
                }
            }
        }
        for (m, row) in a.iter_mut().enumerate() {
            row[m] += lambda * row[m].max(1e-12);
        }
        solve(a, b)
    }
}

/// Solves the symmetric positive definite `a·x = b` by Cholesky; `None` when it is not.
fn solve(mut a: [[f64; 9]; 9], mut b: [f64; 9]) -> Option<[f64; 9]> {
    for j in 0..9 {
        let d = a[j][j] - (0..j).map(|k| a[j][k] * a[j][k]).sum::<f64>();
        if d.is_nan() || d <= 0.0 {
            return None;
        }
        a[j][j] = d.sqrt();
        for i in j + 1..9 {
            a[i][j] = (a[i][j] - (0..j).map(|k| a[i][k] * a[j][k]).sum::<f64>()) / a[j][j];
        }
    }
    for i in 0..9 {
        b[i] = (b[i] - (0..i).map(|k| a[i][k] * b[k]).sum::<f64>()) / a[i][i];
    }
    for i in (0..9).rev() {
        b[i] = (b[i] - (i + 1..9).map(|k| a[k][i] * b[k]).sum::<f64>()) / a[i][i];
    }
    b.iter().all(|v| v.is_finite()).then_some(b)
}

/// Registers `view` against `model` (`scene`, through `renderer`) rendered at its pose over
/// `sky`, threshold depth at `m`; returns the registration and that render.
pub fn register_at(
    isa: Isa,
    renderer: &mut ViewRenderer<NerfField>,
    scene: &Scene<'_, NerfField>,
    view: &View,
    sky: [f32; 3],
    m: DensityThreshold,
) -> (Registration, RenderedView) {
    let r = renderer.render(isa, scene, &view.intrinsics, &view.pose, sky, m);
    (register(view, &r.rgb, &r.threshold_z), r)
}

/// Registers each of `views` against `model` rendered at its pose ([`register_at`]).
pub fn register_all(isa: Isa, model: &Nerf, views: &[View], sky: [f32; 3], m: DensityThreshold) -> Vec<Registration> {
    let mut renderer = ViewRenderer::new();
    let scene = Scene::from(model);
    views.iter().map(|v| register_at(isa, &mut renderer, &scene, v, sky, m).0).collect()
}

/// A capture's registration passes (docs/DECISIONS.md, "Registration against the
/// background"): `passes` times, a NeRF trained on `views` (with `field` and `cfg`; `log(pass,
/// step)` sees its steps), every view registered against it ([`register_all`], over
/// `cfg.background`, threshold depth at the default σ) and moved to its registered pose;
/// `report(pass, registrations)` sees each pass's outcome. Training again at the final poses
/// gives the NeRF of a capture whose poses came from a robot arm.
pub fn registration_passes(
    isa: Isa,
    views: &mut [View],
    field: NerfConfig,
    cfg: &TrainConfig,
    passes: u32,
    mut log: impl FnMut(u32, StepStats),
    mut report: impl FnMut(u32, &[Registration]),
) -> Result<(), TrainError> {
    for pass in 1..=passes {
        let first = train_nerf(isa, views, field.clone(), cfg, 10, |s| log(pass, s))?;
        let regs = register_all(isa, &first, views, cfg.background, DensityThreshold::DEFAULT);
        for (v, r) in views.iter_mut().zip(&regs) {
            v.pose = r.pose;
        }
        report(pass, &regs);
    }
    Ok(())
}

/// The rotation and the shift from pose `a` to pose `b` (degrees, scene units).
pub fn pose_difference(a: &Pose, b: &Pose) -> (f64, f64) {
    let d = Rigid::of(a).r.transpose() * Rigid::of(b).r;
    let angle = Rigid { r: d, t: DVec3::ZERO }.angle().to_degrees();
    (angle, (b.translation - a.translation).as_dvec3().length())
}
