//! Adam over fp32 master weights, optionally writing an fp16 mirror in the same pass
//! (tiny-cuda-nn's mixed-precision scheme; DESIGN §2.1).
//!
//! With gradient `g` (plus `l2 · p` when L2 regularisation is on), at step `t = 1, 2, …`:
//! `m ← β₁m + (1−β₁)g`, `v ← β₂v + (1−β₂)g²`,
//! `p ← p − lr_t · m / (√v + ε)` with the bias correction folded into
//! `lr_t = lr · √(1−β₂ᵗ) / (1−β₁ᵗ)`; then `mirror ← fp16(p)` (round to nearest even).
//!
//! Element-wise, so the parallel split cannot change the result. [`scalar`] is the spec.

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "aarch64")]
mod neon;
pub mod scalar;

use crate::simd::{CpuLevel, Isa};
use rayon::prelude::*;

/// Adam hyper-parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct AdamConfig {
    /// First-moment decay β₁. Defaults to 0.9.
    pub beta1: f32,
    /// Second-moment decay β₂. Defaults to 0.99 (Instant-NGP).
    pub beta2: f32,
    /// ε in the denominator. Defaults to 1e-15 (Instant-NGP).
    pub epsilon: f32,
    /// L2 regularisation added to the gradient as `l2 · p`. Defaults to 0.
    pub l2: f32,
}

impl Default for AdamConfig {
    fn default() -> Self {
        AdamConfig { beta1: 0.9, beta2: 0.99, epsilon: 1e-15, l2: 0.0 }
    }
}

/// The per-step constants a kernel needs.
#[derive(Clone, Copy, Debug)]
pub struct AdamStep {
    /// Bias-corrected learning rate `lr_t`.
    pub lr_t: f32,
    /// β₁.
    pub beta1: f32,
    /// β₂.
    pub beta2: f32,
    /// ε.
    pub epsilon: f32,
    /// L2 coefficient.
    pub l2: f32,
}

/// Adam state for one parameter buffer.
#[derive(Clone, Debug)]
pub struct Adam {
    /// Hyper-parameters.
    pub config: AdamConfig,
    m: Vec<f32>,
    v: Vec<f32>,
    t: u32,
    /// Whether this optimiser has updated every parameter of its buffer since it was made or
    /// restored, so the mirror holds `fp16(p)` everywhere and idle blocks may be left alone
    /// ([`IDLE_BLOCK`]).
    swept: bool,
}

/// Parameters per parallel task (the split never changes the result: the update is element-wise).
const PAR_CHUNK: usize = 1 << 16;

/// Parameters per idle test. A parameter whose gradient and both moments are exactly zero (a
/// hash-table entry no sample has reached yet: most of a residual model's middle levels, whose
/// change region is a small part of the room) is left as it is by the update, bits included
/// (`m = v = 0`, `p − lr_t · 0 / (0 + ε) = p`, and the mirror already holds `fp16(p)`), so a
/// block of them is skipped: its `p`, `m`, `v` and mirror are neither read back nor written.
/// Only without L2 (whose `l2 · p` makes the gradient non-zero) and after a first full update
/// (which makes the mirror `fp16(p)` everywhere). 64 parameters: a few cache lines of each
/// buffer, checked in one pass.
const IDLE_BLOCK: usize = 64;

impl Adam {
    /// Zeroed moments for `n` parameters.
    pub fn new(n: usize, config: AdamConfig) -> Adam {
        Adam { config, m: vec![0.0; n], v: vec![0.0; n], t: 0, swept: false }
    }

    /// Steps taken so far.
    pub fn steps(&self) -> u32 {
        self.t
    }

    /// First and second moments (for checkpoints and tests).
    pub fn moments(&self) -> (&[f32], &[f32]) {
        (&self.m, &self.v)
    }

    /// Restores a state saved from [`Adam::moments`] and [`Adam::steps`].
    pub fn restore(&mut self, m: Vec<f32>, v: Vec<f32>, t: u32) {
        assert!(m.len() == self.m.len() && v.len() == self.v.len(), "adam: restored moments have the wrong length");
        self.m = m;
        self.v = v;
        self.t = t;
        self.swept = false;
    }

