//! What the trainer trains: a [`Model`] maps samples to activated density and colour, back-
//! propagates dL/dσ and dL/dc into its gradients, and lists its parameter groups for Adam.
//! Two models exist: a plain NeRF ([`NerfField`]) and a residual model
//! ([`ResidualField`]: frozen background + residual + Mixnet).
//!
//! A model runs two ways. The batch methods ([`Model::forward`], [`Model::backward`]) take any
//! number of samples and parallelise inside; rendering uses the forward, and the backward is
//! the reference the fused step is tested against. The training step itself is fused
//! ([`crate::train::trainer`]): each thread takes a *chunk* of whole rays — a few hundred
//! samples — through [`Model::chunk_density`] → [`Model::chunk_colour`] (on the samples
//! before each ray's opaque point) → compositing and loss → [`Model::chunk_backward`] while
//! the chunk's activations are in L1/L2, accumulating into its [`Model::Slot`]; once all
//! chunks are done, [`Model::finish_step`] reduces the slots in a fixed order and scatters the
//! samples' feature gradients into the hash grids, one level per task.

use crate::encoding::FeatureLevels;
use crate::field::mix::MixKind;
use crate::field::residual::{
    ResidualChunk, ResidualContext, ResidualField, ResidualGrads, ResidualNetGrads, ResidualParams,
};
use crate::field::{FieldChunk, FieldContext, NerfField, NerfGrads, NerfParams, NetGrads};
use crate::mlp::{keep_rows, Activation};
use crate::rng::Rng;
use crate::simd::Isa;
use crate::slots::accumulate_in_order;
use crate::GradientMode;
use glam::Vec3;

/// One optimiser group: fp32 master values, their gradients, the fp16 mirror to rewrite (hash
/// grids) and the L2 weight.
pub struct ParamGroup<'a> {
    /// Values the optimiser updates.
    pub master: &'a mut [f32],
    /// dL/d(values).
    pub grad: &'a [f32],
    /// fp16 mirror (packed pairs) written in the same pass, for hash grids.
    pub mirror: Option<&'a mut [u16]>,
    /// L2 regularisation (Instant-NGP: 1e-6 on network weights, none on grids).
    pub l2: f32,
}

/// A trainable radiance field.
pub trait Model: Sync {
    /// Trainable parameters.
    type Params: Clone + Send + Sync;
    /// Their gradients.
    type Grads: Send;
    /// What a forward saves for backward.
    type Context: Default + Send;

