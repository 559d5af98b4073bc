//! Per-image appearance gains learned with the field: NeRF-W's appearance codes reduced to
//! three numbers, for captures whose auto-exposure and white balance move from shot to shot.
//!
//! Training image `v` is modelled as `g_v ⊙ C`, where `C` is the ray's composited colour
//! (Eq. 2, background term included) and `g_v = exp(a_v)` a per-channel gain. The field then
//! learns one appearance for the whole capture instead of memorising each image's exposure
//! through its view-dependent colour (and floaters in front of the cameras). With
//! `e = g_v ⊙ C − target` and the step's loss `Σ e² / 3N` (N rays), the ray's contribution to
//! the gradients is `∂/∂C = (2/3N)·g_v ⊙ e` and `∂/∂a_v = (2/3N)·e ⊙ g_v ⊙ C`.
//!
//! - **Identity prior**: `λ · (1/V) Σ_v ‖a_v‖²` (V images) added to the loss, through Adam's L2
//!   term (`l2 = 2λ/V`): an image whose rays are rare stays near the identity.
//! - **Gauge**: a gain common to all images and a field colour scaled by its inverse give the
//!   same images, so after every step each channel's log-gains are re-centred on 0 (the gains'
//!   geometric mean over the capture is 1): the field renders the capture's mean appearance,
//!   which is what rendering and evaluation show (they apply no gain).
//! - The gains are optimised with the field by their own Adam at the field's learning rate and
//!   schedule; a step skipped for a non-finite value leaves them as they were.

use super::{Adam, AdamConfig};
use crate::simd::Isa;

/// Default weight λ of the identity prior ([`crate::train::trainer::TrainConfig::image_gains`]):
/// weak next to the photometric loss. Derived, not measured: at equilibrium the prior's pull
/// `2λ·a` balances the data's `(2/3)·E[C²]·(a* − a)`, so on a 0.5-grey image a log-gain is
/// shrunk by the factor `0.167 / (0.167 + 2λ)` ≈ 0.988 (a true gain of 1.15 would settle near
/// 1.148). `tests/image_gains.rs` measures the whole effect: slope 0.94 of learned on true.
pub const GAIN_PRIOR: f32 = 1e-3;

/// The learned log-gains of a run's training images and their optimiser.
#[derive(Clone, Debug)]
pub struct ImageGains {
    /// `a_v` per training image (channel order r, g, b); the gain is `exp(a_v)`.
    pub log_gains: Vec<[f32; 3]>,
    /// Adam over the flattened log-gains.
    pub adam: Adam,
}

impl ImageGains {
    /// Identity gains for `views` images, with prior weight `prior` (λ).
    pub fn new(views: usize, prior: f32) -> ImageGains {
        ImageGains { log_gains: vec![[0.0; 3]; views], adam: Adam::new(3 * views, Self::adam_config(views, prior)) }
    }

    /// Adam's settings for `views` images at prior weight `prior`: the prior as its L2 term.
    pub fn adam_config(views: usize, prior: f32) -> AdamConfig {
        AdamConfig { l2: 2.0 * prior / views.max(1) as f32, ..Default::default() }
    }

    /// The gains `exp(a_v)`.
    pub fn gains(&self) -> Vec<[f32; 3]> {
        self.log_gains.iter().map(|a| a.map(f32::exp)).collect()
    }

    /// One optimiser step on the log-gains with their gradient `grads` (one per image), then
    /// the re-centring of each channel on 0.
    pub fn step(&mut self, isa: Isa, lr: f32, grads: &[[f32; 3]]) {
        let params: &mut [f32] = bytemuck::cast_slice_mut(&mut self.log_gains);
        self.adam.step(isa, lr, params, bytemuck::cast_slice(grads), None);
        let n = self.log_gains.len().max(1) as f64;
        for c in 0..3 {
            let mean = (self.log_gains.iter().map(|a| a[c] as f64).sum::<f64>() / n) as f32;
            for a in &mut self.log_gains {
                a[c] -= mean;
            }
        }
    }
}

/// One ray's colour error under gain `gain` and its gradients: returns `e = gain ⊙ c − target`
/// and adds `scale · e ⊙ gain ⊙ c` to `d_log_gain`; `scale · gain ⊙ e` is the gradient
/// compositing takes for `c`.
#[inline]
pub fn gained_error(
    c: [f32; 3],
    target: [f32; 3],
    gain: [f32; 3],
    scale: f32,
    d_log_gain: &mut [f32; 3],
) -> ([f32; 3], [f32; 3]) {
    let mut err = [0.0; 3];
    let mut d_c = [0.0; 3];
    for i in 0..3 {
        let pred = gain[i] * c[i];
        err[i] = pred - target[i];
        d_log_gain[i] += scale * err[i] * pred;
        d_c[i] = scale * err[i] * gain[i];
    }
    (err, d_c)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The ray's gradients against f64 central differences of `Σ e²·scale/2`.
    #[test]
    fn gained_error_gradients_match_finite_differences() {
        let (c, target, a, scale) = ([0.3f32, 0.6, 0.9], [0.4f32, 0.5, 0.7], [0.1f32, -0.2, 0.05], 0.7f32);
        let gain = a.map(f32::exp);
        let mut d_a = [0.0; 3];
        let (_, d_c) = gained_error(c, target, gain, scale, &mut d_a);
        let loss = |c: [f64; 3], a: [f64; 3]| -> f64 {
            (0..3).map(|i| (a[i].exp() * c[i] - target[i] as f64).powi(2)).sum::<f64>() * scale as f64 / 2.0
        };
        let (c64, a64) = (c.map(|v| v as f64), a.map(|v| v as f64));
        let h = 1e-6;
        for i in 0..3 {
            let bump = |x: [f64; 3], d: f64| {
                let mut y = x;
                y[i] += d;
                y
            };
            let dc = (loss(bump(c64, h), a64) - loss(bump(c64, -h), a64)) / (2.0 * h);
            let da = (loss(c64, bump(a64, h)) - loss(c64, bump(a64, -h))) / (2.0 * h);
            assert!((dc - d_c[i] as f64).abs() < 1e-5, "dC[{i}] {dc} vs {}", d_c[i]);
            assert!((da - d_a[i] as f64).abs() < 1e-5, "da[{i}] {da} vs {}", d_a[i]);
        }
    }

    /// A step keeps each channel's log-gains centred on 0.
    #[test]
    fn a_step_keeps_the_gains_geometric_mean_at_one() {
        let mut g = ImageGains::new(4, GAIN_PRIOR);
        let grads = [[1.0, -2.0, 0.5], [0.3, 0.1, -0.4], [-0.2, 0.0, 0.9], [0.0, 0.7, 0.1]];
        for _ in 0..5 {
            g.step(Isa::scalar(), 1e-2, &grads);
        }
        for c in 0..3 {
            let s: f32 = g.log_gains.iter().map(|a| a[c]).sum();
            assert!(s.abs() < 1e-6, "channel {c} sums to {s}");
        }
        assert!(g.log_gains[0][0] < 0.0 && g.log_gains[0][1] > 0.0, "the gains follow their gradients");
    }
}
