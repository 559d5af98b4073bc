//! Fused tiny MLP (DESIGN §2.1): bias-free dense layers of a const-generic hidden width
//! `W ∈ {16, 32, 64}`, a hidden activation and a separate output activation.
//!
//! **Fusion.** [`Mlp::forward`] walks the batch in tiles of [`TILE`] samples and pushes each
//! tile through *all* layers while it is in L1, saving every layer's output in the
//! [`MlpContext`]; [`Mlp::backward`] walks the same tiles back through all layers, producing
//! dL/dweights (per [`GradientMode`]) and optionally dL/dinput. [`Mlp::forward_first`] is the
//! forward for callers that read only the first output (a density network's σ when only depth
//! is wanted): the last layer's column 0 alone, the same bits.
//!
//! **Padding.** Input and output widths are padded to multiples of 16 (the SIMD tile);
//! callers lay rows out with [`Mlp::input_stride`] / [`Mlp::output_stride`]. Padded weights
//! start at zero and their gradients are forced to zero, so they stay zero under Adam and
//! whatever the caller leaves in padding columns never reaches the result. The output
//! layer's backward runs on its real columns only, rounded up to 4 (a 3-output colour network
//! or a 1-output Mixnet pads to 16): the same sums, see `narrow_output_backward`.
//!
//! **Weights.** One flat `f32` buffer; layer `l` is a `k_l × o_l` row-major view
//! (`w[kk · o_l + j]`), layers in order.
//!
//! Per layer, `z = x·W`, `y = act(z)`; backward: `dz = dy ⊙ act′(y)`, `dW += xᵀ·dz`,
//! `dx = dz·Wᵀ`. Kernels: [`scalar`] is the spec, `avx2`/`avx512`/`neon` its twins (the
//! AVX-512 level runs `avx512`'s layer kernels and `avx2`'s first-column kernel; `avx2` and
//! `avx512` give the same bits).

pub mod activation;
#[cfg(target_arch = "x86_64")]
pub(crate) mod amx;
#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;
#[cfg(target_arch = "aarch64")]
mod neon;
pub mod scalar;

mod dispatch;
mod params;

pub use activation::Activation;
use dispatch::{first_column_fma, matmul, matmul_first, matmul_tn_acc, LayerWeights};
pub use dispatch::{matmul_first_with, matmul_tn_acc_with, matmul_with};
pub use params::{bf16_bits, pack_vnni, MlpParams};

use crate::rng::Rng;
use crate::simd::{CpuLevel, Isa};
use crate::GradientMode;

/// Samples per tile pushed through all layers together.
pub const TILE: usize = 64;

/// Shape and activations of an MLP.
#[derive(Clone, Debug, PartialEq)]
pub struct MlpConfig {
    /// Input features. No default (network specific).
    pub input: usize,
    /// Output features. No default (network specific).
    pub output: usize,
    /// Hidden layers of width `W` (≥ 1).
    pub hidden_layers: usize,
    /// Activation after each hidden layer. Usually [`Activation::Relu`].
    pub hidden_activation: Activation,
    /// Activation of the output layer. Usually [`Activation::None`]: the field applies
    /// trunc_exp / sigmoid itself, because Residual-NeRF mixes pre-activation values.
    pub output_activation: Activation,
}

/// Where one layer's weights live in the flat parameter buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LayerShape {
    /// First weight of the layer.
    pub offset: usize,
    /// Padded input width.
    pub k: usize,
    /// Padded output width.
    pub o: usize,
    /// Unpadded input width.
    pub k_real: usize,
    /// Unpadded output width.
    pub o_real: usize,
}

/// A bias-free MLP of hidden width `W`. Holds only the geometry; weights are a flat slice.
#[derive(Clone, Debug)]
pub struct Mlp<const W: usize> {
    config: MlpConfig,
    layers: Vec<LayerShape>,
    n_params: usize,
}

fn pad16(n: usize) -> usize {
    n.div_ceil(16) * 16
}

