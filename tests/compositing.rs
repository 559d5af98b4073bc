//! Compositing (paper Eq. 2): identities, analytic cases, and the backward against f64
//! central finite differences.

mod common;

use common::cases;
use proptest::prelude::*;
use residual_nerf::render::distortion::distortion_backward;
use residual_nerf::render::{composite_ray, composite_ray_backward, weights_from_density, EARLY_STOP_TRANSMITTANCE};

/// A ray whose optical depth stays below 8, so T never reaches the early stop.
fn ray(max_n: usize) -> impl Strategy<Value = (Vec<f32>, Vec<f32>, Vec<f32>, Vec<[f32; 3]>)> {
    (0..=max_n)
        .prop_flat_map(|n| {
            (
                prop::collection::vec(0.0f32..20.0, n),
                prop::collection::vec(0.001f32..0.05, n),
                prop::collection::vec(prop::array::uniform3(0.0f32..1.0), n),
            )
        })
        .prop_filter("optical depth < 8", |(s, d, _)| s.iter().zip(d).map(|(a, b)| a * b).sum::<f32>() < 8.0)
        .prop_map(|(s, d, c)| {
            let mut t = Vec::with_capacity(d.len());
            let mut acc = 0.5;
            for &di in &d {
                t.push(acc + 0.5 * di);
                acc += di;
            }
            (s, d, t, c)
        })
}

/// f64 forward: C = Σ w_i c_i + T c_bg (no early stop: the strategies keep T > 1e-4).
fn composite_f64(sigma: &[f64], delta: &[f32], rgb: &[[f64; 3]], bg: [f32; 3]) -> [f64; 3] {
    let mut trans = 1.0f64;
    let mut c = [0f64; 3];
    for i in 0..sigma.len() {
        let keep = (-sigma[i] * delta[i] as f64).exp();
        for k in 0..3 {
            c[k] += trans * (1.0 - keep) * rgb[i][k];
        }
        trans *= keep;
    }
    for k in 0..3 {
        c[k] += trans * bg[k] as f64;
    }
    c
}

/// f64 distortion loss straight from its definition (O(n²)).
fn distortion_f64(sigma: &[f64], delta: &[f32], t: &[f32]) -> f64 {
    let mut trans = 1.0f64;
    let mut w = Vec::new();
    for i in 0..sigma.len() {
        let keep = (-sigma[i] * delta[i] as f64).exp();
        w.push(trans * (1.0 - keep));
        trans *= keep;
    }
    let mut l = 0.0;
    for i in 0..w.len() {
        for j in 0..w.len() {
            l += w[i] * w[j] * (t[i] as f64 - t[j] as f64).abs();
        }
        l += w[i] * w[i] * delta[i] as f64 / 3.0;
    }
    l
}

