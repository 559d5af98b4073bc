//! The residual field (paper Eqs. 5–6, DESIGN §2.3): a frozen background [`Nerf`] (evaluated,
//! never differentiated), a residual NeRF field and a [`Mixnet`], combined per sample by
//! [`super::mix`]. Forward gives activated σ and colour (what compositing needs); backward
//! takes dL/dσ and dL/dc and fills gradients of the residual and the Mixnet only.

use super::mix::{mix_backward, mix_backward_rows, mix_forward, MixInput, MixKind, MixOutput};
use super::mixnet::{Mixnet, MixnetChunk, MixnetContext, MixnetEncoding, MixnetGrads, MixnetParams};
use super::model::FrozenOutside;
use super::{FieldChunk, FieldContext, Nerf, NerfConfig, NerfField, NerfGrads, NerfParams, NetGrads};
use crate::geometry::ChangeRegion;
use crate::mlp::Activation;
use crate::rng::Rng;
use crate::simd::Isa;
use crate::GradientMode;
use glam::Vec3;

/// A residual model's architecture: the residual NeRF's config (same scene box as the
/// background), how the two mix, and the Mixnet's encoding.
#[derive(Clone, Debug, PartialEq)]
pub struct ResidualConfig {
    /// Residual NeRF (its `aabb` must be the background's).
    pub residual: NerfConfig,
    /// Mixing rule. Defaults to a Mixnet with raw density mixing.
    pub kind: MixKind,
    /// Mixnet encoding: its own grid ([`super::mixnet::default_mixnet_grid`] by default) or
    /// the residual's.
    pub mixnet: MixnetEncoding,
}

/// The field: frozen background, residual, Mixnet, and optionally the change region outside
/// which the field is the background ([`ChangeRegion`]).
#[derive(Clone, Debug)]
pub struct ResidualField {
    /// The frozen background (its parameters are never changed here).
    pub background: Nerf,
    residual: NerfField,
    mixnet: Mixnet,
    kind: MixKind,
    region: Option<ChangeRegion>,
    /// The region's cells' bounding box ([`ChangeRegion::bounds`]), kept with it.
    region_bounds: Option<crate::geometry::Aabb>,
    /// `(σ, ln σ)` at and above which the background is solid: there the mix keeps the
    /// background's density and mixes colour only ([`ResidualField::with_solid_background`]).
    solid: Option<(f32, f32)>,
}

/// Trainable parameters of a residual model.
#[derive(Clone, Debug, PartialEq)]
pub struct ResidualParams {
    /// Residual NeRF.
    pub residual: NerfParams,
    /// Mixnet (unused by [`MixKind::Sum`]).
    pub mixnet: MixnetParams,
}

/// Gradients of [`ResidualParams`].
#[derive(Clone, Debug, PartialEq)]
pub struct ResidualGrads {
    /// Of the residual NeRF.
    pub residual: NerfGrads,
    /// Of the Mixnet.
    pub mixnet: MixnetGrads,
}

/// A trained residual model: the field (with its frozen background), the trained parameters,
/// and the occupancy grid of the **mixed** field (DESIGN §2.3).
#[derive(Clone, Debug)]
pub struct ResidualModel {
    /// Background + residual + Mixnet.
    pub field: ResidualField,
    /// Residual and Mixnet parameters.
    pub params: ResidualParams,
    /// Occupancy of the mixed field.
    pub occupancy: crate::geometry::OccupancyGrid,
}

/// What a residual forward saves.
#[derive(Clone, Debug, Default)]
pub struct ResidualContext {
    bg: FieldContext,
    res: FieldContext,
    mix: MixnetContext,
    inputs: Vec<MixInput>,
    outputs: Vec<MixOutput>,
    raw: Vec<f32>,
    rgb_raw: Vec<[f32; 3]>,
    logits: Vec<f32>,
    d_raw: Vec<f32>,
    d_rgb_raw: Vec<[f32; 3]>,
    d_logits: Vec<f32>,
    s_res: Vec<f32>,
}

