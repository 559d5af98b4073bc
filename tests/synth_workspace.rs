//! The workspace synthesiser: glass appears only where the mask says, the background and
//! scene sets agree everywhere else, and a written dataset loads back through the ordinary
//! loader with the same poses, colours (to 8 bits), depth, masks and crops.

mod common;

use residual_nerf::data::workspace::{self, Glass, GLASS};
use residual_nerf::data::{Dataset, LoadOptions};
use std::path::Path;

/// Two renders of the same geometry: equal depth, NaN where either has no surface.
fn assert_same_depth(a: &[f32], b: &[f32]) {
    for (x, y) in a.iter().zip(b) {
        assert!(x == y || (x.is_nan() && y.is_nan()), "{x} against {y}");
    }
}

#[test]
fn glass_changes_only_the_masked_pixels_and_crops_hold_the_mask() {
    let t0 = std::time::Instant::now();
    let scene = workspace::workspace(64, 30, 0.0, true);
    eprintln!("64x64 x 30 views with glass: {:.2} s", t0.elapsed().as_secs_f64());
    let bg = workspace::workspace(64, 30, 0.0, false);
    let mut masked = 0;
    for i in 0..30 {
        let (s, b, m) = (&scene.views[i], &bg.views[i], &scene.masks[i]);
        assert_eq!(s.pose, b.pose);
        let c = scene.crops[i];
        let mut changed = 0;
        for p in 0..s.rgb.len() {
            let (x, y) = (p as u32 % 64, p as u32 / 64);
            if m[p] {
                masked += 1;
                assert!(x >= c[0] && x < c[2] && y >= c[1] && y < c[3], "view {i}: mask pixel outside the crop");
                changed += (s.rgb[p] != b.rgb[p]) as usize;
                // First hit is the glass: in front of what the background sees there.
                assert!(scene.depth[i][p] < bg.depth[i][p], "view {i}: glass depth not in front");
            } else {
                assert_eq!(s.rgb[p], b.rgb[p], "view {i}: pixel {p} outside the mask changed");
                assert_eq!(scene.depth[i][p].to_bits(), bg.depth[i][p].to_bits());
            }
        }
        let n_mask = m.iter().filter(|&&v| v).count();
        assert!(changed * 10 >= n_mask * 9, "view {i}: glass should look different from what is behind it");
        assert!(bg.masks[i].iter().all(|&v| !v) && bg.crops[i] == [0, 0, 64, 64]);
    }
    // The sphere (radius 0.16 m at 1.6 m, 50° FOV) covers a few hundred pixels per 64² view.
    assert!(masked > 30 * 150, "glass too small: {masked} masked pixels");
    assert!(GLASS.1 > 0.0);
}

#[test]
fn written_dataset_loads_back() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("synth_workspace");
    let _ = std::fs::remove_dir_all(&dir);
    let scene = workspace::workspace(24, 4, 0.3, true);
    scene.write_split(&dir, "test").unwrap();
    let d = Dataset::load(&dir, "test", &LoadOptions::default()).unwrap();
    assert_eq!(d.aabb, scene.aabb);
    for (i, (v, f)) in d.views.iter().zip(&d.frames).enumerate() {
        let want = &scene.views[i];
        assert!((v.pose.translation - want.pose.translation).length() < 1e-5);
        assert!((v.intrinsics.fx - want.intrinsics.fx).abs() < 1e-3);
        for (a, b) in v.rgb.iter().zip(&want.rgb) {
            for c in 0..3 {
                assert!((a[c] - b[c].clamp(0.0, 1.0)).abs() <= 0.5 / 255.0 + 1e-6);
            }
        }
        let z = f.depth.as_ref().unwrap();
        for (a, b) in z.iter().zip(&scene.depth[i]) {
            assert!((a.is_nan() && !b.is_finite()) || a == b);
        }
        assert_eq!(f.mask.as_ref().unwrap(), &scene.masks[i]);
        assert_eq!(f.crop, Some(scene.crops[i]));
    }
}

/// The tall glass stands higher than the sphere: in every view its mask is seen, and its
/// crop reaches higher in the image (cameras look down at the table from 25°–65°) than the
/// sphere's, into what is empty air in the background.
#[test]
fn the_tall_glass_rises_above_the_sphere() {
    let sphere = workspace::workspace_with(32, 6, 0.0, Glass::Sphere);
    let tall = workspace::workspace_with(32, 6, 0.0, Glass::Tall);
    let empty = workspace::workspace_with(32, 6, 0.0, Glass::None);
    for v in 0..6 {
        assert!(tall.masks[v].iter().any(|&m| m), "view {v}: the tall glass is not seen");
        assert!(empty.masks[v].iter().all(|&m| !m), "view {v}: glass in the empty workspace");
        assert!(tall.crops[v][1] < sphere.crops[v][1], "view {v}: {:?} vs {:?}", tall.crops[v], sphere.crops[v]);
    }
}

