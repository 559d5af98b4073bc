//! AMX-BF16 layer product: `out = relu?(x·W)` on the tile unit, the MLP's forward and dL/dx
//! products at [`CpuLevel::Amx`](crate::simd::CpuLevel::Amx).
//!
//! **Numerics.** `x` is rounded to bf16 (round to nearest even, `vcvtne2ps2bf16`) as it is
//! staged for the tiles; `W` arrives already rounded and packed ([`super::pack_vnni`], once per
//! optimiser step in `MlpParams::sync`). `tdpbf16ps` multiplies bf16 pairs (exactly, in fp32)
//! and sums them into fp32 accumulators, 32 k-values per instruction in the unit's own order,
//! so its sums differ from [`scalar::matmul_bf16`](super::scalar::matmul_bf16), the twin that
//! defines the rounding, by fp32 summation order only. Each output's value depends on its row
//! of `x` and its column of `W` alone (not on the tile it falls in), so results do not depend
//! on the batch split or the thread count.
//!
//! **Tiling.** All 8 tile registers are 16 rows × 64 bytes: per block of 32 rows × 32 columns,
//! two `A` tiles (16 rows × 32 k-values of `x`, bf16), two `B` tiles (32 k-values × 16
//! columns of `W`, in the VNNI pair layout) and four fp32 accumulators. A block of 16 rows or
//! 16 columns runs the same instructions on half the tiles. `x` is staged per 32-row block into
//! a stack buffer (zero rows below the last, zero columns past `k`); full 16-row accumulators
//! are stored straight into `out`, a partial last one into a stack buffer first.
//!
//! The tile state is configured (`ldtilecfg`) at the start of each call and released
//! (`tilerelease`) at its end: no tile register carries anything between calls, and the
//! compiler never emits tile instructions of its own.

use std::arch::asm;
use std::arch::x86_64::*;

use crate::simd::safe_entry;

/// Widest `k` (input width) the stack staging buffer takes.
pub const MAX_K: usize = 256;

/// The tile configuration (palette 1): 8 tiles of 16 rows × 64 bytes.
#[repr(C, align(64))]
struct TileConfig([u8; 64]);

const fn tile_config() -> TileConfig {
    let mut c = [0u8; 64];
    c[0] = 1;
    let mut t = 0;
    while t < 8 {
        c[16 + 2 * t] = 64;
        c[48 + t] = 16;
        t += 1;
    }
    TileConfig(c)
}

static CONFIG: TileConfig = tile_config();

/// Stages rows `b0..b0+n` of `x` (`k` wide, `n ≤ 32`) as bf16 at `a` (32 rows × `k32`),
/// zero past column `k` and below row `n`: every value of the 32 rows is written.
///
/// # Safety
/// AVX-512F/BW/BF16; rows `b0..b0+n` of `x` in bounds; `a` writable for 32 × `k32` values.
#[target_feature(enable = "avx512f,avx512bw,avx512bf16")]
unsafe fn stage_rows(x: &[f32], k: usize, b0: usize, n: usize, k32: usize, a: *mut u16) {
    // SAFETY: every load is masked to columns < k of a row < b0+n (in bounds by the caller's
    // contract), and every store writes 32 values inside row r of `a` (32 × k32 values).
    unsafe {
        for r in 0..32 {
            let dst = a.add(r * k32);
            if r >= n {
                for c in (0..k32).step_by(32) {
                    _mm512_storeu_si512(dst.add(c) as *mut _, _mm512_setzero_si512());
                }
                continue;
            }
            let src = x.as_ptr().add((b0 + r) * k);
            for c in (0..k32).step_by(32) {
                let m = |from: usize| -> __mmask16 {
                    let left = k.saturating_sub(from).min(16);
                    ((1u32 << left) - 1) as __mmask16
                };
                let lo = _mm512_maskz_loadu_ps(m(c), src.add(c.min(k)));
                let hi = _mm512_maskz_loadu_ps(m(c + 16), src.add((c + 16).min(k)));
                let v = _mm512_cvtne2ps_pbh(hi, lo);
                _mm512_storeu_si512(dst.add(c) as *mut _, std::mem::transmute::<__m512bh, __m512i>(v));
            }
        }
    }
}

safe_entry!(Amx, matmul => matmul_unchecked(x: &[f32], rows: usize, k: usize, packed: &[u16], o: usize, out: &mut [f32], relu: bool));

