//! The NeRF field (DESIGN §2.1): world position → hash grid → density MLP → raw density `s`
//! and 15 geometry features; SH(direction) ⊕ features → colour MLP → pre-sigmoid colour `c′`.
//! `σ = trunc_exp(s)` and `c = sigmoid(c′)` are applied by the caller (the renderer), because
//! Residual-NeRF mixes the pre-activation values.
//!
//! Batches run in parallel at the batch level only: the grid encodes all samples (chunks on
//! the rayon pool), the MLPs run per [`SLOTS`] slot with their own contexts and gradient
//! buffers, reduced in slot order, and the grid backward runs one level per task — so results
//! do not depend on the thread count.

pub mod mix;
pub mod mixnet;
pub mod model;
pub mod residual;

use crate::encoding::{sh4, HashGrid, HashGridConfig, HashGridParams, SH4_COEFFS};
use crate::geometry::Aabb;
use crate::mlp::{Activation, Mlp, MlpConfig, MlpContext, MlpParams, MlpWorkspace};
use crate::rng::Rng;
use crate::simd::Isa;
use crate::slots::{accumulate_in_order, slot_range, split_rows, SLOTS};
use crate::GradientMode;
use glam::Vec3;
use rayon::prelude::*;

/// Geometry features passed from the density to the colour network.
pub const GEO_FEATURES: usize = 15;

/// The NeRF's architecture (DESIGN §2.1).
#[derive(Clone, Debug, PartialEq)]
pub struct NerfConfig {
    /// Hash-grid encoding. Defaults to [`HashGridConfig::default`].
    pub grid: HashGridConfig,
    /// Scene box mapped to the grid's unit cube. No default (scene specific).
    pub aabb: Aabb,
}

/// Trainable parameters of a NeRF field.
#[derive(Clone, Debug, PartialEq)]
pub struct NerfParams {
    /// Hash-grid table (fp32 master + fp16 mirror).
    pub grid: HashGridParams,
    /// Density MLP 32 → 64 → 16.
    pub density: MlpParams,
    /// Colour MLP 31 → 64 → 64 → 3.
    pub colour: MlpParams,
}

/// Gradients of [`NerfParams`], flat.
#[derive(Clone, Debug, PartialEq)]
pub struct NerfGrads {
    /// dL/d(grid master), entry-major pairs.
    pub grid: Vec<f32>,
    /// dL/d(density weights).
    pub density: Vec<f32>,
    /// dL/d(colour weights).
    pub colour: Vec<f32>,
}

/// A trained (or training) NeRF: field, parameters and the occupancy grid that says where
/// it is worth sampling. What a model file holds.
#[derive(Clone, Debug)]
pub struct Nerf {
    /// Architecture.
    pub field: NerfField,
    /// Parameters.
    pub params: NerfParams,
    /// Occupancy grid over the scene box.
    pub occupancy: crate::geometry::OccupancyGrid,
}

/// The field's geometry and kernels (parameters live in [`NerfParams`]).
#[derive(Clone, Debug)]
pub struct NerfField {
    config: NerfConfig,
    grid: HashGrid,
    density: Mlp<64>,
    colour: Mlp<64>,
}

/// The two networks' state for one run of rows — a slot of a batch pass or a chunk of the
/// fused training step: saved activations, the colour network's input and backward scratch.
#[derive(Clone, Debug, Default)]
struct Nets {
    density: MlpContext,
    colour_in: Vec<f32>,
    colour: MlpContext,
    ws: MlpWorkspace,
    /// Scratch: dL/d(output) of the colour, then of the density network.
    d_out: Vec<f32>,
    d_colour_in: Vec<f32>,
}

/// Per-slot state of a batch pass: the networks' and their gradients.
#[derive(Clone, Debug, Default)]
struct Slot {
    nets: Nets,
    g: NetGrads,
}