    /// Fresh parameters.
    fn init_params(&self, rng: &mut Rng) -> Self::Params;
    /// Zeroed gradients.
    fn zero_grads(&self) -> Self::Grads;
    /// Activated density σ at `positions` (occupancy updates): the cheap path.
    fn density(&self, isa: Isa, p: &Self::Params, positions: &[Vec3], sigma: &mut [f32], ctx: &mut Self::Context);
    /// Activated density and colour, saving what [`Model::backward`] needs.
    #[allow(clippy::too_many_arguments)]
    fn forward(
        &self,
        isa: Isa,
        p: &Self::Params,
        positions: &[Vec3],
        dirs: &[Vec3],
        sigma: &mut [f32],
        rgb: &mut [[f32; 3]],
        ctx: &mut Self::Context,
    );
    /// dL/dσ and dL/dc of the last forward → `grads` (overwritten).
    fn backward(
        &self,
        isa: Isa,
        p: &Self::Params,
        ctx: &mut Self::Context,
        d_sigma: &[f32],
        d_rgb: &[[f32; 3]],
        grads: &mut Self::Grads,
    );
    /// What one chunk of the fused step saves between its forward and backward.
    type Chunk: Default + Send;
    /// What one slot of the fused step accumulates over its chunks: network weight gradients
    /// and, per trained hash grid, the samples' feature gradients ([`FeatureLevels`]).
    type Slot: Default + Send;
    /// Empties `slot` for a new step.
    fn begin_slot(&self, slot: &mut Self::Slot);
    /// Fused step, on this thread: `positions` become the chunk's rows `from..` (rows before
    /// `from` kept: a ray evaluated segment by segment grows its chunk; `from = 0` starts a new
    /// one) — their activated density σ (encodings and density networks) into `sigma`, saving
    /// what the rest of the chunk needs. A chunk grown in steps holds the same bits as one call.
    fn chunk_density(
        &self,
        isa: Isa,
        p: &Self::Params,
        from: usize,
        positions: &[Vec3],
        sigma: &mut [f32],
        c: &mut Self::Chunk,
    );
    /// [`Model::density`] on this thread, for a chunk (depth-only rendering): density
    /// networks' first outputs only; `c` is then scratch, not a chunk [`Model::chunk_colour`]
    /// can continue. The σ is exact, or with `min_sigma` (the threshold the caller compares
    /// against), where the model can tell without evaluating everything which side of
    /// `min_sigma` a sample's σ lies on, a value on that side (a residual model skips its
    /// Mixnet where β cannot move σ across it).
    fn chunk_density_only(
        &self,
        isa: Isa,
        p: &Self::Params,
        positions: &[Vec3],
        min_sigma: Option<f32>,
        sigma: &mut [f32],
        c: &mut Self::Chunk,
    );
    /// Keeps rows `keep` (strictly increasing) of the last [`Model::chunk_density`] and writes
    /// their activated colours, seen along `dirs` (one per kept row), into `rgb`.
    fn chunk_colour(
        &self,
        isa: Isa,
        p: &Self::Params,
        keep: &[u32],
        dirs: &[Vec3],
        rgb: &mut [[f32; 3]],
        c: &mut Self::Chunk,
    );
    /// dL/dσ and dL/dc of the kept rows → accumulated into `slot`.
    fn chunk_backward(
        &self,
        isa: Isa,
        p: &Self::Params,
        c: &mut Self::Chunk,
        d_sigma: &[f32],
        d_rgb: &[[f32; 3]],
        slot: &mut Self::Slot,
    );
    /// The step's gradients from its slots (overwriting `grads`): network gradients summed in
    /// slot order, the grids' scattered from the slots' feature gradients in slot order — the
    /// same bits on any thread count.
    fn finish_step(&self, isa: Isa, slots: &[Self::Slot], grads: &mut Self::Grads);
    /// The optimiser groups, in a fixed order.
    fn groups<'a>(&self, p: &'a mut Self::Params, g: &'a Self::Grads) -> Vec<ParamGroup<'a>>;
    /// Re-derives what the optimiser's writes made stale (the MLPs' transposed copies).
    fn after_step(&self, p: &mut Self::Params);
    /// β of the kept rows of the last [`Model::chunk_colour`] and a zeroed buffer of extra
    /// dL/dβ (a regulariser's, [`crate::train::beta`]) that [`Model::chunk_backward`] adds;
    /// `None` for models without a Mixnet.
    fn chunk_beta<'c>(&self, _c: &'c mut Self::Chunk) -> Option<(&'c [f32], &'c mut [f32])> {
        None
    }
    /// β per sample of the last forward into `out` (empty for models without a Mixnet).
    fn betas(&self, _ctx: &Self::Context, out: &mut Vec<f32>) {
        out.clear();
    }
    /// The model as a frozen field outside a region, when it is one (a residual model with a
    /// change region); `None` for the rest.
    fn frozen_outside(&self) -> Option<&dyn FrozenOutside<Self::Params, Self::Chunk>> {
        None
    }
}

