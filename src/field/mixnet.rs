//! The Mixnet Φ_mix (DESIGN §2.3): position → features h(x) → MLP (1 hidden layer of 32) → one
//! logit `m`, β = sigmoid(m). Position only; trained (unlike the authors' code, whose Mixnet
//! weights never reached the optimiser). h(x) is either the Mixnet's own small hash grid
//! ([`MixnetEncoding::Own`]) or the residual NeRF's grid features ([`MixnetEncoding::Shared`],
//! the authors' code): then the caller passes the features in and adds the Mixnet's
//! dL/dh(x) into the residual's encoding gradient. Parallel like the NeRF field: grid encoding
//! on the pool, MLP per fixed slot, gradients reduced in slot order.

use crate::encoding::{HashGrid, HashGridConfig, HashGridParams};
use crate::geometry::Aabb;
use crate::mlp::{Activation, Mlp, MlpConfig, MlpContext, MlpParams, MlpWorkspace};
use crate::rng::Rng;
use crate::simd::Isa;
use crate::slots::{accumulate_in_order, slot_range, split_rows, SLOTS};
use crate::GradientMode;
use glam::Vec3;
use rayon::prelude::*;

/// The Mixnet's default encoding: 8 levels, 2^15 entries, resolutions 16..512 (β varies
/// smoothly: it marks where the scene changed).
pub fn default_mixnet_grid() -> HashGridConfig {
    HashGridConfig { levels: 8, log2_table_size: 15, base_resolution: 16, finest_resolution: 512 }
}

/// Where the Mixnet's features h(x) come from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MixnetEncoding {
    /// Its own hash grid (default: [`default_mixnet_grid`]).
    Own(HashGridConfig),
    /// The residual NeRF's hash-grid features; the Mixnet's gradient trains the residual's table.
    Shared,
}

impl Default for MixnetEncoding {
    fn default() -> Self {
        MixnetEncoding::Own(default_mixnet_grid())
    }
}

/// The Mixnet's geometry and kernels.
#[derive(Clone, Debug)]
pub struct Mixnet {
    aabb: Aabb,
    /// `None`: features come from the caller ([`MixnetEncoding::Shared`]).
    grid: Option<HashGrid>,
    mlp: Mlp<32>,
}

/// Mixnet parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct MixnetParams {
    /// Hash-grid table.
    pub grid: HashGridParams,
    /// MLP weights.
    pub mlp: MlpParams,
}

/// Mixnet gradients, flat.
#[derive(Clone, Debug, PartialEq)]
pub struct MixnetGrads {
    /// dL/d(grid master).
    pub grid: Vec<f32>,
    /// dL/d(MLP weights).
    pub mlp: Vec<f32>,
}

/// What one chunk of the fused training step saves (see [`super::FieldChunk`]).
#[derive(Clone, Debug, Default)]
pub struct MixnetChunk {
    unit: Vec<[f32; 3]>,
    enc: Vec<f32>,
    ctx: MlpContext,
    ws: MlpWorkspace,
    d_out: Vec<f32>,
    d_enc: Vec<f32>,
}

impl MixnetChunk {
    /// The rows' unit-cube positions (own encoding only; empty when shared).
    pub fn unit(&self) -> &[[f32; 3]] {
        &self.unit
    }

    /// dL/d(features) of the last [`Mixnet::chunk_backward`] (rows × input stride).
    pub fn feature_grad(&self) -> &[f32] {
        &self.d_enc
    }
}

#[derive(Clone, Debug, Default)]
struct Slot {
    ctx: MlpContext,
    ws: MlpWorkspace,
    d_out: Vec<f32>,
    g: Vec<f32>,
}

/// What a Mixnet forward saves.
#[derive(Clone, Debug, Default)]
pub struct MixnetContext {
    n: usize,
    unit: Vec<[f32; 3]>,
    enc: Vec<f32>,
    d_enc: Vec<f32>,
    slots: Vec<Slot>,
}

impl Mixnet {
    /// A Mixnet over `aabb` with `encoding`; `shared_width` is the width of the features a
    /// shared encoding passes in (unused for [`MixnetEncoding::Own`]).
    pub fn new(aabb: Aabb, encoding: MixnetEncoding, shared_width: usize) -> Mixnet {
        let grid = match encoding {
            MixnetEncoding::Own(g) => Some(HashGrid::new(g)),
            MixnetEncoding::Shared => None,
        };
        let mlp = Mlp::new(MlpConfig {
            input: grid.as_ref().map_or(shared_width, |g| g.features()),
            output: 1,
            hidden_layers: 1,
            hidden_activation: Activation::Relu,
            output_activation: Activation::None,
        });
        assert!(grid.is_some() || mlp.input_stride() == shared_width, "mixnet: shared features must be padded rows");
        Mixnet { aabb, grid, mlp }
    }

    /// Its own hash grid (`None` when the encoding is shared).
    pub fn grid(&self) -> Option<&HashGrid> {
        self.grid.as_ref()
    }

    /// The encoding.
    pub fn encoding(&self) -> MixnetEncoding {
        self.grid.as_ref().map_or(MixnetEncoding::Shared, |g| MixnetEncoding::Own(*g.config()))
    }