/// What a forward pass saves (reused across batches; grows only with the batch).
#[derive(Clone, Debug, Default)]
pub struct FieldContext {
    n: usize,
    unit: Vec<[f32; 3]>,
    enc: Vec<f32>,
    d_enc: Vec<f32>,
    slots: Vec<Slot>,
}

impl FieldContext {
    /// Samples of the last forward pass.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Whether the last forward pass had no samples.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// The encoded features of the last forward or density pass (`n × encoding width`).
    pub fn features(&self) -> &[f32] {
        &self.enc
    }
}

/// What one chunk of the fused training step saves ([`NerfField::chunk_density`] →
/// [`NerfField::chunk_keep`] → [`NerfField::chunk_colour`] → [`NerfField::chunk_backward`]):
/// a chunk is a few hundred samples on one thread, so all of it stays in L1/L2 between the
/// forward and the backward.
#[derive(Clone, Debug, Default)]
pub struct FieldChunk {
    unit: Vec<[f32; 3]>,
    enc: Vec<f32>,
    nets: Nets,
    d_enc: Vec<f32>,
}

impl FieldChunk {
    /// Rows held (after [`NerfField::chunk_keep`], the kept ones).
    pub fn len(&self) -> usize {
        self.unit.len()
    }

    /// Whether the chunk holds no rows.
    pub fn is_empty(&self) -> bool {
        self.unit.is_empty()
    }

    /// The rows' unit-cube positions.
    pub fn unit(&self) -> &[[f32; 3]] {
        &self.unit
    }

    /// The rows' encoded features (`len() × encoding width`).
    pub fn features(&self) -> &[f32] {
        &self.enc
    }

    /// dL/d(features) of the last [`NerfField::chunk_backward`] (`len() × encoding width`).
    pub fn feature_grad(&self) -> &[f32] {
        &self.d_enc
    }
}

/// The networks' weight gradients accumulated by one slot of the fused training step (the
/// grid's come from the samples' feature gradients, scattered once per step).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NetGrads {
    /// dL/d(density weights).
    pub density: Vec<f32>,
    /// dL/d(colour weights).
    pub colour: Vec<f32>,
}

impl NetGrads {
    /// Zeroes the gradients (sized on first use).
    pub fn clear(&mut self, field: &NerfField) {
        self.density.clear();
        self.density.resize(field.density.n_params(), 0.0);
        self.colour.clear();
        self.colour.resize(field.colour.n_params(), 0.0);
    }
}

impl NerfField {
    /// The field of `config`.
    pub fn new(config: NerfConfig) -> NerfField {
        let grid = HashGrid::new(config.grid);
        // The grid pads its rows exactly as the MLP pads its input (both to 16).
        debug_assert_eq!(grid.output_width(), grid.features().div_ceil(16) * 16);
        let density = Mlp::new(MlpConfig {
            input: grid.features(),
            output: 1 + GEO_FEATURES,
            hidden_layers: 1,
            hidden_activation: Activation::Relu,
            output_activation: Activation::None,
        });
        let colour = Mlp::new(MlpConfig {
            input: SH4_COEFFS + GEO_FEATURES,
            output: 3,
            hidden_layers: 2,
            hidden_activation: Activation::Relu,
            output_activation: Activation::None,
        });
        NerfField { config, grid, density, colour }
    }

    /// The configuration.
    pub fn config(&self) -> &NerfConfig {
        &self.config
    }

    /// The hash grid.
    pub fn grid(&self) -> &HashGrid {
        &self.grid
    }

    /// The density and the colour networks (DESIGN §2.1: 32 → 64 → 16 and 31 → 64 → 64 → 3).
    pub fn networks(&self) -> (&Mlp<64>, &Mlp<64>) {
        (&self.density, &self.colour)
    }

    /// Layers of the density network (flat-buffer views).
    pub fn density_layers(&self) -> &[crate::mlp::LayerShape] {
        self.density.layers()
    }

    /// Layers of the colour network (flat-buffer views).
    pub fn colour_layers(&self) -> &[crate::mlp::LayerShape] {
        self.colour.layers()
    }