/// A model that is a frozen NeRF outside a region of the scene box: a residual model with a
/// change region, where β = 0 outside. A sample outside the region has the frozen NeRF's
/// density and colour whatever the parameters, so a training ray's samples there can be
/// evaluated once and reused over many steps (`train::pool`); the samples inside run
/// through the chunk path with the frozen NeRF's outputs handed in instead of evaluated.
pub trait FrozenOutside<P, C>: Sync {
    /// The frozen NeRF.
    fn frozen(&self) -> &crate::field::Nerf;
    /// Whether `p` is inside the region (where the parameters matter).
    fn is_inside(&self, p: Vec3) -> bool;
    /// A box holding the whole region (its cells' bounding box); `None` for an empty region.
    fn region_bounds(&self) -> Option<crate::geometry::Aabb>;
    /// Activated density and colour of a sample outside the region from the frozen NeRF's raw
    /// density `s` and pre-sigmoid colour `c`: the same bits as the model's chunk path gives it.
    fn outside(&self, s: f32, c: [f32; 3]) -> (f32, [f32; 3]);
    /// [`Model::chunk_density`] of a new chunk whose rows are all inside the region, with the
    /// frozen NeRF's raw densities `frozen` (one per row) given instead of evaluated: the same
    /// bits as evaluating them.
    #[allow(clippy::too_many_arguments)]
    fn chunk_density_over(&self, isa: Isa, p: &P, positions: &[Vec3], frozen: &[f32], sigma: &mut [f32], c: &mut C);
    /// [`Model::chunk_colour`] after [`FrozenOutside::chunk_density_over`], with the frozen
    /// NeRF's pre-sigmoid colours of the kept rows (`frozen`, one per kept row) given.
    #[allow(clippy::too_many_arguments)]
    fn chunk_colour_over(
        &self,
        isa: Isa,
        p: &P,
        keep: &[u32],
        dirs: &[Vec3],
        frozen: &[[f32; 3]],
        rgb: &mut [[f32; 3]],
        c: &mut C,
    );
    /// The frozen NeRF's own activated density and colour (the mix at β = 0) of the kept rows
    /// of the last [`Model::chunk_colour`], into `sigma` and `rgb`: what the frozen field alone
    /// puts at those samples, inside the region too.
    fn chunk_frozen(&self, c: &C, sigma: &mut Vec<f32>, rgb: &mut Vec<[f32; 3]>);
}

/// The NeRF's forward context plus the activated values backward differentiates through.
#[derive(Default)]
pub struct NerfContext {
    field: FieldContext,
    raw: Vec<f32>,
    rgb_raw: Vec<[f32; 3]>,
    sigma: Vec<f32>,
    rgb: Vec<[f32; 3]>,
    d_raw: Vec<f32>,
    d_rgb_raw: Vec<[f32; 3]>,
}

fn grid_group<'a>(grid: &'a mut crate::encoding::HashGridParams, grad: &'a [f32]) -> ParamGroup<'a> {
    ParamGroup { master: &mut grid.master, grad, mirror: Some(bytemuck::cast_slice_mut(&mut grid.table)), l2: 0.0 }
}

const MLP_L2: f32 = 1e-6;

/// A NeRF chunk of the fused step: the field's chunk state and the activated outputs.
#[derive(Default)]
pub struct NerfChunk {
    field: FieldChunk,
    raw: Vec<f32>,
    sigma: Vec<f32>,
    rgb_raw: Vec<[f32; 3]>,
    rgb: Vec<[f32; 3]>,
    d_raw: Vec<f32>,
    d_rgb_raw: Vec<[f32; 3]>,
}

/// What one slot of a NeRF's fused step accumulates.
#[derive(Default)]
pub struct NerfSlot {
    nets: NetGrads,
    grid: FeatureLevels,
}

/// What one slot of a residual model's fused step accumulates.
#[derive(Default)]
pub struct ResidualSlot {
    nets: ResidualNetGrads,
    residual_grid: FeatureLevels,
    mixnet_grid: FeatureLevels,
}

/// The NeRF's activations backwards: dL/ds = dL/dσ · trunc_exp′ and dL/dc′ = dL/dc · sigmoid′,
/// both derivatives from the activated outputs `sigma` and `rgb`.
fn raw_grads(
    sigma: &[f32],
    rgb: &[[f32; 3]],
    d_sigma: &[f32],
    d_rgb: &[[f32; 3]],
    d_raw: &mut Vec<f32>,
    d_rgb_raw: &mut Vec<[f32; 3]>,
) {
    d_raw.clear();
    d_raw.extend(sigma.iter().zip(d_sigma).map(|(&s, &d)| d * Activation::TruncExp.derivative_from_output(s)));
    d_rgb_raw.clear();
    d_rgb_raw.extend(
        rgb.iter()
            .zip(d_rgb)
            .map(|(c, d)| std::array::from_fn(|k| d[k] * Activation::Sigmoid.derivative_from_output(c[k]))),
    );
}

/// `out = Σ parts` in part order.
fn reduce<'a>(parts: impl IntoIterator<Item = &'a [f32]>, out: &mut [f32]) {
    out.fill(0.0);
    accumulate_in_order(parts, out);
}

