//! AVX2+FMA MLP kernels: register tiles of `R` rows × 16 columns (2R ymm accumulators; R = 6
//! fills 12 of the 16 registers, enough independent FMA chains to cover the FMA latency on
//! both ports), the weight row loaded once per k and each input broadcast.
//! Twin of [`super::scalar`]. Requires `o % 16 == 0` and `k % 4 == 0` (widths are padded to 16).

use crate::simd::safe_entry;
use std::arch::x86_64::*;

/// Rows per register tile in the main loop.
const R: usize = 6;

/// `out[b0..b0+RR][j..j+16] = relu?(x[b0..b0+RR] · w[:, j..j+16])`.
///
/// # Safety
/// AVX2+FMA; rows `b0..b0+RR` of `x` (`k` wide) and `out` (`o` wide), columns `j..j+16`
/// and `k` rows of `w` are in bounds.
#[inline(always)]
unsafe fn tile_fwd<const RR: usize>(
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
        let zero = _mm256_setzero_ps();
        let mut c = [[zero; 2]; RR];
        for kk in 0..k {
            let w0 = _mm256_loadu_ps(wp.add(kk * o + j));
            let w1 = _mm256_loadu_ps(wp.add(kk * o + j + 8));
            for r in 0..RR {
                let xv = _mm256_broadcast_ss(&*xp.add((b0 + r) * k + kk));
                c[r][0] = _mm256_fmadd_ps(xv, w0, c[r][0]);
                c[r][1] = _mm256_fmadd_ps(xv, w1, c[r][1]);
            }
        }
        for r in 0..RR {
            let (mut lo, mut hi) = (c[r][0], c[r][1]);
            if relu {
                lo = _mm256_max_ps(lo, zero);
                hi = _mm256_max_ps(hi, zero);
            }
            _mm256_storeu_ps(op.add((b0 + r) * o + j), lo);
            _mm256_storeu_ps(op.add((b0 + r) * o + j + 8), hi);
        }
    }
}

/// AVX2 twin of [`super::scalar::matmul`].
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
unsafe fn matmul_unchecked(x: &[f32], rows: usize, k: usize, w: &[f32], o: usize, out: &mut [f32], relu: bool) {
    assert!(o.is_multiple_of(16) && x.len() >= rows * k && w.len() >= k * o && out.len() >= rows * o);
    let (xp, wp, op) = (x.as_ptr(), w.as_ptr(), out.as_mut_ptr());
    let mut b = 0;
    while b + R <= rows {
        for j in (0..o).step_by(16) {
            // SAFETY: b + R <= rows, j + 16 <= o; the assert bounds x, w and out.
            unsafe { tile_fwd::<R>(xp, k, wp, o, op, b, j, relu) };
        }
        b += R;
    }
    // Remainder rows: the widest tiles that fit (a 1-row tile has only 2 FMA chains).
    while b < rows {
        let left = rows - b;
        for j in (0..o).step_by(16) {
            // SAFETY: b + tile rows <= rows, j + 16 <= o; the assert bounds x, w and out.
            unsafe {
                match left {
                    4.. => tile_fwd::<4>(xp, k, wp, o, op, b, j, relu),
                    2..=3 => tile_fwd::<2>(xp, k, wp, o, op, b, j, relu),
                    _ => tile_fwd::<1>(xp, k, wp, o, op, b, j, relu),
                }
            }
        }
        b += match left {
            4.. => 4,
            2..=3 => 2,
            _ => 1,
        };
    }
}

/// The columns of an 8×8 block: `rows[i][j]` → `out[j][i]`.
///
/// # Safety
/// AVX2.
#[inline(always)]
unsafe fn transpose8(r: [__m256; 8]) -> [__m256; 8] {
    // SAFETY: register-only AVX operations; the caller guarantees AVX2.
    unsafe {
        let t0 = _mm256_unpacklo_ps(r[0], r[1]);
        let t1 = _mm256_unpackhi_ps(r[0], r[1]);
        let t2 = _mm256_unpacklo_ps(r[2], r[3]);
        let t3 = _mm256_unpackhi_ps(r[2], r[3]);
        let t4 = _mm256_unpacklo_ps(r[4], r[5]);
        let t5 = _mm256_unpackhi_ps(r[4], r[5]);
        let t6 = _mm256_unpacklo_ps(r[6], r[7]);
        let t7 = _mm256_unpackhi_ps(r[6], r[7]);
        let u0 = _mm256_shuffle_ps::<0x44>(t0, t2);
        let u1 = _mm256_shuffle_ps::<0xEE>(t0, t2);
        let u2 = _mm256_shuffle_ps::<0x44>(t1, t3);
        let u3 = _mm256_shuffle_ps::<0xEE>(t1, t3);
        let u4 = _mm256_shuffle_ps::<0x44>(t4, t6);
        let u5 = _mm256_shuffle_ps::<0xEE>(t4, t6);
        let u6 = _mm256_shuffle_ps::<0x44>(t5, t7);
        let u7 = _mm256_shuffle_ps::<0xEE>(t5, t7);
        [
            _mm256_permute2f128_ps::<0x20>(u0, u4),
            _mm256_permute2f128_ps::<0x20>(u1, u5),
            _mm256_permute2f128_ps::<0x20>(u2, u6),
            _mm256_permute2f128_ps::<0x20>(u3, u7),
            _mm256_permute2f128_ps::<0x31>(u0, u4),
            _mm256_permute2f128_ps::<0x31>(u1, u5),
            _mm256_permute2f128_ps::<0x31>(u2, u6),
            _mm256_permute2f128_ps::<0x31>(u3, u7),
        ]
    }
}

