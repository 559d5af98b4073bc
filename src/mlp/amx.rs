//! AMX-BF16 layer products on the tile unit, the MLP's products at
//! [`CpuLevel::Amx`](crate::simd::CpuLevel::Amx): `out = relu?(x·W)` ([`matmul`]: the forward,
//! and dL/dx with `Wᵀ`) and `dW += xᵀ·dz` ([`matmul_tn_acc`]: weight gradients, summed over
//! the samples — `x` staged transposed in registers, `dz` in pairs of rows).
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
//! a stack buffer (zero columns past `k`, zero rows up to the last loaded tile's end); full
//! 16-row accumulators are stored straight into `out`, a partial last one into a stack buffer
//! first. The weight gradient tiles `dW` the same way, its rows being `x`'s columns: `x` staged
//! transposed (`A`: 16 of its columns × 32 samples), `dz` in pairs of samples (`B`), each block
//! of `dW` loaded into the accumulators and stored back (through a stack buffer when `k` is not
//! a multiple of 16).
//!
//! The tile state is configured (`ldtilecfg`) once per thread, on its first call, and kept:
//! a configure + release pair costs ~56 ns (measured), and a training step makes ~9 calls per
//! 64 samples. No tile register carries anything from one call to the next (each call zeroes
//! or loads every tile it reads), and the compiler never emits tile instructions of its own.

use std::arch::asm;
use std::arch::x86_64::*;

use crate::simd::safe_entry;

/// Widest `k` (input width) the stack staging buffer takes.
pub const MAX_K: usize = 256;

thread_local! {
    /// Whether this thread has loaded [`CONFIG`].
    static CONFIGURED: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Loads [`CONFIG`] into this thread's tile state unless it already has it.
///
/// # Safety
/// AMX with the tile state permitted (the callers are AMX-level kernels).
unsafe fn configure_tiles() {
    CONFIGURED.with(|c| {
        if !c.get() {
            // SAFETY: CONFIG is a valid palette-1 configuration; the caller guarantees AMX
            // and the tile permission.
            unsafe { asm!("ldtilecfg [{}]", in(reg) CONFIG.0.as_ptr(), options(nostack, readonly)) };
            c.set(true);
        }
    });
}

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

/// Stages rows `b0..b0+n` of `x` (`k` wide, `n ≤ 32`) as bf16 at `a` (rows of `k32`), zero
/// past column `k` and in rows `n..` up to the next multiple of 16: every value the tile
/// loads read is written.
///
/// # Safety
/// AVX-512F/BW/BF16; rows `b0..b0+n` of `x` in bounds; `a` writable for 32 × `k32` values.
#[target_feature(enable = "avx512f,avx512bw,avx512bf16")]
unsafe fn stage_rows(x: &[f32], k: usize, b0: usize, n: usize, k32: usize, a: *mut u16) {
    // SAFETY: every load is masked to columns < k of a row < b0+n (in bounds by the caller's
    // contract), and every store writes 32 values inside row r of `a` (32 × k32 values).
    unsafe {
        for r in 0..n.next_multiple_of(16) {
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
    // Staging buffers, written before they are read (stage_rows writes every row a tile load
    // reads; a tile store fills `part` before it is copied from): left uninitialised.
    let mut a = std::mem::MaybeUninit::<[u16; 32 * MAX_K]>::uninit();
    let a = a.as_mut_ptr() as *mut u16;
    let mut part = std::mem::MaybeUninit::<[f32; 16 * 16]>::uninit();
    let part = part.as_mut_ptr() as *mut f32;
    // Byte strides: staged x rows, packed W pair-rows, out rows, the partial-tile buffer.
    let (sa, sb, so, sp) = (2 * k32, 4 * o, 4 * o, 4 * 16);
    // SAFETY: the level guarantees AMX and the permission (checked at detection).
    unsafe { configure_tiles() };
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
                    products(two_rows, two_cols, ap, ap.add(16 * k32), sa, bp, bp.add(32), sb);
                }
            }
            for (t, dr, dc) in accumulators(two_rows, two_cols) {
                let r0 = b0 + dr;
                let valid = (rows - r0).min(16);
                if valid == 16 {
                    // SAFETY: rows r0..r0+16 and columns j+dc..j+dc+16 of out are in bounds.
                    unsafe { store_tile(t, out.as_mut_ptr().add(r0 * o + j + dc), so) };
                } else {
                    // SAFETY: `part` holds 16 rows of 16 floats (`sp` bytes), all of which
                    // the store initialises.
                    let part = unsafe {
                        store_tile(t, part, sp);
                        std::slice::from_raw_parts(part, 16 * 16)
                    };
                    for r in 0..valid {
                        out[(r0 + r) * o + j + dc..][..16].copy_from_slice(&part[r * 16..r * 16 + 16]);
                    }
                }
            }
        }
        if relu {
            out[b0 * o..(b0 + n) * o].iter_mut().for_each(|v| *v = v.max(0.0));
        }
    }
}

