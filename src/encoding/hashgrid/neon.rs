//! NEON hash-grid kernels: 4 samples per vector; corners fetched lane by lane (NEON has no
//! gather) and expanded with `fcvtl` (ARMv8.0 base ISA, so no FP16 arithmetic extension is
//! needed). Twin of [`super::scalar`].

use super::{LevelInfo, Soa, PRIME_Y, PRIME_Z};
use crate::simd::neon::cvt_f16x4_f32x4;
use crate::simd::safe_entry;
use std::arch::aarch64::*;

#[inline(always)]
unsafe fn corners4(level: &LevelInfo, soa: &Soa, i: usize) -> ([uint32x4_t; 8], [float32x4_t; 8]) {
    // SAFETY: the caller guarantees NEON and `i + 4 <= CHUNK` (the SoA arrays' length).
    unsafe {
        let zero = vdupq_n_f32(0.0);
        let one = vdupq_n_f32(1.0);
        let r = vdupq_n_f32(level.resolution as f32);
        let r_minus_1 = vdupq_n_f32(level.resolution as f32 - 1.0);
        let x = vld1q_f32(soa.x.as_ptr().add(i));
        let y = vld1q_f32(soa.y.as_ptr().add(i));
        let z = vld1q_f32(soa.z.as_ptr().add(i));
        let inside_1d = |v: float32x4_t| vandq_u32(vcgeq_f32(v, zero), vcleq_f32(v, one));
        let inside = vandq_u32(vandq_u32(inside_1d(x), inside_1d(y)), inside_1d(z));
        // fmaxnm/fminnm return the number when one operand is NaN.
        let locate = |v: float32x4_t| {
            let q = vminnmq_f32(vmaxnmq_f32(vmulq_f32(v, r), zero), r);
            let f = vminq_f32(vrndmq_f32(q), r_minus_1);
            (vcvtq_u32_f32(f), vsubq_f32(q, f))
        };
        let (cx, wx) = locate(x);
        let (cy, wy) = locate(y);
        let (cz, wz) = locate(z);
        let (sy, sz) = if level.dense {
            let s = level.resolution + 1;
            (s, s * s)
        } else {
            (PRIME_Y, PRIME_Z)
        };
        let xs = [cx, vaddq_u32(cx, vdupq_n_u32(1))];
        let y0 = vmulq_n_u32(cy, sy);
        let z0 = vmulq_n_u32(cz, sz);
        let ys = [y0, vaddq_u32(y0, vdupq_n_u32(sy))];
        let zs = [z0, vaddq_u32(z0, vdupq_n_u32(sz))];
        let wxs = [vsubq_f32(one, wx), wx];
        let wys = [vsubq_f32(one, wy), wy];
        let keep = |w: float32x4_t| vreinterpretq_f32_u32(vandq_u32(vreinterpretq_u32_f32(w), inside));
        let wzs = [keep(vsubq_f32(one, wz)), keep(wz)];
        let mask = vdupq_n_u32((level.size as u32).wrapping_sub(1));
        let mut idx = [vdupq_n_u32(0); 8];
        let mut w = [zero; 8];
        for c in 0..8 {
            let (bx, by, bz) = (c & 1, (c >> 1) & 1, (c >> 2) & 1);
            idx[c] = if level.dense {
                vaddq_u32(vaddq_u32(xs[bx], ys[by]), zs[bz])
            } else {
                vandq_u32(veorq_u32(veorq_u32(xs[bx], ys[by]), zs[bz]), mask)
            };
            w[c] = vmulq_f32(wxs[bx], vmulq_f32(wys[by], wzs[bz]));
        }
        (idx, w)
    }
}

