//! AVX-512F hash-grid forward: 16 samples per vector, one 16-lane `vpgatherdd` per corner
//! (each lane fetches a packed fp16 pair), `vcvtph2ps` to expand. The weights and the FMA
//! chain per feature are those of [`super::avx2`] (so the same bits); only the lane count
//! differs. The backward runs the AVX2 kernel (its scatter-add is scalar either way).

use super::{LevelInfo, Soa, PRIME_Y, PRIME_Z};
use crate::simd::safe_entry;
use std::arch::x86_64::*;

// The loop below reads the SoA 16 lanes at a time.
const _: () = assert!(super::CHUNK.is_multiple_of(16));

/// Corner indices and weights of samples `i..i+16` (weights zeroed outside the unit cube,
/// indices clamped into the level so every gather stays in bounds); the operations of
/// `avx2::corners8`, 16 lanes wide.
#[inline(always)]
unsafe fn corners16(level: &LevelInfo, soa: &Soa, i: usize) -> ([__m512i; 8], [__m512; 8]) {
    // SAFETY: the caller guarantees AVX-512F and `i + 16 <= CHUNK` (the SoA arrays' length).
    unsafe {
        let zero = _mm512_setzero_ps();
        let one = _mm512_set1_ps(1.0);
        let r = _mm512_set1_ps(level.resolution as f32);
        let r_minus_1 = _mm512_set1_ps(level.resolution as f32 - 1.0);
        let x = _mm512_loadu_ps(soa.x.as_ptr().add(i));
        let y = _mm512_loadu_ps(soa.y.as_ptr().add(i));
        let z = _mm512_loadu_ps(soa.z.as_ptr().add(i));
        // Ordered comparisons: NaN is outside.
        let inside_1d =
            |v: __m512| _mm512_cmp_ps_mask::<_CMP_GE_OQ>(v, zero) & _mm512_cmp_ps_mask::<_CMP_LE_OQ>(v, one);
        let inside = inside_1d(x) & inside_1d(y) & inside_1d(z);
        // max(q, 0) returns 0 for NaN q, so the cell index is always valid.
        let locate = |v: __m512| {
            let q = _mm512_min_ps(_mm512_max_ps(_mm512_mul_ps(v, r), zero), r);
            let f = _mm512_min_ps(_mm512_roundscale_ps::<{ _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC }>(q), r_minus_1);
            (_mm512_cvttps_epi32(f), _mm512_sub_ps(q, f))
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
        let x1 = _mm512_add_epi32(cx, _mm512_set1_epi32(1));
        let y0 = _mm512_mullo_epi32(cy, _mm512_set1_epi32(sy as i32));
        let y1 = _mm512_add_epi32(y0, _mm512_set1_epi32(sy as i32));
        let z0 = _mm512_mullo_epi32(cz, _mm512_set1_epi32(sz as i32));
        let z1 = _mm512_add_epi32(z0, _mm512_set1_epi32(sz as i32));
        let xs = [cx, x1];
        let ys = [y0, y1];
        let zs = [z0, z1];
        let wxs = [_mm512_sub_ps(one, wx), wx];
        let wys = [_mm512_sub_ps(one, wy), wy];
        let wzs = [_mm512_maskz_mov_ps(inside, _mm512_sub_ps(one, wz)), _mm512_maskz_mov_ps(inside, wz)];
        let mask = _mm512_set1_epi32((level.size as u32).wrapping_sub(1) as i32);
        let mut idx = [_mm512_setzero_si512(); 8];
        let mut w = [zero; 8];
        for c in 0..8 {
            let (bx, by, bz) = (c & 1, (c >> 1) & 1, (c >> 2) & 1);
            idx[c] = if level.dense {
                _mm512_add_epi32(_mm512_add_epi32(xs[bx], ys[by]), zs[bz])
            } else {
                _mm512_and_si512(_mm512_xor_si512(_mm512_xor_si512(xs[bx], ys[by]), zs[bz]), mask)
            };
            w[c] = _mm512_mul_ps(wxs[bx], _mm512_mul_ps(wys[by], wzs[bz]));
        }
        (idx, w)
    }
}

/// AVX-512 twin of [`super::scalar::forward_level`].
///
/// # Safety
/// The CPU must support AVX-512F; `table` is the level's slice.
#[target_feature(enable = "avx512f")]
unsafe fn forward_level_unchecked(
    level: &LevelInfo,
    table: &[u32],
    soa: &Soa,
    n: usize,
    out: &mut [f32],
    stride: usize,
) {
    assert!(table.len() >= level.size, "hash grid: level table too short");
    let dup_lo = _mm512_setr_epi32(0, 0, 1, 1, 2, 2, 3, 3, 4, 4, 5, 5, 6, 6, 7, 7);
    let dup_hi = _mm512_setr_epi32(8, 8, 9, 9, 10, 10, 11, 11, 12, 12, 13, 13, 14, 14, 15, 15);
    let base = table.as_ptr() as *const i32;
    let mut pairs = [0f32; 32];
    let mut i = 0;
    while i < n {
        // SAFETY: i + 16 <= CHUNK (CHUNK is a multiple of 16); every index is < level.size
        // (clamped cell, dense extent or hash mask), so the gathers read inside `table`.
        unsafe {
            let (idx, w) = corners16(level, soa, i);
            let mut acc_lo = _mm512_setzero_ps();
            let mut acc_hi = _mm512_setzero_ps();
            for c in 0..8 {
                let g = _mm512_i32gather_epi32::<4>(idx[c], base);
                let lo = _mm512_cvtph_ps(_mm512_castsi512_si256(g));
                let hi = _mm512_cvtph_ps(_mm512_extracti64x4_epi64::<1>(g));
                acc_lo = _mm512_fmadd_ps(lo, _mm512_permutexvar_ps(dup_lo, w[c]), acc_lo);
                acc_hi = _mm512_fmadd_ps(hi, _mm512_permutexvar_ps(dup_hi, w[c]), acc_hi);
            }
            _mm512_storeu_ps(pairs.as_mut_ptr(), acc_lo);
            _mm512_storeu_ps(pairs.as_mut_ptr().add(16), acc_hi);
        }
        for s in 0..(n - i).min(16) {
            let o = (i + s) * stride;
            out[o] = pairs[2 * s];
            out[o + 1] = pairs[2 * s + 1];
        }
        i += 16;
    }
}

safe_entry!(Avx512, forward_level => forward_level_unchecked(level: &LevelInfo, table: &[u32], soa: &Soa, n: usize, out: &mut [f32], stride: usize));