    /// Length of the density network's flat weight buffer.
    pub fn density_params(&self) -> usize {
        self.density.n_params()
    }

    /// Length of the colour network's flat weight buffer.
    pub fn colour_params(&self) -> usize {
        self.colour.n_params()
    }

    /// Density-network parameters from a flat weight buffer.
    pub fn density_params_from(&self, weights: Vec<f32>) -> MlpParams {
        MlpParams::new(&self.density, weights)
    }

    /// Colour-network parameters from a flat weight buffer.
    pub fn colour_params_from(&self, weights: Vec<f32>) -> MlpParams {
        MlpParams::new(&self.colour, weights)
    }

    /// Freshly initialised parameters.
    pub fn init_params(&self, rng: &mut Rng) -> NerfParams {
        NerfParams {
            grid: HashGridParams::init(&self.grid, rng),
            density: self.density.init_params(rng),
            colour: self.colour.init_params(rng),
        }
    }

    /// Zeroed gradient buffers.
    pub fn zero_grads(&self) -> NerfGrads {
        NerfGrads {
            grid: crate::memory::zeroed_vec(self.grid.n_params()),
            density: vec![0.0; self.density.n_params()],
            colour: vec![0.0; self.colour.n_params()],
        }
    }

    fn encode(&self, isa: Isa, params: &NerfParams, positions: &[Vec3], ctx: &mut FieldContext) {
        let n = positions.len();
        ctx.n = n;
        ctx.unit.clear();
        ctx.unit.extend(positions.iter().map(|&p| self.config.aabb.to_unit(p).to_array()));
        let w = self.grid.output_width();
        ctx.enc.resize(n * w, 0.0);
        self.grid.forward_par(isa, &params.grid.table, &ctx.unit, &mut ctx.enc);
        ctx.slots.resize_with(SLOTS, Slot::default);
    }

    /// Raw densities `s` only (the density network; no colour): for occupancy updates and
    /// depth-only rendering. Writes `raw[i]` for `positions[i]`.
    pub fn density(&self, isa: Isa, params: &NerfParams, positions: &[Vec3], raw: &mut [f32], ctx: &mut FieldContext) {
        assert_eq!(raw.len(), positions.len(), "field: output length differs from the sample count");
        self.encode(isa, params, positions, ctx);
        let (n, w) = (positions.len(), self.grid.output_width());
        let enc = &ctx.enc;
        let raw_parts = split_rows(raw, n, 1);
        ctx.slots.par_iter_mut().zip(raw_parts).enumerate().for_each(|(s, (slot, out))| {
            let r = slot_range(n, s);
            self.nets_density_only(isa, params, &enc[r.start * w..r.end * w], out, &mut slot.nets);
        });
    }

    /// Full forward of samples at `positions` seen along unit `dirs`: writes raw density
    /// `raw[i]` and pre-sigmoid colour `rgb_raw[i]`, saving what [`NerfField::backward`] needs.
    pub fn forward(
        &self,
        isa: Isa,
        params: &NerfParams,
        positions: &[Vec3],
        dirs: &[Vec3],
        raw: &mut [f32],
        rgb_raw: &mut [[f32; 3]],
        ctx: &mut FieldContext,
    ) {
        let n = positions.len();
        assert!(dirs.len() == n && raw.len() == n && rgb_raw.len() == n, "field: buffers differ from the sample count");
        self.encode(isa, params, positions, ctx);
        let w = self.grid.output_width();
        let enc = &ctx.enc;
        let parts = split_rows(raw, n, 1).into_par_iter().zip(split_rows(rgb_raw, n, 1));
        ctx.slots.par_iter_mut().zip(parts).enumerate().for_each(|(s, (slot, (raw, rgb)))| {
            let r = slot_range(n, s);
            self.nets_density(isa, params, &enc[r.start * w..r.end * w], 0, raw, &mut slot.nets);
            self.nets_colour(isa, params, &dirs[r], rgb, &mut slot.nets);
        });
    }