/// NEON twin of [`super::scalar::forward_level`].
///
/// # Safety
/// The CPU must support NEON; `table` is the level's slice.
#[target_feature(enable = "neon")]
unsafe fn forward_level_unchecked(
    level: &LevelInfo,
    table: &[u32],
    soa: &Soa,
    n: usize,
    out: &mut [f32],
    stride: usize,
) {
    let mut pairs = [0f32; 8];
    let mut lanes = [0u32; 4];
    let mut i = 0;
    while i < n {
        // SAFETY: i + 4 <= CHUNK (the SoA is padded to 8); indices are < level.size.
        unsafe {
            let (idx, w) = corners4(level, soa, i);
            let mut acc_lo = vdupq_n_f32(0.0);
            let mut acc_hi = vdupq_n_f32(0.0);
            for c in 0..8 {
                vst1q_u32(lanes.as_mut_ptr(), idx[c]);
                let fetched = [
                    table[lanes[0] as usize],
                    table[lanes[1] as usize],
                    table[lanes[2] as usize],
                    table[lanes[3] as usize],
                ];
                let g = vreinterpretq_u16_u32(vld1q_u32(fetched.as_ptr()));
                let lo = cvt_f16x4_f32x4(vget_low_u16(g));
                let hi = cvt_f16x4_f32x4(vget_high_u16(g));
                acc_lo = vfmaq_f32(acc_lo, lo, vzip1q_f32(w[c], w[c]));
                acc_hi = vfmaq_f32(acc_hi, hi, vzip2q_f32(w[c], w[c]));
            }
            vst1q_f32(pairs.as_mut_ptr(), acc_lo);
            vst1q_f32(pairs.as_mut_ptr().add(4), acc_hi);
        }
        for s in 0..(n - i).min(4) {
            let o = (i + s) * stride;
            out[o] = pairs[2 * s];
            out[o + 1] = pairs[2 * s + 1];
        }
        i += 4;
    }
}

/// NEON twin of [`super::scalar::backward_level`] (same scatter order, each corner's two features
/// as one 2-float pair with the same per-feature operations: bit-identical).
///
/// # Safety
/// The CPU must support NEON; `grads` is the level's slice.
#[target_feature(enable = "neon")]
unsafe fn backward_level_unchecked(
    level: &LevelInfo,
    grads: &mut [f32],
    soa: &Soa,
    n: usize,
    d: &[f32],
    stride: usize,
) {
    assert!(grads.len() >= 2 * level.size, "hash grid: level gradient too short");
    let gp = grads.as_mut_ptr();
    let mut idx = [[0u32; 4]; 8];
    let mut w = [[0f32; 4]; 8];
    let mut i = 0;
    while i < n {
        // SAFETY: i + 4 <= CHUNK; stores go to local arrays of 4 lanes.
        unsafe {
            let (vi, vw) = corners4(level, soa, i);
            for c in 0..8 {
                vst1q_u32(idx[c].as_mut_ptr(), vi[c]);
                vst1q_f32(w[c].as_mut_ptr(), vw[c]);
            }
        }
        for s in 0..(n - i).min(4) {
            let pair = [d[(i + s) * stride], d[(i + s) * stride + 1]];
            // SAFETY: `pair` holds 2 floats.
            let g = unsafe { vld1_f32(pair.as_ptr()) };
            for c in 0..8 {
                // SAFETY: idx < level.size (see corners4), so floats e and e + 1 are inside
                // `grads` (asserted to hold 2 · level.size); a 2-float load and store of them.
                unsafe {
                    let p = gp.add(2 * idx[c][s] as usize);
                    vst1_f32(p, vadd_f32(vld1_f32(p), vmul_n_f32(g, w[c][s])));
                }
            }
        }
        i += 4;
    }
}

safe_entry!(Neon, forward_level => forward_level_unchecked(level: &LevelInfo, table: &[u32], soa: &Soa, n: usize, out: &mut [f32], stride: usize));

safe_entry!(Neon, backward_level => backward_level_unchecked(level: &LevelInfo, grads: &mut [f32], soa: &Soa, n: usize, d: &[f32], stride: usize));