impl<const W: usize> Mlp<W> {
    /// Lays out the layers. Panics when `W ∉ {16, 32, 64}`, a width is 0 or there is no hidden layer.
    pub fn new(config: MlpConfig) -> Mlp<W> {
        assert!(matches!(W, 16 | 32 | 64), "mlp: hidden width must be 16, 32 or 64");
        assert!(config.input > 0 && config.output > 0, "mlp: input and output widths must be positive");
        assert!(config.hidden_layers >= 1, "mlp: at least one hidden layer");
        let mut dims = vec![(config.input, pad16(config.input))];
        dims.extend(std::iter::repeat_n((W, W), config.hidden_layers));
        dims.push((config.output, pad16(config.output)));
        let mut offset = 0;
        let layers = dims
            .windows(2)
            .map(|d| {
                let s = LayerShape { offset, k: d[0].1, o: d[1].1, k_real: d[0].0, o_real: d[1].0 };
                offset += s.k * s.o;
                s
            })
            .collect();
        Mlp { config, layers, n_params: offset }
    }

    /// The configuration.
    pub fn config(&self) -> &MlpConfig {
        &self.config
    }

    /// Layer views into the parameter buffer.
    pub fn layers(&self) -> &[LayerShape] {
        &self.layers
    }

    /// Length of the flat weight buffer (including zero padding).
    pub fn n_params(&self) -> usize {
        self.n_params
    }

    /// Floats per input row (input width padded to 16).
    pub fn input_stride(&self) -> usize {
        self.layers[0].k
    }

    /// Floats per output row (output width padded to 16).
    pub fn output_stride(&self) -> usize {
        self.layers.last().unwrap().o
    }

    /// Multiply-adds per sample of one forward pass, padded (what the kernels execute) and
    /// real (what the network needs).
    pub fn macs_per_sample(&self) -> (usize, usize) {
        let padded = self.layers.iter().map(|l| l.k * l.o).sum();
        let real = self.layers.iter().map(|l| l.k_real * l.o_real).sum();
        (padded, real)
    }

    /// Multiply-adds per sample that one [`Mlp::forward`] and one [`Mlp::backward`] with
    /// weight and input gradients execute: the padded forward, and per layer `xᵀ·dz` and
    /// `dz·Wᵀ` at padded widths, except the output layer's two, which run on its real columns
    /// rounded up to 4.
    pub fn fwd_bwd_macs_per_sample(&self) -> usize {
        let last = self.layers.len() - 1;
        let backward: usize = self
            .layers
            .iter()
            .enumerate()
            .map(|(l, s)| 2 * s.k * if l == last { self.output_backward_columns() } else { s.o })
            .sum();
        self.macs_per_sample().0 + backward
    }

    /// Columns of `dz` the output layer's backward reads: its real width rounded up to 4 (the
    /// kernels' step), at most its padded width (see `narrow_output_backward`).
    fn output_backward_columns(&self) -> usize {
        let out = self.layers.last().unwrap();
        out.o_real.next_multiple_of(4).min(out.o)
    }

    /// Xavier-uniform initialisation (`U(±√(6/(fan_in+fan_out)))` on the real weights),
    /// zeros in the padding.
    pub fn init_params(&self, rng: &mut Rng) -> MlpParams {
        let mut p = vec![0.0; self.n_params];
        for l in &self.layers {
            let s = (6.0 / (l.k_real + l.o_real) as f32).sqrt();
            for kk in 0..l.k_real {
                for j in 0..l.o_real {
                    p[l.offset + kk * l.o + j] = rng.uniform(-s, s);
                }
            }
        }
        MlpParams::new(self, p)
    }

    /// Runs the MLP on `n` rows of `input` (`n × input_stride()`), saving what backward needs
    /// in `ctx`; the result is `ctx.output()` (`n × output_stride()`). One thread.
    pub fn forward(&self, isa: Isa, params: &MlpParams, input: &[f32], n: usize, ctx: &mut MlpContext) {
        self.forward_from(isa, params, input, 0, n, ctx);
    }