proptest! {
    #![proptest_config(cases(64))]

    /// The distortion loss and its ∂L/∂σ against the f64 definition and central differences;
    /// the gradient is added to what `d_sigma` held.
    #[test]
    fn distortion_matches_its_definition_and_finite_differences((s, d, t, _c) in ray(24), scale in 0.1f32..3.0) {
        let mut ds = vec![0.25; s.len()];
        let mut scratch = Vec::new();
        let l = distortion_backward(&s, &d, &t, scale, &mut ds, &mut scratch);
        let s64: Vec<f64> = s.iter().map(|&v| v as f64).collect();
        let want = distortion_f64(&s64, &d, &t);
        prop_assert!((l as f64 - want).abs() < 1e-5 + 1e-4 * want.abs(), "L {} vs {}", l, want);
        let h = 1e-6;
        for k in 0..s.len() {
            let (mut up, mut dn) = (s64.clone(), s64.clone());
            up[k] += h;
            dn[k] -= h;
            let fd = scale as f64 * (distortion_f64(&up, &d, &t) - distortion_f64(&dn, &d, &t)) / (2.0 * h);
            let got = ds[k] as f64 - 0.25;
            prop_assert!((got - fd).abs() < 1e-4 + 1e-3 * fd.abs(), "dσ[{}]: {} vs {}", k, got, fd);
        }
    }

    /// Σw + T_final = 1, w ≥ 0, T non-increasing, opacity = 1 − T; empty rays included.
    #[test]
    fn weights_and_transmittance_identities((s, d, t, c) in ray(64), bg in prop::array::uniform3(0.0f32..1.0)) {
        let mut w = vec![0.0; s.len()];
        let (t_final, used) = weights_from_density(&s, &d, &mut w);
        prop_assert_eq!(used, s.len());
        prop_assert!(w.iter().all(|&x| x >= 0.0));
        prop_assert!((w.iter().sum::<f32>() + t_final - 1.0).abs() < 1e-5);
        let mut trans = 1.0f32;
        for (&si, &di) in s.iter().zip(&d) {
            let next = trans * (-si * di).exp();
            prop_assert!(next <= trans);
            trans = next;
        }
        let r = composite_ray(&s, &d, &t, &c, bg);
        prop_assert!((r.opacity + r.transmittance - 1.0).abs() < 1e-5);
        prop_assert!((r.transmittance - t_final).abs() < 1e-6);
        if s.is_empty() {
            prop_assert_eq!(r.rgb, bg);
            prop_assert_eq!((r.opacity, r.depth, r.transmittance, r.samples_used), (0.0, 0.0, 1.0, 0));
        }
    }

    /// Compositing a ray in two chunks equals compositing it whole:
    /// C = C_a(no background) + T_a · C_b(with background), T = T_a · T_b.
    #[test]
    fn two_chunks_equal_the_whole((s, d, t, c) in ray(48), split in 0usize..48, bg in prop::array::uniform3(0.0f32..1.0)) {
        let k = split.min(s.len());
        let whole = composite_ray(&s, &d, &t, &c, bg);
        let a = composite_ray(&s[..k], &d[..k], &t[..k], &c[..k], [0.0; 3]);
        let b = composite_ray(&s[k..], &d[k..], &t[k..], &c[k..], bg);
        for ch in 0..3 {
            prop_assert!((whole.rgb[ch] - (a.rgb[ch] + a.transmittance * b.rgb[ch])).abs() < 1e-5);
        }
        prop_assert!((whole.transmittance - a.transmittance * b.transmittance).abs() < 1e-6);
        prop_assert!((whole.depth - (a.depth + a.transmittance * b.depth)).abs() < 1e-4);
    }

    /// A constant-density slab of length L has transmittance e^{−σL}, however it is sampled.
    #[test]
    fn slab_transmittance_is_exponential(sigma in 0.0f32..8.0, len in 0.01f32..1.0, n in 1usize..200) {
        let d = vec![len / n as f32; n];
        let s = vec![sigma; n];
        let t: Vec<f32> = (0..n).map(|i| (i as f32 + 0.5) * len / n as f32).collect();
        let r = composite_ray(&s, &d, &t, &vec![[1.0, 0.5, 0.0]; n], [0.0; 3]);
        let want = (-(sigma as f64) * len as f64).exp();
        prop_assert!((r.transmittance as f64 - want).abs() < 2e-5 * (1.0 + n as f64 / 50.0), "{} vs {}", r.transmittance, want);
        // A uniform-colour slab composites to (1 − T) times its colour.
        prop_assert!((r.rgb[1] as f64 - 0.5 * (1.0 - want)).abs() < 1e-4);
    }

    /// ∂L/∂σ_k and ∂L/∂c_k (L = g·C) against central differences of the f64 forward.
    #[test]
    fn backward_matches_finite_differences((s, d, t, c) in ray(24), g in prop::array::uniform3(-1.0f32..1.0), bg in prop::array::uniform3(0.0f32..1.0)) {
        let fwd = composite_ray(&s, &d, &t, &c, bg);
        let mut ds = vec![0.0; s.len()];
        let mut dc = vec![[0.0; 3]; s.len()];
        composite_ray_backward(&s, &d, &c, &fwd, g, &mut ds, &mut dc);
        let s64: Vec<f64> = s.iter().map(|&v| v as f64).collect();
        let c64: Vec<[f64; 3]> = c.iter().map(|v| v.map(|x| x as f64)).collect();
        let loss = |s: &[f64], c: &[[f64; 3]]| composite_f64(s, &d, c, bg).iter().zip(&g).map(|(a, b)| a * *b as f64).sum::<f64>();
        let h = 1e-6;
        for k in 0..s.len() {
            let (mut up, mut dn) = (s64.clone(), s64.clone());
            up[k] += h;
            dn[k] -= h;
            let fd = (loss(&up, &c64) - loss(&dn, &c64)) / (2.0 * h);
            prop_assert!((ds[k] as f64 - fd).abs() < 1e-4 + 1e-3 * fd.abs(), "dσ[{}]: {} vs {}", k, ds[k], fd);
            for ch in 0..3 {
                let (mut up, mut dn) = (c64.clone(), c64.clone());
                up[k][ch] += h;
                dn[k][ch] -= h;
                let fd = (loss(&s64, &up) - loss(&s64, &dn)) / (2.0 * h);
                prop_assert!((dc[k][ch] as f64 - fd).abs() < 1e-5 + 1e-3 * fd.abs(), "dc[{}][{}]: {} vs {}", k, ch, dc[k][ch], fd);
            }
        }
    }
}

