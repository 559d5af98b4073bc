//! Scalar hash-grid kernels: the specification the SIMD kernels are tested against.
//!
//! Corner `c` of a cell has offsets `(c & 1, c >> 1 & 1, c >> 2 & 1)` and trilinear weight
//! `w_c = wx_c · (wy_c · wz_c)` with `wx_c = wx` if the x bit is set, else `1 − wx`
//! (the SIMD kernels multiply in the same order).

use super::{unpack_entry, LevelInfo, Soa};

/// Cell corner and fractional position of `p` on `level`, or `None` outside the unit cube
/// (including NaN coordinates).
#[inline(always)]
pub fn locate(level: &LevelInfo, p: [f32; 3]) -> Option<([u32; 3], [f32; 3])> {
    if !p.iter().all(|&v| (0.0..=1.0).contains(&v)) {
        return None;
    }
    let r = level.resolution as f32;
    let mut cell = [0u32; 3];
    let mut frac = [0f32; 3];
    for k in 0..3 {
        let q = p[k] * r;
        let f = q.floor().min(r - 1.0);
        cell[k] = f as u32;
        frac[k] = q - f;
    }
    Some((cell, frac))
}

/// Table indices and trilinear weights of the 8 corners around `p` (`None` outside).
#[inline(always)]
pub fn corners(level: &LevelInfo, p: [f32; 3]) -> Option<([u32; 8], [f32; 8])> {
    let (cell, w) = locate(level, p)?;
    let mut idx = [0u32; 8];
    let mut wt = [0f32; 8];
    for c in 0..8 {
        let (bx, by, bz) = (c & 1, (c >> 1) & 1, (c >> 2) & 1);
        idx[c] = level.index(cell[0] + bx as u32, cell[1] + by as u32, cell[2] + bz as u32);
        let wx = if bx == 1 { w[0] } else { 1.0 - w[0] };
        let wy = if by == 1 { w[1] } else { 1.0 - w[1] };
        let wz = if bz == 1 { w[2] } else { 1.0 - w[2] };
        wt[c] = wx * (wy * wz);
    }
    Some((idx, wt))
}

/// Encodes `n` samples of `soa` on one level: writes features `(f0, f1)` of sample `s` to
/// `out[s · stride]` and `out[s · stride + 1]`. `table` is this level's slice.
pub(crate) fn forward_level(level: &LevelInfo, table: &[u32], soa: &Soa, n: usize, out: &mut [f32], stride: usize) {
    for s in 0..n {
        let mut f = [0f32; 2];
        if let Some((idx, w)) = corners(level, [soa.x[s], soa.y[s], soa.z[s]]) {
            for c in 0..8 {
                let e = unpack_entry(table[idx[c] as usize]);
                f[0] += w[c] * e[0];
                f[1] += w[c] * e[1];
            }
        }
        out[s * stride] = f[0];
        out[s * stride + 1] = f[1];
    }
}

/// Accumulates `grads[2i + f] += w_c · d[s · stride + f]` over the corners `i` of each of the
/// `n` samples, in sample order. `grads` is this level's slice of the gradient.
pub(crate) fn backward_level(level: &LevelInfo, grads: &mut [f32], soa: &Soa, n: usize, d: &[f32], stride: usize) {
    for s in 0..n {
        let (g0, g1) = (d[s * stride], d[s * stride + 1]);
        if let Some((idx, w)) = corners(level, [soa.x[s], soa.y[s], soa.z[s]]) {
            for c in 0..8 {
                let i = 2 * idx[c] as usize;
                grads[i] += w[c] * g0;
                grads[i + 1] += w[c] * g1;
            }
        }
    }
}

/// dL/dp of one level's features at `p`, given `g = dL/d(f0, f1)`.
pub fn position_gradient(level: &LevelInfo, table: &[u32], p: [f32; 3], g: [f32; 2]) -> [f32; 3] {
    let Some((cell, w)) = locate(level, p) else {
        return [0.0; 3];
    };
    let r = level.resolution as f32;
    let mut d = [0f32; 3];
    for c in 0..8u32 {
        let b = [c & 1, (c >> 1) & 1, (c >> 2) & 1];
        let e = unpack_entry(table[level.index(cell[0] + b[0], cell[1] + b[1], cell[2] + b[2]) as usize]);
        let dl = g[0] * e[0] + g[1] * e[1];
        let sel = |k: usize| if b[k] == 1 { w[k] } else { 1.0 - w[k] };
        let sign = |k: usize| if b[k] == 1 { r } else { -r };
        d[0] += dl * sign(0) * sel(1) * sel(2);
        d[1] += dl * sel(0) * sign(1) * sel(2);
        d[2] += dl * sel(0) * sel(1) * sign(2);
    }
    d
}