    /// [`Mlp::forward`] of rows `from..n` of `input`, keeping rows `0..from` of the last pass
    /// in `ctx` (a chunk that grows: the same bits as one forward of all `n` rows, each row's
    /// result being independent of the others).
    pub fn forward_from(
        &self,
        isa: Isa,
        params: &MlpParams,
        input: &[f32],
        from: usize,
        n: usize,
        ctx: &mut MlpContext,
    ) {
        assert_eq!(params.weights.len(), self.n_params, "mlp: parameter buffer has the wrong length");
        assert!(input.len() >= n * self.input_stride(), "mlp: input holds fewer than n rows");
        assert!(from == 0 || (from <= n && from <= ctx.n), "mlp: forward_from continues the last pass's rows");
        assert!(
            isa.level().mlp_is_fp32() || params.synced,
            "mlp: weights changed since the last MlpParams::sync (stale bf16 copy)"
        );
        ctx.prepare(n, self.layers.iter().map(|l| l.o));
        let last = self.layers.len() - 1;
        for t0 in (from..n).step_by(TILE) {
            let rows = TILE.min(n - t0);
            for (l, s) in self.layers.iter().enumerate() {
                let act = if l == last { self.config.output_activation } else { self.config.hidden_activation };
                let (before, after) = ctx.acts.split_at_mut(l);
                let x = if l == 0 {
                    &input[t0 * s.k..(t0 + rows) * s.k]
                } else {
                    &before[l - 1][t0 * s.k..(t0 + rows) * s.k]
                };
                let y = &mut after[0][t0 * s.o..(t0 + rows) * s.o];
                matmul(isa, x, rows, s.k, params.layer(l), s.o, y, act == Activation::Relu);
                if !act.fused_in_kernel() {
                    y.iter_mut().for_each(|v| *v = act.forward(*v));
                }
            }
        }
    }

    /// The network's first output only (activated), for `n` rows of `input`, into `out`
    /// (`n` values): the same bits as [`Mlp::forward`]'s column 0, without the rest of the
    /// last layer (a density network's σ without its geometry features: 1 of 16 columns).
    /// `ctx` is scratch afterwards — nothing [`Mlp::backward`] can use. One thread.
    pub fn forward_first(
        &self,
        isa: Isa,
        params: &MlpParams,
        input: &[f32],
        n: usize,
        ctx: &mut MlpContext,
        out: &mut [f32],
    ) {
        assert!(out.len() >= n, "mlp: output holds fewer than n values");
        if !isa.level().mlp_is_fp32() {
            // The tile unit computes 16 columns as fast as one: the whole forward, column 0.
            self.forward(isa, params, input, n, ctx);
            let o = self.output_stride();
            out[..n].iter_mut().zip(ctx.output().chunks_exact(o)).for_each(|(y, row)| *y = row[0]);
            return;
        }
        let params = params.weights();
        assert_eq!(params.len(), self.n_params, "mlp: parameter buffer has the wrong length");
        assert!(input.len() >= n * self.input_stride(), "mlp: input holds fewer than n rows");
        let last = self.layers.len() - 1;
        ctx.prepare(n, self.layers[..last].iter().map(|l| l.o));
        ctx.n = 0;
        let act = self.config.output_activation;
        for t0 in (0..n).step_by(TILE) {
            let rows = TILE.min(n - t0);
            for (l, s) in self.layers.iter().enumerate() {
                let w = LayerWeights { f32: &params[s.offset..s.offset + s.k * s.o], bf16: &[] };
                let (before, after) = ctx.acts.split_at_mut(l);
                let x = if l == 0 {
                    &input[t0 * s.k..(t0 + rows) * s.k]
                } else {
                    &before[l - 1][t0 * s.k..(t0 + rows) * s.k]
                };
                if l == last {
                    let y = &mut out[t0..t0 + rows];
                    matmul_first(isa, x, rows, s.k, w.f32, s.o, y, act == Activation::Relu);
                    if !act.fused_in_kernel() {
                        y.iter_mut().for_each(|v| *v = act.forward(*v));
                    }
                } else {
                    let y = &mut after[0][t0 * s.o..(t0 + rows) * s.o];
                    let hidden = self.config.hidden_activation;
                    matmul(isa, x, rows, s.k, w, s.o, y, hidden == Activation::Relu);
                    if !hidden.fused_in_kernel() {
                        y.iter_mut().for_each(|v| *v = hidden.forward(*v));
                    }
                }
            }
        }
    }