    /// Back-propagates dL/ds (`d_raw`) and dL/dc′ (`d_rgb_raw`) of the last [`NerfField::forward`]
    /// (same `params`) into `grads` per `mode`.
    pub fn backward(
        &self,
        isa: Isa,
        params: &NerfParams,
        ctx: &mut FieldContext,
        d_raw: &[f32],
        d_rgb_raw: &[[f32; 3]],
        grads: &mut NerfGrads,
        mode: GradientMode,
    ) {
        self.backward_with_feature_grad(isa, params, ctx, d_raw, d_rgb_raw, &[], grads, mode);
    }

    /// Chunk forward, first half, on this thread: `positions` become the chunk's rows `from..`
    /// (rows before `from` are kept: a ray evaluated segment by segment grows its chunk;
    /// `from = 0` starts a new one; rows at `from` and after it are replaced, so a ray may take
    /// back its last samples) — encoded and through the density network; their raw densities
    /// `s` into `raw`. A chunk grown in steps holds the same bits as one call.
    pub fn chunk_density(
        &self,
        isa: Isa,
        params: &NerfParams,
        from: usize,
        positions: &[Vec3],
        raw: &mut [f32],
        c: &mut FieldChunk,
    ) {
        assert_eq!(raw.len(), positions.len(), "field: output length differs from the sample count");
        assert!(from <= c.len(), "field: a chunk grows from its rows");
        self.chunk_encode(isa, params, positions, c, from);
        self.nets_density(isa, params, &c.enc, from, raw, &mut c.nets);
    }

    /// The chunk's rows `from..` become `positions`: their unit-cube coordinates and encodings,
    /// into `c`, on this thread.
    fn chunk_encode(&self, isa: Isa, params: &NerfParams, positions: &[Vec3], c: &mut FieldChunk, from: usize) {
        let w = self.grid.output_width();
        c.unit.truncate(from);
        c.unit.extend(positions.iter().map(|&p| self.config.aabb.to_unit(p).to_array()));
        c.enc.resize(c.unit.len() * w, 0.0);
        self.grid.forward(isa, &params.grid.table, &c.unit[from..], &mut c.enc[from * w..]);
    }

    /// [`NerfField::density`] on this thread, for a chunk (depth-only rendering): encodes
    /// `positions` into `c` and writes raw densities `s`; the chunk is not one
    /// [`NerfField::chunk_colour`] can continue (no geometry features are computed).
    pub fn chunk_density_only(
        &self,
        isa: Isa,
        params: &NerfParams,
        positions: &[Vec3],
        raw: &mut [f32],
        c: &mut FieldChunk,
    ) {
        assert_eq!(raw.len(), positions.len(), "field: output length differs from the sample count");
        self.chunk_encode(isa, params, positions, c, 0);
        self.nets_density_only(isa, params, &c.enc, raw, &mut c.nets);
    }

    /// Keeps rows `keep` (strictly increasing) of the last [`NerfField::chunk_density`]: the
    /// rest of the chunk runs as if only those samples had been given.
    pub fn chunk_keep(&self, c: &mut FieldChunk, keep: &[u32]) {
        crate::mlp::keep_rows(&mut c.unit, 1, keep);
        c.unit.truncate(keep.len());
        crate::mlp::keep_rows(&mut c.enc, self.grid.output_width(), keep);
        c.enc.truncate(keep.len() * self.grid.output_width());
        c.nets.density.keep_rows(keep);
    }

    /// Chunk forward, second half: the colour network on the chunk's rows seen along `dirs`;
    /// writes pre-sigmoid colours into `rgb_raw`.
    pub fn chunk_colour(
        &self,
        isa: Isa,
        params: &NerfParams,
        dirs: &[Vec3],
        rgb_raw: &mut [[f32; 3]],
        c: &mut FieldChunk,
    ) {
        assert_eq!(dirs.len(), c.len(), "field: directions differ from the chunk's rows");
        self.nets_colour(isa, params, dirs, rgb_raw, &mut c.nets);
    }