/// `out (rows × o) = relu?(bf16(x) · W)`, `W` packed by [`super::pack_vnni`]. Requires `o % 16 == 0`,
/// `k ≤ MAX_K`.
///
/// # Safety
/// AMX-BF16 with the tile state permitted, AVX-512F/BW/BF16.
#[target_feature(enable = "avx512f,avx512bw,avx512bf16")]
unsafe fn matmul_unchecked(x: &[f32], rows: usize, k: usize, packed: &[u16], o: usize, out: &mut [f32], relu: bool) {
    let k32 = k.next_multiple_of(32);
    assert!(o.is_multiple_of(16) && k <= MAX_K, "amx matmul: o must be a multiple of 16, k at most {MAX_K}");
    assert!(x.len() >= rows * k && out.len() >= rows * o && packed.len() >= k32 * o, "amx matmul: buffers too short");
    if rows == 0 {
        return;
    }
    // Staging buffers, written before they are read (stage_rows writes all 32 rows; a tile
    // store fills `part` before it is copied from): left uninitialised, not cleared per call.
    let mut a = std::mem::MaybeUninit::<[u16; 32 * MAX_K]>::uninit();
    let a = a.as_mut_ptr() as *mut u16;
    let mut part = std::mem::MaybeUninit::<[f32; 16 * 16]>::uninit();
    let part = part.as_mut_ptr() as *mut f32;
    // Byte strides: staged x rows, packed W pair-rows, out rows, the partial-tile buffer.
    let (sa, sb, so, sp) = (2 * k32, 4 * o, 4 * o, 4 * 16);
    // SAFETY: CONFIG is a valid palette-1 configuration; the level guarantees AMX and the
    // permission (checked at detection).
    unsafe { asm!("ldtilecfg [{}]", in(reg) CONFIG.0.as_ptr(), options(nostack, readonly)) };
    for b0 in (0..rows).step_by(32) {
        let n = (rows - b0).min(32);
        // SAFETY: rows b0..b0+n of x are in bounds (asserted above); `a` is 32 × MAX_K ≥ 32 × k32.
        unsafe { stage_rows(x, k, b0, n, k32, a) };
        let two_rows = n > 16;
        for j in (0..o).step_by(32) {
            let two_cols = j + 16 < o;
            // SAFETY: the A tiles read 16 rows of `sa` bytes from `a` (32 rows × k32 staged);
            // the B tiles read 16 pair-rows of 64 bytes at column j (and j + 16 when
            // two_cols) of the packed k32 × o matrix. Tiles 0-3 accumulate, 4-5 hold x, 6-7 W.
            unsafe {
                asm!("tilezero tmm0", "tilezero tmm1", "tilezero tmm2", "tilezero tmm3", options(nostack, nomem));
                for kk in (0..k32).step_by(32) {
                    let ap = a.add(kk) as *const u16;
                    let bp = packed.as_ptr().add((kk / 2) * 2 * o + 2 * j);
                    match (two_rows, two_cols) {
                        (true, true) => asm!(
                            "tileloadd tmm4, [{a} + {sa}*1]",
                            "tileloadd tmm5, [{a2} + {sa}*1]",
                            "tileloadd tmm6, [{b} + {sb}*1]",
                            "tileloadd tmm7, [{b2} + {sb}*1]",
                            "tdpbf16ps tmm0, tmm4, tmm6",
                            "tdpbf16ps tmm1, tmm4, tmm7",
                            "tdpbf16ps tmm2, tmm5, tmm6",
                            "tdpbf16ps tmm3, tmm5, tmm7",
                            a = in(reg) ap, a2 = in(reg) ap.add(16 * k32), sa = in(reg) sa,
                            b = in(reg) bp, b2 = in(reg) bp.add(32), sb = in(reg) sb,
                            options(nostack, readonly)),
                        (true, false) => asm!(
                            "tileloadd tmm4, [{a} + {sa}*1]",
                            "tileloadd tmm5, [{a2} + {sa}*1]",
                            "tileloadd tmm6, [{b} + {sb}*1]",
                            "tdpbf16ps tmm0, tmm4, tmm6",
                            "tdpbf16ps tmm2, tmm5, tmm6",
                            a = in(reg) ap, a2 = in(reg) ap.add(16 * k32), sa = in(reg) sa,
                            b = in(reg) bp, sb = in(reg) sb,
                            options(nostack, readonly)),
                        (false, true) => asm!(
                            "tileloadd tmm4, [{a} + {sa}*1]",
                            "tileloadd tmm6, [{b} + {sb}*1]",
                            "tileloadd tmm7, [{b2} + {sb}*1]",
                            "tdpbf16ps tmm0, tmm4, tmm6",
                            "tdpbf16ps tmm1, tmm4, tmm7",
                            a = in(reg) ap, sa = in(reg) sa,
                            b = in(reg) bp, b2 = in(reg) bp.add(32), sb = in(reg) sb,
                            options(nostack, readonly)),
                        (false, false) => asm!(
                            "tileloadd tmm4, [{a} + {sa}*1]",
                            "tileloadd tmm6, [{b} + {sb}*1]",
                            "tdpbf16ps tmm0, tmm4, tmm6",
                            a = in(reg) ap, sa = in(reg) sa,
                            b = in(reg) bp, sb = in(reg) sb,
                            options(nostack, readonly)),
                    }
                }
            }
            // Store the accumulators: tile 0 (rows 0-15, column j), 1 (j + 16), 2 (rows
            // 16-31, j), 3 (rows 16-31, j + 16).
            for (t, dr, dc) in [(0, 0, 0), (1, 0, 16), (2, 16, 0), (3, 16, 16)] {
                if (dc == 16 && !two_cols) || (dr == 16 && !two_rows) {
                    continue;
                }
                let r0 = b0 + dr;
                let valid = (rows - r0).min(16);
                if valid == 16 {
                    // SAFETY: rows r0..r0+16 and columns j+dc..j+dc+16 of out are in bounds.
                    unsafe { store_tile(t, out.as_mut_ptr().add(r0 * o + j + dc), so) };
                    if relu {
                        for r in 0..16 {
                            let row = &mut out[(r0 + r) * o + j + dc..][..16];
                            row.iter_mut().for_each(|v| *v = v.max(0.0));
                        }
                    }
                } else {
                    // SAFETY: `part` holds 16 rows of 16 floats (`sp` bytes), all of which
                    // the store initialises.
                    let part = unsafe {
                        store_tile(t, part, sp);
                        std::slice::from_raw_parts(part, 16 * 16)
                    };
                    for r in 0..valid {
                        let row = &mut out[(r0 + r) * o + j + dc..][..16];
                        for (d, &s) in row.iter_mut().zip(&part[r * 16..r * 16 + 16]) {
                            *d = if relu { s.max(0.0) } else { s };
                        }
                    }
                }
            }
        }
    }
    // SAFETY: releases the tile state configured above.
    unsafe { asm!("tilerelease", options(nostack, nomem)) };
}

