//! A field fit: a procedural 3-D colour field learnt by the hash grid and an MLP.
//!
//! It runs every kernel the NeRF trainer stands on — hash-grid forward/backward, fused MLP
//! forward/backward, Adam with the fp16 mirror, thread-independent gradient slots — on a
//! target with a known answer, and reports held-out PSNR (`tests/field_fit.rs`).

use crate::encoding::{HashGrid, HashGridConfig, HashGridParams};
use crate::mlp::{Activation, Mlp, MlpConfig, MlpContext, MlpParams, MlpWorkspace};
use crate::rng::Rng;
use crate::simd::Isa;
use crate::slots::{accumulate_in_order, slot_range, split_rows, SLOTS};
use crate::train::{Adam, AdamConfig, LrSchedule};
use crate::GradientMode;
use rayon::prelude::*;
use std::time::Instant;

/// Settings of the field fit.
#[derive(Clone, Debug)]
pub struct FieldFitConfig {
    /// Training steps. Defaults to 1500.
    pub steps: u32,
    /// Points per step. Defaults to 16384.
    pub batch: usize,
    /// Hash-grid table size. Defaults to 17.
    pub log2_table_size: u32,
    /// Seed of initialisation and sampling. Defaults to 0.
    pub seed: u64,
}

impl Default for FieldFitConfig {
    fn default() -> Self {
        FieldFitConfig { steps: 1500, batch: 1 << 14, log2_table_size: 17, seed: 0 }
    }
}

/// The target: a smooth colour pattern with a sharp-edged sphere in it (values in [0, 1]).
pub fn target_colour(p: [f32; 3]) -> [f32; 3] {
    let tau = std::f32::consts::TAU;
    let d = ((p[0] - 0.5).powi(2) + (p[1] - 0.5).powi(2) + (p[2] - 0.5).powi(2)).sqrt();
    if d < 0.3 {
        [0.9, 0.2 + 0.6 * p[2], 0.1]
    } else {
        [
            0.5 + 0.4 * (tau * 3.0 * p[0]).sin() * (tau * 2.0 * p[1]).cos(),
            0.5 + 0.4 * (tau * 5.0 * p[2]).sin(),
            0.5 + 0.4 * (tau * 4.0 * (p[0] + p[1])).cos(),
        ]
    }
}

/// Result of a fit.
#[derive(Clone, Debug)]
pub struct FieldFitReport {
    /// Held-out PSNR (dB) after training.
    pub psnr: f64,
    /// Held-out PSNR at initialisation.
    pub psnr_initial: f64,
    /// Wall time of training.
    pub seconds: f64,
    /// Final fp32 master parameters (grid, then MLP), for determinism checks.
    pub params_checksum: f64,
    /// Steps run.
    pub steps: u32,
}

impl std::fmt::Display for FieldFitReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "field fit: {} steps in {:.2} s, held-out PSNR {:.2} dB (from {:.2} dB at init)",
            self.steps, self.seconds, self.psnr, self.psnr_initial
        )
    }
}

struct Model {
    grid: HashGrid,
    table: HashGridParams,
    mlp: Mlp<64>,
    weights: MlpParams,
}

impl Model {
    /// Predicted colours of `pos` (the MLP ends in a sigmoid).
    fn predict(&self, isa: Isa, pos: &[[f32; 3]]) -> Vec<[f32; 3]> {
        let mut enc = vec![0.0; pos.len() * self.grid.output_width()];
        self.grid.forward_par(isa, &self.table.table, pos, &mut enc);
        let stride = self.mlp.output_stride();
        let mut ctx = MlpContext::default();
        self.mlp.forward(isa, &self.weights, &enc, pos.len(), &mut ctx);
        ctx.output().chunks(stride).map(|o| [o[0], o[1], o[2]]).collect()
    }
}

fn psnr(isa: Isa, model: &Model, pos: &[[f32; 3]]) -> f64 {
    let pred = model.predict(isa, pos);
    let mse: f64 = pred
        .iter()
        .zip(pos)
        .map(|(c, &p)| {
            let t = target_colour(p);
            (0..3).map(|k| ((c[k] - t[k]) as f64).powi(2)).sum::<f64>()
        })
        .sum::<f64>()
        / (3 * pos.len()) as f64;
    -10.0 * mse.log10()
}