    /// Back-propagates `d_output` (`n × output_stride()`, dL/d of the activated outputs;
    /// padding columns are ignored) through the pass saved in `ctx`.
    /// dL/dweights goes to `grads` per `mode`; dL/dinput to `d_input` (`n × input_stride()`)
    /// when given. `input` must be the forward's input. One thread.
    #[allow(clippy::too_many_arguments)]
    pub fn backward(
        &self,
        isa: Isa,
        params: &MlpParams,
        input: &[f32],
        ctx: &MlpContext,
        d_output: &[f32],
        grads: &mut [f32],
        mode: GradientMode,
        mut d_input: Option<&mut [f32]>,
        ws: &mut MlpWorkspace,
    ) {
        let n = ctx.n;
        assert!(params.synced, "mlp: weights changed since the last MlpParams::sync (stale transposed copy)");
        assert_eq!(params.weights.len(), self.n_params, "mlp: parameter buffer has the wrong length");
        assert_eq!(grads.len(), self.n_params, "mlp: gradient buffer has the wrong length");
        assert!(input.len() >= n * self.input_stride(), "mlp: input holds fewer than n rows");
        assert!(d_output.len() >= n * self.output_stride(), "mlp: d_output holds fewer than n rows");
        if let Some(d) = d_input.as_deref() {
            assert!(d.len() >= n * self.input_stride(), "mlp: d_input holds fewer than n rows");
        }
        if mode == GradientMode::Overwrite {
            grads.fill(0.0);
        }
        let want_params = mode != GradientMode::Ignore;
        if !want_params && d_input.is_none() {
            return;
        }
        ws.reserve(&self.layers);
        let last = self.layers.len() - 1;
        let out = self.layers[last];
        // The output layer's dz is zero past its real columns: its backward reads only the
        // first `narrow` of them (see `narrow_output_backward`).
        let narrow = self.output_backward_columns();
        for t0 in (0..n).step_by(TILE) {
            let rows = TILE.min(n - t0);
            // dz of the output layer: dy ⊙ act′(y), padding columns zeroed.
            let y = &ctx.acts[last][t0 * out.o..(t0 + rows) * out.o];
            let dy = &d_output[t0 * out.o..(t0 + rows) * out.o];
            self.config.output_activation.backward_slice(y, dy, &mut ws.dz[..rows * out.o]);
            if out.o_real < out.o {
                ws.dz[..rows * out.o].chunks_mut(out.o).for_each(|r| r[out.o_real..].fill(0.0));
            }
            for l in (0..=last).rev() {
                let s = self.layers[l];
                let x = if l == 0 {
                    &input[t0 * s.k..(t0 + rows) * s.k]
                } else {
                    &ctx.acts[l - 1][t0 * s.k..(t0 + rows) * s.k]
                };
                if l == last && narrow < s.o {
                    let g = want_params.then(|| &mut grads[s.offset..s.offset + s.k * s.o]);
                    narrow_output_backward(isa, params, l, narrow, x, rows, g, ws);
                    self.config.hidden_activation.backward_slice(x, &ws.dx[..rows * s.k], &mut ws.dz[..rows * s.k]);
                    continue;
                }
                if want_params {
                    matmul_tn_acc(
                        isa,
                        x,
                        rows,
                        s.k,
                        &ws.dz[..rows * s.o],
                        s.o,
                        &mut grads[s.offset..s.offset + s.k * s.o],
                    );
                }
                if l > 0 {
                    // dx = dz · Wᵀ, then through the hidden activation.
                    let wt = params.layer_transposed(l);
                    matmul(isa, &ws.dz[..rows * s.o], rows, s.o, wt, s.k, &mut ws.dx[..rows * s.k], false);
                    self.config.hidden_activation.backward_slice(x, &ws.dx[..rows * s.k], &mut ws.dz[..rows * s.k]);
                } else if let Some(d) = d_input.as_deref_mut() {
                    let wt = params.layer_transposed(l);
                    matmul(isa, &ws.dz[..rows * s.o], rows, s.o, wt, s.k, &mut d[t0 * s.k..(t0 + rows) * s.k], false);
                }
            }
        }
        if want_params {
            // Gradients of the input-padding rows (non-zero only if the caller left junk in
            // the padding columns) are forced to zero so padded weights stay zero.
            let first = self.layers[0];
            grads[first.offset + first.k_real * first.o..first.offset + first.k * first.o].fill(0.0);
        }
    }
}

