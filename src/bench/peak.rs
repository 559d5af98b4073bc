//! Machine limits measured in the same run as the kernels: an fp32 FMA loop with 12
//! independent accumulators (the peak the MLP is compared to) per CPU level, and at the AMX
//! level the tile unit's bf16 product loop.

use crate::simd::{CpuLevel, Isa};

/// Runs `iters` iterations of 12 independent vector FMAs; returns (checksum, FLOPs done).
pub fn fma_loop(isa: Isa, iters: u64, seed: f32) -> (f32, f64) {
    match isa.level() {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: an `Isa` of level Avx2 exists only when the CPU has AVX2 and FMA.
        CpuLevel::Avx2 => (unsafe { fma_avx2(iters, seed) }, iters as f64 * 12.0 * 8.0 * 2.0),
        #[cfg(target_arch = "x86_64")]
        // SAFETY: an `Isa` of level Avx512 or Amx exists only when the CPU has AVX-512F.
        CpuLevel::Avx512 | CpuLevel::Amx => (unsafe { fma_avx512(iters, seed) }, iters as f64 * 12.0 * 16.0 * 2.0),
        #[cfg(target_arch = "aarch64")]
        // SAFETY: an `Isa` of level Neon exists only when the CPU has NEON.
        CpuLevel::Neon => (unsafe { fma_neon(iters, seed) }, iters as f64 * 12.0 * 4.0 * 2.0),
        _ => (fma_scalar(iters, seed), iters as f64 * 12.0 * 2.0),
    }
}

/// The AMX tile unit's bf16 peak, FLOPs done by `iters` rounds (`None` below the AMX level).
pub fn tile_loop(isa: Isa, iters: u64) -> Option<f64> {
    #[cfg(target_arch = "x86_64")]
    if isa.level() == CpuLevel::Amx {
        let mut sink = [0f32; 256];
        crate::mlp::amx::tile_peak_loop(isa, iters, &mut sink);
        std::hint::black_box(&sink);
        return Some(iters as f64 * crate::mlp::amx::TILE_PEAK_FLOPS_PER_ITER);
    }
    let _ = (isa, iters);
    None
}

fn fma_scalar(iters: u64, seed: f32) -> f32 {
    let mut r: [f32; 12] = std::array::from_fn(|i| seed + i as f32);
    for _ in 0..iters {
        for x in r.iter_mut() {
            *x = x.mul_add(0.999_999, 1e-9);
        }
        std::hint::black_box(&mut r);
    }
    r.iter().sum()
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn fma_avx2(iters: u64, seed: f32) -> f32 {
    use std::arch::x86_64::*;
    let a = _mm256_set1_ps(0.999_999);
    let b = _mm256_set1_ps(1e-9);
    let mut r: [__m256; 12] = std::array::from_fn(|i| _mm256_set1_ps(seed + i as f32));
    for _ in 0..iters {
        for x in r.iter_mut() {
            *x = _mm256_fmadd_ps(*x, a, b);
        }
    }
    let mut s = _mm256_setzero_ps();
    for x in r {
        s = _mm256_add_ps(s, x);
    }
    let mut out = [0f32; 8];
    // SAFETY: `out` holds 8 floats.
    unsafe { _mm256_storeu_ps(out.as_mut_ptr(), s) };
    out.iter().sum()
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn fma_avx512(iters: u64, seed: f32) -> f32 {
    use std::arch::x86_64::*;
    let a = _mm512_set1_ps(0.999_999);
    let b = _mm512_set1_ps(1e-9);
    let mut r: [__m512; 12] = std::array::from_fn(|i| _mm512_set1_ps(seed + i as f32));
    for _ in 0..iters {
        for x in r.iter_mut() {
            *x = _mm512_fmadd_ps(*x, a, b);
        }
    }
    let mut s = _mm512_setzero_ps();
    for x in r {
        s = _mm512_add_ps(s, x);
    }
    _mm512_reduce_add_ps(s)
}

#[cfg(target_arch = "aarch64")]
#[target_feature(enable = "neon")]
unsafe fn fma_neon(iters: u64, seed: f32) -> f32 {
    use std::arch::aarch64::*;
    let a = vdupq_n_f32(0.999_999);
    let b = vdupq_n_f32(1e-9);
    let mut r: [float32x4_t; 12] = std::array::from_fn(|i| vdupq_n_f32(seed + i as f32));
    for _ in 0..iters {
        for x in r.iter_mut() {
            *x = vfmaq_f32(b, *x, a);
        }
    }
    let mut s = vdupq_n_f32(0.0);
    for x in r {
        s = vaddq_f32(s, x);
    }
    vaddvq_f32(s)
}
