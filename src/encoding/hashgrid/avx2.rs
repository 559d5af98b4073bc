//! AVX2 + FMA + F16C hash-grid kernels: 8 samples per vector, one 8-lane load per corner
//! (each lane a packed fp16 pair: `vpgatherdd`, or eight scalar loads on AMD, see
//! [`CornerLoads`]), `vcvtph2ps` to expand. Twin of [`super::scalar`].

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

/// How the forward fetches a corner's eight table words. Either way the same words, so the
/// same bits; only the speed differs, by CPU vendor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CornerLoads {
    /// One `vpgatherdd`: executed in hardware on Intel cores (the AVX-512 level's 16-lane
    /// gather took 3.2–3.8 ns on an L1-resident table, BENCHMARKS.md's Xeon notes).
    Gather,
    /// Eight scalar loads: AMD Zen microcodes `vpgatherdd`, and Intel's Gather Data Sampling
    /// ("Downfall") microcode slows it on the Intel cores it mitigates; on a Zen 3 guest the
    /// scalar loads made threshold-depth views faster with the same bits (docs/DECISIONS.md,
    /// "The hash grid's corner loads on AVX2").
    Scalar,
}

impl CornerLoads {
    /// The host's: [`CornerLoads::Scalar`] on AMD (and Hygon) CPUs and where Linux reports the
    /// Gather Data Sampling mitigation active, else [`CornerLoads::Gather`]. Read once per
    /// process.
    pub fn detect() -> CornerLoads {
        static LOADS: std::sync::OnceLock<CornerLoads> = std::sync::OnceLock::new();
        *LOADS.get_or_init(|| {
            // Leaf 0: the vendor string, in EBX, EDX, ECX (every x86_64 CPU has it).
            let id = __cpuid(0);
            let amd = [id.ebx, id.edx, id.ecx] == AMD || [id.ebx, id.edx, id.ecx] == HYGON;
            let gds_mitigated = || {
                std::fs::read_to_string("/sys/devices/system/cpu/vulnerabilities/gather_data_sampling")
                    .is_ok_and(|s| s.starts_with("Mitigation"))
            };
            if amd || gds_mitigated() {
                CornerLoads::Scalar
            } else {
                CornerLoads::Gather
            }
        })
    }
}

/// `cpuid` leaf 0's vendor words (EBX, EDX, ECX) of "AuthenticAMD" and "HygonGenuine".
const AMD: [u32; 3] = [u32::from_le_bytes(*b"Auth"), u32::from_le_bytes(*b"enti"), u32::from_le_bytes(*b"cAMD")];
const HYGON: [u32; 3] = [u32::from_le_bytes(*b"Hygo"), u32::from_le_bytes(*b"nGen"), u32::from_le_bytes(*b"uine")];

/// The 32-bit words `base[idx[0..8]]` as one vector, fetched as `SCALAR` says
/// ([`CornerLoads`]).
///
/// # Safety
/// AVX2; every lane of `idx` indexes inside the slice `base` points into.
#[inline(always)]
unsafe fn load8<const SCALAR: bool>(base: *const i32, idx: __m256i) -> __m256i {
    // SAFETY: the caller guarantees AVX2 and in-bounds indices.
    unsafe {
        if !SCALAR {
            return _mm256_i32gather_epi32::<4>(base, idx);
        }
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

/// AVX2 twin of [`super::scalar::forward_level`], its corner loads the host's
/// ([`CornerLoads::detect`]).
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
    // SAFETY: forwarded from the caller.
    unsafe {
        match CornerLoads::detect() {
            CornerLoads::Gather => forward_with::<false>(level, table, soa, n, out, stride),
            CornerLoads::Scalar => forward_with::<true>(level, table, soa, n, out, stride),
        }
    }
}

/// [`forward_level_unchecked`] with `SCALAR` corner loads ([`load8`]).
///
/// # Safety
/// As [`forward_level_unchecked`].
#[target_feature(enable = "avx2,fma,f16c")]
unsafe fn forward_with<const SCALAR: bool>(
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
        // (clamped cell, dense extent or hash mask), so the loads read inside `table`.
        unsafe {
            let (idx, w) = corners8(level, soa, i);
            let mut acc_lo = _mm256_setzero_ps();
            let mut acc_hi = _mm256_setzero_ps();
            for c in 0..8 {
                let g = load8::<SCALAR>(base, idx[c]);
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

#[cfg(test)]
mod tests {
    use super::super::{scalar, HashGrid, HashGridConfig, HashGridParams, Soa, CHUNK};
    use super::*;
    use crate::rng::Rng;

    /// Both corner loads give the same bits, within rounding of the scalar kernel (whose
    /// mul + add the AVX2 kernel fuses), on every level, dense and hashed, with points outside
    /// the unit cube and a partial last group of 8.
    #[test]
    fn both_corner_loads_give_the_same_bits() {
        if !(is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma") && is_x86_feature_detected!("f16c")) {
            return;
        }
        let grid = HashGrid::new(HashGridConfig { log2_table_size: 12, ..Default::default() });
        let mut rng = Rng::new(3);
        let mut params = HashGridParams::init(&grid, &mut rng);
        params.master.iter_mut().for_each(|p| *p = rng.uniform(-1.0, 1.0));
        params.sync_mirror();
        let n = CHUNK - 3;
        let pos: Vec<[f32; 3]> = (0..n).map(|_| std::array::from_fn(|_| rng.uniform(-0.1, 1.1))).collect();
        let mut soa = Soa::default();
        soa.fill(&pos);
        for level in grid.levels() {
            let table = &params.table[level.offset..level.offset + level.size];
            let mut want = vec![0f32; 2 * n];
            scalar::forward_level(level, table, &soa, n, &mut want, 2);
            let mut got = [vec![0f32; 2 * n], vec![0f32; 2 * n]];
            for (scalar, got) in [false, true].into_iter().zip(&mut got) {
                // SAFETY: AVX2, FMA and F16C checked above; the table is the level's.
                unsafe {
                    match scalar {
                        false => forward_with::<false>(level, table, &soa, n, got, 2),
                        true => forward_with::<true>(level, table, &soa, n, got, 2),
                    }
                }
                let close = got.iter().zip(&want).all(|(a, b)| (a - b).abs() <= 2e-6);
                assert!(close, "scalar loads {scalar} on level {level:?}: not the scalar kernel's encoding");
            }
            let same = got[0].iter().zip(&got[1]).all(|(a, b)| a.to_bits() == b.to_bits());
            assert!(same, "the two corner loads differ on level {level:?}");
        }
    }

    /// The vendor words decode as the kernel's `/proc/cpuinfo` names them: AMD hosts take the
    /// scalar loads; Intel hosts without the Gather Data Sampling mitigation keep the gather.
    #[test]
    fn corner_loads_follow_the_cpu_vendor() {
        let Ok(info) = std::fs::read_to_string("/proc/cpuinfo") else { return };
        let vendor =
            info.lines().find_map(|l| l.strip_prefix("vendor_id")).map(|v| v.trim_start_matches([' ', '\t', ':']));
        let gds = std::fs::read_to_string("/sys/devices/system/cpu/vulnerabilities/gather_data_sampling");
        match vendor {
            Some("AuthenticAMD" | "HygonGenuine") => assert_eq!(CornerLoads::detect(), CornerLoads::Scalar),
            Some("GenuineIntel") if !gds.is_ok_and(|s| s.starts_with("Mitigation")) => {
                assert_eq!(CornerLoads::detect(), CornerLoads::Gather)
            }
            _ => {}
        }
    }
}