    /// One update of `params` from `grads` at learning rate `lr`; when `mirror` is given
    /// (fp16 bits, one per parameter) it receives the updated weights. Runs on the rayon pool.
    pub fn step(&mut self, isa: Isa, lr: f32, params: &mut [f32], grads: &[f32], mirror: Option<&mut [u16]>) {
        let n = self.m.len();
        assert!(params.len() == n && grads.len() == n, "adam: buffers must match the optimiser's size");
        self.t += 1;
        let c = &self.config;
        let t = self.t as i32;
        let lr_t = (lr as f64 * (1.0 - (c.beta2 as f64).powi(t)).sqrt() / (1.0 - (c.beta1 as f64).powi(t))) as f32;
        let hp = AdamStep { lr_t, beta1: c.beta1, beta2: c.beta2, epsilon: c.epsilon, l2: c.l2 };
        let skip_idle = self.swept && c.l2 == 0.0;
        self.swept = true;
        let run = |p: &mut [f32], g: &[f32], m: &mut [f32], v: &mut [f32], mut h: Option<&mut [u16]>| {
            if !skip_idle {
                return step_kernel(isa, hp, p, g, m, v, h);
            }
            // The kernel on each run of busy blocks (some gradient or moment not exactly zero);
            // the idle block that ends a run is left as the update would leave it.
            let n = p.len();
            let idle = |b: usize, m: &[f32], v: &[f32]| {
                let r = b * IDLE_BLOCK..((b + 1) * IDLE_BLOCK).min(n);
                let bits = |x: &[f32]| x.iter().fold(0u32, |acc, v| acc | v.to_bits());
                bits(&g[r.clone()]) | bits(&m[r.clone()]) | bits(&v[r]) == 0
            };
            let blocks = n.div_ceil(IDLE_BLOCK);
            let mut b = 0;
            while b < blocks {
                let first = b;
                while b < blocks && !idle(b, m, v) {
                    b += 1;
                }
                if b > first {
                    let r = first * IDLE_BLOCK..(b * IDLE_BLOCK).min(n);
                    let h = h.as_deref_mut().map(|h| &mut h[r.clone()]);
                    step_kernel(isa, hp, &mut p[r.clone()], &g[r.clone()], &mut m[r.clone()], &mut v[r], h);
                }
                b += 1;
            }
        };
        let chunks = params
            .par_chunks_mut(PAR_CHUNK)
            .zip(grads.par_chunks(PAR_CHUNK))
            .zip(self.m.par_chunks_mut(PAR_CHUNK))
            .zip(self.v.par_chunks_mut(PAR_CHUNK));
        match mirror {
            Some(h) => {
                assert_eq!(h.len(), n, "adam: mirror must hold one half per parameter");
                chunks.zip(h.par_chunks_mut(PAR_CHUNK)).for_each(|((((p, g), m), v), h)| run(p, g, m, v, Some(h)));
            }
            None => chunks.for_each(|(((p, g), m), v)| run(p, g, m, v, None)),
        }
    }
}

/// One thread's Adam update over equal-length slices, dispatched on `isa`.
pub fn step_kernel(
    isa: Isa,
    hp: AdamStep,
    p: &mut [f32],
    g: &[f32],
    m: &mut [f32],
    v: &mut [f32],
    mirror: Option<&mut [u16]>,
) {
    let n = p.len();
    assert!(g.len() == n && m.len() == n && v.len() == n && mirror.as_ref().is_none_or(|h| h.len() == n));
    match isa.level() {
        #[cfg(target_arch = "x86_64")]
        CpuLevel::Avx2 | CpuLevel::Avx512 | CpuLevel::Amx => avx2::step(isa, hp, p, g, m, v, mirror),
        #[cfg(target_arch = "aarch64")]
        CpuLevel::Neon => neon::step(isa, hp, p, g, m, v, mirror),
        _ => scalar::step(hp, p, g, m, v, mirror),
    }
}

/// Learning rate against step: linear warm-up, then constant, then exponential decay
/// (`lr = base · factor^⌊(step − decay_start) / interval⌋` past `decay_start`).
#[derive(Clone, Debug, PartialEq)]
pub struct LrSchedule {
    /// Peak learning rate. Defaults to 1e-2 (Instant-NGP).
    pub base: f32,
    /// Steps of linear warm-up from `base / warmup_steps`. Defaults to 0.
    pub warmup_steps: u32,
    /// First step of the decay. Defaults to `u32::MAX` (no decay).
    pub decay_start: u32,
    /// Steps between decays. Defaults to 1000.
    pub decay_interval: u32,
    /// Factor per decay. Defaults to 0.33 (Instant-NGP).
    pub decay_factor: f32,
}

impl Default for LrSchedule {
    fn default() -> Self {
        LrSchedule { base: 1e-2, warmup_steps: 0, decay_start: u32::MAX, decay_interval: 1000, decay_factor: 0.33 }
    }
}

impl LrSchedule {
    /// The learning rate of step `step` (0-based).
    pub fn lr(&self, step: u32) -> f32 {
        let warm = if step < self.warmup_steps { (step + 1) as f32 / self.warmup_steps as f32 } else { 1.0 };
        let decays =
            if step >= self.decay_start { (step - self.decay_start) / self.decay_interval.max(1) + 1 } else { 0 };
        self.base * warm * self.decay_factor.powi(decays as i32)
    }
}