/// Rows of `x` and `dz` one pass of [`matmul_tn_acc`] stages (a training chunk's [`super::TILE`]).
const TN_ROWS: usize = 64;

/// Transposes the 16 × 16 block whose rows are `r` (16 lanes each): lane `i` of result `c`
/// is lane `c` of row `i`. Unpacks, in-lane shuffles, then two 128-bit-lane shuffles.
#[target_feature(enable = "avx512f")]
fn transpose16(r: [__m512; 16]) -> [__m512; 16] {
    let mut t = [_mm512_setzero_ps(); 16];
    for i in 0..8 {
        t[2 * i] = _mm512_unpacklo_ps(r[2 * i], r[2 * i + 1]);
        t[2 * i + 1] = _mm512_unpackhi_ps(r[2 * i], r[2 * i + 1]);
    }
    let mut u = [_mm512_setzero_ps(); 16];
    for i in 0..4 {
        u[4 * i] = _mm512_shuffle_ps::<0x44>(t[4 * i], t[4 * i + 2]);
        u[4 * i + 1] = _mm512_shuffle_ps::<0xEE>(t[4 * i], t[4 * i + 2]);
        u[4 * i + 2] = _mm512_shuffle_ps::<0x44>(t[4 * i + 1], t[4 * i + 3]);
        u[4 * i + 3] = _mm512_shuffle_ps::<0xEE>(t[4 * i + 1], t[4 * i + 3]);
    }
    let mut v = [_mm512_setzero_ps(); 16];
    for i in 0..4 {
        v[i] = _mm512_shuffle_f32x4::<0x88>(u[i], u[i + 4]);
        v[i + 4] = _mm512_shuffle_f32x4::<0xDD>(u[i], u[i + 4]);
        v[i + 8] = _mm512_shuffle_f32x4::<0x88>(u[i + 8], u[i + 12]);
        v[i + 12] = _mm512_shuffle_f32x4::<0xDD>(u[i + 8], u[i + 12]);
    }
    let mut w = [_mm512_setzero_ps(); 16];
    for i in 0..4 {
        w[i] = _mm512_shuffle_f32x4::<0x88>(v[i], v[i + 8]);
        w[i + 8] = _mm512_shuffle_f32x4::<0xDD>(v[i], v[i + 8]);
        w[i + 4] = _mm512_shuffle_f32x4::<0x88>(v[i + 4], v[i + 12]);
        w[i + 12] = _mm512_shuffle_f32x4::<0xDD>(v[i + 4], v[i + 12]);
    }
    w
}

/// Stages rows `b0..b0+n` (`n ≤ TN_ROWS`) of `x` (`k` wide) transposed, as bf16: `xt[kk][r]`
/// (rows of `r32 = n` rounded up to 32), zero for `r ≥ n` and for `kk` in `k..k16`. Blocks of
/// 32 rows × 16 columns: two register transposes, then each column's 32 values converted.
///
/// # Safety
/// AVX-512F/BW/BF16; rows `b0..b0+n` of `x` in bounds; `xt` writable for `k16 × r32` values.
#[target_feature(enable = "avx512f,avx512bw,avx512bf16")]
unsafe fn stage_transposed(x: &[f32], k: usize, b0: usize, n: usize, k16: usize, r32: usize, xt: *mut u16) {
    // SAFETY: each load reads columns kk.. (masked to < k) of a row < b0 + n, in bounds by
    // the caller's contract; each store writes 32 values inside row kk + c < k16 of `xt`.
    unsafe {
        for kk in (0..k16).step_by(16) {
            let cols = ((1u32 << (k - kk).min(16)) - 1) as __mmask16;
            let rows = |r: usize| -> [__m512; 16] {
                std::array::from_fn(|i| {
                    if r + i < n {
                        _mm512_maskz_loadu_ps(cols, x.as_ptr().add((b0 + r + i) * k + kk))
                    } else {
                        _mm512_setzero_ps()
                    }
                })
            };
            for r in (0..r32).step_by(32) {
                let (lo, hi) = (transpose16(rows(r)), transpose16(rows(r + 16)));
                for c in 0..16 {
                    let v = _mm512_cvtne2ps_pbh(hi[c], lo[c]);
                    _mm512_storeu_si512(
                        xt.add((kk + c) * r32 + r) as *mut _,
                        std::mem::transmute::<__m512bh, __m512i>(v),
                    );
                }
            }
        }
    }
}