/// What one chunk of the fused training step saves (see [`FieldChunk`]): the background's,
/// the residual's and the Mixnet's chunk state and the per-sample mix.
#[derive(Clone, Debug, Default)]
pub struct ResidualChunk {
    bg: FieldChunk,
    res: FieldChunk,
    mix: MixnetChunk,
    s_bg: Vec<f32>,
    s_res: Vec<f32>,
    logits: Vec<f32>,
    c_bg: Vec<[f32; 3]>,
    c_res: Vec<[f32; 3]>,
    inputs: Vec<MixInput>,
    outputs: Vec<MixOutput>,
    /// dL/d(s_res, c′_res, m) of the inside rows (the residual's and the Mixnet's rows).
    d_s_res: Vec<f32>,
    d_c_res: Vec<[f32; 3]>,
    d_m: Vec<f32>,
    /// β of the kept rows, and extra dL/dβ (a regulariser's) for the backward to add.
    beta: Vec<f32>,
    d_beta: Vec<f32>,
    /// The chunk's rows the residual and the Mixnet evaluate, ascending: all rows, or with a
    /// change region those inside it (outside it the field is the background and they are
    /// skipped). Row `k` of `res` and `mix` is chunk row `inside[k]`.
    inside: Vec<u32>,
    /// Scratch for the inside rows: positions or directions, outputs, kept rows.
    sub_pos: Vec<Vec3>,
    sub_out: Vec<f32>,
    sub_rgb: Vec<[f32; 3]>,
    sub_keep: Vec<u32>,
    sub_inside: Vec<u32>,
}

impl ResidualChunk {
    /// β of the kept rows of the last [`ResidualField::chunk_colour`] and a zeroed buffer of
    /// extra dL/dβ that [`ResidualField::chunk_backward`] adds to the Mixnet's gradient
    /// ([`crate::train::beta`]).
    pub fn beta_and_grad(&mut self) -> (&[f32], &mut [f32]) {
        (&self.beta, &mut self.d_beta)
    }

    /// The residual's chunk state (its rows' unit positions for the grid's backward).
    pub fn residual(&self) -> &FieldChunk {
        &self.res
    }

    /// The Mixnet's chunk state.
    pub fn mixnet(&self) -> &MixnetChunk {
        &self.mix
    }
}

/// The networks' weight gradients accumulated by one slot of the fused training step.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ResidualNetGrads {
    /// The residual NeRF's networks.
    pub residual: NetGrads,
    /// The Mixnet's MLP.
    pub mixnet: Vec<f32>,
}

impl ResidualField {
    /// A residual field on top of `background`. Panics when the boxes differ (callers check
    /// and report that as an input error first).
    pub fn new(background: Nerf, config: ResidualConfig) -> ResidualField {
        assert_eq!(
            background.field.config().aabb,
            config.residual.aabb,
            "residual: scene box differs from the background's"
        );
        let residual = NerfField::new(config.residual);
        let mixnet = Mixnet::new(residual.config().aabb, config.mixnet, residual.encoding_width());
        ResidualField {
            background,
            residual,
            mixnet,
            kind: config.kind,
            region: None,
            region_bounds: None,
            solid: None,
        }
    }

    /// The field with colour-only mixing where the background is solid (σ_bg ≥ `sigma`): there
    /// the residual's density is replaced by the background's, so β changes the colour (a
    /// shadow, a caustic, a reflection on the table) and never the density: the background's
    /// surfaces keep their depth. Elsewhere (the background's air, where a glass can stand)
    /// both mix as before. Panics for [`MixKind::Sum`] (no β) or a non-positive `sigma`.
    pub fn with_solid_background(mut self, sigma: f32) -> ResidualField {
        assert!(matches!(self.kind, MixKind::Mixnet(_)), "residual: colour-only mixing needs a Mixnet's β");
        assert!(sigma > 0.0 && sigma.is_finite(), "residual: the solid background's σ must be positive");
        self.solid = Some((sigma, sigma.ln()));
        self
    }

    /// The σ at and above which the background is solid (colour-only mixing), if set.
    pub fn solid_background(&self) -> Option<f32> {
        self.solid.map(|s| s.0)
    }

    /// Whether the background's raw density `s_bg` is solid (colour-only mixing there).
    #[inline]
    fn is_solid(&self, s_bg: f32) -> bool {
        self.solid.is_some_and(|(_, l)| s_bg >= l)
    }