    /// Chunk backward: dL/ds (`d_raw`) and dL/dc′ (`d_rgb_raw`) of the chunk's rows →
    /// network weight gradients added into `g`, and dL/d(features) left in
    /// [`FieldChunk::feature_grad`] for the grid's backward.
    pub fn chunk_backward(
        &self,
        isa: Isa,
        params: &NerfParams,
        c: &mut FieldChunk,
        d_raw: &[f32],
        d_rgb_raw: &[[f32; 3]],
        g: &mut NetGrads,
    ) {
        c.d_enc.resize(c.len() * self.grid.output_width(), 0.0);
        self.nets_backward(isa, params, &c.enc, d_raw, d_rgb_raw, &mut c.nets, g, &mut c.d_enc);
    }

    /// The density network on rows `from..from + raw.len()` of encoded features `enc` (rows
    /// before `from` kept from the last call: a growing chunk); their raw densities into `raw`.
    fn nets_density(&self, isa: Isa, params: &NerfParams, enc: &[f32], from: usize, raw: &mut [f32], nets: &mut Nets) {
        let (n, so) = (from + raw.len(), self.density.output_stride());
        self.density.forward_from(isa, &params.density, enc, from, n, &mut nets.density);
        for (o, row) in raw.iter_mut().zip(nets.density.output()[from * so..].chunks(so)) {
            *o = row[0];
        }
    }

    /// Raw densities only (the density network's first output; the same bits as
    /// [`NerfField::nets_density`]'s, without the geometry features): `nets` cannot go on to
    /// the colour network.
    fn nets_density_only(&self, isa: Isa, params: &NerfParams, enc: &[f32], raw: &mut [f32], nets: &mut Nets) {
        self.density.forward_first(isa, &params.density, enc, raw.len(), &mut nets.density, raw);
    }

    /// The colour network on the rows of the last [`NerfField::nets_density`], seen along
    /// `dirs`: SH(direction) ⊕ geometry features → pre-sigmoid colours into `rgb_raw`.
    fn nets_colour(&self, isa: Isa, params: &NerfParams, dirs: &[Vec3], rgb_raw: &mut [[f32; 3]], nets: &mut Nets) {
        let n = nets.density.n();
        assert!(dirs.len() == n && rgb_raw.len() == n, "field: buffers differ from the sample count");
        let (so, ci, co) = (self.density.output_stride(), self.colour.input_stride(), self.colour.output_stride());
        nets.colour_in.clear();
        nets.colour_in.resize(n * ci, 0.0);
        for ((row, dens), dir) in nets.colour_in.chunks_mut(ci).zip(nets.density.output().chunks(so)).zip(dirs) {
            row[..SH4_COEFFS].copy_from_slice(&sh4(dir.to_array()));
            row[SH4_COEFFS..SH4_COEFFS + GEO_FEATURES].copy_from_slice(&dens[1..1 + GEO_FEATURES]);
        }
        self.colour.forward(isa, &params.colour, &nets.colour_in, n, &mut nets.colour);
        for (o, row) in rgb_raw.iter_mut().zip(nets.colour.output().chunks(co)) {
            *o = [row[0], row[1], row[2]];
        }
    }

