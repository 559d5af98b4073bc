//! Depth extraction on analytic scenes with known answers.

mod common;

use common::cases;
use glam::Vec3;
use proptest::prelude::*;
use residual_nerf::render::{composite_ray, expected_depth, threshold_depth, DensityThreshold, Ray};

/// Uniform samples t_i = t0 + (i + ½)δ of a density field along a ray: (t, δ, raw s = ln σ).
fn march(ray: &Ray, t0: f32, t1: f32, n: usize, sigma: impl Fn(Vec3) -> f32) -> (Vec<f32>, Vec<f32>, Vec<f32>) {
    let d = (t1 - t0) / n as f32;
    let t: Vec<f32> = (0..n).map(|i| t0 + (i as f32 + 0.5) * d).collect();
    let raw = t.iter().map(|&ti| sigma(ray.at(ti)).max(1e-30).ln()).collect();
    (t, vec![d; n], raw)
}

proptest! {
    #![proptest_config(cases(64))]

    /// An opaque sphere (σ = 1e4 inside): the threshold depth of a ray that hits it is the
    /// analytic entry distance b − √(b² − |o−c|² + R²), to within one step; a ray that misses is
    /// a hole. Expected depth agrees too, since the surface is opaque.
    #[test]
    fn opaque_sphere_threshold_depth(dx in -0.6f32..0.6, dy in -0.6f32..0.6, r in 0.2f32..0.8) {
        let centre = Vec3::new(0.0, 0.0, -3.0);
        let ray = Ray { origin: Vec3::ZERO, dir: Vec3::new(dx, dy, -1.0).normalize(), z_per_t: 1.0 };
        let inside = |p: Vec3| if (p - centre).length() < r { 1e4 } else { 0.0 };
        let n = 2000;
        let (t, delta, raw) = march(&ray, 0.0, 6.0, n, inside);
        let b = ray.dir.dot(centre - ray.origin);
        let disc = b * b - ((ray.origin - centre).length_squared() - r * r);
        let got = threshold_depth(&t, &raw, DensityThreshold::Sigma(3.0));
        if disc > 1e-3 {
            let want = b - disc.sqrt();
            let hit = got.expect("a ray through the sphere must hit it");
            // One step, plus f32 rounding: a sample a hair inside the surface can test as outside
            // (found at dx = 0.029367818, dy = -0.150156, r = 0.57732743: 3.0012e-3 past it).
            prop_assert!((hit - want).abs() <= 6.0 / n as f32 + 1e-5, "{} vs {}", hit, want);
            let c = composite_ray(&raw.iter().map(|s| s.exp()).collect::<Vec<_>>(), &delta, &t, &vec![[0.5; 3]; n], [0.0; 3]);
            prop_assert!((expected_depth(&c) - want).abs() <= 6.0 / n as f32 + 1e-3, "{} vs {}", expected_depth(&c), want);
        } else if disc < -1e-3 {
            prop_assert_eq!(got, None);
        }
    }
}

/// The two threshold spaces: σ ≥ m compares e^s with m; Raw compares s itself (authors' s > 3).
#[test]
fn threshold_units() {
    let t = [1.0, 2.0, 3.0];
    let raw = [2.0, 3.5, 10.0]; // σ = e^2 ≈ 7.4, e^3.5 ≈ 33, e^10
    assert_eq!(threshold_depth(&t, &raw, DensityThreshold::Sigma(3.0)), Some(1.0));
    assert_eq!(threshold_depth(&t, &raw, DensityThreshold::Sigma(20.0)), Some(2.0));
    assert_eq!(threshold_depth(&t, &raw, DensityThreshold::Raw(3.0)), Some(2.0));
    assert_eq!(threshold_depth(&t, &raw, DensityThreshold::Raw(11.0)), None);
    assert_eq!(threshold_depth(&[], &[], DensityThreshold::Sigma(3.0)), None);
}

/// Renderers compare σ against `min_sigma` instead of taking logs: the same verdict as
/// `is_hit` on the raw value, away from exact ties.
#[test]
fn min_sigma_agrees_with_the_raw_test() {
    for th in [
        DensityThreshold::Sigma(3.0),
        DensityThreshold::Sigma(0.0),
        DensityThreshold::Raw(3.0),
        DensityThreshold::Raw(-1.0),
    ] {
        for s in [-20.0f32, -1.5, 0.0, 1.0, 1.0986, 1.1, 2.9, 3.1, 10.0] {
            assert_eq!(s.exp() >= th.min_sigma(), th.is_hit(s), "{th:?} at s = {s}");
        }
    }
}