    /// The MLP.
    pub fn mlp(&self) -> &Mlp<32> {
        &self.mlp
    }

    /// MLP parameters from a flat weight buffer.
    pub fn mlp_params_from(&self, weights: Vec<f32>) -> MlpParams {
        MlpParams::new(&self.mlp, weights)
    }

    /// Fresh parameters. The output layer starts at zero, so β = ½ everywhere at first.
    pub fn init_params(&self, rng: &mut Rng) -> MixnetParams {
        let grid = match &self.grid {
            Some(g) => HashGridParams::init(g, rng),
            None => HashGridParams::from_master(Vec::new()),
        };
        let mut mlp = self.mlp.init_params(rng);
        let last = *self.mlp.layers().last().expect("one output layer");
        mlp.weights_mut()[last.offset..last.offset + last.k * last.o].fill(0.0);
        mlp.sync();
        MixnetParams { grid, mlp }
    }

    /// Zeroed gradients.
    pub fn zero_grads(&self) -> MixnetGrads {
        let grid = self.grid.as_ref().map_or(0, |g| g.n_params());
        MixnetGrads { grid: crate::memory::zeroed_vec(grid), mlp: vec![0.0; self.mlp.n_params()] }
    }

    /// The features the MLP reads for rows `0..from + positions.len()`: rows `from..` encoded
    /// from `positions` by the own grid into `unit` and `enc` (on the rayon pool when `par`;
    /// rows before `from` kept from the last call), or the caller's `shared` features (all rows).
    #[allow(clippy::too_many_arguments)]
    fn features<'a>(
        &self,
        isa: Isa,
        params: &MixnetParams,
        positions: &[Vec3],
        from: usize,
        shared: Option<&'a [f32]>,
        unit: &mut Vec<[f32; 3]>,
        enc: &'a mut Vec<f32>,
        par: bool,
    ) -> &'a [f32] {
        let n = from + positions.len();
        let enc = match (&self.grid, shared) {
            (Some(grid), None) => {
                let w = grid.output_width();
                unit.truncate(from);
                unit.extend(positions.iter().map(|&p| self.aabb.to_unit(p).to_array()));
                enc.resize(n * w, 0.0);
                let (unit, out) = (&unit[from..], &mut enc[from * w..]);
                match par {
                    true => grid.forward_par(isa, &params.grid.table, unit, out),
                    false => grid.forward(isa, &params.grid.table, unit, out),
                }
                &enc[..]
            }
            (None, Some(f)) => {
                unit.clear();
                f
            }
            _ => panic!("mixnet: shared features are given exactly when the encoding is shared"),
        };
        let w = self.mlp.input_stride();
        assert_eq!(enc.len(), n * w, "mixnet: features are not {w} per sample");
        enc
    }

    /// Logits `m` (β = sigmoid(m)) at world `positions`, saving what backward needs. With a
    /// shared encoding, `shared` holds the residual's features of those positions
    /// (`positions.len()` rows); with its own grid it must be `None`.
    pub fn forward(
        &self,
        isa: Isa,
        params: &MixnetParams,
        positions: &[Vec3],
        shared: Option<&[f32]>,
        logits: &mut [f32],
        ctx: &mut MixnetContext,
    ) {
        let n = positions.len();
        assert_eq!(logits.len(), n, "mixnet: output length differs from the sample count");
        ctx.n = n;
        ctx.slots.resize_with(SLOTS, Slot::default);
        let enc = self.features(isa, params, positions, 0, shared, &mut ctx.unit, &mut ctx.enc, true);
        let (w, so) = (self.mlp.input_stride(), self.mlp.output_stride());
        let parts = split_rows(logits, n, 1);
        ctx.slots.par_iter_mut().zip(parts).enumerate().for_each(|(s, (slot, out))| {
            let r = slot_range(n, s);
            self.mlp.forward(isa, &params.mlp, &enc[r.start * w..r.end * w], r.len(), &mut slot.ctx);
            for (o, row) in out.iter_mut().zip(slot.ctx.output().chunks(so)) {
                *o = row[0];
            }
        });
    }

    /// Chunk forward on this thread: `positions` become the chunk's rows `from..` (rows before
    /// `from` kept; `from = 0` starts a new chunk), their logits `m` into `logits`. `shared`,
    /// when the encoding is shared, holds the features of all the chunk's rows. A chunk grown
    /// in steps holds the same bits as one call.
    #[allow(clippy::too_many_arguments)]
    pub fn chunk_forward(
        &self,
        isa: Isa,
        params: &MixnetParams,
        from: usize,
        positions: &[Vec3],
        shared: Option<&[f32]>,
        logits: &mut [f32],
        c: &mut MixnetChunk,
    ) {
        let n = positions.len();
        assert_eq!(logits.len(), n, "mixnet: output length differs from the sample count");
        let enc = self.features(isa, params, positions, from, shared, &mut c.unit, &mut c.enc, false);
        let so = self.mlp.output_stride();
        self.mlp.forward_from(isa, &params.mlp, enc, from, from + n, &mut c.ctx);
        for (o, row) in logits.iter_mut().zip(c.ctx.output()[from * so..].chunks(so)) {
            *o = row[0];
        }
    }

    /// [`Mixnet::chunk_forward`]'s logits alone (the same bits; depth-only rendering): `c` is
    /// not a chunk [`Mixnet::chunk_keep`] or a backward can continue.
    pub fn chunk_logits(
        &self,
        isa: Isa,
        params: &MixnetParams,
        positions: &[Vec3],
        shared: Option<&[f32]>,
        logits: &mut [f32],
        c: &mut MixnetChunk,
    ) {
        let n = positions.len();
        assert_eq!(logits.len(), n, "mixnet: output length differs from the sample count");
        let enc = self.features(isa, params, positions, 0, shared, &mut c.unit, &mut c.enc, false);
        self.mlp.forward_first(isa, &params.mlp, enc, n, &mut c.ctx, logits);
    }

    /// Keeps rows `keep` (strictly increasing) of the last [`Mixnet::chunk_forward`].
    pub fn chunk_keep(&self, c: &mut MixnetChunk, keep: &[u32]) {
        if let Some(grid) = &self.grid {
            crate::mlp::keep_rows(&mut c.unit, 1, keep);
            c.unit.truncate(keep.len());
            crate::mlp::keep_rows(&mut c.enc, grid.output_width(), keep);
            c.enc.truncate(keep.len() * grid.output_width());
        }
        c.ctx.keep_rows(keep);
    }

    /// Chunk backward: dL/dm of the chunk's rows → MLP weight gradients added into `g`, and
    /// dL/d(features) left in [`MixnetChunk::feature_grad`] (the own grid's, or the residual's
    /// shared features' share). `shared` as given to the forward (kept rows).
    pub fn chunk_backward(
        &self,
        isa: Isa,
        params: &MixnetParams,
        c: &mut MixnetChunk,
        shared: Option<&[f32]>,
        d_logits: &[f32],
        g: &mut [f32],
    ) {
        let n = c.ctx.n();
        let (w, so) = (self.mlp.input_stride(), self.mlp.output_stride());
        assert_eq!(d_logits.len(), n, "mixnet: gradient length differs from the chunk's rows");
        c.d_enc.resize(n * w, 0.0);
        c.d_out.clear();
        c.d_out.resize(n * so, 0.0);
        for (row, &d) in c.d_out.chunks_mut(so).zip(d_logits) {
            row[0] = d;
        }
        let enc = shared.unwrap_or(&c.enc);
        let d_enc = Some(&mut c.d_enc[..]);
        self.mlp.backward(isa, &params.mlp, enc, &c.ctx, &c.d_out, g, GradientMode::Accumulate, d_enc, &mut c.ws);
    }

    /// dL/dh(x) of the last backward with a shared encoding (`n × width`), for the caller to add
    /// into the residual's encoding gradient.
    pub fn feature_grad<'c>(&self, ctx: &'c MixnetContext) -> &'c [f32] {
        &ctx.d_enc[..ctx.n * self.mlp.input_stride()]
    }

    /// Back-propagates dL/dm of the last forward into `grads` per `mode`; `shared` as given to
    /// forward. With a shared encoding dL/dh(x) is left in [`Mixnet::feature_grad`].
    #[allow(clippy::too_many_arguments)]
    pub fn backward(
        &self,
        isa: Isa,
        params: &MixnetParams,
        ctx: &mut MixnetContext,
        shared: Option<&[f32]>,
        d_logits: &[f32],
        grads: &mut MixnetGrads,
        mode: GradientMode,
    ) {
        let n = ctx.n;
        assert_eq!(d_logits.len(), n, "mixnet: gradient length differs from the sample count");
        if mode == GradientMode::Ignore {
            return;
        }
        let (w, so) = (self.mlp.input_stride(), self.mlp.output_stride());
        ctx.d_enc.resize(n * w, 0.0);
        let enc = shared.unwrap_or(&ctx.enc);
        let parts = split_rows(&mut ctx.d_enc, n, w);
        ctx.slots.par_iter_mut().zip(parts).enumerate().for_each(|(s, (slot, d_enc))| {
            let r = slot_range(n, s);
            slot.d_out.clear();
            slot.d_out.resize(r.len() * so, 0.0);
            for (row, &d) in slot.d_out.chunks_mut(so).zip(&d_logits[r.clone()]) {
                row[0] = d;
            }
            slot.g.clear();
            slot.g.resize(self.mlp.n_params(), 0.0);
            self.mlp.backward(
                isa,
                &params.mlp,
                &enc[r.start * w..r.end * w],
                &slot.ctx,
                &slot.d_out,
                &mut slot.g,
                GradientMode::Overwrite,
                Some(d_enc),
                &mut slot.ws,
            );
        });
        if mode == GradientMode::Overwrite {
            grads.mlp.fill(0.0);
        }
        accumulate_in_order(ctx.slots.iter().map(|s| s.g.as_slice()), &mut grads.mlp);
        if let Some(grid) = &self.grid {
            grid.backward_params(isa, &ctx.unit, &ctx.d_enc, &mut grads.grid, mode);
        }
    }
}