impl Model for NerfField {
    type Params = NerfParams;
    type Grads = NerfGrads;
    type Context = NerfContext;

    fn init_params(&self, rng: &mut Rng) -> NerfParams {
        NerfField::init_params(self, rng)
    }

    fn zero_grads(&self) -> NerfGrads {
        NerfField::zero_grads(self)
    }

    fn density(&self, isa: Isa, p: &NerfParams, positions: &[Vec3], sigma: &mut [f32], ctx: &mut NerfContext) {
        if positions.is_empty() {
            return;
        }
        NerfField::density(self, isa, p, positions, sigma, &mut ctx.field);
        sigma.iter_mut().for_each(|s| *s = Activation::TruncExp.forward(*s));
    }

    fn forward(
        &self,
        isa: Isa,
        p: &NerfParams,
        positions: &[Vec3],
        dirs: &[Vec3],
        sigma: &mut [f32],
        rgb: &mut [[f32; 3]],
        ctx: &mut NerfContext,
    ) {
        let n = positions.len();
        ctx.raw.resize(n, 0.0);
        ctx.rgb_raw.resize(n, [0.0; 3]);
        if n > 0 {
            NerfField::forward(self, isa, p, positions, dirs, &mut ctx.raw, &mut ctx.rgb_raw, &mut ctx.field);
        }
        for i in 0..n {
            sigma[i] = Activation::TruncExp.forward(ctx.raw[i]);
            rgb[i] = ctx.rgb_raw[i].map(|v| Activation::Sigmoid.forward(v));
        }
        ctx.sigma.clear();
        ctx.sigma.extend_from_slice(sigma);
        ctx.rgb.clear();
        ctx.rgb.extend_from_slice(rgb);
    }

    fn backward(
        &self,
        isa: Isa,
        p: &NerfParams,
        ctx: &mut NerfContext,
        d_sigma: &[f32],
        d_rgb: &[[f32; 3]],
        grads: &mut NerfGrads,
    ) {
        let n = ctx.sigma.len();
        raw_grads(&ctx.sigma, &ctx.rgb, d_sigma, d_rgb, &mut ctx.d_raw, &mut ctx.d_rgb_raw);
        if n == 0 {
            grads.grid.fill(0.0);
            grads.density.fill(0.0);
            grads.colour.fill(0.0);
            return;
        }
        NerfField::backward(self, isa, p, &mut ctx.field, &ctx.d_raw, &ctx.d_rgb_raw, grads, GradientMode::Overwrite);
    }

    type Chunk = NerfChunk;
    type Slot = NerfSlot;

    fn begin_slot(&self, slot: &mut NerfSlot) {
        slot.nets.clear(self);
        slot.grid.clear();
    }

    fn chunk_density(
        &self,
        isa: Isa,
        p: &NerfParams,
        from: usize,
        positions: &[Vec3],
        sigma: &mut [f32],
        c: &mut NerfChunk,
    ) {
        c.sigma.truncate(from);
        c.raw.resize(from + positions.len(), 0.0);
        let raw = &mut c.raw[from..];
        NerfField::chunk_density(self, isa, p, from, positions, raw, &mut c.field);
        for (s, &r) in sigma.iter_mut().zip(raw.iter()) {
            *s = Activation::TruncExp.forward(r);
        }
        c.sigma.extend_from_slice(sigma);
    }

    fn chunk_density_only(
        &self,
        isa: Isa,
        p: &NerfParams,
        positions: &[Vec3],
        _min_sigma: Option<f32>,
        sigma: &mut [f32],
        c: &mut NerfChunk,
    ) {
        c.raw.resize(positions.len(), 0.0);
        NerfField::chunk_density_only(self, isa, p, positions, &mut c.raw, &mut c.field);
        for (s, &r) in sigma.iter_mut().zip(&c.raw) {
            *s = Activation::TruncExp.forward(r);
        }
    }