/// Backward of an output layer whose `dz` (`ws.dz`, `rows × o`) is zero past column `c` (its
/// real width rounded up to 4, as the kernels want): a 3-output colour network or a 1-output
/// Mixnet would otherwise spend 13/16 of three layer products on zero columns.
/// - Weight gradient: `dW[:, ..c] += xᵀ·dz[:, ..c]` is run as its transpose,
///   `dWᵀ[..c] += dz[:, ..c]ᵀ·x` — `c` rows of a `k`-wide weight-gradient product instead of
///   one 16-column block whose kernel broadcasts an input per multiply-add. `dWᵀ[..c]` is copied
///   out of `grads` and back, so each entry runs the same chain of products (which commute)
///   from the same start: the same bits on every level.
/// - `ws.dx = dz[:, ..c]·Wᵀ[..c]`: the full product's sums without its trailing `+ 0·0` terms,
///   which cannot change a sum that starts at +0 (it is never −0): the same bits.
#[allow(clippy::too_many_arguments)]
fn narrow_output_backward(
    isa: Isa,
    params: &MlpParams,
    l: usize,
    c: usize,
    x: &[f32],
    rows: usize,
    grads: Option<&mut [f32]>,
    ws: &mut MlpWorkspace,
) {
    let s = params.layers[l];
    let dz = &mut ws.narrow_dz[..rows * c];
    for (row, full) in dz.chunks_exact_mut(c).zip(ws.dz.chunks_exact(s.o)) {
        row.copy_from_slice(&full[..c]);
    }
    if let Some(g) = grads {
        let dwt = &mut ws.narrow_dwt[..c * s.k];
        for j in 0..c {
            for kk in 0..s.k {
                dwt[j * s.k + kk] = g[kk * s.o + j];
            }
        }
        matmul_tn_acc(isa, dz, rows, c, x, s.k, dwt);
        for j in 0..c {
            for kk in 0..s.k {
                g[kk * s.o + j] = dwt[j * s.k + kk];
            }
        }
    }
    // Wᵀ's first c rows: the f32 copy's prefix; the bf16 pack's pair-rows (of which the
    // kernel reads c rounded up to 32, the rest zero-padded weights or zero padding).
    let wt = params.layer_transposed(l);
    let wt = LayerWeights { f32: &wt.f32[..c * s.k], bf16: wt.bf16 };
    matmul(isa, dz, rows, c, wt, s.k, &mut ws.dx[..rows * s.k], false);
}

/// What [`Mlp::forward`] saves for [`Mlp::backward`]: every layer's activated output.
/// Reused across calls; it allocates only when a batch is larger than any before.
#[derive(Clone, Debug, Default)]
pub struct MlpContext {
    n: usize,
    widths: Vec<usize>,
    acts: Vec<Vec<f32>>,
}

impl MlpContext {
    fn prepare(&mut self, n: usize, widths: impl Iterator<Item = usize>) {
        self.n = n;
        self.widths.clear();
        self.widths.extend(widths);
        self.acts.resize_with(self.widths.len(), Vec::new);
        for (a, &w) in self.acts.iter_mut().zip(&self.widths) {
            if a.len() < n * w {
                // dynamic allocation: only when the batch grows
                a.resize(n * w, 0.0);
            }
        }
    }

    /// Rows in the last forward pass.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Keeps only rows `keep` (strictly increasing) of every saved layer output, in that order,
    /// as if the forward had run on those rows alone: a backward then differentiates them.
    pub fn keep_rows(&mut self, keep: &[u32]) {
        debug_assert!(keep.windows(2).all(|w| w[0] < w[1]) && keep.last().is_none_or(|&k| (k as usize) < self.n));
        for (a, &w) in self.acts.iter_mut().zip(&self.widths) {
            keep_rows(a, w, keep);
        }
        self.n = keep.len();
    }

    /// The network's output of the last forward pass, `n × output_stride()`.
    pub fn output(&self) -> &[f32] {
        match (self.acts.last(), self.widths.last()) {
            (Some(a), Some(&w)) => &a[..self.n * w],
            _ => &[],
        }
    }
}

/// Moves rows `keep` (strictly increasing) of `buf` (rows of `width`) to its front, in order.
pub fn keep_rows<T: Copy>(buf: &mut [T], width: usize, keep: &[u32]) {
    for (dst, &src) in keep.iter().enumerate() {
        let src = src as usize;
        if src != dst {
            buf.copy_within(src * width..(src + 1) * width, dst * width);
        }
    }
}

/// Scratch for [`Mlp::backward`]: one tile of gradients flowing back.
#[derive(Clone, Debug)]
pub struct MlpWorkspace {
    dz: Vec<f32>,
    dx: Vec<f32>,
    /// The output layer's real dz columns (`TILE × c`, see `narrow_output_backward`).
    narrow_dz: Vec<f32>,
    /// Its weight gradient, transposed (`c × k`).
    narrow_dwt: Vec<f32>,
}