/// Stores accumulator tile `t` (0-3), 16 rows of 64 bytes, at `p` with byte stride `stride`.
///
/// # Safety
/// Tiles configured; 16 rows of 64 bytes at `p`, `stride` apart, writable.
#[inline(always)]
unsafe fn store_tile(t: usize, p: *mut f32, stride: usize) {
    // SAFETY: the caller guarantees the 16 × 64-byte destination.
    unsafe {
        match t {
            0 => asm!("tilestored [{p} + {s}*1], tmm0", p = in(reg) p, s = in(reg) stride, options(nostack)),
            1 => asm!("tilestored [{p} + {s}*1], tmm1", p = in(reg) p, s = in(reg) stride, options(nostack)),
            2 => asm!("tilestored [{p} + {s}*1], tmm2", p = in(reg) p, s = in(reg) stride, options(nostack)),
            _ => asm!("tilestored [{p} + {s}*1], tmm3", p = in(reg) p, s = in(reg) stride, options(nostack)),
        }
    }
}

safe_entry!(Amx, tile_peak_entry => tile_peak_loop_unchecked(iters: u64, sink: &mut [f32; 256]));

/// See [`tile_peak_loop_unchecked`]; for `bench::peak`.
pub(crate) fn tile_peak_loop(isa: crate::simd::Isa, iters: u64, sink: &mut [f32; 256]) {
    tile_peak_entry(isa, iters, sink)
}

/// The tile unit's limit: `iters` rounds of four independent `tdpbf16ps` (16 × 16 outputs ×
/// 32 k-values each, 65 536 FLOPs per round) on operands loaded once; accumulator 0 is
/// stored to `sink` so the work is observable. For `rnerf bench`'s peak beside the FMA loop.
///
/// # Safety
/// AMX-BF16 with the tile state permitted.
unsafe fn tile_peak_loop_unchecked(iters: u64, sink: &mut [f32; 256]) {
    let ones = [0x3f80u16; 512]; // bf16 1.0: 16 rows × 64 bytes
                                 // SAFETY: CONFIG is a valid configuration; the operand tiles read 16 rows of 64 bytes from
                                 // `ones` (stride 64), the store writes 16 rows of 64 bytes into `sink`.
    unsafe {
        asm!("ldtilecfg [{}]", in(reg) CONFIG.0.as_ptr(), options(nostack, readonly));
        asm!(
            "tilezero tmm0", "tilezero tmm1", "tilezero tmm2", "tilezero tmm3",
            "tileloadd tmm4, [{p} + {s}*1]", "tileloadd tmm5, [{p} + {s}*1]",
            "tileloadd tmm6, [{p} + {s}*1]", "tileloadd tmm7, [{p} + {s}*1]",
            p = in(reg) ones.as_ptr(), s = in(reg) 64usize, options(nostack, readonly));
        for _ in 0..iters {
            asm!(
                "tdpbf16ps tmm0, tmm4, tmm6",
                "tdpbf16ps tmm1, tmm4, tmm7",
                "tdpbf16ps tmm2, tmm5, tmm6",
                "tdpbf16ps tmm3, tmm5, tmm7",
                options(nostack, nomem)
            );
        }
        store_tile(0, sink.as_mut_ptr(), 64);
        asm!("tilerelease", options(nostack, nomem));
    }
}

/// FLOPs of one round of [`tile_peak_loop`].
pub(crate) const TILE_PEAK_FLOPS_PER_ITER: f64 = 4.0 * 16.0 * 16.0 * 32.0 * 2.0;
