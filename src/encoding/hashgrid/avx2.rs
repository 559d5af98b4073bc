//! AVX2 + FMA + F16C hash-grid kernels: 8 samples per vector, one 8-lane load per corner
//! (each lane a packed fp16 pair, fetched by eight scalar loads rather than `vpgatherdd`:
//! see [`load8`]), `vcvtph2ps` to expand. Twin of [`super::scalar`].

use super::{LevelInfo, Soa, PRIME_Y, PRIME_Z};
use crate::simd::safe_entry;
use std::arch::x86_64::*;

/// Corner indices and weights of samples `i..i+8` (weights zeroed outside the unit cube,
/// indices clamped into the level so every gather stays in bounds).
#[inline(always)]
unsafe fn corners8(level: &LevelInfo, soa: &Soa, i: usize) -> ([__m256i; 8], [__m256; 8]) {
    // SAFETY: the caller guarantees AVX2+FMA and `i + 8 <= CHUNK` (the SoA arrays' length).
    unsafe {
        let zero = _mm256_setzero_ps();
        let one = _mm256_set1_ps(1.0);
        let r = _mm256_set1_ps(level.resolution as f32);
        let r_minus_1 = _mm256_set1_ps(level.resolution as f32 - 1.0);
        let x = _mm256_loadu_ps(soa.x.as_ptr().add(i));
        let y = _mm256_loadu_ps(soa.y.as_ptr().add(i));
        let z = _mm256_loadu_ps(soa.z.as_ptr().add(i));
        // Ordered comparisons: NaN is outside.
        let inside_1d =
            |v: __m256| _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(v, zero), _mm256_cmp_ps::<_CMP_LE_OQ>(v, one));
        let inside = _mm256_and_ps(_mm256_and_ps(inside_1d(x), inside_1d(y)), inside_1d(z));
        // max(q, 0) returns 0 for NaN q, so the cell index is always valid.
        let locate = |v: __m256| {
            let q = _mm256_min_ps(_mm256_max_ps(_mm256_mul_ps(v, r), zero), r);
            let f = _mm256_min_ps(_mm256_round_ps::<{ _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC }>(q), r_minus_1);
            (_mm256_cvttps_epi32(f), _mm256_sub_ps(q, f))
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
        let x0 = cx;
        let x1 = _mm256_add_epi32(cx, _mm256_set1_epi32(1));
        let y0 = _mm256_mullo_epi32(cy, _mm256_set1_epi32(sy as i32));
        let y1 = _mm256_add_epi32(y0, _mm256_set1_epi32(sy as i32));
        let z0 = _mm256_mullo_epi32(cz, _mm256_set1_epi32(sz as i32));
        let z1 = _mm256_add_epi32(z0, _mm256_set1_epi32(sz as i32));
        let xs = [x0, x1];
        let ys = [y0, y1];
        let zs = [z0, z1];
        let wxs = [_mm256_sub_ps(one, wx), wx];
        let wys = [_mm256_sub_ps(one, wy), wy];
        let wzs = [_mm256_and_ps(_mm256_sub_ps(one, wz), inside), _mm256_and_ps(wz, inside)];
        let mask = _mm256_set1_epi32((level.size as u32).wrapping_sub(1) as i32);
        let mut idx = [_mm256_setzero_si256(); 8];
        let mut w = [zero; 8];
        for c in 0..8 {
            let (bx, by, bz) = (c & 1, (c >> 1) & 1, (c >> 2) & 1);
            idx[c] = if level.dense {
                _mm256_add_epi32(_mm256_add_epi32(xs[bx], ys[by]), zs[bz])
            } else {
                _mm256_and_si256(_mm256_xor_si256(_mm256_xor_si256(xs[bx], ys[by]), zs[bz]), mask)
            };
            w[c] = _mm256_mul_ps(wxs[bx], _mm256_mul_ps(wys[by], wzs[bz]));
        }
        (idx, w)
    }
}

/// The 32-bit words `base[idx[0..8]]` as one vector: eight scalar loads, not `vpgatherdd`.
/// The gather instruction is microcoded on AMD Zen 2/3 and slowed by Intel's Gather Data
/// Sampling mitigation; the scalar loads gave 3–7% faster threshold-depth views on a Zen 3
/// guest with the same bits (docs/DECISIONS.md, "The hash grid's AVX2 corner loads").
///
/// # Safety
/// AVX2; every lane of `idx` indexes inside the slice `base` points into.
#[inline(always)]
unsafe fn load8(base: *const i32, idx: __m256i) -> __m256i {
    // SAFETY: the caller guarantees AVX2 and in-bounds indices.
    unsafe {
        let mut ix = [0i32; 8];
        _mm256_storeu_si256(ix.as_mut_ptr() as *mut __m256i, idx);
        _mm256_setr_epi32(
            *base.add(ix[0] as usize),
            *base.add(ix[1] as usize),
            *base.add(ix[2] as usize),
            *base.add(ix[3] as usize),
            *base.add(ix[4] as usize),
            *base.add(ix[5] as usize),
            *base.add(ix[6] as usize),
            *base.add(ix[7] as usize),
        )
    }
}