    /// The residual's raw density as the mix takes it: the background's where that is solid.
    #[inline]
    fn gated(&self, s_bg: f32, s_res: f32) -> f32 {
        if self.is_solid(s_bg) {
            s_bg
        } else {
            s_res
        }
    }

    /// The field restricted to `region`: β = 0 outside it, so there the field is the
    /// background bit for bit. Panics for [`MixKind::Sum`] (no β) or a region over another box.
    pub fn with_region(mut self, region: ChangeRegion) -> ResidualField {
        assert!(matches!(self.kind, MixKind::Mixnet(_)), "residual: a change region needs a Mixnet's β");
        assert_eq!(*region.aabb(), self.residual.config().aabb, "residual: region box differs from the scene box");
        self.region_bounds = region.bounds();
        self.region = Some(region);
        self
    }

    /// The change region, if the field has one.
    pub fn region(&self) -> Option<&ChangeRegion> {
        self.region.as_ref()
    }

    /// Whether the residual NeRF has the background's architecture, so it can start as a copy of
    /// it ([`ResidualField::warm_params`]).
    pub fn can_warm_start(&self) -> bool {
        *self.residual.config() == *self.background.field.config()
    }

    /// Parameters that start at the background: the residual NeRF a copy of the background's
    /// weights (so any β mixes two equal fields and the mixed field equals the background at
    /// step 0, for either density mix), the Mixnet fresh. `None` when the architectures differ.
    pub fn warm_params(&self, rng: &mut Rng) -> Option<ResidualParams> {
        self.can_warm_start()
            .then(|| ResidualParams { residual: self.background.params.clone(), mixnet: self.mixnet.init_params(rng) })
    }

    /// Sets the logit of every sample outside the change region to −∞ (β = 0).
    fn mask_logits(&self, positions: &[Vec3], logits: &mut [f32]) {
        if let Some(r) = &self.region {
            for (m, &p) in logits.iter_mut().zip(positions) {
                if !r.contains(p) {
                    *m = f32::NEG_INFINITY;
                }
            }
        }
    }

    /// The Mixnet's encoding.
    pub fn mixnet_encoding(&self) -> MixnetEncoding {
        self.mixnet.encoding()
    }

    /// The mixing rule.
    pub fn kind(&self) -> MixKind {
        self.kind
    }

    /// The residual NeRF field.
    pub fn residual(&self) -> &NerfField {
        &self.residual
    }

    /// The Mixnet.
    pub fn mixnet(&self) -> &Mixnet {
        &self.mixnet
    }

    /// Fresh trainable parameters.
    pub fn init_params(&self, rng: &mut Rng) -> ResidualParams {
        ResidualParams { residual: self.residual.init_params(rng), mixnet: self.mixnet.init_params(rng) }
    }

    /// Zeroed gradients.
    pub fn zero_grads(&self) -> ResidualGrads {
        ResidualGrads { residual: self.residual.zero_grads(), mixnet: self.mixnet.zero_grads() }
    }

    /// Evaluates background, residual and Mixnet at the samples and mixes them.
    fn evaluate(
        &self,
        isa: Isa,
        params: &ResidualParams,
        positions: &[Vec3],
        dirs: &[Vec3],
        ctx: &mut ResidualContext,
    ) {
        let n = positions.len();
        let bg = &self.background;
        ctx.raw.resize(n, 0.0);
        ctx.rgb_raw.resize(n, [0.0; 3]);
        ctx.logits.clear();
        ctx.logits.resize(n, 0.0);
        ctx.inputs.clear();
        if n == 0 {
            ctx.outputs.clear();
            return;
        }
        bg.field.forward(isa, &bg.params, positions, dirs, &mut ctx.raw, &mut ctx.rgb_raw, &mut ctx.bg);
        ctx.inputs.extend(ctx.raw.iter().zip(&ctx.rgb_raw).map(|(&s_bg, &c_bg)| MixInput {
            s_bg,
            c_bg,
            s_res: 0.0,
            c_res: [0.0; 3],
            m: 0.0,
        }));
        self.residual.forward(isa, &params.residual, positions, dirs, &mut ctx.raw, &mut ctx.rgb_raw, &mut ctx.res);
        if matches!(self.kind, MixKind::Mixnet(_)) {
            let shared = self.shared_features(&ctx.res);
            self.mixnet.forward(isa, &params.mixnet, positions, shared, &mut ctx.logits, &mut ctx.mix);
            self.mask_logits(positions, &mut ctx.logits);
        }
        for (i, x) in ctx.inputs.iter_mut().enumerate() {
            (x.s_res, x.c_res, x.m) = (self.gated(x.s_bg, ctx.raw[i]), ctx.rgb_raw[i], ctx.logits[i]);
        }
        ctx.outputs.clear();
        ctx.outputs.extend(ctx.inputs.iter().map(|x| mix_forward(self.kind, x)));
    }