    fn chunk_colour(
        &self,
        isa: Isa,
        p: &NerfParams,
        keep: &[u32],
        dirs: &[Vec3],
        rgb: &mut [[f32; 3]],
        c: &mut NerfChunk,
    ) {
        let n = keep.len();
        self.chunk_keep(&mut c.field, keep);
        keep_rows(&mut c.sigma, 1, keep);
        c.sigma.truncate(n);
        c.rgb_raw.resize(n, [0.0; 3]);
        NerfField::chunk_colour(self, isa, p, dirs, &mut c.rgb_raw, &mut c.field);
        for (o, r) in rgb.iter_mut().zip(&c.rgb_raw) {
            *o = r.map(|v| Activation::Sigmoid.forward(v));
        }
        c.rgb.clear();
        c.rgb.extend_from_slice(rgb);
    }

    fn chunk_backward(
        &self,
        isa: Isa,
        p: &NerfParams,
        c: &mut NerfChunk,
        d_sigma: &[f32],
        d_rgb: &[[f32; 3]],
        slot: &mut NerfSlot,
    ) {
        raw_grads(&c.sigma, &c.rgb, d_sigma, d_rgb, &mut c.d_raw, &mut c.d_rgb_raw);
        NerfField::chunk_backward(self, isa, p, &mut c.field, &c.d_raw, &c.d_rgb_raw, &mut slot.nets);
        slot.grid.append(self.grid(), c.field.unit(), c.field.feature_grad());
    }

    fn finish_step(&self, isa: Isa, slots: &[NerfSlot], grads: &mut NerfGrads) {
        reduce(slots.iter().map(|s| s.nets.density.as_slice()), &mut grads.density);
        reduce(slots.iter().map(|s| s.nets.colour.as_slice()), &mut grads.colour);
        let parts: Vec<_> = slots.iter().map(|s| &s.grid).collect();
        self.grid().backward_params_levels(isa, &parts, &mut grads.grid, GradientMode::Overwrite);
    }

    fn groups<'a>(&self, p: &'a mut NerfParams, g: &'a NerfGrads) -> Vec<ParamGroup<'a>> {
        vec![
            grid_group(&mut p.grid, &g.grid),
            ParamGroup { master: p.density.weights_mut(), grad: &g.density, mirror: None, l2: MLP_L2 },
            ParamGroup { master: p.colour.weights_mut(), grad: &g.colour, mirror: None, l2: MLP_L2 },
        ]
    }

    fn after_step(&self, p: &mut NerfParams) {
        p.density.sync();
        p.colour.sync();
    }
}

impl Model for ResidualField {
    type Params = ResidualParams;
    type Grads = ResidualGrads;
    type Context = ResidualContext;

    fn init_params(&self, rng: &mut Rng) -> ResidualParams {
        ResidualField::init_params(self, rng)
    }

    fn zero_grads(&self) -> ResidualGrads {
        ResidualField::zero_grads(self)
    }

    fn density(&self, isa: Isa, p: &ResidualParams, positions: &[Vec3], sigma: &mut [f32], ctx: &mut ResidualContext) {
        ResidualField::density(self, isa, p, positions, sigma, ctx);
    }

    fn forward(
        &self,
        isa: Isa,
        p: &ResidualParams,
        positions: &[Vec3],
        dirs: &[Vec3],
        sigma: &mut [f32],
        rgb: &mut [[f32; 3]],
        ctx: &mut ResidualContext,
    ) {
        ResidualField::forward(self, isa, p, positions, dirs, sigma, rgb, ctx);
    }

    fn backward(
        &self,
        isa: Isa,
        p: &ResidualParams,
        ctx: &mut ResidualContext,
        d_sigma: &[f32],
        d_rgb: &[[f32; 3]],
        grads: &mut ResidualGrads,
    ) {
        ResidualField::backward(self, isa, p, ctx, d_sigma, d_rgb, grads, GradientMode::Overwrite);
    }

    type Chunk = ResidualChunk;
    type Slot = ResidualSlot;

    fn begin_slot(&self, slot: &mut ResidualSlot) {
        slot.nets.residual.clear(self.residual());
        slot.nets.mixnet.clear();
        slot.nets.mixnet.resize(self.mixnet().mlp().n_params(), 0.0);
        slot.residual_grid.clear();
        slot.mixnet_grid.clear();
    }

