//! NEON MLP kernels: register tiles of 4 rows × 16 columns (16 q-register accumulators).
//! Twin of [`super::scalar`]. Requires `o.is_multiple_of(16)` and `k.is_multiple_of(4)`.

use crate::simd::safe_entry;
use std::arch::aarch64::*;

/// NEON twin of [`super::scalar::matmul`].
///
/// # Safety
/// The CPU must support NEON.
#[target_feature(enable = "neon")]
unsafe fn matmul_unchecked(x: &[f32], rows: usize, k: usize, w: &[f32], o: usize, out: &mut [f32], relu: bool) {
    assert!(o.is_multiple_of(16) && x.len() >= rows * k && w.len() >= k * o && out.len() >= rows * o);
    let (xp, wp, op) = (x.as_ptr(), w.as_ptr(), out.as_mut_ptr());
    let zero = vdupq_n_f32(0.0);
    let mut b = 0;
    while b < rows {
        let tile = if b + 4 <= rows { 4 } else { 1 };
        let mut j = 0;
        while j < o {
            // SAFETY: b + tile <= rows, j + 16 <= o, kk < k; the assert bounds x, w and out.
            unsafe {
                let mut c = [[zero; 4]; 4];
                for kk in 0..k {
                    let wv = [
                        vld1q_f32(wp.add(kk * o + j)),
                        vld1q_f32(wp.add(kk * o + j + 4)),
                        vld1q_f32(wp.add(kk * o + j + 8)),
                        vld1q_f32(wp.add(kk * o + j + 12)),
                    ];
                    for r in 0..tile {
                        let xv = *xp.add((b + r) * k + kk);
                        for q in 0..4 {
                            c[r][q] = vfmaq_n_f32(c[r][q], wv[q], xv);
                        }
                    }
                }
                for r in 0..tile {
                    for q in 0..4 {
                        let v = if relu { vmaxq_f32(c[r][q], zero) } else { c[r][q] };
                        vst1q_f32(op.add((b + r) * o + j + 4 * q), v);
                    }
                }
            }
            j += 16;
        }
        b += tile;
    }
}

/// NEON twin of [`super::scalar::matmul_first`]: 4 rows per vector (lane = row), the rows'
/// 4×4 blocks transposed in registers so each lane runs [`matmul_unchecked`]'s FMA chain for
/// column 0 — the same bits as its column 0.
///
/// # Safety
/// The CPU must support NEON.
#[target_feature(enable = "neon")]
unsafe fn matmul_first_unchecked(x: &[f32], rows: usize, k: usize, w: &[f32], o: usize, out: &mut [f32], relu: bool) {
    assert!(k.is_multiple_of(4) && x.len() >= rows * k && w.len() >= k * o && out.len() >= rows);
    let (xp, wp) = (x.as_ptr(), w.as_ptr());
    let zero = vdupq_n_f32(0.0);
    let mut b = 0;
    while b + 4 <= rows {
        let mut acc = zero;
        for k0 in (0..k).step_by(4) {
            // SAFETY: rows b..b+4 and columns k0..k0+4 of x, rows k0..k0+4 of w are in bounds
            // (asserted above).
            unsafe {
                let r: [float32x4_t; 4] = std::array::from_fn(|i| vld1q_f32(xp.add((b + i) * k + k0)));
                // 4×4 transpose: pairs of rows interleaved, then 64-bit halves.
                let (a0, a1) = (vtrn1q_f32(r[0], r[1]), vtrn2q_f32(r[0], r[1]));
                let (a2, a3) = (vtrn1q_f32(r[2], r[3]), vtrn2q_f32(r[2], r[3]));
                let f = |lo: float32x4_t, hi: float32x4_t, first: bool| {
                    let (l, h) = (vreinterpretq_f64_f32(lo), vreinterpretq_f64_f32(hi));
                    vreinterpretq_f32_f64(if first { vtrn1q_f64(l, h) } else { vtrn2q_f64(l, h) })
                };
                let cols = [f(a0, a2, true), f(a1, a3, true), f(a0, a2, false), f(a1, a3, false)];
                for (c, col) in cols.into_iter().enumerate() {
                    acc = vfmaq_n_f32(acc, col, *wp.add((k0 + c) * o));
                }
            }
        }
        if relu {
            acc = vmaxq_f32(acc, zero);
        }
        // SAFETY: b + 4 <= rows <= out.len().
        unsafe { vst1q_f32(out.as_mut_ptr().add(b), acc) };
        b += 4;
    }
    super::first_column_fma(x, k, w, o, b..rows, out, relu);
}

/// NEON twin of [`super::scalar::matmul_tn_acc`].
///
/// # Safety
/// The CPU must support NEON.
#[target_feature(enable = "neon")]
unsafe fn matmul_tn_acc_unchecked(x: &[f32], rows: usize, k: usize, dz: &[f32], o: usize, dw: &mut [f32]) {
    assert!(
        o.is_multiple_of(16) && k.is_multiple_of(4) && x.len() >= rows * k && dz.len() >= rows * o && dw.len() >= k * o
    );
    let (xp, dp, wp) = (x.as_ptr(), dz.as_ptr(), dw.as_mut_ptr());
    let zero = vdupq_n_f32(0.0);
    let mut kk = 0;
    while kk < k {
        let mut j = 0;
        while j < o {
            // SAFETY: kk + 4 <= k, j + 16 <= o, b < rows; the assert bounds x, dz and dw.
            unsafe {
                let mut c = [[zero; 4]; 4];
                for b in 0..rows {
                    let dv = [
                        vld1q_f32(dp.add(b * o + j)),
                        vld1q_f32(dp.add(b * o + j + 4)),
                        vld1q_f32(dp.add(b * o + j + 8)),
                        vld1q_f32(dp.add(b * o + j + 12)),
                    ];
                    for r in 0..4 {
                        let xv = *xp.add(b * k + kk + r);
                        for q in 0..4 {
                            c[r][q] = vfmaq_n_f32(c[r][q], dv[q], xv);
                        }
                    }
                }
                for r in 0..4 {
                    for q in 0..4 {
                        let p = wp.add((kk + r) * o + j + 4 * q);
                        vst1q_f32(p, vaddq_f32(vld1q_f32(p), c[r][q]));
                    }
                }
            }
            j += 16;
        }
        kk += 4;
    }
}

safe_entry!(Neon, matmul => matmul_unchecked(x: &[f32], rows: usize, k: usize, w: &[f32], o: usize, out: &mut [f32], relu: bool));

safe_entry!(Neon, matmul_first => matmul_first_unchecked(x: &[f32], rows: usize, k: usize, w: &[f32], o: usize, out: &mut [f32], relu: bool));

safe_entry!(Neon, matmul_tn_acc => matmul_tn_acc_unchecked(x: &[f32], rows: usize, k: usize, dz: &[f32], o: usize, dw: &mut [f32]));
