//! The distortion loss of mip-NeRF 360 (Barron et al. 2022, Eq. 15) along one ray, forward and
//! backward to the densities: it pulls each ray's weights together, which removes the
//! spread-out "fog" and floaters a NeRF otherwise keeps when trained for a few thousand steps
//! (DESIGN §2.2 leaves regularisation open; docs/DECISIONS.md records the choice).
//!
//! With sample midpoints `m_i` (= `t_i`), steps `δ_i` and weights `w_i` (compositing, Eq. 2):
//! `L = Σ_{i,j} w_i w_j |m_i − m_j| + ⅓ Σ_i w_i² δ_i`, in the scene's distance units.
//! `∂L/∂w_i = g_i = 2 Σ_j w_j |m_i − m_j| + ⅔ w_i δ_i`, computed in O(n) from prefix sums of
//! `w` and `w·m` (samples are sorted by `t`). Through compositing (see [`super::composite`]):
//! `∂L/∂σ_k = δ_k (g_k T_{k+1} − Σ_{i>k} g_i w_i)`.

use super::composite::EARLY_STOP_TRANSMITTANCE;

/// Adds `scale · ∂L/∂σ_i` of the distortion loss to `d_sigma` and returns `L` (samples after
/// the early stop, as in compositing, carry no weight). `scratch` is reused between rays.
pub fn distortion_backward(
    sigma: &[f32],
    delta: &[f32],
    t: &[f32],
    scale: f32,
    d_sigma: &mut [f32],
    scratch: &mut Vec<f32>,
) -> f32 {
    let n = sigma.len();
    assert!(delta.len() == n && t.len() == n && d_sigma.len() == n, "distortion: sample arrays differ in length");
    // Weights and the transmittance after each sample.
    scratch.clear();
    scratch.resize(3 * n, 0.0);
    let (w, rest) = scratch.split_at_mut(n);
    let (t_next, g) = rest.split_at_mut(n);
    let mut trans = 1.0f32;
    let mut used = n;
    for i in 0..n {
        if trans < EARLY_STOP_TRANSMITTANCE {
            used = i;
            break;
        }
        let keep = (-sigma[i] * delta[i]).exp();
        w[i] = trans * (1.0 - keep);
        trans *= keep;
        t_next[i] = trans;
    }
    let (w_tot, wm_tot) = (0..used).fold((0.0f64, 0.0f64), |(a, b), i| (a + w[i] as f64, b + (w[i] * t[i]) as f64));
    // g_i and the loss, with running prefix sums (f64: the sums are differences of large terms).
    let (mut w_pre, mut wm_pre) = (0.0f64, 0.0f64);
    let mut loss = 0.0f64;
    let mut gw_tot = 0.0f64;
    for i in 0..used {
        let (wi, mi) = (w[i] as f64, t[i] as f64);
        let w_post = w_tot - w_pre - wi;
        let wm_post = wm_tot - wm_pre - wi * mi;
        let spread = mi * w_pre - wm_pre + wm_post - mi * w_post;
        let gi = 2.0 * spread + 2.0 / 3.0 * wi * delta[i] as f64;
        loss += wi * spread + wi * wi * delta[i] as f64 / 3.0;
        g[i] = gi as f32;
        gw_tot += gi * wi;
        w_pre += wi;
        wm_pre += wi * mi;
    }
    // ∂L/∂σ_k = δ_k (g_k T_{k+1} − Σ_{i>k} g_i w_i).
    let mut gw_pre = 0.0f64;
    for k in 0..used {
        gw_pre += g[k] as f64 * w[k] as f64;
        let suffix = gw_tot - gw_pre;
        d_sigma[k] += scale * delta[k] * (g[k] * t_next[k] - suffix as f32);
    }
    loss as f32
}
