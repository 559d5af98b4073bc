//! Regularisers of a residual model's Mixnet β along one training ray (the background-aware
//! Residual-NeRF, docs/DECISIONS.md):
//!
//! - **β penalty on unchanged rays**: a ray whose pixel did not change (no change against the
//!   background, [`crate::train::prior`]) says that every point it sees is the background's, so
//!   `L_u = λ_u · Σ_i T_i δ_i β_i`, the visible length of the ray over which β is lit (scene
//!   units). Threshold depth fires on density far too faint to change a colour, so the
//!   photometric loss alone leaves such floaters in the change region; this term removes them
//!   wherever an unchanged view looks through.
//! - **β entropy**: `L_e = λ_e · Σ_i T_i δ_i H(β_i)`, `H(β) = −β ln β − (1−β) ln(1−β)`, pushes β
//!   to 0 or 1 so the raw density mix does not blend two surfaces' log-densities.
//!
//! `T_i = exp(−Σ_{j<i} σ_j δ_j)` is the transmittance in front of sample i, taken as a weight
//! (no gradient flows into σ through it: the terms must not reward density that hides β).
//! Both are per ray; the trainer averages them over the step's rays.

/// The weights of the β regularisers (0 turns a term off).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BetaRegulariser {
    /// λ_u of the β penalty on rays of unchanged pixels (per scene unit of visible ray).
    pub unchanged: f32,
    /// λ_e of the β entropy on every ray (per scene unit of visible ray).
    pub entropy: f32,
    /// Share of the run's steps after which the entropy term starts (training has settled).
    pub entropy_from: f32,
}

impl BetaRegulariser {
    /// Whether any term is on.
    pub fn is_on(&self) -> bool {
        self.unchanged > 0.0 || self.entropy > 0.0
    }
}

/// β is clamped into `[EPS, 1 − EPS]` inside the entropy's logarithms.
const EPS: f32 = 1e-6;

/// One ray's β terms: adds `dL/dβ_i` into `d_beta` and returns the ray's loss. `unchanged`
/// weights the penalty (λ_u, or 0 on a changed ray), `entropy` the entropy (λ_e, or 0).
pub fn beta_terms(sigma: &[f32], delta: &[f32], beta: &[f32], unchanged: f32, entropy: f32, d_beta: &mut [f32]) -> f32 {
    let n = sigma.len();
    assert!(delta.len() == n && beta.len() == n && d_beta.len() == n, "beta: sample arrays differ in length");
    let (mut log_t, mut loss) = (0.0f32, 0.0f32);
    for i in 0..n {
        let w = log_t.exp() * delta[i];
        let b = beta[i].clamp(EPS, 1.0 - EPS);
        let h = -(b * b.ln() + (1.0 - b) * (1.0 - b).ln());
        loss += w * (unchanged * beta[i] + entropy * h);
        d_beta[i] += w * (unchanged + entropy * ((1.0 - b) / b).ln());
        log_t -= sigma[i] * delta[i];
    }
    loss
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unchanged_ray_pays_for_visible_beta_only() {
        // Sample 1 is opaque: sample 2 behind it is not seen and costs nothing.
        let (sigma, delta, beta) = ([0.0, 1e4, 0.0], [0.1, 0.1, 0.1], [0.5, 0.25, 1.0]);
        let mut d = [0.0; 3];
        let loss = beta_terms(&sigma, &delta, &beta, 2.0, 0.0, &mut d);
        assert!((loss - 2.0 * 0.1 * (0.5 + 0.25)).abs() < 1e-6, "{loss}");
        assert!((d[0] - 0.2).abs() < 1e-6 && (d[1] - 0.2).abs() < 1e-6 && d[2].abs() < 1e-6, "{d:?}");
    }

    #[test]
    fn entropy_is_flat_at_a_half_and_zero_at_the_ends() {
        let mut d = [0.0; 3];
        let loss = beta_terms(&[0.0; 3], &[1.0; 3], &[0.5, 0.0, 1.0], 0.0, 1.0, &mut d);
        assert!((loss - std::f32::consts::LN_2).abs() < 1e-4, "{loss}");
        assert!(d[0].abs() < 1e-6, "{d:?}");
        assert!(d[1] > 0.0 && d[2] < 0.0 && d.iter().all(|x| x.is_finite()), "{d:?}");
    }
}
