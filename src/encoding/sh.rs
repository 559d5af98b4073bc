//! Real spherical harmonics of degree 4 (16 coefficients) of a unit view direction
//! (DESIGN §2.1), orthonormal on the sphere: ∫ Y_i Y_j dΩ = δ_ij. Band order
//! l = 0, 1, 2, 3 with m = −l..l, the convention of Instant-NGP / tiny-cuda-nn.
//!
//! Directions are not trained, so there is no backward pass. Cost is ~30 multiplies per
//! ray (all samples of a ray share it), far off the hot path: no SIMD twin is needed.

/// Number of coefficients of the degree-4 encoding.
pub const SH4_COEFFS: usize = 16;

/// The 16 real SH values of unit direction `d`.
pub fn sh4(d: [f32; 3]) -> [f32; SH4_COEFFS] {
    let [x, y, z] = d;
    let (xx, yy, zz) = (x * x, y * y, z * z);
    let (xy, yz, xz) = (x * y, y * z, x * z);
    [
        0.282_094_8,
        -0.488_602_5 * y,
        0.488_602_5 * z,
        -0.488_602_5 * x,
        1.092_548_4 * xy,
        -1.092_548_4 * yz,
        0.946_174_7 * zz - 0.315_391_57,
        -1.092_548_4 * xz,
        0.546_274_2 * (xx - yy),
        0.590_043_6 * y * (-3.0 * xx + yy),
        2.890_611_4 * xy * z,
        0.457_045_8 * y * (1.0 - 5.0 * zz),
        0.373_176_33 * z * (5.0 * zz - 3.0),
        0.457_045_8 * x * (1.0 - 5.0 * zz),
        1.445_305_7 * z * (xx - yy),
        0.590_043_6 * x * (-xx + 3.0 * yy),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Gram matrix over a Fibonacci sphere: ∫ Y_i Y_j dΩ ≈ δ_ij.
    #[test]
    fn sh4_is_orthonormal_on_the_sphere() {
        let n = 20_000;
        let mut gram = [[0f64; SH4_COEFFS]; SH4_COEFFS];
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        for k in 0..n {
            let z = 1.0 - 2.0 * (k as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = golden * k as f64;
            let y = sh4([(r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32]);
            for i in 0..SH4_COEFFS {
                for j in 0..SH4_COEFFS {
                    gram[i][j] += y[i] as f64 * y[j] as f64;
                }
            }
        }
        let area = 4.0 * std::f64::consts::PI / n as f64;
        for i in 0..SH4_COEFFS {
            for j in 0..SH4_COEFFS {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((gram[i][j] * area - want).abs() < 2e-3, "({i},{j}): {}", gram[i][j] * area);
            }
        }
    }
}
