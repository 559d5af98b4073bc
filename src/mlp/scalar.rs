//! Scalar MLP kernels: the specification of the SIMD twins.
//!
//! Shapes: `x` is `rows × k`, `w` is `k × o` (row-major, k-major), `out` is `rows × o`.

/// `out[b][j] = act(Σ_kk x[b][kk] · w[kk][j])` with `act` ReLU when `relu`, else identity.
pub fn matmul(x: &[f32], rows: usize, k: usize, w: &[f32], o: usize, out: &mut [f32], relu: bool) {
    for b in 0..rows {
        let row = &mut out[b * o..(b + 1) * o];
        row.fill(0.0);
        for kk in 0..k {
            let xv = x[b * k + kk];
            for (r, wv) in row.iter_mut().zip(&w[kk * o..(kk + 1) * o]) {
                *r += xv * wv;
            }
        }
        if relu {
            for r in row.iter_mut() {
                *r = r.max(0.0);
            }
        }
    }
}

/// `out[b] = act(Σ_kk x[b][kk] · w[kk][0])`: column 0 of [`matmul`] alone, summed in the same
/// order (a network's first output without the rest of its last layer).
pub fn matmul_first(x: &[f32], rows: usize, k: usize, w: &[f32], o: usize, out: &mut [f32], relu: bool) {
    for (b, y) in out[..rows].iter_mut().enumerate() {
        let mut acc = 0.0f32;
        for kk in 0..k {
            acc += x[b * k + kk] * w[kk * o];
        }
        *y = if relu { acc.max(0.0) } else { acc };
    }
}

/// `dw[kk][j] += Σ_b x[b][kk] · dz[b][j]` (the weight gradient `xᵀ·dz`).
pub fn matmul_tn_acc(x: &[f32], rows: usize, k: usize, dz: &[f32], o: usize, dw: &mut [f32]) {
    for b in 0..rows {
        for kk in 0..k {
            let xv = x[b * k + kk];
            for (d, g) in dw[kk * o..(kk + 1) * o].iter_mut().zip(&dz[b * o..(b + 1) * o]) {
                *d += xv * g;
            }
        }
    }
}

/// The AMX level's product, defined: [`matmul`] of `x` and `w` each rounded to bf16 (nearest
/// even), products exact in fp32, summed in fp32 in `k` order. The tile unit sums each group
/// of 32 products in its own order, so its results differ from this by fp32 summation order.
pub fn matmul_bf16(x: &[f32], rows: usize, k: usize, w: &[f32], o: usize, out: &mut [f32], relu: bool) {
    let round = |v: &f32| f32::from_bits((super::bf16_bits(*v) as u32) << 16);
    let xb: Vec<f32> = x[..rows * k].iter().map(round).collect();
    let wb: Vec<f32> = w[..k * o].iter().map(round).collect();
    matmul(&xb, rows, k, &wb, o, out, relu)
}

/// The AMX level's weight gradient, defined: [`matmul_tn_acc`] of `x` and `dz` each rounded to
/// bf16 (nearest even), products exact in fp32, summed in fp32 in row order onto `dw`. The
/// tile unit sums each group of 32 rows in its own order (to fp32 summation error).
pub fn matmul_tn_acc_bf16(x: &[f32], rows: usize, k: usize, dz: &[f32], o: usize, dw: &mut [f32]) {
    let round = |v: &f32| f32::from_bits((super::bf16_bits(*v) as u32) << 16);
    let xb: Vec<f32> = x[..rows * k].iter().map(round).collect();
    let db: Vec<f32> = dz[..rows * o].iter().map(round).collect();
    matmul_tn_acc(&xb, rows, k, &db, o, dw)
}
