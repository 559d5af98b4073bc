//! Activations as (f, f′) pairs, with f′ written from the **output** y = f(x) so a backward
//! pass needs only the saved outputs (dfdx's trick).

/// Element-wise activation of a layer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Activation {
    /// Identity.
    None,
    /// max(x, 0).
    Relu,
    /// 1 / (1 + e^−x).
    Sigmoid,
    /// Instant-NGP's truncated exponential: forward e^x, backward e^clamp(x, −15, 15).
    TruncExp,
}

/// e^±15: the clamp of [`Activation::TruncExp`]'s derivative, expressed on its output.
const TRUNC_EXP_LO: f32 = 3.059_023_2e-7;
const TRUNC_EXP_HI: f32 = 3_269_017.5;

impl Activation {
    /// f(x).
    #[inline(always)]
    pub fn forward(self, x: f32) -> f32 {
        match self {
            Activation::None => x,
            Activation::Relu => x.max(0.0),
            Activation::Sigmoid => 1.0 / (1.0 + (-x).exp()),
            Activation::TruncExp => x.exp(),
        }
    }

    /// f′(x) written in terms of y = f(x).
    #[inline(always)]
    pub fn derivative_from_output(self, y: f32) -> f32 {
        match self {
            Activation::None => 1.0,
            Activation::Relu => {
                if y > 0.0 {
                    1.0
                } else {
                    0.0
                }
            }
            Activation::Sigmoid => y * (1.0 - y),
            // e^clamp(x,−15,15) = clamp(e^x, e^−15, e^15): monotone, so clamp the output.
            Activation::TruncExp => y.clamp(TRUNC_EXP_LO, TRUNC_EXP_HI),
        }
    }

    /// `dz[i] = dy[i] · f′(y[i])` over slices, with the activation chosen once outside the
    /// loop so each arm is a plain (auto-vectorised) element-wise pass.
    #[inline]
    pub fn backward_slice(self, y: &[f32], dy: &[f32], dz: &mut [f32]) {
        let it = dz.iter_mut().zip(y).zip(dy);
        match self {
            Activation::None => it.for_each(|((z, _), d)| *z = *d),
            // Branch-free (a sign-dependent branch mispredicts half the time): keep d's bits
            // where y > 0, else +0.0; vectorises.
            Activation::Relu => it.for_each(|((z, y), d)| {
                let keep = 0u32.wrapping_sub((*y > 0.0) as u32);
                *z = f32::from_bits(d.to_bits() & keep)
            }),
            Activation::Sigmoid => it.for_each(|((z, y), d)| *z = d * (y * (1.0 - y))),
            Activation::TruncExp => it.for_each(|((z, y), d)| *z = d * Activation::TruncExp.derivative_from_output(*y)),
        }
    }

    /// Whether the SIMD matmul kernels apply this activation themselves (the others are
    /// applied by a scalar pass over the tile right after).
    pub(crate) fn fused_in_kernel(self) -> bool {
        matches!(self, Activation::None | Activation::Relu)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trunc_exp_clamp_constants_are_exp_15() {
        assert!((TRUNC_EXP_LO as f64 - (-15f64).exp()).abs() < 1e-12);
        assert!((TRUNC_EXP_HI as f64 / 15f64.exp() - 1.0).abs() < 1e-6);
    }
}