    fn chunk_density(
        &self,
        isa: Isa,
        p: &ResidualParams,
        from: usize,
        positions: &[Vec3],
        sigma: &mut [f32],
        c: &mut ResidualChunk,
    ) {
        ResidualField::chunk_density(self, isa, p, from, positions, sigma, c);
    }

    fn chunk_density_only(
        &self,
        isa: Isa,
        p: &ResidualParams,
        positions: &[Vec3],
        min_sigma: Option<f32>,
        sigma: &mut [f32],
        c: &mut ResidualChunk,
    ) {
        ResidualField::chunk_density_only(self, isa, p, positions, min_sigma, sigma, c);
    }

    fn chunk_colour(
        &self,
        isa: Isa,
        p: &ResidualParams,
        keep: &[u32],
        dirs: &[Vec3],
        rgb: &mut [[f32; 3]],
        c: &mut ResidualChunk,
    ) {
        ResidualField::chunk_colour(self, isa, p, keep, dirs, rgb, c);
    }

    fn chunk_backward(
        &self,
        isa: Isa,
        p: &ResidualParams,
        c: &mut ResidualChunk,
        d_sigma: &[f32],
        d_rgb: &[[f32; 3]],
        slot: &mut ResidualSlot,
    ) {
        ResidualField::chunk_backward(self, isa, p, c, d_sigma, d_rgb, &mut slot.nets);
        let res = c.residual();
        slot.residual_grid.append(self.residual().grid(), res.unit(), res.feature_grad());
        if let (MixKind::Mixnet(_), Some(grid)) = (self.kind(), self.mixnet().grid()) {
            slot.mixnet_grid.append(grid, c.mixnet().unit(), c.mixnet().feature_grad());
        }
    }

    fn finish_step(&self, isa: Isa, slots: &[ResidualSlot], grads: &mut ResidualGrads) {
        let g = &mut grads.residual;
        reduce(slots.iter().map(|s| s.nets.residual.density.as_slice()), &mut g.density);
        reduce(slots.iter().map(|s| s.nets.residual.colour.as_slice()), &mut g.colour);
        reduce(slots.iter().map(|s| s.nets.mixnet.as_slice()), &mut grads.mixnet.mlp);
        let parts: Vec<_> = slots.iter().map(|s| &s.residual_grid).collect();
        self.residual().grid().backward_params_levels(isa, &parts, &mut g.grid, GradientMode::Overwrite);
        if let Some(grid) = self.mixnet().grid() {
            let parts: Vec<_> = slots.iter().map(|s| &s.mixnet_grid).collect();
            grid.backward_params_levels(isa, &parts, &mut grads.mixnet.grid, GradientMode::Overwrite);
        }
    }

    fn groups<'a>(&self, p: &'a mut ResidualParams, g: &'a ResidualGrads) -> Vec<ParamGroup<'a>> {
        let (r, m) = (&mut p.residual, &mut p.mixnet);
        vec![
            grid_group(&mut r.grid, &g.residual.grid),
            ParamGroup { master: r.density.weights_mut(), grad: &g.residual.density, mirror: None, l2: MLP_L2 },
            ParamGroup { master: r.colour.weights_mut(), grad: &g.residual.colour, mirror: None, l2: MLP_L2 },
            grid_group(&mut m.grid, &g.mixnet.grid),
            ParamGroup { master: m.mlp.weights_mut(), grad: &g.mixnet.mlp, mirror: None, l2: MLP_L2 },
        ]
    }

    fn chunk_beta<'c>(&self, c: &'c mut ResidualChunk) -> Option<(&'c [f32], &'c mut [f32])> {
        matches!(self.kind(), MixKind::Mixnet(_)).then(|| c.beta_and_grad())
    }

    fn betas(&self, ctx: &ResidualContext, out: &mut Vec<f32>) {
        ResidualField::betas(self, ctx, out);
    }

    fn frozen_outside(&self) -> Option<&dyn FrozenOutside<ResidualParams, ResidualChunk>> {
        self.region().is_some().then_some(self as &dyn FrozenOutside<ResidualParams, ResidualChunk>)
    }

    fn after_step(&self, p: &mut ResidualParams) {
        p.residual.density.sync();
        p.residual.colour.sync();
        p.mixnet.mlp.sync();
    }
}