/// Concentrating the same opacity in one sample lowers the distortion loss; one sample alone
/// costs exactly w²δ/3.
#[test]
fn distortion_prefers_compact_weights() {
    let mut scratch = Vec::new();
    let (d, t) = (vec![0.1f32; 10], (0..10).map(|i| 1.0 + 0.1 * i as f32).collect::<Vec<_>>());
    let mut sink = vec![0.0; 10];
    let spread = distortion_backward(&[1.0; 10], &d, &t, 1.0, &mut sink, &mut scratch);
    let mut compact = vec![0.0f32; 10];
    compact[4] = 10.0; // the same optical depth (1.0) in one sample
    let one = distortion_backward(&compact, &d, &t, 1.0, &mut sink, &mut scratch);
    let w = 1.0 - (-1.0f32).exp();
    assert!((one - w * w * 0.1 / 3.0).abs() < 1e-6, "{one}");
    assert!(one < spread / 5.0, "compact {one} vs spread {spread}");
}

/// The worked example of the module docs.
#[test]
fn worked_example() {
    let ln2 = std::f32::consts::LN_2;
    let r = composite_ray(&[ln2, ln2], &[1.0, 1.0], &[1.0, 2.0], &[[1.0; 3], [0.0; 3]], [0.0; 3]);
    assert!((r.rgb[0] - 0.5).abs() < 1e-6 && (r.transmittance - 0.25).abs() < 1e-6);
    assert!((r.depth - (0.5 * 1.0 + 0.25 * 2.0)).abs() < 1e-6);
}

/// Marching stops once T < 1e-4: later samples get no weight and no gradient.
#[test]
fn early_stop() {
    let n = 10;
    let s = vec![50.0; n];
    let d = vec![0.1; n]; // T = e^{−5k}: below 1e-4 after 2 samples
    let t: Vec<f32> = (0..n).map(|i| i as f32 * 0.1).collect();
    let c = vec![[0.3, 0.6, 0.9]; n];
    let r = composite_ray(&s, &d, &t, &c, [1.0; 3]);
    assert_eq!(r.samples_used, 2);
    assert!(r.transmittance < EARLY_STOP_TRANSMITTANCE);
    let mut w = vec![1.0; n];
    assert_eq!(weights_from_density(&s, &d, &mut w).1, 2);
    assert!(w[2..].iter().all(|&x| x == 0.0));
    let (mut ds, mut dc) = (vec![1.0; n], vec![[1.0; 3]; n]);
    composite_ray_backward(&s, &d, &c, &r, [1.0; 3], &mut ds, &mut dc);
    assert!(ds[2..].iter().all(|&x| x == 0.0) && dc[2..].iter().all(|x| *x == [0.0; 3]));
}