/// Stages rows `b0..b0+n` of `dz` (`o` wide, `o % 16 == 0`) as bf16 in the VNNI pair layout:
/// `dzv[r/2][2j + r%2] = dz[r][j]`, `r32 / 2` pair-rows, zero for `r ≥ n`.
///
/// # Safety
/// AVX-512F/BW/BF16; rows `b0..b0+n` of `dz` in bounds; `dzv` writable for `r32 × o` values.
#[target_feature(enable = "avx512f,avx512bw,avx512bf16")]
unsafe fn stage_pairs(dz: &[f32], o: usize, b0: usize, n: usize, r32: usize, dzv: *mut u16) {
    // SAFETY: loads read rows < b0 + n of dz (16 columns inside o); stores write 32 values
    // inside pair-row r/2 of `dzv` (r32/2 rows of 2·o values).
    unsafe {
        // [lo0, hi0, lo1, hi1, …]: lo = the even row's 16 values (the lower half of the
        // conversion), hi = the odd row's (the upper half).
        let interleave = _mm512_set_epi16(
            31, 15, 30, 14, 29, 13, 28, 12, 27, 11, 26, 10, 25, 9, 24, 8, 23, 7, 22, 6, 21, 5, 20, 4, 19, 3, 18, 2, 17,
            1, 16, 0,
        );
        let row = |r: usize, j: usize| {
            if r < n {
                _mm512_loadu_ps(dz.as_ptr().add((b0 + r) * o + j))
            } else {
                _mm512_setzero_ps()
            }
        };
        for r in (0..r32).step_by(2) {
            for j in (0..o).step_by(16) {
                let v: __m512i = std::mem::transmute(_mm512_cvtne2ps_pbh(row(r + 1, j), row(r, j)));
                let v = _mm512_permutexvar_epi16(interleave, v);
                _mm512_storeu_si512(dzv.add((r / 2) * 2 * o + 2 * j) as *mut _, v);
            }
        }
    }
}

safe_entry!(Amx, matmul_tn_acc => matmul_tn_acc_unchecked(x: &[f32], rows: usize, k: usize, dz: &[f32], o: usize, dw: &mut [f32]));