impl Default for MlpWorkspace {
    fn default() -> Self {
        MlpWorkspace {
            dz: vec![0.0; TILE * 64],
            dx: vec![0.0; TILE * 64],
            narrow_dz: vec![0.0; TILE * 16],
            narrow_dwt: vec![0.0; 16 * 64],
        }
    }
}

impl MlpWorkspace {
    fn reserve(&mut self, layers: &[LayerShape]) {
        let widest = layers.iter().map(|l| l.k.max(l.o)).max().unwrap_or(0);
        if self.dz.len() < TILE * widest {
            // dynamic allocation: only for a network wider than any before
            self.dz.resize(TILE * widest, 0.0);
            self.dx.resize(TILE * widest, 0.0);
        }
        let out = layers.last().map_or(0, |l| l.o);
        if self.narrow_dz.len() < TILE * out || self.narrow_dwt.len() < out * widest {
            self.narrow_dz.resize(TILE * out, 0.0);
            self.narrow_dwt.resize(out * widest, 0.0);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    #[should_panic(expected = "stale transposed copy")]
    fn backward_refuses_weights_changed_without_sync() {
        let mlp = Mlp::<16>::new(MlpConfig {
            input: 3,
            output: 1,
            hidden_layers: 1,
            hidden_activation: Activation::Relu,
            output_activation: Activation::None,
        });
        let mut params = mlp.init_params(&mut Rng::new(1));
        let x = vec![0.5; 2 * mlp.input_stride()];
        let mut ctx = MlpContext::default();
        mlp.forward(Isa::scalar(), &params, &x, 2, &mut ctx);
        params.weights_mut()[0] += 1.0;
        let d = vec![1.0; 2 * mlp.output_stride()];
        let mut g = vec![0.0; mlp.n_params()];
        mlp.backward(
            Isa::scalar(),
            &params,
            &x,
            &ctx,
            &d,
            &mut g,
            GradientMode::Overwrite,
            None,
            &mut MlpWorkspace::default(),
        );
    }

    /// The narrow output-layer backward against the full-width kernels it replaces, on every
    /// level the host runs: the same weight gradients (accumulated onto non-zero ones) and the
    /// same dL/dx, bit for bit, for 1..=16 real outputs.
    #[test]
    fn narrow_output_backward_is_the_full_width_product() {
        let mut rng = Rng::new(7);
        for o_real in [1usize, 3, 4, 5, 12, 16] {
            let mlp = Mlp::<64>::new(MlpConfig {
                input: 31,
                output: o_real,
                hidden_layers: 2,
                hidden_activation: Activation::Relu,
                output_activation: Activation::None,
            });
            let last = mlp.layers().len() - 1;
            let s = mlp.layers()[last];
            let c = o_real.next_multiple_of(4);
            let params = mlp.init_params(&mut rng);
            let rows = 37;
            // ReLU outputs: some exact zeros.
            let x: Vec<f32> = (0..rows * s.k).map(|_| rng.uniform(-1.0, 1.0).max(0.0)).collect();
            let mut dz = vec![0.0f32; rows * s.o];
            for row in dz.chunks_exact_mut(s.o) {
                row[..o_real].iter_mut().for_each(|v| *v = rng.uniform(-1.0, 1.0));
            }
            let g0: Vec<f32> = (0..s.k * s.o).map(|_| rng.uniform(-1.0, 1.0)).collect();
            for isa in Isa::all() {
                let mut g_full = g0.clone();
                matmul_tn_acc(isa, &x, rows, s.k, &dz, s.o, &mut g_full);
                let mut dx_full = vec![0.0f32; rows * s.k];
                matmul(isa, &dz, rows, s.o, params.layer_transposed(last), s.k, &mut dx_full, false);

                let mut ws = MlpWorkspace::default();
                ws.reserve(mlp.layers());
                ws.dz[..rows * s.o].copy_from_slice(&dz);
                let mut g = g0.clone();
                let mut all = vec![0.0f32; mlp.n_params()];
                all[s.offset..].copy_from_slice(&g);
                narrow_output_backward(isa, &params, last, c, &x, rows, Some(&mut all[s.offset..]), &mut ws);
                g.copy_from_slice(&all[s.offset..]);
                let bits = |v: &[f32]| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&g), bits(&g_full), "{isa}: weight gradient, {o_real} outputs");
                assert_eq!(bits(&ws.dx[..rows * s.k]), bits(&dx_full), "{isa}: dL/dx, {o_real} outputs");
            }
        }
    }
}