    /// Both networks backwards over the rows of the last forward (`enc` their features):
    /// weight gradients added into `g`, dL/d(features) written into `d_enc`.
    #[allow(clippy::too_many_arguments)]
    fn nets_backward(
        &self,
        isa: Isa,
        params: &NerfParams,
        enc: &[f32],
        d_raw: &[f32],
        d_rgb_raw: &[[f32; 3]],
        nets: &mut Nets,
        g: &mut NetGrads,
        d_enc: &mut [f32],
    ) {
        let n = nets.density.n();
        assert!(d_raw.len() == n && d_rgb_raw.len() == n, "field: gradient buffers differ from the sample count");
        let (so, ci, co) = (self.density.output_stride(), self.colour.input_stride(), self.colour.output_stride());
        // Colour network: dL/dc′ → weights, and dL/d(colour input) for the geometry features.
        nets.d_out.clear();
        nets.d_out.resize(n * co, 0.0);
        for (row, d) in nets.d_out.chunks_mut(co).zip(d_rgb_raw) {
            row[..3].copy_from_slice(d);
        }
        nets.d_colour_in.resize(n * ci, 0.0);
        self.colour.backward(
            isa,
            &params.colour,
            &nets.colour_in,
            &nets.colour,
            &nets.d_out,
            &mut g.colour,
            GradientMode::Accumulate,
            Some(&mut nets.d_colour_in),
            &mut nets.ws,
        );
        // Density network: d_out = (dL/ds, dL/d geometry features).
        nets.d_out.clear();
        nets.d_out.resize(n * so, 0.0);
        for (b, row) in nets.d_out.chunks_mut(so).enumerate() {
            row[0] = d_raw[b];
            row[1..1 + GEO_FEATURES]
                .copy_from_slice(&nets.d_colour_in[b * ci + SH4_COEFFS..b * ci + SH4_COEFFS + GEO_FEATURES]);
        }
        self.density.backward(
            isa,
            &params.density,
            enc,
            &nets.density,
            &nets.d_out,
            &mut g.density,
            GradientMode::Accumulate,
            Some(d_enc),
            &mut nets.ws,
        );
    }

    /// Width of the encoded features per sample ([`FieldContext::features`] rows).
    pub fn encoding_width(&self) -> usize {
        self.grid.output_width()
    }

    /// [`NerfField::backward`] when another network also read the encoded features (a Mixnet
    /// sharing the residual's encoding): `feature_grad` (`n × encoding_width`, or empty) is its
    /// dL/d(features), added before the grid's backward.
    #[allow(clippy::too_many_arguments)]
    pub fn backward_with_feature_grad(
        &self,
        isa: Isa,
        params: &NerfParams,
        ctx: &mut FieldContext,
        d_raw: &[f32],
        d_rgb_raw: &[[f32; 3]],
        feature_grad: &[f32],
        grads: &mut NerfGrads,
        mode: GradientMode,
    ) {
        let n = ctx.n;
        assert!(d_raw.len() == n && d_rgb_raw.len() == n, "field: gradient buffers differ from the sample count");
        if mode == GradientMode::Ignore {
            return;
        }
        let w = self.grid.output_width();
        ctx.d_enc.resize(n * w, 0.0);
        let enc = &ctx.enc;
        let d_enc_parts = split_rows(&mut ctx.d_enc, n, w);
        ctx.slots.par_iter_mut().zip(d_enc_parts).enumerate().for_each(|(s, (slot, d_enc))| {
            let r = slot_range(n, s);
            slot.g.clear(self);
            let (enc, d_raw, d_rgb_raw) = (&enc[r.start * w..r.end * w], &d_raw[r.clone()], &d_rgb_raw[r]);
            self.nets_backward(isa, params, enc, d_raw, d_rgb_raw, &mut slot.nets, &mut slot.g, d_enc);
        });
        if mode == GradientMode::Overwrite {
            grads.colour.fill(0.0);
            grads.density.fill(0.0);
        }
        accumulate_in_order(ctx.slots.iter().map(|s| s.g.colour.as_slice()), &mut grads.colour);
        accumulate_in_order(ctx.slots.iter().map(|s| s.g.density.as_slice()), &mut grads.density);
        if !feature_grad.is_empty() {
            assert_eq!(feature_grad.len(), ctx.d_enc.len(), "field: feature gradient is not n × encoding width");
            ctx.d_enc.iter_mut().zip(feature_grad).for_each(|(d, g)| *d += g);
        }
        self.grid.backward_params(isa, &ctx.unit, &ctx.d_enc, &mut grads.grid, mode);
    }
}