/// AVX2 twin of [`super::scalar::forward_level`].
///
/// # Safety
/// The CPU must support AVX2, FMA and F16C; `table` is the level's slice.
#[target_feature(enable = "avx2,fma,f16c")]
unsafe fn forward_level_unchecked(
    level: &LevelInfo,
    table: &[u32],
    soa: &Soa,
    n: usize,
    out: &mut [f32],
    stride: usize,
) {
    assert!(table.len() >= level.size, "hash grid: level table too short");
    let dup_lo = _mm256_setr_epi32(0, 0, 1, 1, 2, 2, 3, 3);
    let dup_hi = _mm256_setr_epi32(4, 4, 5, 5, 6, 6, 7, 7);
    let base = table.as_ptr() as *const i32;
    let mut pairs = [0f32; 16];
    let mut i = 0;
    while i < n {
        // SAFETY: i + 8 <= CHUNK (the SoA is padded to 8); every index is < level.size
        // (clamped cell, dense extent or hash mask), so the gathers read inside `table`.
        unsafe {
            let (idx, w) = corners8(level, soa, i);
            let mut acc_lo = _mm256_setzero_ps();
            let mut acc_hi = _mm256_setzero_ps();
            for c in 0..8 {
                let g = load8(base, idx[c]);
                let lo = _mm256_cvtph_ps(_mm256_castsi256_si128(g));
                let hi = _mm256_cvtph_ps(_mm256_extracti128_si256::<1>(g));
                acc_lo = _mm256_fmadd_ps(lo, _mm256_permutevar8x32_ps(w[c], dup_lo), acc_lo);
                acc_hi = _mm256_fmadd_ps(hi, _mm256_permutevar8x32_ps(w[c], dup_hi), acc_hi);
            }
            _mm256_storeu_ps(pairs.as_mut_ptr(), acc_lo);
            _mm256_storeu_ps(pairs.as_mut_ptr().add(8), acc_hi);
        }
        for s in 0..(n - i).min(8) {
            let o = (i + s) * stride;
            out[o] = pairs[2 * s];
            out[o + 1] = pairs[2 * s + 1];
        }
        i += 8;
    }
}

/// AVX2 twin of [`super::scalar::backward_level`]: indices and weights 8 samples at a time,
/// then the scatter-add in the scalar kernel's order (sample, then corner), each corner's two
/// features read, multiplied, added and written as one 64-bit pair (the same per-feature
/// operations), so the result is bit-identical to it.
///
/// # Safety
/// The CPU must support AVX2, FMA and F16C; `grads` is the level's slice.
#[target_feature(enable = "avx2,fma,f16c")]
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
    let mut idx = [[0u32; 8]; 8];
    let mut w = [[0f32; 8]; 8];
    let mut i = 0;
    while i < n {
        // SAFETY: i + 8 <= CHUNK; stores go to local arrays of 8 lanes.
        unsafe {
            let (vi, vw) = corners8(level, soa, i);
            for c in 0..8 {
                _mm256_storeu_si256(idx[c].as_mut_ptr() as *mut __m256i, vi[c]);
                _mm256_storeu_ps(w[c].as_mut_ptr(), vw[c]);
            }
        }
        for s in 0..(n - i).min(8) {
            let g = _mm_setr_ps(d[(i + s) * stride], d[(i + s) * stride + 1], 0.0, 0.0);
            for c in 0..8 {
                // SAFETY: idx < level.size (see corners8), so floats e and e + 1 are inside
                // `grads` (asserted to hold 2 · level.size); 8-byte loads and stores of them.
                unsafe {
                    let p = gp.add(2 * idx[c][s] as usize) as *mut f64;
                    let cur = _mm_castpd_ps(_mm_load_sd(p));
                    let sum = _mm_add_ps(cur, _mm_mul_ps(_mm_set1_ps(w[c][s]), g));
                    _mm_store_sd(p, _mm_castps_pd(sum));
                }
            }
        }
        i += 8;
    }
}

safe_entry!(Avx2, forward_level => forward_level_unchecked(level: &LevelInfo, table: &[u32], soa: &Soa, n: usize, out: &mut [f32], stride: usize));

safe_entry!(Avx2, backward_level => backward_level_unchecked(level: &LevelInfo, grads: &mut [f32], soa: &Soa, n: usize, d: &[f32], stride: usize));
