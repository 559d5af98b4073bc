//! Lens distortion: the two models of Instant-NGP's and nerfstudio's `transforms.json`
//! (`camera_model` `OPENCV` and `OPENCV_FISHEYE`), in OpenCV's normalised image coordinates
//! (x right, y down, the camera looking down +z; a pixel is `(cx + fx·x_d, cy + fy·y_d)`).
//!
//! - [`Distortion::Radial`] (`OPENCV`): `r² = x² + y²`,
//!   `x_d = x·R + 2p₁xy + p₂(r² + 2x²)`, `y_d = y·R + p₁(r² + 2y²) + 2p₂xy` with
//!   `R = 1 + k₁r² + k₂r⁴ + k₃r⁶ + k₄r⁸` (nerfstudio's radial polynomial; COLMAP's `OPENCV` is
//!   the case `k₃ = k₄ = 0`).
//! - [`Distortion::Fisheye`] (`OPENCV_FISHEYE`): the angle θ of a direction from the axis maps
//!   to the image radius `θ_d = θ(1 + k₁θ² + k₂θ⁴ + k₃θ⁶ + k₄θ⁸)`, along the direction's azimuth.
//!
//! Rays are generated through the distortion exactly: a pixel's distorted point is undistorted by
//! Newton's method in f64 ([`Distortion::undistort`]) and the projection of a world point
//! ([`Distortion::distort`]) is its inverse; [`Distortion::check`] refuses a model that cannot be
//! inverted over an image (it folds back on itself), so a dataset with such a lens fails to load
//! with a one-line error instead of training on wrong rays.

use glam::DVec3;

/// A lens's distortion (see the module documentation for the equations).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum Distortion {
    /// A pinhole camera.
    #[default]
    None,
    /// `OPENCV`: radial `k₁…k₄` and tangential `p₁, p₂`.
    Radial {
        /// `[k1, k2, k3, k4]`.
        k: [f32; 4],
        /// `[p1, p2]`.
        p: [f32; 2],
    },
    /// `OPENCV_FISHEYE`: the equidistant projection with a polynomial in θ, `k₁…k₄`.
    Fisheye {
        /// `[k1, k2, k3, k4]`.
        k: [f32; 4],
    },
}

/// Newton iterations of the undistortion at most (the loop stops at [`TOLERANCE`]).
const ITERATIONS: usize = 20;
/// Convergence tolerance of the undistortion in normalised image units (≈ 10⁻⁷ px at f = 1000).
const TOLERANCE: f64 = 1e-10;
/// Largest round-trip error [`Distortion::check`] accepts, in pixels.
const ROUND_TRIP_PX: f64 = 1e-3;
/// Samples per image side in [`Distortion::check`]: a lattice over the whole image, borders
/// and corners included.
const CHECK_SAMPLES: u32 = 33;

impl Distortion {
    /// Whether this is a pinhole camera.
    pub fn is_none(&self) -> bool {
        matches!(self, Distortion::None)
    }

    /// The coefficients as the json's keys name them (`k1 k2 k3 k4 p1 p2`; zero where the model
    /// has no such term).
    pub fn coefficients(&self) -> [(&'static str, f32); 6] {
        let (k, p) = match *self {
            Distortion::None => ([0.0; 4], [0.0; 2]),
            Distortion::Radial { k, p } => (k, p),
            Distortion::Fisheye { k } => (k, [0.0; 2]),
        };
        [("k1", k[0]), ("k2", k[1]), ("k3", k[2]), ("k4", k[3]), ("p1", p[0]), ("p2", p[1])]
    }

    /// The `camera_model` name of the json (`PINHOLE`, `OPENCV`, `OPENCV_FISHEYE`).
    pub fn model_name(&self) -> &'static str {
        match self {
            Distortion::None => "PINHOLE",
            Distortion::Radial { .. } => "OPENCV",
            Distortion::Fisheye { .. } => "OPENCV_FISHEYE",
        }
    }

