//! A pixel's footprint for training ([`super::trainer::TrainConfig::pixel_rays`]): a pixel's
//! colour is the light over its filter, not along its centre ray. Renderers and cameras both
//! blend a silhouette's colour into the pixels beside it — Cycles (the dev set) with a
//! Blackman–Harris filter 1.5 px wide, a camera with its pixel's area and its demosaicing —
//! while depth and masks are the centre's. Scored against one centre ray, that blend can only
//! be fitted by faint density on the ray, a halo around the object that threshold depth reports
//! as a pixel-wide rim. Scored against the mean of rays through the filter's footprint, the
//! object's edge crossing the footprint already explains it.
//!
//! Offsets are drawn per axis from the separable Blackman–Harris filter of width
//! [`FILTER_WIDTH`] (Cycles' default pixel filter), stratified: `K` rays take `K` strata of
//! each axis' cumulative distribution, paired by a random permutation (a Latin hypercube), so
//! their mean has little variance.

use crate::data::View;
use crate::geometry::camera::{image_ray, Ray};
use crate::rng::Rng;

/// Width of the training pixel filter in pixels (Cycles' default Blackman–Harris filter).
pub const FILTER_WIDTH: f32 = 1.5;

/// Blackman–Harris coefficients (four terms).
const BH: [f64; 4] = [0.35875, 0.48829, 0.14128, 0.01168];

/// The Blackman–Harris window's cumulative distribution at `s ∈ [0, 1]` (the window's
/// argument across its width), normalised to 1 at `s = 1`.
fn cdf(s: f64) -> f64 {
    use std::f64::consts::TAU;
    let [a0, a1, a2, a3] = BH;
    (a0 * s - a1 / TAU * (TAU * s).sin() + a2 / (2.0 * TAU) * (2.0 * TAU * s).sin()
        - a3 / (3.0 * TAU) * (3.0 * TAU * s).sin())
        / a0
}

/// The offset from the pixel centre (pixels) whose cumulative probability is `u ∈ [0, 1]`.
pub fn offset_at(u: f32) -> f32 {
    let u = u.clamp(0.0, 1.0) as f64;
    // The CDF is increasing on [0, 1]: bisection to well below a float's resolution.
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if cdf(mid) < u {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    ((0.5 * (lo + hi) - 0.5) * FILTER_WIDTH as f64) as f32
}

/// `k` stratified offsets `(dx, dy)` from a pixel's centre, drawn from the filter, into `out`
/// (its old contents replaced; the y strata are first laid out in it as the permutation).
pub fn offsets(k: usize, rng: &mut Rng, out: &mut Vec<(f32, f32)>) {
    // The Latin hypercube's pairing: x stratum i takes y stratum out[i].1.
    out.clear();
    out.extend((0..k).map(|i| (0.0, i as f32)));
    for i in (1..k).rev() {
        out.swap(i, rng.below(i as u64 + 1) as usize);
    }
    for (i, o) in out.iter_mut().enumerate() {
        let ux = (i as f32 + rng.uniform(0.0, 1.0)) / k as f32;
        let uy = (o.1 + rng.uniform(0.0, 1.0)) / k as f32;
        *o = (offset_at(ux), offset_at(uy));
    }
}

/// The ray through pixel `p` of `v` moved by `offset` pixels from its centre.
pub fn ray(v: &View, p: u32, offset: (f32, f32)) -> Ray {
    let w = v.intrinsics.width;
    let (x, y) = ((p % w) as f32 + 0.5 + offset.0, (p / w) as f32 + 0.5 + offset.1);
    image_ray(&v.intrinsics, &v.pose, x, y)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_filter_is_symmetric_and_spans_its_width() {
        assert!(offset_at(0.5).abs() < 1e-9);
        assert!((offset_at(0.0) + FILTER_WIDTH / 2.0).abs() < 1e-6);
        assert!((offset_at(1.0) - FILTER_WIDTH / 2.0).abs() < 1e-6);
        for u in [0.01f32, 0.1, 0.3, 0.45] {
            assert!((offset_at(u) + offset_at(1.0 - u)).abs() < 1e-5, "{u}");
            assert!(offset_at(u) < offset_at(u + 0.01));
        }
        // Most of the window's mass is within half a pixel of the centre.
        let inside = cdf((0.5 + 0.5 / FILTER_WIDTH) as f64) - cdf((0.5 - 0.5 / FILTER_WIDTH) as f64);
        assert!(inside > 0.9 && inside < 1.0, "{inside}");
    }

    #[test]
    fn stratified_offsets_take_one_stratum_of_each_axis() {
        let mut rng = Rng::new(3);
        for k in [1usize, 2, 4, 5] {
            let mut o = Vec::new();
            offsets(k, &mut rng, &mut o);
            for axis in 0..2 {
                let mut strata: Vec<usize> = o
                    .iter()
                    .map(|&(x, y)| {
                        let v = if axis == 0 { x } else { y };
                        ((cdf((v / FILTER_WIDTH + 0.5) as f64) * k as f64) as usize).min(k - 1)
                    })
                    .collect();
                strata.sort();
                assert_eq!(strata, (0..k).collect::<Vec<_>>(), "k = {k}, axis {axis}");
            }
        }
    }
}