    /// Mixed density σ only (background and residual density networks and the Mixnet; no
    /// colour): for occupancy updates and depth-only rendering.
    pub fn density(
        &self,
        isa: Isa,
        params: &ResidualParams,
        positions: &[Vec3],
        sigma: &mut [f32],
        ctx: &mut ResidualContext,
    ) {
        let n = positions.len();
        assert_eq!(sigma.len(), n, "residual: output length differs from the sample count");
        if n == 0 {
            return;
        }
        let bg = &self.background;
        ctx.raw.resize(n, 0.0);
        ctx.s_res.resize(n, 0.0);
        ctx.logits.clear();
        ctx.logits.resize(n, 0.0);
        bg.field.density(isa, &bg.params, positions, &mut ctx.raw, &mut ctx.bg);
        self.residual.density(isa, &params.residual, positions, &mut ctx.s_res, &mut ctx.res);
        if matches!(self.kind, MixKind::Mixnet(_)) {
            let shared = self.shared_features(&ctx.res);
            self.mixnet.forward(isa, &params.mixnet, positions, shared, &mut ctx.logits, &mut ctx.mix);
            self.mask_logits(positions, &mut ctx.logits);
        }
        for i in 0..n {
            let s_res = self.gated(ctx.raw[i], ctx.s_res[i]);
            let x = MixInput { s_bg: ctx.raw[i], c_bg: [0.0; 3], s_res, c_res: [0.0; 3], m: ctx.logits[i] };
            sigma[i] = mix_forward(self.kind, &x).sigma;
        }
    }

    /// Mixed density σ and colour per sample (saving what backward needs).
    pub fn forward(
        &self,
        isa: Isa,
        params: &ResidualParams,
        positions: &[Vec3],
        dirs: &[Vec3],
        sigma: &mut [f32],
        rgb: &mut [[f32; 3]],
        ctx: &mut ResidualContext,
    ) {
        assert!(
            sigma.len() == positions.len() && rgb.len() == positions.len(),
            "residual: buffers differ from the sample count"
        );
        self.evaluate(isa, params, positions, dirs, ctx);
        for (i, o) in ctx.outputs.iter().enumerate() {
            sigma[i] = o.sigma;
            rgb[i] = o.rgb;
        }
    }

    /// β per sample of the last forward (empty for [`MixKind::Sum`]).
    pub fn betas(&self, ctx: &ResidualContext, out: &mut Vec<f32>) {
        out.clear();
        if matches!(self.kind, MixKind::Mixnet(_)) {
            out.extend(ctx.outputs.iter().map(|o| o.beta));
        }
    }

    /// Back-propagates dL/dσ and dL/dc of the last forward into the residual's and the
    /// Mixnet's gradients (per `mode`); the background gets nothing.
    pub fn backward(
        &self,
        isa: Isa,
        params: &ResidualParams,
        ctx: &mut ResidualContext,
        d_sigma: &[f32],
        d_rgb: &[[f32; 3]],
        grads: &mut ResidualGrads,
        mode: GradientMode,
    ) {
        let n = ctx.inputs.len();
        assert!(d_sigma.len() == n && d_rgb.len() == n, "residual: gradient buffers differ from the sample count");
        let (d_s, d_c, d_m) = (&mut ctx.d_raw, &mut ctx.d_rgb_raw, &mut ctx.d_logits);
        mix_backward_rows(self.kind, &ctx.inputs, &ctx.outputs, d_sigma, d_rgb, d_s, d_c, d_m);
        if n == 0 {
            return;
        }
        // Where the background is solid the mix took its density, not the residual's.
        for (d, x) in d_s.iter_mut().zip(&ctx.inputs) {
            if self.is_solid(x.s_bg) {
                *d = 0.0;
            }
        }
        // The Mixnet first: with a shared encoding its dL/dh(x) joins the residual's.
        let mut feature_grad: &[f32] = &[];
        if matches!(self.kind, MixKind::Mixnet(_)) {
            let shared = self.shared_features(&ctx.res);
            self.mixnet.backward(isa, &params.mixnet, &mut ctx.mix, shared, &ctx.d_logits, &mut grads.mixnet, mode);
            if shared.is_some() {
                feature_grad = self.mixnet.feature_grad(&ctx.mix);
            }
        }
        self.residual.backward_with_feature_grad(
            isa,
            &params.residual,
            &mut ctx.res,
            &ctx.d_raw,
            &ctx.d_rgb_raw,
            feature_grad,
            &mut grads.residual,
            mode,
        );
    }

