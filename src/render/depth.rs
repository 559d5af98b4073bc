//! Depth along a ray (paper Eq. 3 and Dex-NeRF; DESIGN §2.4).
//!
//! - [`expected_depth`]: `D = Σ w_i t_i` (the "NeRF" baseline), from a [`RayComposite`].
//! - [`threshold_depth`]: the `t` of the first sample whose density reaches the threshold
//!   (Dex-NeRF; the paper's method for transparent objects). `None` is a **hole**.
//!
//! Units: [`DensityThreshold::Sigma`] compares σ in **1/length of the dataset's coordinates**
//! (per metre for our datasets). The paper's m = 3 and the authors' code compare different
//! things: their code tests the **raw** network output `s > 3`, i.e. σ = e^s > e³ ≈ 20 in their
//! units (their scenes are scaled ×2); [`DensityThreshold::Raw`] reproduces that test. Neither
//! is converted into the other silently.
//!
//! Depths here are ranges along the unit-length ray; [`crate::render::Ray::range_to_z`] gives
//! z-depth.

use super::composite::RayComposite;

/// What "the first sample that is solid" means.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DensityThreshold {
    /// σ ≥ m, σ in 1/(dataset length unit), e.g. per metre.
    Sigma(f32),
    /// Raw density network output s ≥ value (σ = trunc_exp(s)); the authors' code uses s > 3.
    Raw(f32),
}

impl DensityThreshold {
    /// The default threshold: σ ≥ 10 per dataset unit (per metre). The paper's m = 3 is in its
    /// own units (the authors' code tests raw s > 3, σ > e³); on the dev background σ ≥ 10/m
    /// gave the lowest depth error of 3, 10 and 20 (docs/DECISIONS.md, "The engine").
    pub const DEFAULT: DensityThreshold = DensityThreshold::Sigma(10.0);

    /// Whether a sample with raw density `s` (σ = e^s) is solid.
    #[inline]
    pub fn is_hit(self, raw: f32) -> bool {
        match self {
            // σ = e^s ≥ m ⇔ s ≥ ln m (m > 0); m ≤ 0 makes every sample solid.
            DensityThreshold::Sigma(m) => m <= 0.0 || raw >= m.ln(),
            DensityThreshold::Raw(v) => raw >= v,
        }
    }
}

impl DensityThreshold {
    /// The smallest activated density σ that is solid: `m`, or `e^S` for a raw threshold
    /// (renderers compare σ once per sample instead of taking its log).
    pub fn min_sigma(self) -> f32 {
        match self {
            DensityThreshold::Sigma(m) => m.max(0.0),
            DensityThreshold::Raw(v) => v.exp(),
        }
    }
}

/// How depth is read off each ray: the renderer, the command line (`--depth`, `--m`,
/// `--m-raw`) and the onboard API take this one type.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DepthMethod {
    /// Dex-NeRF: the first sample whose density reaches the threshold (holes where none does).
    /// The default, at [`DensityThreshold::DEFAULT`].
    Threshold(DensityThreshold),
    /// NeRF's expected depth `Σ w_i t_i` (paper Eq. 3); never a hole, blurred at glass.
    Expected,
}

impl Default for DepthMethod {
    fn default() -> Self {
        DepthMethod::Threshold(DensityThreshold::DEFAULT)
    }
}

impl DepthMethod {
    /// The density threshold of threshold depth; for [`DepthMethod::Expected`] the default one
    /// (a full render reports threshold depth beside the expected one).
    pub fn threshold(self) -> DensityThreshold {
        match self {
            DepthMethod::Threshold(m) => m,
            DepthMethod::Expected => DensityThreshold::DEFAULT,
        }
    }
}

/// `Σ w_i t_i` of a composited ray.
pub fn expected_depth(c: &RayComposite) -> f32 {
    c.depth
}

/// The `t` of the first sample with raw density `raw[i]` solid under `threshold`; `None` when
/// no sample is (a hole).
pub fn threshold_depth(t: &[f32], raw: &[f32], threshold: DensityThreshold) -> Option<f32> {
    assert_eq!(t.len(), raw.len(), "depth: sample arrays differ in length");
    raw.iter().position(|&s| threshold.is_hit(s)).map(|i| t[i])
}
