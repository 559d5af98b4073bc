//! Cameras and rays (DESIGN §3 conventions): pinhole intrinsics with an optional lens
//! distortion ([`Distortion`]: OpenCV's radial-tangential or fisheye model).
//!
//! Poses are camera-to-world in the OpenGL / NeRF-synthetic convention: the camera looks down
//! its −Z axis with +Y up and +X right. Pixel `(i, j)` (column `i`, row `j` from the top) is the
//! ray through image point `(i + ½, j + ½)`, camera-space direction
//! `((i + ½ − cx)/fx, −(j + ½ − cy)/fy, −1)`, rotated to world and normalised; with a lens
//! distortion the point `((i + ½ − cx)/fx, (j + ½ − cy)/fy)` is first undistorted (OpenCV's
//! normalised coordinates, y down).
//!
//! Distances along a ray are **range** `t` (unit-length direction). Robots and the datasets'
//! ground truth use **z-depth**, the distance along the viewing axis: `z = t · (d · forward)`
//! ([`Ray::z_per_t`]); equivalently `t = z · √(1 + x² + y²)` for the camera-space direction
//! `(x, y, −1)`.

use super::distortion::Distortion;
use glam::{DMat3, DVec3, Mat3, Vec3};

/// Intrinsics in pixels: a pinhole camera and its lens distortion.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Intrinsics {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Focal length along x (pixels).
    pub fx: f32,
    /// Focal length along y (pixels).
    pub fy: f32,
    /// Principal point x (pixels).
    pub cx: f32,
    /// Principal point y (pixels).
    pub cy: f32,
    /// The lens distortion ([`Distortion::None`] for a pinhole camera).
    pub distortion: Distortion,
}

impl Intrinsics {
    /// `Err` with a one-line message when the pinhole part is not a camera: focal lengths not
    /// finite and positive, or a principal point not finite (the lens is checked by
    /// [`Distortion::check`]).
    pub fn check_pinhole(&self) -> Result<(), String> {
        let Intrinsics { fx, fy, cx, cy, .. } = *self;
        match fx.is_finite() && fy.is_finite() && fx > 0.0 && fy > 0.0 && cx.is_finite() && cy.is_finite() {
            true => Ok(()),
            false => Err(format!("intrinsics fx={fx} fy={fy} cx={cx} cy={cy} are not a camera")),
        }
    }

    /// [`Intrinsics::check_pinhole`], then the lens ([`Distortion::check`], its message after
    /// `intrinsics: `): the camera a caller hands the onboard renderer or the scene phase.
    pub fn check(&self) -> Result<(), String> {
        self.check_pinhole()?;
        match self.distortion.is_none() {
            true => Ok(()),
            false => self
                .distortion
                .check(self.width, self.height, self.fx, self.fy, self.cx, self.cy)
                .map_err(|m| format!("intrinsics: {m}")),
        }
    }

    /// A pinhole camera (no distortion).
    pub fn pinhole(width: u32, height: u32, fx: f32, fy: f32, cx: f32, cy: f32) -> Intrinsics {
        Intrinsics { width, height, fx, fy, cx, cy, distortion: Distortion::None }
    }

    /// Square pixels from a horizontal field of view (`camera_angle_x`), principal point at the
    /// image centre: `f = ½ w / tan(½ fov)`.
    pub fn from_fov_x(width: u32, height: u32, camera_angle_x: f32) -> Intrinsics {
        let f = 0.5 * width as f32 / (0.5 * camera_angle_x).tan();
        Intrinsics::pinhole(width, height, f, f, 0.5 * width as f32, 0.5 * height as f32)
    }