    /// Chunk forward, first half, on this thread: `positions` become the chunk's rows `from..`
    /// (rows before `from` kept; `from = 0` starts a new chunk), their activated mixed σ
    /// (background and residual density networks, the Mixnet) into `sigma`, saving for the rest
    /// of the chunk. A chunk grown in steps holds the same bits as one call.
    pub fn chunk_density(
        &self,
        isa: Isa,
        params: &ResidualParams,
        from: usize,
        positions: &[Vec3],
        sigma: &mut [f32],
        c: &mut ResidualChunk,
    ) {
        self.chunk_sigma(isa, params, positions, sigma, c, Some(from), None, None);
    }

    /// [`ResidualField::density`] on this thread, for a chunk (depth-only rendering): the
    /// density networks' and the Mixnet's first outputs only; `c` is not a chunk
    /// [`ResidualField::chunk_colour`] can continue. With `min_sigma`, a sample whose
    /// background and residual densities lie on one side of it (by a margin rounding cannot
    /// cross) skips the Mixnet: the mix lies between the two for any β, so its σ is on that
    /// side too, and the mix at β = ½ is written instead (its own Mixnet grid only).
    pub fn chunk_density_only(
        &self,
        isa: Isa,
        params: &ResidualParams,
        positions: &[Vec3],
        min_sigma: Option<f32>,
        sigma: &mut [f32],
        c: &mut ResidualChunk,
    ) {
        let threshold = min_sigma.filter(|_| self.mixnet.grid().is_some());
        self.chunk_sigma(isa, params, positions, sigma, c, None, None, threshold);
    }