/// `dw (k × o) += bf16(x)ᵀ · bf16(dz)`, summed over the rows on the tiles, `TN_ROWS` rows per
/// pass: `x` staged transposed, `dz` in pairs of rows, blocks of 32 × 32 of `dw` loaded into
/// the accumulators, summed into and stored back. Requires `o % 16 == 0`, `k ≤ MAX_K`, `o ≤
/// MAX_K`. A block of fewer than 16 rows of `dw` (`k % 16 ≠ 0`) goes through a stack buffer.
///
/// # Safety
/// AMX-BF16 with the tile state permitted, AVX-512F/BW/BF16.
#[target_feature(enable = "avx512f,avx512bw,avx512bf16")]
unsafe fn matmul_tn_acc_unchecked(x: &[f32], rows: usize, k: usize, dz: &[f32], o: usize, dw: &mut [f32]) {
    assert!(
        o.is_multiple_of(16) && k <= MAX_K && o <= MAX_K,
        "amx matmul_tn_acc: o must be a multiple of 16, k and o at most {MAX_K}"
    );
    assert!(x.len() >= rows * k && dz.len() >= rows * o && dw.len() >= k * o, "amx matmul_tn_acc: buffers too short");
    let k16 = k.next_multiple_of(16);
    let mut xt = std::mem::MaybeUninit::<[u16; MAX_K * TN_ROWS]>::uninit();
    let xt = xt.as_mut_ptr() as *mut u16;
    let mut dzv = std::mem::MaybeUninit::<[u16; TN_ROWS * MAX_K]>::uninit();
    let dzv = dzv.as_mut_ptr() as *mut u16;
    // A partial accumulator (the rows of dw past k): 16 rows of 16 floats.
    let mut part = [0f32; 16 * 16];
    // SAFETY: the level guarantees AMX and the permission (checked at detection).
    unsafe { configure_tiles() };
    for b0 in (0..rows).step_by(TN_ROWS) {
        let n = (rows - b0).min(TN_ROWS);
        let r32 = n.next_multiple_of(32);
        // SAFETY: rows b0..b0+n of x and dz are in bounds (asserted); the buffers hold
        // MAX_K × TN_ROWS ≥ k16 × r32 and TN_ROWS × MAX_K ≥ r32 × o values.
        unsafe {
            stage_transposed(x, k, b0, n, k16, r32, xt);
            stage_pairs(dz, o, b0, n, r32, dzv);
        }
        // Byte strides: xt rows, dzv pair-rows, dw rows, the partial buffer.
        let (sa, sb, sc, sp) = (2 * r32, 4 * o, 4 * o, 4 * 16);
        for kb in (0..k16).step_by(32) {
            let two_k = kb + 16 < k16;
            for j in (0..o).step_by(32) {
                let two_j = j + 16 < o;
                // The accumulators hold blocks of dw (rows kb + dr, columns j + dc); a block
                // with fewer than 16 rows of dw (r0 < k always: k16 - k < 16) goes via `part`.
                for (t, dr, dc) in accumulators(two_k, two_j) {
                    let r0 = kb + dr;
                    let valid = (k - r0).min(16);
                    // SAFETY: a full block loads 16 rows × 16 columns of dw (in bounds); a
                    // partial one loads `part` (16 × 16 floats), its first `valid` rows
                    // copied from dw and the rest zero.
                    unsafe {
                        if valid == 16 {
                            load_tile(t, dw.as_ptr().add(r0 * o + j + dc), sc);
                        } else {
                            part.fill(0.0);
                            for r in 0..valid {
                                part[r * 16..r * 16 + 16].copy_from_slice(&dw[(r0 + r) * o + j + dc..][..16]);
                            }
                            load_tile(t, part.as_ptr(), sp);
                        }
                    }
                }
                // SAFETY: A tiles read 16 rows (kk) × 64 bytes (32 r) of xt at column r,
                // B tiles 16 pair-rows × 64 bytes of dzv at column j (and j + 16).
                unsafe {
                    for r in (0..r32).step_by(32) {
                        let ap = (xt as *const u16).add(kb * r32 + r);
                        let bp = (dzv as *const u16).add((r / 2) * 2 * o + 2 * j);
                        products(two_k, two_j, ap, ap.add(16 * r32), sa, bp, bp.add(32), sb);
                    }
                }
                for (t, dr, dc) in accumulators(two_k, two_j) {
                    let r0 = kb + dr;
                    let valid = (k - r0).min(16);
                    // SAFETY: as for the loads above.
                    unsafe {
                        if valid == 16 {
                            store_tile(t, dw.as_mut_ptr().add(r0 * o + j + dc), sc);
                        } else {
                            store_tile(t, part.as_mut_ptr(), sp);
                            for r in 0..valid {
                                dw[(r0 + r) * o + j + dc..][..16].copy_from_slice(&part[r * 16..r * 16 + 16]);
                            }
                        }
                    }
                }
            }
        }
    }
}

/// The accumulator tiles a block uses, as [`products`] assigns them: `(tile, row offset, column
/// offset)` — tile 0 at (0, 0), 1 at (0, 16) when `two_b`, 2 at (16, 0) when `two_a`, 3 at
/// (16, 16) when both.
fn accumulators(two_a: bool, two_b: bool) -> impl Iterator<Item = (usize, usize, usize)> {
    [(0, 0, 0), (1, 0, 16), (2, 16, 0), (3, 16, 16)]
        .into_iter()
        .filter(move |&(_, dr, dc)| (dc == 0 || two_b) && (dr == 0 || two_a))
}

