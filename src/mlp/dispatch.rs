//! The layer products at each CPU level: one call per layer, dispatched on [`Isa`] to the
//! kernel of that level (`scalar` the spec; `avx2`, `avx512`, `neon` its twins; `amx` on bf16
//! tiles), fp32 weights or their bf16 VNNI packing ([`LayerWeights`]).

use super::*;

/// One layer's weights as the kernels of each level take them: `f32` (`k × o` row-major) for
/// the fp32 levels, `bf16` (the same, packed by [`pack_vnni`]) for the AMX level.
#[derive(Clone, Copy)]
pub(super) struct LayerWeights<'a> {
    pub(super) f32: &'a [f32],
    pub(super) bf16: &'a [u16],
}

pub(super) fn matmul(
    isa: Isa,
    x: &[f32],
    rows: usize,
    k: usize,
    w: LayerWeights,
    o: usize,
    out: &mut [f32],
    relu: bool,
) {
    match isa.level() {
        #[cfg(target_arch = "x86_64")]
        CpuLevel::Avx2 => avx2::matmul(isa, x, rows, k, w.f32, o, out, relu),
        #[cfg(target_arch = "x86_64")]
        CpuLevel::Avx512 => avx512::matmul(isa, x, rows, k, w.f32, o, out, relu),
        #[cfg(target_arch = "x86_64")]
        CpuLevel::Amx => amx::matmul(isa, x, rows, k, w.bf16, o, out, relu),
        #[cfg(target_arch = "aarch64")]
        CpuLevel::Neon => neon::matmul(isa, x, rows, k, w.f32, o, out, relu),
        _ => scalar::matmul(x, rows, k, w.f32, o, out, relu),
    }
}

pub(super) fn matmul_first(
    isa: Isa,
    x: &[f32],
    rows: usize,
    k: usize,
    w: &[f32],
    o: usize,
    out: &mut [f32],
    relu: bool,
) {
    match isa.level() {
        #[cfg(target_arch = "x86_64")]
        CpuLevel::Avx2 | CpuLevel::Avx512 => avx2::matmul_first(isa, x, rows, k, w, o, out, relu),
        #[cfg(target_arch = "x86_64")]
        CpuLevel::Amx => {
            // Column 0 of the tile product (forward_first does not come here: it runs the
            // whole forward at this level).
            let mut full = vec![0.0; rows * o];
            matmul_with(isa, x, rows, k, w, o, &mut full, relu);
            out[..rows].iter_mut().zip(full.chunks_exact(o)).for_each(|(y, r)| *y = r[0]);
        }
        #[cfg(target_arch = "aarch64")]
        CpuLevel::Neon => neon::matmul_first(isa, x, rows, k, w, o, out, relu),
        _ => scalar::matmul_first(x, rows, k, w, o, out, relu),
    }
}

/// Rows `rows` of the SIMD first-column kernels one at a time (their remainder rows), with the
/// fused multiply-add chain each of their lanes runs — so the same bits as those lanes.
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
#[inline(always)]
pub(super) fn first_column_fma(
    x: &[f32],
    k: usize,
    w: &[f32],
    o: usize,
    rows: std::ops::Range<usize>,
    out: &mut [f32],
    relu: bool,
) {
    for b in rows {
        let row = &x[b * k..(b + 1) * k];
        let acc = row.iter().enumerate().fold(0.0f32, |acc, (kk, &xv)| xv.mul_add(w[kk * o], acc));
        out[b] = if relu { acc.max(0.0) } else { acc };
    }
}

pub(super) fn matmul_tn_acc(isa: Isa, x: &[f32], rows: usize, k: usize, dz: &[f32], o: usize, dw: &mut [f32]) {
    match isa.level() {
        #[cfg(target_arch = "x86_64")]
        CpuLevel::Avx2 => avx2::matmul_tn_acc(isa, x, rows, k, dz, o, dw),
        #[cfg(target_arch = "x86_64")]
        CpuLevel::Avx512 => avx512::matmul_tn_acc(isa, x, rows, k, dz, o, dw),
        #[cfg(target_arch = "x86_64")]
        CpuLevel::Amx => amx::matmul_tn_acc(isa, x, rows, k, dz, o, dw),
        #[cfg(target_arch = "aarch64")]
        CpuLevel::Neon => neon::matmul_tn_acc(isa, x, rows, k, dz, o, dw),
        _ => scalar::matmul_tn_acc(x, rows, k, dz, o, dw),
    }
}

/// The public face of the layer kernels, for tests and benchmarks: `out = relu?(x·W)`.
pub fn matmul_with(isa: Isa, x: &[f32], rows: usize, k: usize, w: &[f32], o: usize, out: &mut [f32], relu: bool) {
    assert!(o.is_multiple_of(16) && k.is_multiple_of(4), "matmul: o must be a multiple of 16, k of 4");
    let mut packed = Vec::new();
    if !isa.level().mlp_is_fp32() {
        packed.resize(k.next_multiple_of(32) * o, 0);
        pack_vnni(w, k, o, &mut packed);
    }
    matmul(isa, x, rows, k, LayerWeights { f32: w, bf16: &packed }, o, out, relu)
}

/// The public face of the first-column kernel, for tests and benchmarks: `out[b] = relu?(x[b]·W[:, 0])`.
pub fn matmul_first_with(isa: Isa, x: &[f32], rows: usize, k: usize, w: &[f32], o: usize, out: &mut [f32], relu: bool) {
    assert!(o.is_multiple_of(16) && k.is_multiple_of(8), "matmul_first: o must be a multiple of 16, k of 8");
    matmul_first(isa, x, rows, k, w, o, out, relu)
}

/// The public face of the weight-gradient kernel, for tests and benchmarks: `dw += xᵀ·dz`.
pub fn matmul_tn_acc_with(isa: Isa, x: &[f32], rows: usize, k: usize, dz: &[f32], o: usize, dw: &mut [f32]) {
    assert!(o.is_multiple_of(16) && k.is_multiple_of(4), "matmul_tn_acc: o must be a multiple of 16, k of 4");
    matmul_tn_acc(isa, x, rows, k, dz, o, dw)
}