    /// The distorted normalised image point of a camera-space direction `d` (OpenCV axes, need
    /// not be unit), or `None` where the model does not image it (behind the camera for the
    /// perspective models; beyond 180° for the fisheye).
    pub fn distort(&self, d: DVec3) -> Option<(f64, f64)> {
        match *self {
            Distortion::None | Distortion::Radial { .. } if d.z <= 0.0 => None,
            Distortion::None => Some((d.x / d.z, d.y / d.z)),
            Distortion::Radial { k, p } => Some(radial(k, p, d.x / d.z, d.y / d.z).0),
            Distortion::Fisheye { k } => {
                let r = (d.x * d.x + d.y * d.y).sqrt();
                if r == 0.0 {
                    return (d.z > 0.0).then_some((0.0, 0.0));
                }
                let theta = r.atan2(d.z);
                let theta_d = fisheye(k, theta).0;
                Some((theta_d * d.x / r, theta_d * d.y / r))
            }
        }
    }

    /// The camera-space direction (OpenCV axes; `z = 1` for the perspective models, unit for the
    /// fisheye) whose image is the distorted normalised point `(xd, yd)`, or `None` when Newton's
    /// method does not converge there (outside where the model can be inverted).
    pub fn undistort(&self, xd: f64, yd: f64) -> Option<DVec3> {
        match *self {
            Distortion::None => Some(DVec3::new(xd, yd, 1.0)),
            Distortion::Radial { k, p } => {
                let (mut x, mut y) = (xd, yd);
                for _ in 0..ITERATIONS {
                    let ((fx, fy), [[a, b], [c, d]]) = radial(k, p, x, y);
                    let (ex, ey) = (fx - xd, fy - yd);
                    if ex.hypot(ey) < TOLERANCE {
                        return Some(DVec3::new(x, y, 1.0));
                    }
                    let det = a * d - b * c;
                    if det.abs() < 1e-12 || !det.is_finite() {
                        return None;
                    }
                    x -= (d * ex - b * ey) / det;
                    y -= (a * ey - c * ex) / det;
                }
                let ((fx, fy), _) = radial(k, p, x, y);
                ((fx - xd).hypot(fy - yd) < 1e3 * TOLERANCE).then_some(DVec3::new(x, y, 1.0))
            }
            Distortion::Fisheye { k } => {
                let theta_d = xd.hypot(yd);
                if theta_d == 0.0 {
                    return Some(DVec3::Z);
                }
                let mut theta = theta_d;
                let mut converged = false;
                for _ in 0..ITERATIONS {
                    let (f, df) = fisheye(k, theta);
                    if (f - theta_d).abs() < TOLERANCE {
                        converged = true;
                        break;
                    }
                    if df <= 0.0 || !df.is_finite() {
                        return None;
                    }
                    theta -= (f - theta_d) / df;
                }
                if !(converged || (fisheye(k, theta).0 - theta_d).abs() < 1e3 * TOLERANCE)
                    || !(0.0..std::f64::consts::PI).contains(&theta)
                {
                    return None;
                }
                let s = theta.sin() / theta_d;
                Some(DVec3::new(xd * s, yd * s, theta.cos()))
            }
        }
    }