/// AVX2 twin of [`super::scalar::matmul_first`]: 8 rows per vector (lane = row), the rows'
/// 8×8 blocks transposed in registers so each lane runs [`tile_fwd`]'s FMA chain for column 0
/// — the same bits as [`matmul`]'s column 0.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
unsafe fn matmul_first_unchecked(x: &[f32], rows: usize, k: usize, w: &[f32], o: usize, out: &mut [f32], relu: bool) {
    assert!(k.is_multiple_of(8) && x.len() >= rows * k && w.len() >= k * o && out.len() >= rows);
    let (xp, wp) = (x.as_ptr(), w.as_ptr());
    let zero = _mm256_setzero_ps();
    let mut b = 0;
    while b + 8 <= rows {
        let mut acc = zero;
        for k0 in (0..k).step_by(8) {
            // SAFETY: rows b..b+8 and columns k0..k0+8 of x, rows k0..k0+8 of w are in bounds
            // (asserted above); out has b + 8 <= rows values.
            unsafe {
                let block = transpose8(std::array::from_fn(|i| _mm256_loadu_ps(xp.add((b + i) * k + k0))));
                for (c, col) in block.into_iter().enumerate() {
                    acc = _mm256_fmadd_ps(col, _mm256_set1_ps(*wp.add((k0 + c) * o)), acc);
                }
            }
        }
        if relu {
            acc = _mm256_max_ps(acc, zero);
        }
        // SAFETY: b + 8 <= rows <= out.len().
        unsafe { _mm256_storeu_ps(out.as_mut_ptr().add(b), acc) };
        b += 8;
    }
    super::first_column_fma(x, k, w, o, b..rows, out, relu);
}

/// `dw[kk0..kk0+KK][j..j+16] += Σ_b x[b][kk0..kk0+KK]ᵀ · dz[b][j..j+16]`.
///
/// # Safety
/// AVX2+FMA; `rows` rows of `x` (`k` wide) and `dz` (`o` wide), columns `kk0..kk0+KK` of `x`,
/// rows `kk0..kk0+KK` and columns `j..j+16` of `dw` are in bounds.
#[inline(always)]
unsafe fn tile_tn<const KK: usize>(
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
        let zero = _mm256_setzero_ps();
        let mut c = [[zero; 2]; KK];
        for b in 0..rows {
            let d0 = _mm256_loadu_ps(dp.add(b * o + j));
            let d1 = _mm256_loadu_ps(dp.add(b * o + j + 8));
            for r in 0..KK {
                let xv = _mm256_broadcast_ss(&*xp.add(b * k + kk0 + r));
                c[r][0] = _mm256_fmadd_ps(xv, d0, c[r][0]);
                c[r][1] = _mm256_fmadd_ps(xv, d1, c[r][1]);
            }
        }
        for r in 0..KK {
            let p = wp.add((kk0 + r) * o + j);
            _mm256_storeu_ps(p, _mm256_add_ps(_mm256_loadu_ps(p), c[r][0]));
            _mm256_storeu_ps(p.add(8), _mm256_add_ps(_mm256_loadu_ps(p.add(8)), c[r][1]));
        }
    }
}

/// AVX2 twin of [`super::scalar::matmul_tn_acc`]: tiles of 6 (then 4, 2, 1) weight rows ×
/// 16 columns accumulated in registers over all `rows` samples, then added to `dw`.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
unsafe fn matmul_tn_acc_unchecked(x: &[f32], rows: usize, k: usize, dz: &[f32], o: usize, dw: &mut [f32]) {
    assert!(o.is_multiple_of(16) && x.len() >= rows * k && dz.len() >= rows * o && dw.len() >= k * o);
    let (xp, dp, wp) = (x.as_ptr(), dz.as_ptr(), dw.as_mut_ptr());
    for j in (0..o).step_by(16) {
        let mut kk = 0;
        while kk + R <= k {
            // SAFETY: kk + R <= k, j + 16 <= o; the assert bounds x, dz and dw.
            unsafe { tile_tn::<R>(xp, rows, k, dp, o, wp, kk, j) };
            kk += R;
        }
        while kk + 2 <= k {
            // SAFETY: kk + 2 <= k, j + 16 <= o; the assert bounds x, dz and dw.
            unsafe { tile_tn::<2>(xp, rows, k, dp, o, wp, kk, j) };
            kk += 2;
        }
        if kk < k {
            // SAFETY: kk < k, j + 16 <= o; the assert bounds x, dz and dw.
            unsafe { tile_tn::<1>(xp, rows, k, dp, o, wp, kk, j) };
        }
    }
}

safe_entry!(Avx2, matmul => matmul_unchecked(x: &[f32], rows: usize, k: usize, w: &[f32], o: usize, out: &mut [f32], relu: bool));

safe_entry!(Avx2, matmul_first => matmul_first_unchecked(x: &[f32], rows: usize, k: usize, w: &[f32], o: usize, out: &mut [f32], relu: bool));

safe_entry!(Avx2, matmul_tn_acc => matmul_tn_acc_unchecked(x: &[f32], rows: usize, k: usize, dz: &[f32], o: usize, dw: &mut [f32]));
