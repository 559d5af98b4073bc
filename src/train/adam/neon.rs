//! NEON Adam: 4 parameters per iteration, the fp16 mirror written with `fcvtn`.
//! Twin of [`super::scalar::step`].

use super::AdamStep;
use crate::simd::neon::cvt_f32x4_f16x4;
use crate::simd::safe_entry;
use std::arch::aarch64::*;

/// NEON twin of [`super::scalar::step`].
///
/// # Safety
/// The CPU must support NEON; slices have equal lengths.
#[target_feature(enable = "neon")]
unsafe fn step_unchecked(
    hp: AdamStep,
    p: &mut [f32],
    g: &[f32],
    m: &mut [f32],
    v: &mut [f32],
    mut mirror: Option<&mut [u16]>,
) {
    let n = p.len();
    assert!(g.len() == n && m.len() == n && v.len() == n);
    let b1 = vdupq_n_f32(hp.beta1);
    let nb1 = vdupq_n_f32(1.0 - hp.beta1);
    let b2 = vdupq_n_f32(hp.beta2);
    let nb2 = vdupq_n_f32(1.0 - hp.beta2);
    let eps = vdupq_n_f32(hp.epsilon);
    let lr = vdupq_n_f32(hp.lr_t);
    let l2 = vdupq_n_f32(hp.l2);
    let body = n / 4 * 4;
    let mut i = 0;
    while i < body {
        // SAFETY: i + 4 <= n for every slice (equal lengths asserted above).
        unsafe {
            let pi = vld1q_f32(p.as_ptr().add(i));
            let gi = vfmaq_f32(vld1q_f32(g.as_ptr().add(i)), l2, pi);
            let mi = vfmaq_f32(vmulq_f32(nb1, gi), b1, vld1q_f32(m.as_ptr().add(i)));
            let vi = vfmaq_f32(vmulq_f32(nb2, vmulq_f32(gi, gi)), b2, vld1q_f32(v.as_ptr().add(i)));
            let upd = vdivq_f32(mi, vaddq_f32(vsqrtq_f32(vi), eps));
            let pn = vfmsq_f32(pi, lr, upd);
            vst1q_f32(p.as_mut_ptr().add(i), pn);
            vst1q_f32(m.as_mut_ptr().add(i), mi);
            vst1q_f32(v.as_mut_ptr().add(i), vi);
            if let Some(h) = mirror.as_deref_mut() {
                assert!(h.len() == n);
                vst1_u16(h.as_mut_ptr().add(i), cvt_f32x4_f16x4(pn));
            }
        }
        i += 4;
    }
    super::scalar::step(hp, &mut p[body..], &g[body..], &mut m[body..], &mut v[body..], mirror.map(|h| &mut h[body..]));
}

safe_entry!(Neon, step => step_unchecked(hp: AdamStep, p: &mut [f32], g: &[f32], m: &mut [f32], v: &mut [f32], mirror: Option<&mut [u16]>));