    /// Checks that the model can be inverted over a `width × height` image with focal lengths
    /// `fx, fy` and principal point `cx, cy`: on a lattice of pixels (corners and borders
    /// included) the undistortion converges, distorting the result gives the pixel back within
    /// 10⁻³ px, and the mapping does not fold (the radius grows along each lattice ray from the
    /// principal point). The error says where it fails.
    pub fn check(&self, width: u32, height: u32, fx: f32, fy: f32, cx: f32, cy: f32) -> Result<(), String> {
        if self.is_none() {
            return Ok(());
        }
        if let Some((name, v)) = self.coefficients().into_iter().find(|(_, v)| !v.is_finite()) {
            return Err(format!("{name} = {v} is not finite"));
        }
        let (fx, fy, cx, cy) = (fx as f64, fy as f64, cx as f64, cy as f64);
        let n = CHECK_SAMPLES;
        for j in 0..n {
            for i in 0..n {
                let (u, v) = (width as f64 * i as f64 / (n - 1) as f64, height as f64 * j as f64 / (n - 1) as f64);
                let (xd, yd) = ((u - cx) / fx, (v - cy) / fy);
                let Some(dir) = self.undistort(xd, yd) else {
                    return Err(format!(
                        "the {} distortion cannot be inverted at pixel ({u:.0}, {v:.0}) of the {width}x{height} image",
                        self.model_name()
                    ));
                };
                let back = self.distort(dir).map(|(x, y)| ((x - xd) * fx).hypot((y - yd) * fy));
                if back.is_none_or(|e| e.is_nan() || e > ROUND_TRIP_PX) {
                    return Err(format!(
                        "the {} distortion does not round-trip at pixel ({u:.0}, {v:.0}) of the {width}x{height} image",
                        self.model_name()
                    ));
                }
                // No fold: the undistorted radius grows with the distorted one along the
                // ray from the principal point.
                let inner = self.undistort(0.98 * xd, 0.98 * yd);
                let angle = |d: DVec3| d.x.hypot(d.y).atan2(d.z);
                if (xd, yd) != (0.0, 0.0) && inner.is_none_or(|d| angle(d) >= angle(dir)) {
                    return Err(format!(
                        "the {} distortion folds back on itself near pixel ({u:.0}, {v:.0}) of the {width}x{height} image",
                        self.model_name()
                    ));
                }
            }
        }
        Ok(())
    }
}

/// The radial-tangential model at `(x, y)`: the distorted point and its Jacobian
/// `[[∂x_d/∂x, ∂x_d/∂y], [∂y_d/∂x, ∂y_d/∂y]]`.
fn radial(k: [f32; 4], p: [f32; 2], x: f64, y: f64) -> ((f64, f64), [[f64; 2]; 2]) {
    let [k1, k2, k3, k4] = k.map(f64::from);
    let [p1, p2] = p.map(f64::from);
    let r2 = x * x + y * y;
    let big_r = 1.0 + r2 * (k1 + r2 * (k2 + r2 * (k3 + r2 * k4)));
    let dr = k1 + r2 * (2.0 * k2 + r2 * (3.0 * k3 + r2 * 4.0 * k4)); // dR/d(r²)
    let xd = x * big_r + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
    let yd = y * big_r + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
    let cross = 2.0 * x * y * dr + 2.0 * p1 * x + 2.0 * p2 * y;
    let jac = [
        [big_r + 2.0 * x * x * dr + 2.0 * p1 * y + 6.0 * p2 * x, cross],
        [cross, big_r + 2.0 * y * y * dr + 6.0 * p1 * y + 2.0 * p2 * x],
    ];
    ((xd, yd), jac)
}

/// The fisheye's `θ_d(θ)` and its derivative.
fn fisheye(k: [f32; 4], theta: f64) -> (f64, f64) {
    let [k1, k2, k3, k4] = k.map(f64::from);
    let t2 = theta * theta;
    let f = theta * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))));
    let df = 1.0 + t2 * (3.0 * k1 + t2 * (5.0 * k2 + t2 * (7.0 * k3 + t2 * 9.0 * k4)));
    (f, df)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_radial_jacobian_matches_finite_differences() {
        let (k, p) = ([-0.3, 0.12, -0.02, 0.004], [0.001, -0.002]);
        for (x, y) in [(0.3, -0.2), (-0.5, 0.4), (0.01, 0.6)] {
            let (_, j) = radial(k, p, x, y);
            let h = 1e-6;
            let dx = |dx: f64, dy: f64| radial(k, p, x + dx, y + dy).0;
            let (a, b) = (dx(h, 0.0), dx(-h, 0.0));
            let (c, d) = (dx(0.0, h), dx(0.0, -h));
            let num = [
                [(a.0 - b.0) / (2.0 * h), (c.0 - d.0) / (2.0 * h)],
                [(a.1 - b.1) / (2.0 * h), (c.1 - d.1) / (2.0 * h)],
            ];
            for r in 0..2 {
                for c in 0..2 {
                    assert!((num[r][c] - j[r][c]).abs() < 1e-6, "({x}, {y}) [{r}][{c}]: {} vs {}", num[r][c], j[r][c]);
                }
            }
        }
    }
}
