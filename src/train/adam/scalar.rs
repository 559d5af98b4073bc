//! Scalar Adam: the specification of the SIMD twins.

use super::AdamStep;

/// Updates `p`, `m`, `v` in place from `g`; writes fp16 bits of the new `p` to `mirror`.
pub fn step(hp: AdamStep, p: &mut [f32], g: &[f32], m: &mut [f32], v: &mut [f32], mut mirror: Option<&mut [u16]>) {
    for i in 0..p.len() {
        let gi = g[i] + hp.l2 * p[i];
        let mi = hp.beta1 * m[i] + (1.0 - hp.beta1) * gi;
        let vi = hp.beta2 * v[i] + (1.0 - hp.beta2) * (gi * gi);
        let pi = p[i] - hp.lr_t * (mi / (vi.sqrt() + hp.epsilon));
        m[i] = mi;
        v[i] = vi;
        p[i] = pi;
        if let Some(h) = mirror.as_deref_mut() {
            h[i] = half::f16::from_f32(pi).to_bits();
        }
    }
}