/// Loads accumulator tile `t` (0-3), 16 rows of 64 bytes, from `p` with byte stride `stride`.
///
/// # Safety
/// Tiles configured; 16 rows of 64 bytes at `p`, `stride` apart, readable.
#[inline(always)]
unsafe fn load_tile(t: usize, p: *const f32, stride: usize) {
    // SAFETY: the caller guarantees the 16 × 64-byte source.
    unsafe {
        match t {
            0 => asm!("tileloadd tmm0, [{p} + {s}*1]", p = in(reg) p, s = in(reg) stride, options(nostack, readonly)),
            1 => asm!("tileloadd tmm1, [{p} + {s}*1]", p = in(reg) p, s = in(reg) stride, options(nostack, readonly)),
            2 => asm!("tileloadd tmm2, [{p} + {s}*1]", p = in(reg) p, s = in(reg) stride, options(nostack, readonly)),
            _ => asm!("tileloadd tmm3, [{p} + {s}*1]", p = in(reg) p, s = in(reg) stride, options(nostack, readonly)),
        }
    }
}

/// One k-step of a block: loads `A` tiles 4 (rows at `a`) and 5 (at `a2`, when `two_a`) with
/// byte stride `sa`, `B` tiles 6 (at `b`) and 7 (at `b2`, when `two_b`) with stride `sb`, and
/// accumulates their products into tiles 0 (A4·B6), 1 (A4·B7), 2 (A5·B6) and 3 (A5·B7).
///
/// # Safety
/// Tiles configured; each loaded tile's 16 rows of 64 bytes readable.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
unsafe fn products(
    two_a: bool,
    two_b: bool,
    a: *const u16,
    a2: *const u16,
    sa: usize,
    b: *const u16,
    b2: *const u16,
    sb: usize,
) {
    // SAFETY: the caller guarantees the tile configuration and the rows each load reads.
    unsafe {
        match (two_a, two_b) {
            (true, true) => asm!(
                "tileloadd tmm4, [{a} + {sa}*1]",
                "tileloadd tmm5, [{a2} + {sa}*1]",
                "tileloadd tmm6, [{b} + {sb}*1]",
                "tileloadd tmm7, [{b2} + {sb}*1]",
                "tdpbf16ps tmm0, tmm4, tmm6",
                "tdpbf16ps tmm1, tmm4, tmm7",
                "tdpbf16ps tmm2, tmm5, tmm6",
                "tdpbf16ps tmm3, tmm5, tmm7",
                a = in(reg) a, a2 = in(reg) a2, sa = in(reg) sa, b = in(reg) b, b2 = in(reg) b2, sb = in(reg) sb,
                options(nostack, readonly)),
            (true, false) => asm!(
                "tileloadd tmm4, [{a} + {sa}*1]",
                "tileloadd tmm5, [{a2} + {sa}*1]",
                "tileloadd tmm6, [{b} + {sb}*1]",
                "tdpbf16ps tmm0, tmm4, tmm6",
                "tdpbf16ps tmm2, tmm5, tmm6",
                a = in(reg) a, a2 = in(reg) a2, sa = in(reg) sa, b = in(reg) b, sb = in(reg) sb,
                options(nostack, readonly)),
            (false, true) => asm!(
                "tileloadd tmm4, [{a} + {sa}*1]",
                "tileloadd tmm6, [{b} + {sb}*1]",
                "tileloadd tmm7, [{b2} + {sb}*1]",
                "tdpbf16ps tmm0, tmm4, tmm6",
                "tdpbf16ps tmm1, tmm4, tmm7",
                a = in(reg) a, sa = in(reg) sa, b = in(reg) b, b2 = in(reg) b2, sb = in(reg) sb,
                options(nostack, readonly)),
            (false, false) => asm!(
                "tileloadd tmm4, [{a} + {sa}*1]",
                "tileloadd tmm6, [{b} + {sb}*1]",
                "tdpbf16ps tmm0, tmm4, tmm6",
                a = in(reg) a, sa = in(reg) sa, b = in(reg) b, sb = in(reg) sb,
                options(nostack, readonly)),
        }
    }
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
        configure_tiles();
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
    }
}

/// FLOPs of one round of [`tile_peak_loop`].
pub(crate) const TILE_PEAK_FLOPS_PER_ITER: f64 = 4.0 * 16.0 * 16.0 * 32.0 * 2.0;
