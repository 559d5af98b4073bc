//! AVX2+FMA+F16C Adam: 8 parameters per iteration, the fp16 mirror written with
//! `vcvtps2ph` (round to nearest even). Twin of [`super::scalar::step`].

use super::AdamStep;
use crate::simd::safe_entry;
use std::arch::x86_64::*;

/// AVX2 twin of [`super::scalar::step`].
///
/// # Safety
/// The CPU must support AVX2, FMA and F16C; slices have equal lengths.
#[target_feature(enable = "avx2,fma,f16c")]
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
    let b1 = _mm256_set1_ps(hp.beta1);
    let nb1 = _mm256_set1_ps(1.0 - hp.beta1);
    let b2 = _mm256_set1_ps(hp.beta2);
    let nb2 = _mm256_set1_ps(1.0 - hp.beta2);
    let eps = _mm256_set1_ps(hp.epsilon);
    let lr = _mm256_set1_ps(hp.lr_t);
    let l2 = _mm256_set1_ps(hp.l2);
    let body = n / 8 * 8;
    let mut i = 0;
    while i < body {
        // SAFETY: i + 8 <= n for every slice (equal lengths asserted above).
        unsafe {
            let pi = _mm256_loadu_ps(p.as_ptr().add(i));
            let gi = _mm256_fmadd_ps(l2, pi, _mm256_loadu_ps(g.as_ptr().add(i)));
            let mi = _mm256_fmadd_ps(b1, _mm256_loadu_ps(m.as_ptr().add(i)), _mm256_mul_ps(nb1, gi));
            let vi = _mm256_fmadd_ps(b2, _mm256_loadu_ps(v.as_ptr().add(i)), _mm256_mul_ps(nb2, _mm256_mul_ps(gi, gi)));
            let upd = _mm256_div_ps(mi, _mm256_add_ps(_mm256_sqrt_ps(vi), eps));
            let pn = _mm256_fnmadd_ps(lr, upd, pi);
            _mm256_storeu_ps(p.as_mut_ptr().add(i), pn);
            _mm256_storeu_ps(m.as_mut_ptr().add(i), mi);
            _mm256_storeu_ps(v.as_mut_ptr().add(i), vi);
            if let Some(h) = mirror.as_deref_mut() {
                assert!(h.len() == n);
                _mm_storeu_si128(
                    h.as_mut_ptr().add(i) as *mut __m128i,
                    _mm256_cvtps_ph::<_MM_FROUND_TO_NEAREST_INT>(pn),
                );
            }
        }
        i += 8;
    }
    super::scalar::step(hp, &mut p[body..], &g[body..], &mut m[body..], &mut v[body..], mirror.map(|h| &mut h[body..]));
}

safe_entry!(Avx2, step => step_unchecked(hp: AdamStep, p: &mut [f32], g: &[f32], m: &mut [f32], v: &mut [f32], mirror: Option<&mut [u16]>));