    /// Mixed σ of `positions`: as the chunk's rows `from..` when `rows` is `Some(from)`,
    /// keeping everything the colour half needs; σ alone when `None`. The background is
    /// evaluated on every row (or its raw densities taken from `frozen`, with `rows`), the
    /// residual and the Mixnet only on the rows inside the change region (all rows without
    /// one); outside it β = 0 and the mix is the background's. With `threshold` (depth-only,
    /// `rows` `None`) the inside rows whose two densities lie on one side of it skip the
    /// Mixnet ([`ResidualField::chunk_density_only`]).
    #[allow(clippy::too_many_arguments)]
    fn chunk_sigma(
        &self,
        isa: Isa,
        params: &ResidualParams,
        positions: &[Vec3],
        sigma: &mut [f32],
        c: &mut ResidualChunk,
        rows: Option<usize>,
        frozen: Option<&[f32]>,
        threshold: Option<f32>,
    ) {
        let n = positions.len();
        assert_eq!(sigma.len(), n, "residual: output length differs from the sample count");
        let bg = &self.background;
        let from = rows.unwrap_or(0);
        for v in [&mut c.s_bg, &mut c.s_res, &mut c.logits] {
            v.truncate(from);
            v.resize(from + n, 0.0);
        }
        // The rows before `from` stay (a chunk grows from its end); pick the new inside rows.
        c.inside.retain(|&r| (r as usize) < from);
        let sub_from = c.inside.len();
        c.sub_pos.clear();
        for (i, &p) in positions.iter().enumerate() {
            if self.in_region(p) {
                c.inside.push((from + i) as u32);
                c.sub_pos.push(p);
            }
        }
        c.sub_out.clear();
        c.sub_out.resize(c.sub_pos.len(), 0.0);
        let s_bg = &mut c.s_bg[from..];
        match rows {
            Some(_) => {
                match frozen {
                    Some(given) => s_bg.copy_from_slice(given),
                    None => bg.field.chunk_density(isa, &bg.params, from, positions, s_bg, &mut c.bg),
                }
                self.residual.chunk_density(isa, &params.residual, sub_from, &c.sub_pos, &mut c.sub_out, &mut c.res);
            }
            None => {
                bg.field.chunk_density_only(isa, &bg.params, positions, s_bg, &mut c.bg);
                self.residual.chunk_density_only(isa, &params.residual, &c.sub_pos, &mut c.sub_out, &mut c.res);
            }
        }
        // Rows outside: the residual's raw density set to the background's (any finite value
        // mixes to the background at β = 0) and the logit to −∞ (β = 0).
        let new_inside = &c.inside[sub_from..];
        let mut k = 0;
        for i in from..from + n {
            match new_inside.get(k) {
                Some(&r) if r as usize == i => {
                    c.s_res[i] = self.gated(c.s_bg[i], c.sub_out[k]);
                    k += 1;
                }
                _ => {
                    c.s_res[i] = c.s_bg[i];
                    c.logits[i] = f32::NEG_INFINITY;
                }
            }
        }
        // Depth-only with a threshold: the Mixnet on the inside rows β decides only; the rest
        // keep the logit 0 (β = ½), whose mix is on the same side of the threshold as any β's.
        if let (Some(m), MixKind::Mixnet(_), None) = (threshold, self.kind, rows) {
            c.sub_keep.clear();
            c.sub_pos.clear();
            for &r in &c.inside[sub_from..] {
                c.logits[r as usize] = 0.0;
                if !beta_cannot_cross(c.s_bg[r as usize], c.s_res[r as usize], m) {
                    c.sub_keep.push(r);
                    c.sub_pos.push(positions[r as usize - from]);
                }
            }
            c.sub_out.clear();
            c.sub_out.resize(c.sub_pos.len(), 0.0);
            if !c.sub_pos.is_empty() {
                self.mixnet.chunk_logits(isa, &params.mixnet, &c.sub_pos, None, &mut c.sub_out, &mut c.mix);
            }
            for (&r, &m) in c.sub_keep.iter().zip(&c.sub_out) {
                c.logits[r as usize] = m;
            }
        } else if matches!(self.kind, MixKind::Mixnet(_)) {
            let shared = (self.mixnet.grid().is_none()).then(|| c.res.features());
            let (mixnet, p, logits) = (&self.mixnet, &params.mixnet, &mut c.sub_out);
            match rows {
                Some(_) => mixnet.chunk_forward(isa, p, sub_from, &c.sub_pos, shared, logits, &mut c.mix),
                None => mixnet.chunk_logits(isa, p, &c.sub_pos, shared, logits, &mut c.mix),
            }
            for (&r, &m) in c.inside[sub_from..].iter().zip(&c.sub_out) {
                c.logits[r as usize] = m;
            }
        }
        for (i, s) in sigma.iter_mut().enumerate() {
            let j = from + i;
            let x = MixInput { s_bg: c.s_bg[j], c_bg: [0.0; 3], s_res: c.s_res[j], c_res: [0.0; 3], m: c.logits[j] };
            *s = mix_forward(self.kind, &x).sigma;
        }
    }

    /// Chunk forward, second half: keeps rows `keep` (strictly increasing) of the last
    /// [`ResidualField::chunk_density`] and writes their mixed colours, seen along `dirs`
    /// (one per kept row), into `rgb`.
    pub fn chunk_colour(
        &self,
        isa: Isa,
        params: &ResidualParams,
        keep: &[u32],
        dirs: &[Vec3],
        rgb: &mut [[f32; 3]],
        c: &mut ResidualChunk,
    ) {
        self.chunk_colour_from(isa, params, keep, dirs, rgb, c, None);
    }

