//! The density floor of a warm-started residual inside its change region.
//!
//! A warm-started residual copies the background, whose empty air has a log-density far below
//! zero. Every gradient that could grow density there is proportional to σ itself (σ = e^s), so
//! a glass standing in what was empty air grows from a vanishing gradient, and the better the
//! background carved its air, the worse (docs/DECISIONS.md). Before training, this fit lifts
//! the residual's raw density inside the region to at least a floor `s₀` — `s_res(x) ≈
//! max(s_bg(x), s₀)` — by a short regression on points drawn uniformly in the region's cells,
//! so the residual starts "unsure" in the region's air, as a fresh NeRF does, and keeps the
//! background's surfaces. Off by default ([`crate::train::prior::DEFAULT_LIFT`]); `--region-floor
//! 0` turns it on at [`LiftConfig::DEFAULT`].
//!
//! Under the raw mix `σ = exp((1−β)s_bg + βs_res)` (the default) a plain warm start
//! (`s_res = s_bg`) gives `∂σ/∂β = σ·(s_res − s_bg) = 0` and `∂σ/∂s_res = βσ`, vanishing in
//! carved air: the Mixnet learns nothing from density there, and the residual little. After the
//! lift `s_res − s_bg > 0` in the region's air, so β has a gradient wherever the images ask for
//! density. The price is the exact start: with the Mixnet's β = ½ at step 0 the region's air
//! below `s₀` starts at `σ = e^{(s_bg+s₀)/2} ≤ e^{s₀}` (1 per metre at `s₀ = 0`, a tenth of
//! the threshold m), and its surfaces within the fit's error of the background's; outside the
//! region the field is still the background bit for bit. With the activated mix
//! `σ = (1−β)σ_bg + βσ_res` the mixed field starts at the background plus at most `β·e^{s₀}` of
//! fog inside the region.

use crate::field::model::Model;
use crate::field::{Nerf, NerfField, NerfParams};
use crate::geometry::ChangeRegion;
use crate::mlp::Activation;
use crate::rng::Rng;
use crate::simd::Isa;
use crate::train::{Adam, AdamConfig};
use glam::Vec3;

/// Settings of the lift.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LiftConfig {
    /// The floor `s₀` of the raw log-density (σ = e^{s₀} per scene unit).
    pub floor: f32,
    /// Regression steps.
    pub steps: u32,
    /// Points per step.
    pub batch: usize,
    /// Adam's learning rate.
    pub lr: f32,
}

impl LiftConfig {
    /// Floor 0 (σ = 1 per scene unit), 100 steps of 4096 points at 1e-2 (`--region-floor 0`).
    pub const DEFAULT: LiftConfig = LiftConfig { floor: 0.0, steps: 100, batch: 4096, lr: 1e-2 };
}

impl Default for LiftConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// What the lift reached: mean |s − max(s_bg, s₀)| over fresh region points before and after.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LiftReport {
    /// Before the fit.
    pub error_before: f64,
    /// After the fit.
    pub error_after: f64,
}

impl std::fmt::Display for LiftReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "density floor in the change region: mean |s - target| {:.3} -> {:.3}",
            self.error_before, self.error_after
        )
    }
}

/// Lifts the raw density of `field` at `params` (a residual NeRF) inside `region` to at least
/// `cfg.floor` (see the module); `background` gives the targets. Deterministic from `seed`.
pub fn lift_region(
    isa: Isa,
    field: &NerfField,
    params: &mut NerfParams,
    background: &Nerf,
    region: &ChangeRegion,
    cfg: &LiftConfig,
    seed: u64,
) -> LiftReport {
    let cells = region.cells();
    if cells.is_empty() || cfg.steps == 0 {
        return LiftReport { error_before: 0.0, error_after: 0.0 };
    }
    let aabb = region.aabb();
    let cell = (aabb.max - aabb.min) / region.resolution() as f32;
    let draw = |rng: &mut Rng, n: usize| -> Vec<Vec3> {
        (0..n)
            .map(|_| {
                let c = region.cell_centre(cells[rng.below(cells.len() as u64) as usize] as usize);
                c + cell * Vec3::new(rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5))
            })
            .collect()
    };
    let raw = |sigma: f32| sigma.max(1e-30).ln();
    let targets = |pts: &[Vec3]| -> Vec<f32> {
        let mut s = vec![0.0; pts.len()];
        Model::density(&background.field, isa, &background.params, pts, &mut s, &mut Default::default());
        s.iter().map(|&x| raw(x).max(cfg.floor)).collect()
    };
    let error = |params: &NerfParams, pts: &[Vec3], t: &[f32]| -> f64 {
        let mut s = vec![0.0; pts.len()];
        Model::density(field, isa, params, pts, &mut s, &mut Default::default());
        s.iter().zip(t).map(|(&x, &t)| (raw(x) - t).abs() as f64).sum::<f64>() / pts.len() as f64
    };
    let mut rng = Rng::new(seed ^ 0x11F7);
    let held = draw(&mut rng, cfg.batch);
    let held_t = targets(&held);
    let error_before = error(params, &held, &held_t);

    let mut grads = Model::zero_grads(field);
    let mut adams: Vec<Adam> = Model::groups(field, params, &grads)
        .iter()
        .map(|g| Adam::new(g.master.len(), AdamConfig { l2: g.l2, ..Default::default() }))
        .collect();
    Model::after_step(field, params);
    let mut ctx = Default::default();
    let n = cfg.batch;
    let (mut sigma, mut rgb, mut d_sigma) = (vec![0.0; n], vec![[0.0; 3]; n], vec![0.0; n]);
    let (dirs, d_rgb) = (vec![Vec3::Z; n], vec![[0.0; 3]; n]);
    for _ in 0..cfg.steps {
        let pts = draw(&mut rng, n);
        let t = targets(&pts);
        Model::forward(field, isa, params, &pts, &dirs, &mut sigma, &mut rgb, &mut ctx);
        // L = mean (s − t)²; dL/dσ = dL/ds / (ds/dσ⁻¹), so that the backward's trunc_exp
        // derivative turns it back into dL/ds exactly.
        for ((d, &x), &t) in d_sigma.iter_mut().zip(&sigma).zip(&t) {
            *d = 2.0 * (raw(x) - t) / n as f32 / Activation::TruncExp.derivative_from_output(x);
        }
        Model::backward(field, isa, params, &mut ctx, &d_sigma, &d_rgb, &mut grads);
        for (adam, g) in adams.iter_mut().zip(Model::groups(field, params, &grads)) {
            adam.step(isa, cfg.lr, g.master, g.grad, g.mirror);
        }
        Model::after_step(field, params);
    }
    LiftReport { error_before, error_after: error(params, &held, &held_t) }
}
