//! Ray generation and pose conventions against hand-computed rays; range ↔ z conversion.

use glam::{Mat3, Vec3};
use residual_nerf::render::{pixel_ray, Intrinsics, Pose};

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).abs().max_element() < 1e-6
}

/// Identity pose, 4×2 image, f = 2, principal point at the centre (2, 1):
/// pixel (0, 0) → camera direction ((0.5 − 2)/2, −(0.5 − 1)/2, −1) = (−0.75, 0.25, −1).
#[test]
fn identity_pose_pixel_centres() {
    let k = Intrinsics { width: 4, height: 2, fx: 2.0, fy: 2.0, cx: 2.0, cy: 1.0 };
    let pose = Pose { rotation: Mat3::IDENTITY, translation: Vec3::ZERO };
    let r = pixel_ray(&k, &pose, 0, 0);
    let want = Vec3::new(-0.75, 0.25, -1.0);
    assert!(close(r.dir, want.normalize()), "{:?}", r.dir);
    assert!((r.z_per_t - 1.0 / want.length()).abs() < 1e-6);
    // The pixel just right of and below the centre looks down −Z, slightly right and down.
    let c = pixel_ray(&k, &pose, 2, 1);
    assert!(close(c.dir, Vec3::new(0.25, -0.25, -1.0).normalize()));
}

/// A camera at (0, −2, 0.5) looking along world +Y (rotation: x → x, y → z, z → −y),
/// as the rows of a NeRF `transform_matrix`. The centre pixel's ray points along +Y.
#[test]
fn rotated_pose_from_transform_rows() {
    let rows = [[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, -1.0, -2.0], [0.0, 1.0, 0.0, 0.5]];
    let pose = Pose::from_rows(rows);
    assert!(close(pose.forward(), Vec3::Y));
    let k = Intrinsics { width: 3, height: 3, fx: 1.0, fy: 1.0, cx: 1.5, cy: 1.5 };
    let r = pixel_ray(&k, &pose, 1, 1);
    assert!(close(r.origin, Vec3::new(0.0, -2.0, 0.5)));
    assert!(close(r.dir, Vec3::Y));
    assert!((r.z_per_t - 1.0).abs() < 1e-6);
    // Top-left pixel: camera (−1, 1, −1) → world (−1, 1, 1) (camera up is world +Z).
    let tl = pixel_ray(&k, &pose, 0, 0);
    assert!(close(tl.dir, Vec3::new(-1.0, 1.0, 1.0).normalize()), "{:?}", tl.dir);
    // A point 2 m in front along the viewing axis has z = 2 whatever the pixel.
    let t = tl.z_to_range(2.0);
    assert!((tl.at(t).y - (-2.0 + 2.0)).abs() < 1e-6);
}

/// `t = z · √(1 + x² + y²)` for camera-space direction (x, y, −1) — the dev set's formula —
/// and the round trip is exact to f32 rounding.
#[test]
fn range_and_z_conversion() {
    let k = Intrinsics::from_fov_x(200, 200, 0.691_111);
    assert!((k.fx - 277.777_8).abs() < 1e-2, "{}", k.fx);
    let pose = Pose::from_rows([[0.6, 0.0, 0.8, 1.0], [0.0, 1.0, 0.0, 2.0], [-0.8, 0.0, 0.6, 3.0]]);
    for (i, j) in [(0, 0), (199, 0), (57, 123), (100, 100)] {
        let r = pixel_ray(&k, &pose, i, j);
        let (x, y) = ((i as f32 + 0.5 - k.cx) / k.fx, -(j as f32 + 0.5 - k.cy) / k.fy);
        let z = 1.7;
        let t = z * (1.0 + x * x + y * y).sqrt();
        assert!((r.z_to_range(z) - t).abs() < 1e-5, "pixel ({i},{j})");
        assert!((r.range_to_z(r.z_to_range(z)) - z).abs() < 1e-6);
        // The point at range t lies z in front of the camera along its axis.
        assert!(((r.at(t) - pose.translation).dot(pose.forward()) - z).abs() < 1e-5);
    }
}
