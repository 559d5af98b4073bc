//! AVX-512F MLP kernels: register tiles of `RR` rows × `CC` vectors of 16 columns, up to 24
//! zmm accumulators (of 32 registers) — 6 rows × 64 columns on the 64-wide layers, 12 × 32,
//! 12 × 16 — the weight vectors loaded once per k and each input broadcast. Every output
//! runs the same fused multiply-add chain as in [`super::avx2`] (from zero, k in order, one
//! FMA per term), so the two levels give the same bits; the tiling only changes which
//! chains run side by side. Twin of [`super::scalar`]. Requires `o % 16 == 0`.

use crate::simd::safe_entry;
use std::arch::x86_64::*;

/// `out[b0..b0+RR][j..j+16·CC] = relu?(x[b0..b0+RR] · w[:, j..j+16·CC])`.
///
/// # Safety
/// AVX-512F; rows `b0..b0+RR` of `x` (`k` wide) and `out` (`o` wide), columns `j..j+16·CC`
/// and `k` rows of `w` are in bounds.
#[inline(always)]
unsafe fn tile_fwd<const RR: usize, const CC: usize>(
    xp: *const f32,
    k: usize,
    wp: *const f32,
    o: usize,
    op: *mut f32,
    b0: usize,
    j: usize,
    relu: bool,
) {
    // SAFETY: the caller guarantees every pointer offset below is in bounds.
    unsafe {
        let zero = _mm512_setzero_ps();
        let mut c = [[zero; CC]; RR];
        for kk in 0..k {
            let w: [__m512; CC] = std::array::from_fn(|cc| _mm512_loadu_ps(wp.add(kk * o + j + 16 * cc)));
            for r in 0..RR {
                let xv = _mm512_set1_ps(*xp.add((b0 + r) * k + kk));
                for cc in 0..CC {
                    c[r][cc] = _mm512_fmadd_ps(xv, w[cc], c[r][cc]);
                }
            }
        }
        for r in 0..RR {
            for cc in 0..CC {
                let v = if relu { _mm512_max_ps(c[r][cc], zero) } else { c[r][cc] };
                _mm512_storeu_ps(op.add((b0 + r) * o + j + 16 * cc), v);
            }
        }
    }
}

/// The rows (or weight rows) the next tile takes when `left` remain: a full tile of `full`,
/// else the widest of 4, 2 and 1 that fits (a 1-row tile has only `CC` FMA chains).
#[inline(always)]
fn tile_step(left: usize, full: usize) -> usize {
    match left {
        l if l >= full => full,
        4.. => 4,
        2..=3 => 2,
        _ => 1,
    }
}

/// All rows of `x · w` in tiles of `R` rows × `CC` column vectors, the remainder rows in
/// tiles of 4, 2 and 1 ([`tile_step`]). `o` must be a multiple of `16·CC`.
///
/// # Safety
/// AVX-512F; `x`, `w` and `out` hold `rows × k`, `k × o` and `rows × o` values.
#[inline(always)]
unsafe fn matmul_tiles<const R: usize, const CC: usize>(
    xp: *const f32,
    rows: usize,
    k: usize,
    wp: *const f32,
    o: usize,
    op: *mut f32,
    relu: bool,
) {
    let mut b = 0;
    while b < rows {
        let step = tile_step(rows - b, R);
        for j in (0..o).step_by(16 * CC) {
            // SAFETY: b + step <= rows, j + 16·CC <= o; the caller bounds x, w and out.
            unsafe {
                match step {
                    s if s == R => tile_fwd::<R, CC>(xp, k, wp, o, op, b, j, relu),
                    4 => tile_fwd::<4, CC>(xp, k, wp, o, op, b, j, relu),
                    2 => tile_fwd::<2, CC>(xp, k, wp, o, op, b, j, relu),
                    _ => tile_fwd::<1, CC>(xp, k, wp, o, op, b, j, relu),
                }
            }
        }
        b += step;
    }
}

/// AVX-512 twin of [`super::scalar::matmul`].
///
/// # Safety
/// The CPU must support AVX-512F.
#[target_feature(enable = "avx512f")]
unsafe fn matmul_unchecked(x: &[f32], rows: usize, k: usize, w: &[f32], o: usize, out: &mut [f32], relu: bool) {
    assert!(o.is_multiple_of(16) && x.len() >= rows * k && w.len() >= k * o && out.len() >= rows * o);
    let (xp, wp, op) = (x.as_ptr(), w.as_ptr(), out.as_mut_ptr());
    // SAFETY: the assert bounds x, w and out; each arm's o is a multiple of its 16·CC.
    unsafe {
        if o.is_multiple_of(64) {
            matmul_tiles::<6, 4>(xp, rows, k, wp, o, op, relu)
        } else if o.is_multiple_of(32) {
            matmul_tiles::<12, 2>(xp, rows, k, wp, o, op, relu)
        } else {
            matmul_tiles::<12, 1>(xp, rows, k, wp, o, op, relu)
        }
    }
}