    /// Camera-space point `c` (OpenGL axes: the camera looks down −Z) in the image: pixel
    /// coordinates `(u, v)` (`(0, 0)` the top-left corner of the first pixel) through the lens,
    /// or `None` when it is not in front of the camera (z-depth ≤ 1 mm) or the lens does not image it.
    pub fn project(&self, c: Vec3) -> Option<(f32, f32)> {
        let zc = -c.z;
        if zc.is_nan() || zc <= 1e-3 {
            return None;
        }
        match self.distortion {
            Distortion::None => Some((self.cx + self.fx * c.x / zc, self.cy - self.fy * c.y / zc)),
            d => {
                let (x, y) = d.distort(DVec3::new(c.x as f64, -c.y as f64, zc as f64))?;
                Some(((self.cx as f64 + self.fx as f64 * x) as f32, (self.cy as f64 + self.fy as f64 * y) as f32))
            }
        }
    }
}

/// A camera-to-world rigid transform (rotation columns = camera axes in world coordinates).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// Rotation: columns are the camera's +X, +Y, +Z axes in world coordinates.
    pub rotation: Mat3,
    /// Camera centre in world coordinates.
    pub translation: Vec3,
}

impl Pose {
    /// `Err` with a one-line message when the pose holds a non-finite value.
    pub fn check(&self) -> Result<(), String> {
        match self.translation.is_finite() && self.rotation.is_finite() {
            true => Ok(()),
            false => Err("pose holds a non-finite value".to_string()),
        }
    }

    /// A camera at `eye` looking at `target`, world +Z up (the image's up is as close to +Z
    /// as the viewing direction allows; `eye - target` must not be vertical).
    pub fn look_at(eye: Vec3, target: Vec3) -> Pose {
        let forward = (target - eye).normalize();
        let right = forward.cross(Vec3::Z).normalize();
        let up = right.cross(forward);
        Pose { rotation: Mat3::from_cols(right, up, -forward), translation: eye }
    }

    /// From the rows of a `transform_matrix` (3×4 or the top of a 4×4).
    pub fn from_rows(rows: [[f32; 4]; 3]) -> Pose {
        let col = |c: usize| Vec3::new(rows[0][c], rows[1][c], rows[2][c]);
        Pose { rotation: Mat3::from_cols(col(0), col(1), col(2)), translation: col(3) }
    }

    /// The top three rows of the 4×4 `transform_matrix` (inverse of [`Pose::from_rows`]).
    pub fn to_rows(&self) -> [[f32; 4]; 3] {
        let (m, t) = (self.rotation, self.translation);
        std::array::from_fn(|r| [m.x_axis[r], m.y_axis[r], m.z_axis[r], t[r]])
    }

    /// The 4×4 camera-to-world `transform_matrix` as written in transforms json.
    pub fn to_matrix(&self) -> [[f32; 4]; 4] {
        let r = self.to_rows();
        [r[0], r[1], r[2], [0.0, 0.0, 0.0, 1.0]]
    }

    /// The viewing direction (camera −Z) in world coordinates.
    pub fn forward(&self) -> Vec3 {
        -self.rotation.z_axis
    }
}

/// The point a capture's cameras look at: the least-squares point nearest to every camera's
/// viewing axis (each camera's centre along [`Pose::forward`]), computed in f64. `None` when
/// the axes do not meet near one point in front of the cameras: fewer than two cameras, axes
/// all parallel, a point behind most of the cameras, or axes that pass it at a root-mean-square
/// distance above [`FOCUS_SPREAD`] of the cameras' median distance to it (a forward-facing
/// capture whose axes only scatter by a few degrees has a least-squares point too, but one its
/// cameras do not aim at).
pub fn capture_focus(poses: &[Pose]) -> Option<Vec3> {
    let (mut a, mut b) = (DMat3::ZERO, DVec3::ZERO);
    let axes: Vec<(DVec3, DVec3)> =
        poses.iter().map(|p| (p.translation.as_dvec3(), p.forward().as_dvec3().normalize())).collect();
    // I − d dᵀ: the projection onto the plane across the axis.
    let across = |d: DVec3| DMat3::IDENTITY - DMat3::from_cols(d * d.x, d * d.y, d * d.z);
    for &(c, d) in &axes {
        let m = across(d);
        a += m;
        b += m * c;
    }
    let n = poses.len() as f64;
    // The eigenvalues of `a` lie in [0, n]: a determinant this small is a singular system.
    let det = a.determinant();
    if poses.len() < 2 || det.is_nan() || det <= 1e-6 * n * n * n {
        return None;
    }
    let focus = a.inverse() * b;
    let mut ahead: Vec<f64> = axes.iter().map(|&(c, d)| (focus - c).dot(d)).collect();
    ahead.sort_by(f64::total_cmp);
    let miss = (axes.iter().map(|&(c, d)| (across(d) * (focus - c)).length_squared()).sum::<f64>() / n).sqrt();
    let aimed = miss <= (FOCUS_SPREAD * median_distance(poses, focus.as_vec3())) as f64;
    (focus.is_finite() && ahead[ahead.len() / 2] > 0.0 && aimed).then(|| focus.as_vec3())
}