    /// [`ResidualField::chunk_colour`], the background's pre-sigmoid colours of the kept rows
    /// taken from `frozen` when given (after a chunk whose background densities were given).
    #[allow(clippy::too_many_arguments)]
    fn chunk_colour_from(
        &self,
        isa: Isa,
        params: &ResidualParams,
        keep: &[u32],
        dirs: &[Vec3],
        rgb: &mut [[f32; 3]],
        c: &mut ResidualChunk,
        frozen: Option<&[[f32; 3]]>,
    ) {
        let n = keep.len();
        assert!(dirs.len() == n && rgb.len() == n, "residual: buffers differ from the kept rows");
        assert!(frozen.is_none_or(|f| f.len() == n), "residual: frozen colours differ from the kept rows");
        let bg = &self.background;
        if frozen.is_none() {
            bg.field.chunk_keep(&mut c.bg, keep);
        }
        // The kept inside rows: their index among the inside rows (to keep in `res` and `mix`)
        // and among the kept rows (their new chunk row).
        c.sub_keep.clear();
        c.sub_inside.clear();
        c.sub_pos.clear();
        let mut j = 0;
        for (i, &row) in keep.iter().enumerate() {
            while j < c.inside.len() && c.inside[j] < row {
                j += 1;
            }
            if c.inside.get(j) == Some(&row) {
                c.sub_keep.push(j as u32);
                c.sub_inside.push(i as u32);
                c.sub_pos.push(dirs[i]);
            }
        }
        std::mem::swap(&mut c.inside, &mut c.sub_inside);
        self.residual.chunk_keep(&mut c.res, &c.sub_keep);
        if matches!(self.kind, MixKind::Mixnet(_)) {
            self.mixnet.chunk_keep(&mut c.mix, &c.sub_keep);
        }
        for v in [&mut c.s_bg, &mut c.s_res, &mut c.logits] {
            crate::mlp::keep_rows(v, 1, keep);
            v.truncate(n);
        }
        c.c_bg.resize(n, [0.0; 3]);
        match frozen {
            Some(given) => c.c_bg.copy_from_slice(given),
            None => bg.field.chunk_colour(isa, &bg.params, dirs, &mut c.c_bg, &mut c.bg),
        }
        c.sub_rgb.clear();
        c.sub_rgb.resize(c.inside.len(), [0.0; 3]);
        self.residual.chunk_colour(isa, &params.residual, &c.sub_pos, &mut c.sub_rgb, &mut c.res);
        // Rows outside: the background's pre-sigmoid colour (mixes to it at β = 0).
        c.c_res.clear();
        c.c_res.extend_from_slice(&c.c_bg);
        for (&r, &rgb) in c.inside.iter().zip(&c.sub_rgb) {
            c.c_res[r as usize] = rgb;
        }
        c.inputs.clear();
        c.inputs.extend((0..n).map(|i| MixInput {
            s_bg: c.s_bg[i],
            c_bg: c.c_bg[i],
            s_res: c.s_res[i],
            c_res: c.c_res[i],
            m: c.logits[i],
        }));
        c.outputs.clear();
        c.outputs.extend(c.inputs.iter().map(|x| mix_forward(self.kind, x)));
        for (o, out) in rgb.iter_mut().zip(&c.outputs) {
            *o = out.rgb;
        }
        c.beta.clear();
        c.beta.extend(c.outputs.iter().map(|o| o.beta));
        c.d_beta.clear();
        c.d_beta.resize(n, 0.0);
    }

    /// Chunk backward: dL/dσ and dL/dc of the kept rows → the residual's and the Mixnet's
    /// network gradients added into `g`; dL/d(features) of the residual's grid left in
    /// `c.residual().feature_grad()` (with a shared encoding the Mixnet's share included) and of
    /// the Mixnet's own grid in `c.mixnet().feature_grad()`.
    pub fn chunk_backward(
        &self,
        isa: Isa,
        params: &ResidualParams,
        c: &mut ResidualChunk,
        d_sigma: &[f32],
        d_rgb: &[[f32; 3]],
        g: &mut ResidualNetGrads,
    ) {
        let n = c.inputs.len();
        assert!(d_sigma.len() == n && d_rgb.len() == n, "residual: gradient buffers differ from the kept rows");
        // The mix's derivatives on the inside rows only (outside, β = 0: they are zero), in
        // the residual's and the Mixnet's row order; a regulariser's dL/dβ joins dL/dm through
        // β = sigmoid(m) (0 where β is exactly 0 or 1).
        c.d_s_res.clear();
        c.d_c_res.clear();
        c.d_m.clear();
        for &r in &c.inside {
            let r = r as usize;
            let g = mix_backward(self.kind, &c.inputs[r], &c.outputs[r], d_sigma[r], d_rgb[r]);
            let b = c.beta[r];
            // Where the background is solid the mix took its density, not the residual's.
            c.d_s_res.push(if self.is_solid(c.inputs[r].s_bg) { 0.0 } else { g.s_res });
            c.d_c_res.push(g.c_res);
            c.d_m.push(g.m + c.d_beta[r] * b * (1.0 - b));
        }
        let mixnet = matches!(self.kind, MixKind::Mixnet(_));
        let shared = self.mixnet.grid().is_none();
        if mixnet {
            let features = shared.then(|| c.res.features());
            self.mixnet.chunk_backward(isa, &params.mixnet, &mut c.mix, features, &c.d_m, &mut g.mixnet);
        }
        self.residual.chunk_backward(isa, &params.residual, &mut c.res, &c.d_s_res, &c.d_c_res, &mut g.residual);
        if mixnet && shared {
            c.res.d_enc.iter_mut().zip(c.mix.feature_grad()).for_each(|(d, m)| *d += m);
        }
    }

