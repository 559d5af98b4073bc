//! Pinhole cameras and rays (DESIGN §3 conventions).
//!
//! Poses are camera-to-world in the OpenGL / NeRF-synthetic convention: the camera looks down
//! its −Z axis with +Y up and +X right. Pixel `(i, j)` (column `i`, row `j` from the top) is the
//! ray through image point `(i + ½, j + ½)`, camera-space direction
//! `((i + ½ − cx)/fx, −(j + ½ − cy)/fy, −1)`, rotated to world and normalised.
//!
//! Distances along a ray are **range** `t` (unit-length direction). Robots and the datasets'
//! ground truth use **z-depth**, the distance along the viewing axis: `z = t · (d · forward)`
//! ([`Ray::z_per_t`]); equivalently `t = z · √(1 + x² + y²)` for the camera-space direction
//! `(x, y, −1)`.

use glam::{Mat3, Vec3};

/// Pinhole intrinsics in pixels.
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
}

impl Intrinsics {
    /// Square pixels from a horizontal field of view (`camera_angle_x`), principal point at the
    /// image centre: `f = ½ w / tan(½ fov)`.
    pub fn from_fov_x(width: u32, height: u32, camera_angle_x: f32) -> Intrinsics {
        let f = 0.5 * width as f32 / (0.5 * camera_angle_x).tan();
        Intrinsics { width, height, fx: f, fy: f, cx: 0.5 * width as f32, cy: 0.5 * height as f32 }
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

/// The ray through the centre of pixel `(i, j)` (column, row from the top).
pub fn pixel_ray(k: &Intrinsics, pose: &Pose, i: u32, j: u32) -> Ray {
    let cam = Vec3::new((i as f32 + 0.5 - k.cx) / k.fx, -(j as f32 + 0.5 - k.cy) / k.fy, -1.0);
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