/// How far (root mean square, as a share of the cameras' median distance to it) the viewing
/// axes may pass the point [`capture_focus`] finds for it to be the point they look at: 0.1,
/// about 6° of aim. Cameras aimed at one point with 2° of error pass it at ~0.05, the dev
/// capture's at 0; a forward-facing grid of cameras whose axes scatter by 1–3° at 0.19–0.67
/// (`scripts/focus_spread.py`; docs/DECISIONS.md, "The near-camera gradient scaling").
pub const FOCUS_SPREAD: f32 = 0.1;

/// The median distance from the cameras' centres to `point`.
pub fn median_distance(poses: &[Pose], point: Vec3) -> f32 {
    let mut d: Vec<f32> = poses.iter().map(|p| p.translation.distance(point)).collect();
    d.sort_by(f32::total_cmp);
    d.get(d.len() / 2).copied().unwrap_or(0.0)
}

/// A ray with unit direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Origin (the camera centre).
    pub origin: Vec3,
    /// Unit direction.
    pub dir: Vec3,
    /// `d · forward`: multiply a range `t` by this to get z-depth.
    pub z_per_t: f32,
}

impl Ray {
    /// The point at range `t`.
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + t * self.dir
    }

    /// z-depth of range `t`.
    pub fn range_to_z(&self, t: f32) -> f32 {
        t * self.z_per_t
    }

    /// Range of z-depth `z`.
    pub fn z_to_range(&self, z: f32) -> f32 {
        z / self.z_per_t
    }
}

/// The ray through the centre of pixel `(i, j)` (column, row from the top), through the lens.
/// Where a distortion cannot be inverted (outside the region [`Distortion::check`] accepts for a
/// dataset's images) the pixel's distorted point is used as if undistorted.
pub fn pixel_ray(k: &Intrinsics, pose: &Pose, i: u32, j: u32) -> Ray {
    image_ray(k, pose, i as f32 + 0.5, j as f32 + 0.5)
}

/// The ray through the image point `(x, y)` in pixels (pixel `(i, j)` spans `[i, i + 1) × [j,
/// j + 1)`, its centre at `(i + ½, j + ½)`), through the lens, as [`pixel_ray`].
pub fn image_ray(k: &Intrinsics, pose: &Pose, x: f32, y: f32) -> Ray {
    let cam = match k.distortion {
        Distortion::None => Vec3::new((x - k.cx) / k.fx, -(y - k.cy) / k.fy, -1.0),
        d => {
            let x = (x as f64 - k.cx as f64) / k.fx as f64;
            let y = (y as f64 - k.cy as f64) / k.fy as f64;
            let u = d.undistort(x, y).unwrap_or(DVec3::new(x, y, 1.0));
            Vec3::new(u.x as f32, -u.y as f32, -u.z as f32)
        }
    };
    let dir = (pose.rotation * cam).normalize();
    Ray { origin: pose.translation, dir, z_per_t: dir.dot(pose.forward()) }
}

