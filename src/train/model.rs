//! What the trainer trains: a [`Model`] maps samples to activated density and colour, back-
//! propagates dL/dσ and dL/dc into its gradients, and lists its parameter groups for Adam.
//! Two models exist: a plain NeRF ([`NerfField`]) and a residual model
//! ([`ResidualField`]: frozen background + residual + Mixnet).

use crate::field::residual::{ResidualContext, ResidualField, ResidualGrads, ResidualParams};
use crate::field::{FieldContext, NerfField, NerfGrads, NerfParams};
use crate::mlp::Activation;
use crate::rng::Rng;
use crate::simd::Isa;
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
    /// Activated density σ at `positions` (occupancy updates, pruning): the cheap path.
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
    /// The optimiser groups, in a fixed order.
    fn groups<'a>(&self, p: &'a mut Self::Params, g: &'a Self::Grads) -> Vec<ParamGroup<'a>>;
    /// Re-derives what the optimiser's writes made stale (the MLPs' transposed copies).
    fn after_step(&self, p: &mut Self::Params);
    /// β per sample of the last forward into `out` (empty for models without a Mixnet).
    fn betas(&self, _ctx: &Self::Context, out: &mut Vec<f32>) {
        out.clear();
    }
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
        ctx.d_raw.resize(n, 0.0);
        ctx.d_rgb_raw.resize(n, [0.0; 3]);
        // dL/ds = dL/dσ · trunc_exp′, dL/dc′ = dL/dc · sigmoid′ (both from the outputs).
        for i in 0..n {
            ctx.d_raw[i] = d_sigma[i] * Activation::TruncExp.derivative_from_output(ctx.sigma[i]);
            ctx.d_rgb_raw[i] =
                std::array::from_fn(|k| d_rgb[i][k] * Activation::Sigmoid.derivative_from_output(ctx.rgb[i][k]));
        }
        if n == 0 {
            grads.grid.fill(0.0);
            grads.density.fill(0.0);
            grads.colour.fill(0.0);
            return;
        }
        NerfField::backward(self, isa, p, &mut ctx.field, &ctx.d_raw, &ctx.d_rgb_raw, grads, GradientMode::Overwrite);
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

    fn betas(&self, ctx: &ResidualContext, out: &mut Vec<f32>) {
        ResidualField::betas(self, ctx, out);
    }

    fn after_step(&self, p: &mut ResidualParams) {
        p.residual.density.sync();
        p.residual.colour.sync();
        p.mixnet.mlp.sync();
    }
}
