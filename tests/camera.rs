//! Ray generation and pose conventions against hand-computed rays; range ↔ z conversion; lens
//! distortion (the models' equations, rays through a lens projecting back, lenses refused).

mod common;

use glam::{Mat3, Vec3};
use proptest::prelude::*;
use residual_nerf::geometry::Distortion;
use residual_nerf::render::{image_ray, pixel_ray, Intrinsics, Pose};

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).abs().max_element() < 1e-6
}

/// Identity pose, 4×2 image, f = 2, principal point at the centre (2, 1):
/// pixel (0, 0) → camera direction ((0.5 − 2)/2, −(0.5 − 1)/2, −1) = (−0.75, 0.25, −1).
#[test]
fn identity_pose_pixel_centres() {
    let k = Intrinsics::pinhole(4, 2, 2.0, 2.0, 2.0, 1.0);
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
    let k = Intrinsics::pinhole(3, 3, 1.0, 1.0, 1.5, 1.5);
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

// ---- Lens distortion (OpenCV's radial-tangential and fisheye models) ----

fn lens_k(distortion: Distortion) -> Intrinsics {
    Intrinsics { distortion, ..Intrinsics::pinhole(160, 120, 130.0, 128.0, 81.3, 58.7) }
}

proptest! {
    #![proptest_config(common::cases(64))]

    /// Through any lens the crate accepts for an image, the ray of a pixel projects back onto
    /// that pixel's centre (undistortion by Newton's method against the forward model).
    #[test]
    fn a_pixel_ray_projects_back_to_its_pixel(
        fisheye in any::<bool>(),
        k1 in -0.4f32..0.4, k2 in -0.2f32..0.2, k3 in -0.05f32..0.05, k4 in -0.01f32..0.01,
        p1 in -0.01f32..0.01, p2 in -0.01f32..0.01,
        i in 0u32..160, j in 0u32..120,
    ) {
        let d = if fisheye { Distortion::Fisheye { k: [k1, k2, k3, k4] } } else { Distortion::Radial { k: [k1, k2, k3, k4], p: [p1, p2] } };
        let k = lens_k(d);
        prop_assume!(d.check(k.width, k.height, k.fx, k.fy, k.cx, k.cy).is_ok());
        let pose = Pose::look_at(Vec3::new(0.3, -1.2, 0.8), Vec3::new(0.0, 0.1, 0.05));
        let r = pixel_ray(&k, &pose, i, j);
        prop_assert!((r.dir.length() - 1.0).abs() < 1e-5);
        let c = pose.rotation.transpose() * (r.at(1.5) - pose.translation);
        let (u, v) = k.project(c).expect("in front of the camera");
        prop_assert!((u - (i as f32 + 0.5)).abs() < 2e-3 && (v - (j as f32 + 0.5)).abs() < 2e-3, "({u}, {v}) for pixel ({i}, {j})");
    }

    /// A ray through any image point (the training rays jittered over their pixel) projects
    /// back to that point, and at a pixel's centre it is that pixel's ray bit for bit.
    #[test]
    fn an_image_ray_projects_back_to_its_point(
        fisheye in any::<bool>(), lens in any::<bool>(),
        k1 in -0.4f32..0.4, k2 in -0.2f32..0.2,
        x in 0.0f32..160.0, y in 0.0f32..120.0, i in 0u32..160, j in 0u32..120,
    ) {
        let d = match (lens, fisheye) {
            (false, _) => Distortion::None,
            (true, true) => Distortion::Fisheye { k: [k1, k2, 0.0, 0.0] },
            (true, false) => Distortion::Radial { k: [k1, k2, 0.0, 0.0], p: [0.0, 0.0] },
        };
        let k = lens_k(d);
        prop_assume!(d.check(k.width, k.height, k.fx, k.fy, k.cx, k.cy).is_ok());
        let pose = Pose::look_at(Vec3::new(0.3, -1.2, 0.8), Vec3::new(0.0, 0.1, 0.05));
        let r = image_ray(&k, &pose, x, y);
        let c = pose.rotation.transpose() * (r.at(1.5) - pose.translation);
        let (u, v) = k.project(c).expect("in front of the camera");
        prop_assert!((u - x).abs() < 2e-3 && (v - y).abs() < 2e-3, "({u}, {v}) for ({x}, {y})");
        let (a, b) = (pixel_ray(&k, &pose, i, j), image_ray(&k, &pose, i as f32 + 0.5, j as f32 + 0.5));
        prop_assert_eq!((a.origin, a.dir, a.z_per_t), (b.origin, b.dir, b.z_per_t));
    }
}

/// The models' equations at hand-computed points: barrel distortion pulls a point towards the
/// centre by `1 + k₁r²`; a tangential term shifts it; the fisheye maps angle θ to radius θ.
#[test]
fn the_lens_models_at_hand_computed_points() {
    use glam::DVec3;
    let barrel = Distortion::Radial { k: [-0.2, 0.0, 0.0, 0.0], p: [0.0, 0.0] };
    let (x, y) = barrel.distort(DVec3::new(0.3, 0.4, 1.0)).unwrap(); // r² = 0.25, factor 0.95
    assert!((x - 0.285).abs() < 1e-8 && (y - 0.38).abs() < 1e-8); // f32 coefficients
    let tangential = Distortion::Radial { k: [0.0; 4], p: [0.01, 0.02] };
    let (x, y) = tangential.distort(DVec3::new(0.3, 0.4, 1.0)).unwrap();
    // x + 2p₁xy + p₂(r² + 2x²), y + p₁(r² + 2y²) + 2p₂xy
    assert!((x - (0.3 + 2.0 * 0.01 * 0.12 + 0.02 * (0.25 + 0.18))).abs() < 1e-9);
    assert!((y - (0.4 + 0.01 * (0.25 + 0.32) + 2.0 * 0.02 * 0.12)).abs() < 1e-9);
    let equidistant = Distortion::Fisheye { k: [0.0; 4] };
    let (x, y) = equidistant.distort(DVec3::new(1.0, 0.0, 1.0)).unwrap(); // θ = 45°
    assert!((x - std::f64::consts::FRAC_PI_4).abs() < 1e-12 && y == 0.0);
    // A fisheye images directions beyond 90° from the axis; a perspective lens does not.
    assert!(equidistant.distort(DVec3::new(1.0, 0.0, -0.2)).is_some());
    assert!(barrel.distort(DVec3::new(1.0, 0.0, -0.2)).is_none());
    let back = equidistant.undistort(2.0, 0.0).unwrap();
    assert!((back.normalize().x - 2f64.sin()).abs() < 1e-9 && back.z < 0.0);
    // Without distortion a lens is the pinhole: pixel rays are exactly those of `pinhole`.
    let pose = Pose::look_at(Vec3::new(1.0, 1.0, 1.0), Vec3::ZERO);
    let none = lens_k(Distortion::None);
    let pin = Intrinsics::pinhole(160, 120, 130.0, 128.0, 81.3, 58.7);
    assert_eq!(pixel_ray(&none, &pose, 17, 91), pixel_ray(&pin, &pose, 17, 91));
}

/// A lens whose model folds back on itself inside the image (strong barrel distortion on a wide
/// image: the radius stops growing) is refused, and so is a non-finite coefficient.
#[test]
fn a_lens_that_cannot_be_inverted_over_the_image_is_refused() {
    let k = lens_k(Distortion::None);
    let fold = Distortion::Radial { k: [-0.9, 0.0, 0.0, 0.0], p: [0.0, 0.0] };
    let e = fold.check(k.width, k.height, k.fx, k.fy, k.cx, k.cy).unwrap_err();
    assert!(e.contains("OPENCV") && e.contains("160x120"), "{e}");
    // The same lens on a narrow crop of the image is fine.
    assert!(fold.check(40, 30, 130.0, 128.0, 20.0, 15.0).is_ok());
    let nan = Distortion::Fisheye { k: [f32::NAN, 0.0, 0.0, 0.0] };
    assert!(nan.check(k.width, k.height, k.fx, k.fy, k.cx, k.cy).unwrap_err().contains("k1"));
    assert!(Distortion::Radial { k: [-0.1, 0.01, 0.0, 0.0], p: [0.001, 0.0] }
        .check(k.width, k.height, k.fx, k.fy, k.cx, k.cy)
        .is_ok());
}
