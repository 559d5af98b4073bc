//! Residual-NeRF's per-sample mix (paper Eqs. 5–6, DESIGN §2.3), forward and backward, as
//! pure functions of one sample's pre-activation values — the piece the residual field and
//! its tests share.
//!
//! Inputs: the frozen background's raw density `s_bg` and pre-sigmoid colour `c′_bg`, the
//! residual's `s_res`, `c′_res`, and the Mixnet's logit `m` (β = sigmoid(m)).
//! - colour (both mixnet variants): `c = sigmoid((1−β)·c′_bg + β·c′_res)`;
//! - density [`DensityMix::Activated`] (paper Eq. 5): `σ = (1−β)·e^{s_bg} + β·e^{s_res}`;
//! - density [`DensityMix::Raw`] (authors' code): `σ = e^{(1−β)·s_bg + β·s_res}`;
//! - [`MixKind::Sum`] (Residual-NeRF-S, Eq. 6): `σ = e^{s_bg} + e^{s_res}`,
//!   `c = sigmoid(c′_bg + c′_res)` (no β).
//!
//! `e^x` is trunc_exp: its derivative is `e^{clamp(x, −15, 15)}` (DESIGN §2.1). The background
//! receives no gradient: backward returns derivatives for the residual and the Mixnet only.

use crate::mlp::Activation;

/// How the two densities combine under a Mixnet.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DensityMix {
    /// `σ = (1−β)σ_bg + βσ_res` (paper Eq. 5 as written).
    Activated,
    /// `σ = exp((1−β)s_bg + βs_res)` (the authors' code).
    Raw,
}

/// How background and residual combine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MixKind {
    /// A Mixnet's β per point, densities mixed per [`DensityMix`].
    Mixnet(DensityMix),
    /// Residual-NeRF-S: plain sums (paper Eq. 6).
    Sum,
}

/// One sample's pre-activation inputs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MixInput {
    /// Background raw density.
    pub s_bg: f32,
    /// Background pre-sigmoid colour.
    pub c_bg: [f32; 3],
    /// Residual raw density.
    pub s_res: f32,
    /// Residual pre-sigmoid colour.
    pub c_res: [f32; 3],
    /// Mixnet logit (β = sigmoid(m)); ignored by [`MixKind::Sum`].
    pub m: f32,
}

/// One sample's mixed output.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MixOutput {
    /// Density σ.
    pub sigma: f32,
    /// Colour in [0, 1].
    pub rgb: [f32; 3],
    /// β (0 for [`MixKind::Sum`]).
    pub beta: f32,
}

/// Derivatives of the loss with respect to the trainable inputs of one sample.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MixGrad {
    /// dL/ds_res.
    pub s_res: f32,
    /// dL/dc′_res.
    pub c_res: [f32; 3],
    /// dL/dm (the Mixnet logit).
    pub m: f32,
}

#[inline]
fn texp(x: f32) -> f32 {
    Activation::TruncExp.forward(x)
}

/// trunc_exp′(x) = e^{clamp(x, −15, 15)}.
#[inline]
fn texp_grad(x: f32) -> f32 {
    x.clamp(-15.0, 15.0).exp()
}

#[inline]
fn sigmoid(x: f32) -> f32 {
    Activation::Sigmoid.forward(x)
}

/// The mixed density and colour of one sample.
#[inline]
pub fn mix_forward(kind: MixKind, x: &MixInput) -> MixOutput {
    match kind {
        MixKind::Sum => MixOutput {
            sigma: texp(x.s_bg) + texp(x.s_res),
            rgb: std::array::from_fn(|k| sigmoid(x.c_bg[k] + x.c_res[k])),
            beta: 0.0,
        },
        MixKind::Mixnet(d) => {
            let b = sigmoid(x.m);
            let sigma = match d {
                DensityMix::Activated => (1.0 - b) * texp(x.s_bg) + b * texp(x.s_res),
                DensityMix::Raw => texp((1.0 - b) * x.s_bg + b * x.s_res),
            };
            MixOutput { sigma, rgb: std::array::from_fn(|k| sigmoid((1.0 - b) * x.c_bg[k] + b * x.c_res[k])), beta: b }
        }
    }
}

/// The log-density `ln σ` the threshold-depth test compares (for `Raw` mixing it is the mixed
/// raw value itself).
#[inline]
pub fn mixed_log_density(kind: MixKind, x: &MixInput) -> f32 {
    match kind {
        MixKind::Mixnet(DensityMix::Raw) => {
            let b = sigmoid(x.m);
            (1.0 - b) * x.s_bg + b * x.s_res
        }
        _ => mix_forward(kind, x).sigma.ln(),
    }
}

/// [`mix_backward`] of every row: dL/ds_res, dL/dc′_res and dL/dm into `d_s`, `d_c`, `d_m`
/// (resized to the rows).
#[allow(clippy::too_many_arguments)]
pub fn mix_backward_rows(
    kind: MixKind,
    inputs: &[MixInput],
    outputs: &[MixOutput],
    d_sigma: &[f32],
    d_rgb: &[[f32; 3]],
    d_s: &mut Vec<f32>,
    d_c: &mut Vec<[f32; 3]>,
    d_m: &mut Vec<f32>,
) {
    let n = inputs.len();
    d_s.resize(n, 0.0);
    d_c.resize(n, [0.0; 3]);
    d_m.resize(n, 0.0);
    for i in 0..n {
        let g = mix_backward(kind, &inputs[i], &outputs[i], d_sigma[i], d_rgb[i]);
        (d_s[i], d_c[i], d_m[i]) = (g.s_res, g.c_res, g.m);
    }
}

/// Backward of [`mix_forward`] given `out` (its result) and dL/dσ, dL/dc.
#[inline]
pub fn mix_backward(kind: MixKind, x: &MixInput, out: &MixOutput, d_sigma: f32, d_rgb: [f32; 3]) -> MixGrad {
    // dL/dv for the pre-sigmoid mixed colour v.
    let d_v: [f32; 3] = std::array::from_fn(|k| d_rgb[k] * out.rgb[k] * (1.0 - out.rgb[k]));
    match kind {
        MixKind::Sum => MixGrad { s_res: d_sigma * texp_grad(x.s_res), c_res: d_v, m: 0.0 },
        MixKind::Mixnet(d) => {
            let b = out.beta;
            let (d_s_res, d_beta_sigma) = match d {
                DensityMix::Activated => (d_sigma * b * texp_grad(x.s_res), d_sigma * (texp(x.s_res) - texp(x.s_bg))),
                DensityMix::Raw => {
                    let u = (1.0 - b) * x.s_bg + b * x.s_res;
                    let g = d_sigma * texp_grad(u);
                    (g * b, g * (x.s_res - x.s_bg))
                }
            };
            let d_beta_colour: f32 = (0..3).map(|k| d_v[k] * (x.c_res[k] - x.c_bg[k])).sum();
            MixGrad { s_res: d_s_res, c_res: d_v.map(|g| g * b), m: (d_beta_sigma + d_beta_colour) * b * (1.0 - b) }
        }
    }
}