/// What a depth value measures (a dataset's ground truth, an export, the onboard API's output).
/// Both are in the dataset's length unit (metres for ours); holes are NaN.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum DepthKind {
    /// Distance along the camera's viewing axis (what depth cameras report: ROS depth images,
    /// Dex-Net, OpenCV).
    #[default]
    Z,
    /// Distance along each pixel's ray from the camera centre (a lidar's range).
    Range,
}

impl DepthKind {
    /// The name used in json files and reports (`"z"`, `"range"`).
    pub fn name(self) -> &'static str {
        match self {
            DepthKind::Z => "z",
            DepthKind::Range => "range",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Cameras on a ring of `radius` around `target`, at elevations 25–75°, looking at it.
    fn ring(target: Vec3, radius: f32, n: usize) -> Vec<Pose> {
        (0..n)
            .map(|i| {
                let (az, el) = (i as f32 * 2.4, (25.0 + 50.0 * (i as f32 * 0.37).fract()).to_radians());
                let eye = target + radius * Vec3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
                Pose::look_at(eye, target)
            })
            .collect()
    }

    #[test]
    fn a_ring_of_cameras_focuses_on_what_it_looks_at() {
        let target = Vec3::new(0.3, -0.2, 0.05);
        let poses = ring(target, 0.62, 40);
        let focus = capture_focus(&poses).expect("a ring pins its focus");
        assert!(focus.distance(target) < 1e-4, "{focus} against {target}");
        assert!((median_distance(&poses, focus) - 0.62).abs() < 1e-4);
        // Cameras that do not all aim exactly at one point: the nearest point to their axes.
        let mut off = poses.clone();
        off[0] = Pose::look_at(off[0].translation, target + Vec3::new(0.05, 0.0, 0.0));
        assert!(capture_focus(&off).unwrap().distance(target) < 0.01);
        // Every camera off its aim by up to 2°: still the point they look at.
        let mut rng = crate::rng::Rng::new(5);
        let aimed: Vec<Pose> = poses
            .iter()
            .map(|p| {
                let err = Vec3::new(rng.f32() - 0.5, rng.f32() - 0.5, rng.f32() - 0.5) * 2.0 * 0.62 * 2f32.to_radians();
                Pose::look_at(p.translation, target + err)
            })
            .collect();
        assert!(capture_focus(&aimed).expect("aimed within 2°").distance(target) < 0.03);
    }

    #[test]
    fn parallel_or_outward_axes_pin_no_focus() {
        // A forward-facing capture: every camera looks along −Y from a plane.
        let forward: Vec<Pose> = (0..9)
            .map(|i| {
                let eye = Vec3::new((i % 3) as f32 * 0.1, 0.0, (i / 3) as f32 * 0.1);
                Pose::look_at(eye, eye - Vec3::Y)
            })
            .collect();
        assert_eq!(capture_focus(&forward), None);
        // The same grid, each camera tilted by a degree or two at random: the axes have a
        // least-squares point, but it is not one the cameras aim at.
        let mut rng = crate::rng::Rng::new(3);
        let scattered: Vec<Pose> = forward
            .iter()
            .chain(&forward)
            .map(|p| {
                let tilt = Vec3::new(rng.f32() - 0.5, 0.0, rng.f32() - 0.5) * 2.0 * 2f32.to_radians();
                Pose::look_at(p.translation, p.translation - Vec3::Y + tilt)
            })
            .collect();
        assert_eq!(capture_focus(&scattered), None);
        // Cameras on a ring looking outwards: their axes meet behind them.
        let outward: Vec<Pose> =
            ring(Vec3::ZERO, 1.0, 12).iter().map(|p| Pose::look_at(p.translation, 2.0 * p.translation)).collect();
        assert_eq!(capture_focus(&outward), None);
        assert_eq!(capture_focus(&outward[..1]), None);
        assert_eq!(capture_focus(&[]), None);
    }
}