/// The amber cylinder has the clear one's geometry (same masks and depth) and darkens what is
/// seen through it, blue most (its tint keeps 0.15 of blue per pass, twice through a cylinder).
#[test]
fn amber_glass_is_the_tall_glass_darkened() {
    let clear = workspace::workspace_with(32, 4, 0.0, Glass::Tall);
    let amber = workspace::workspace_with(32, 4, 0.0, Glass::TallAmber);
    assert_eq!(clear.masks, amber.masks);
    for v in 0..4 {
        let on_mask = |s: &residual_nerf::data::synth::SynthScene, c: usize| -> f32 {
            let px: Vec<f32> = (0..s.masks[v].len()).filter(|&p| s.masks[v][p]).map(|p| s.views[v].rgb[p][c]).collect();
            px.iter().sum::<f32>() / px.len() as f32
        };
        assert_same_depth(&clear.depth[v], &amber.depth[v]);
        let (blue_clear, blue_amber) = (on_mask(&clear, 2), on_mask(&amber, 2));
        let (red_clear, red_amber) = (on_mask(&clear, 0), on_mask(&amber, 0));
        assert!(blue_amber < 0.5 * blue_clear, "view {v}: blue {blue_amber} against {blue_clear}");
        assert!(
            red_amber < red_clear && red_amber / red_clear > blue_amber / blue_clear,
            "view {v}: red {red_amber} against {red_clear}"
        );
    }
}

/// Exposure jitter: each view's colours are the plain capture's through a gain per channel
/// within 1 ± spread (the dark pixels, far from saturation, show it), different from view to view;
/// depth and masks are the plain capture's.
#[test]
fn exposure_jitter_gives_each_view_its_own_gain() {
    use residual_nerf::data::workspace::Capture;
    let plain = workspace::workspace_capture(32, 4, 0.0, Glass::Sphere, &Capture::default());
    let jitter = Capture { gain_jitter: Some((0.15, 5)), ..Default::default() };
    let shot = workspace::workspace_capture(32, 4, 0.0, Glass::Sphere, &jitter);
    assert_eq!(plain.masks, shot.masks);
    let mut gains = Vec::new();
    for v in 0..4 {
        assert_same_depth(&plain.depth[v], &shot.depth[v]);
        let g = common::observed_gain(&plain.views[v].rgb, &shot.views[v].rgb).map(|g| g as f32);
        assert!(g.iter().all(|g| (0.85 - 1e-4..=1.15 + 1e-4).contains(g)), "view {v}: gain {g:?}");
        gains.push(g);
    }
    assert!(gains.windows(2).all(|w| w[0] != w[1]), "views share a gain: {gains:?}");
}

/// A capture through a lens (OpenCV's radial-tangential model, and a fisheye) written in the
/// dataset layout loads back with the same lens and the same rays; the lens bends the rays
/// (an image corner's ray differs from the pinhole's).
#[test]
fn a_distorted_capture_loads_back_with_its_lens() {
    use residual_nerf::data::workspace::Capture;
    use residual_nerf::geometry::{pixel_ray, Distortion};
    for (name, d) in [
        ("radial", Distortion::Radial { k: [-0.12, 0.03, 0.0, 0.0], p: [0.002, -0.001] }),
        ("fisheye", Distortion::Fisheye { k: [0.05, -0.01, 0.0, 0.0] }),
    ] {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("synth_workspace_lens").join(name);
        let _ = std::fs::remove_dir_all(&dir);
        let capture = Capture { distortion: d, ..Default::default() };
        let scene = workspace::workspace_capture(24, 3, 0.3, Glass::Sphere, &capture);
        scene.write_split(&dir, "train").unwrap();
        let loaded = Dataset::load(&dir, "train", &LoadOptions::default()).unwrap();
        for (a, b) in loaded.views.iter().zip(&scene.views) {
            assert_eq!(a.intrinsics, b.intrinsics, "{name}");
            for (i, j) in [(0, 0), (23, 11), (12, 12)] {
                assert_eq!(pixel_ray(&a.intrinsics, &a.pose, i, j), pixel_ray(&b.intrinsics, &b.pose, i, j));
            }
            let pin = residual_nerf::geometry::Intrinsics { distortion: Distortion::None, ..a.intrinsics };
            let bend = pixel_ray(&a.intrinsics, &a.pose, 0, 0).dir.angle_between(pixel_ray(&pin, &a.pose, 0, 0).dir);
            assert!(bend > 1e-3, "{name}: the corner ray is not bent ({bend} rad)");
        }
    }
}

/// Scenes of 1 to 4 small glass spheres (the update-cost scenes): each added sphere keeps every
/// glass pixel of the scene before it (a pixel whose first hit was glass still hits glass) and
/// adds new ones, and wherever a scene has no glass its depth is the empty workspace's.
#[test]
fn each_added_sphere_adds_glass_and_changes_nothing_else() {
    let empty = workspace::workspace_with(48, 6, 0.0, Glass::None);
    let scenes: Vec<_> = (1..=4).map(|n| workspace::workspace_with(48, 6, 0.0, Glass::Spheres(n))).collect();
    let glass = |s: &residual_nerf::data::synth::SynthScene| s.masks.iter().flatten().filter(|&&m| m).count();
    assert!(glass(&scenes[0]) > 0, "one sphere: no glass seen");
    for (n, pair) in scenes.windows(2).enumerate() {
        for v in 0..6 {
            for (p, (&before, &after)) in pair[0].masks[v].iter().zip(&pair[1].masks[v]).enumerate() {
                assert!(!before || after, "{} spheres, view {v}, pixel {p}: glass lost when a sphere is added", n + 1);
            }
        }
        assert!(glass(&pair[1]) > glass(&pair[0]), "sphere {} adds no glass pixel", n + 2);
    }
    for s in &scenes {
        for v in 0..6 {
            let keep = |z: &[f32]| -> Vec<f32> {
                z.iter().zip(&s.masks[v]).map(|(&z, &m)| if m { f32::NAN } else { z }).collect()
            };
            assert_same_depth(&keep(&s.depth[v]), &keep(&empty.depth[v]));
        }
    }
}