    /// Whether `p` is where the residual and the Mixnet are evaluated: inside the change region,
    /// or anywhere without one.
    fn in_region(&self, p: Vec3) -> bool {
        self.region.as_ref().is_none_or(|r| r.contains(p))
    }

    /// The residual's features of the last forward when the Mixnet shares them.
    fn shared_features<'c>(&self, res: &'c FieldContext) -> Option<&'c [f32]> {
        (self.mixnet.grid().is_none()).then(|| res.features())
    }
}

/// Whether a sample whose raw densities are `a` (background) and `b` (residual) has its mixed
/// σ on the same side of `m` for every β: both densities lie on one side of `m` by a margin
/// that rounding of the mix cannot cross (both density mixes lie between the two: the raw one
/// in log space, the activated one in σ).
fn beta_cannot_cross(a: f32, b: f32, m: f32) -> bool {
    /// Relative margin on σ (≈ 1e-3 on the raw density), far above f32 rounding of the mix.
    const MARGIN: f32 = 1e-3;
    let sigma = |s: f32| Activation::TruncExp.forward(s);
    sigma(a.max(b)) < m * (1.0 - MARGIN) || sigma(a.min(b)) >= m * (1.0 + MARGIN)
}

impl FrozenOutside<ResidualParams, ResidualChunk> for ResidualField {
    fn frozen(&self) -> &Nerf {
        &self.background
    }

    fn is_inside(&self, p: Vec3) -> bool {
        self.in_region(p)
    }

    fn region_bounds(&self) -> Option<crate::geometry::Aabb> {
        self.region_bounds
    }

    /// The mix at β = 0 with the residual's inputs set to the background's, exactly as
    /// [`ResidualField::chunk_density`] and [`ResidualField::chunk_colour`] set them outside.
    fn outside(&self, s: f32, c: [f32; 3]) -> (f32, [f32; 3]) {
        let o = mix_forward(self.kind, &MixInput { s_bg: s, c_bg: c, s_res: s, c_res: c, m: f32::NEG_INFINITY });
        (o.sigma, o.rgb)
    }

    fn chunk_frozen(&self, c: &ResidualChunk, sigma: &mut Vec<f32>, rgb: &mut Vec<[f32; 3]>) {
        sigma.clear();
        rgb.clear();
        for x in &c.inputs {
            let (s, c) = self.outside(x.s_bg, x.c_bg);
            sigma.push(s);
            rgb.push(c);
        }
    }

    fn chunk_density_over(
        &self,
        isa: Isa,
        params: &ResidualParams,
        positions: &[Vec3],
        frozen: &[f32],
        sigma: &mut [f32],
        c: &mut ResidualChunk,
    ) {
        assert_eq!(frozen.len(), positions.len(), "residual: frozen densities differ from the sample count");
        self.chunk_sigma(isa, params, positions, sigma, c, Some(0), Some(frozen), None);
    }

    fn chunk_colour_over(
        &self,
        isa: Isa,
        params: &ResidualParams,
        keep: &[u32],
        dirs: &[Vec3],
        frozen: &[[f32; 3]],
        rgb: &mut [[f32; 3]],
        c: &mut ResidualChunk,
    ) {
        self.chunk_colour_from(isa, params, keep, dirs, rgb, c, Some(frozen));
    }
}