/// `dw[kk0..kk0+KK][j..j+16·CC] += Σ_b x[b][kk0..kk0+KK]ᵀ · dz[b][j..j+16·CC]`.
///
/// # Safety
/// AVX-512F; `rows` rows of `x` (`k` wide) and `dz` (`o` wide), columns `kk0..kk0+KK` of `x`,
/// rows `kk0..kk0+KK` and columns `j..j+16·CC` of `dw` are in bounds.
#[inline(always)]
unsafe fn tile_tn<const KK: usize, const CC: usize>(
    xp: *const f32,
    rows: usize,
    k: usize,
    dp: *const f32,
    o: usize,
    wp: *mut f32,
    kk0: usize,
    j: usize,
) {
    // SAFETY: the caller guarantees every pointer offset below is in bounds.
    unsafe {
        let mut c = [[_mm512_setzero_ps(); CC]; KK];
        for b in 0..rows {
            let d: [__m512; CC] = std::array::from_fn(|cc| _mm512_loadu_ps(dp.add(b * o + j + 16 * cc)));
            for r in 0..KK {
                let xv = _mm512_set1_ps(*xp.add(b * k + kk0 + r));
                for cc in 0..CC {
                    c[r][cc] = _mm512_fmadd_ps(xv, d[cc], c[r][cc]);
                }
            }
        }
        for r in 0..KK {
            for cc in 0..CC {
                let p = wp.add((kk0 + r) * o + j + 16 * cc);
                _mm512_storeu_ps(p, _mm512_add_ps(_mm512_loadu_ps(p), c[r][cc]));
            }
        }
    }
}

/// `dw += xᵀ·dz` in tiles of `KK` weight rows × `CC` column vectors (remainder weight rows in
/// tiles of 4, 2 and 1), each accumulated in registers over all `rows` samples.
///
/// # Safety
/// AVX-512F; `x`, `dz` and `dw` hold `rows × k`, `rows × o` and `k × o` values; `o` is a
/// multiple of `16·CC`.
#[inline(always)]
unsafe fn tn_tiles<const KK: usize, const CC: usize>(
    xp: *const f32,
    rows: usize,
    k: usize,
    dp: *const f32,
    o: usize,
    wp: *mut f32,
) {
    for j in (0..o).step_by(16 * CC) {
        let mut kk = 0;
        while kk < k {
            let step = tile_step(k - kk, KK);
            // SAFETY: kk + step <= k, j + 16·CC <= o; the caller bounds x, dz and dw.
            unsafe {
                match step {
                    s if s == KK => tile_tn::<KK, CC>(xp, rows, k, dp, o, wp, kk, j),
                    4 => tile_tn::<4, CC>(xp, rows, k, dp, o, wp, kk, j),
                    2 => tile_tn::<2, CC>(xp, rows, k, dp, o, wp, kk, j),
                    _ => tile_tn::<1, CC>(xp, rows, k, dp, o, wp, kk, j),
                }
            }
            kk += step;
        }
    }
}

/// AVX-512 twin of [`super::scalar::matmul_tn_acc`].
///
/// # Safety
/// The CPU must support AVX-512F.
#[target_feature(enable = "avx512f")]
unsafe fn matmul_tn_acc_unchecked(x: &[f32], rows: usize, k: usize, dz: &[f32], o: usize, dw: &mut [f32]) {
    assert!(o.is_multiple_of(16) && x.len() >= rows * k && dz.len() >= rows * o && dw.len() >= k * o);
    let (xp, dp, wp) = (x.as_ptr(), dz.as_ptr(), dw.as_mut_ptr());
    // SAFETY: the assert bounds x, dz and dw; each arm's o is a multiple of its 16·CC.
    unsafe {
        if o.is_multiple_of(64) {
            tn_tiles::<6, 4>(xp, rows, k, dp, o, wp)
        } else if o.is_multiple_of(32) {
            tn_tiles::<12, 2>(xp, rows, k, dp, o, wp)
        } else {
            tn_tiles::<12, 1>(xp, rows, k, dp, o, wp)
        }
    }
}

safe_entry!(Avx512, matmul => matmul_unchecked(x: &[f32], rows: usize, k: usize, w: &[f32], o: usize, out: &mut [f32], relu: bool));

safe_entry!(Avx512, matmul_tn_acc => matmul_tn_acc_unchecked(x: &[f32], rows: usize, k: usize, dz: &[f32], o: usize, dw: &mut [f32]));