/// Fits the field; `progress` receives a line every few hundred steps.
pub fn fit_field(cfg: &FieldFitConfig, isa: Isa, mut progress: impl FnMut(String)) -> FieldFitReport {
    let mut rng = Rng::new(cfg.seed);
    let grid = HashGrid::new(HashGridConfig { log2_table_size: cfg.log2_table_size, ..Default::default() });
    let mlp = Mlp::<64>::new(MlpConfig {
        input: grid.features(),
        output: 3,
        hidden_layers: 2,
        hidden_activation: Activation::Relu,
        output_activation: Activation::Sigmoid,
    });
    let mut model =
        Model { table: HashGridParams::init(&grid, &mut rng), weights: mlp.init_params(&mut rng), grid, mlp };
    let held_out: Vec<[f32; 3]> = (0..1 << 14).map(|_| [rng.f32(), rng.f32(), rng.f32()]).collect();
    let psnr_initial = psnr(isa, &model, &held_out);

    let schedule = LrSchedule {
        base: 1e-2,
        decay_start: cfg.steps * 2 / 3,
        decay_interval: cfg.steps.div_ceil(6).max(1),
        ..Default::default()
    };
    let mut adam_grid = Adam::new(model.grid.n_params(), AdamConfig::default());
    let mut adam_mlp = Adam::new(model.mlp.n_params(), AdamConfig { l2: 1e-6, ..Default::default() });
    let n = cfg.batch;
    let width = model.grid.output_width();
    let (in_stride, out_stride) = (model.mlp.input_stride(), model.mlp.output_stride());
    // dynamic allocation: once per fit
    let mut pos = vec![[0f32; 3]; n];
    let mut enc = vec![0f32; n * width];
    let mut d_enc = vec![0f32; n * in_stride];
    let mut grid_grads = vec![0f32; model.grid.n_params()];
    let mut mlp_grads = vec![0f32; model.mlp.n_params()];
    let mut slots: Vec<(Vec<f32>, MlpContext, MlpWorkspace, Vec<f32>)> = (0..SLOTS)
        .map(|_| (vec![0f32; model.mlp.n_params()], MlpContext::default(), MlpWorkspace::default(), Vec::new()))
        .collect();
    let start = Instant::now();
    for step in 0..cfg.steps {
        let mut srng = Rng::stream(cfg.seed, step as u64);
        pos.iter_mut().for_each(|p| *p = [srng.f32(), srng.f32(), srng.f32()]);
        model.grid.forward_par(isa, &model.table.table, &pos, &mut enc);
        // Per slot: MLP forward, MSE gradient, MLP backward into the slot's own buffer.
        let (mlp, weights) = (&model.mlp, &model.weights);
        let d_enc_parts = split_rows(&mut d_enc, n, in_stride);
        let loss: f64 = slots
            .par_iter_mut()
            .zip(d_enc_parts)
            .enumerate()
            .map(|(s, ((grads, ctx, ws, d_out), d_in))| {
                let r = slot_range(n, s);
                let rows = r.len();
                let x = &enc[r.start * width..r.end * width];
                mlp.forward(isa, weights, x, rows, ctx);
                d_out.clear();
                d_out.resize(rows * out_stride, 0.0);
                let mut loss = 0.0;
                for (b, p) in pos[r].iter().enumerate() {
                    let t = target_colour(*p);
                    for c in 0..3 {
                        let e = ctx.output()[b * out_stride + c] - t[c];
                        loss += (e * e) as f64;
                        d_out[b * out_stride + c] = 2.0 * e / (3 * n) as f32;
                    }
                }
                mlp.backward(isa, weights, x, ctx, d_out, grads, GradientMode::Overwrite, Some(d_in), ws);
                loss
            })
            .collect::<Vec<f64>>()
            .iter()
            .sum();
        mlp_grads.fill(0.0);
        accumulate_in_order(slots.iter().map(|s| s.0.as_slice()), &mut mlp_grads);
        model.grid.backward_params(isa, &pos, &d_enc, &mut grid_grads, GradientMode::Overwrite);
        let lr = schedule.lr(step);
        let half: &mut [u16] = bytemuck::cast_slice_mut(&mut model.table.table);
        adam_grid.step(isa, lr, &mut model.table.master, &grid_grads, Some(half));
        adam_mlp.step(isa, lr, model.weights.weights_mut(), &mlp_grads, None);
        model.weights.sync();
        if (step + 1) % 250 == 0 || step + 1 == cfg.steps {
            let mse = loss / (3 * n) as f64;
            progress(format!(
                "step {:>5}/{}  loss {:.5}  train PSNR {:.2} dB  {:.0} points/s",
                step + 1,
                cfg.steps,
                mse,
                -10.0 * mse.log10(),
                ((step + 1) as f64 * n as f64) / start.elapsed().as_secs_f64()
            ));
        }
    }
    let seconds = start.elapsed().as_secs_f64();
    let params_checksum = model
        .table
        .master
        .iter()
        .chain(model.weights.weights())
        .enumerate()
        .map(|(i, &p)| p as f64 * ((i % 97) as f64 + 1.0))
        .sum();
    FieldFitReport { psnr: psnr(isa, &model, &held_out), psnr_initial, seconds, params_checksum, steps: cfg.steps }
}
