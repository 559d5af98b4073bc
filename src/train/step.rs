//! One slot's share of a fused training step ([`Worker`]): the slot's rays in chunks of whole
//! rays, each chunk marched through the occupancy grid, run through the densities, cut at each
//! ray's opaque point, run through the colours, composited (Eq. 2), scored (Eq. 4, plus the
//! optional distortion loss, β terms and near-camera gradient scaling) and back-propagated to
//! its feature gradients before the next chunk starts. The step itself (ray sampling, the slots'
//! reduction, Adam, the occupancy refresh) is [`super::trainer`].

use super::beta::beta_terms;
use super::gains::gained_error;
use super::pool::RayPool;
use super::trainer::TrainConfig;
use crate::field::model::FrozenOutside;
use crate::field::model::Model;
use crate::render::composite::{is_opaque, transmitted, RayComposite};
use crate::render::distortion::distortion_backward;
use crate::render::{composite_ray, composite_ray_backward, OccupancyGrid, PackedSamples, Ray, RayAccumulator};
use crate::simd::Isa;
use glam::Vec3;

/// Scales each sample's gradients by `min(1, (t / distance)²)` ([`TrainConfig::near_gradient`]).
pub fn scale_near_gradients(t: &[f32], distance: f32, d_sigma: &mut [f32], d_rgb: &mut [[f32; 3]]) {
    let inv = 1.0 / distance;
    for ((ds, dc), &t) in d_sigma.iter_mut().zip(d_rgb.iter_mut()).zip(t) {
        let k = (t * inv).min(1.0).powi(2);
        *ds *= k;
        *dc = dc.map(|v| v * k);
    }
}

/// The step's rays, their target colours and the colours behind them.
#[derive(Clone, Default)]
pub(super) struct StepRays {
    pub(super) rays: Vec<Ray>,
    pub(super) targets: Vec<[f32; 3]>,
    pub(super) backgrounds: Vec<[f32; 3]>,
    /// Each ray's background image colour for the photo tail ([`TrainConfig::photo_tail`];
    /// NaN: none).
    pub(super) behind: Vec<[f32; 3]>,
    /// Whether each ray's pixel is known unchanged (the β penalty's rays).
    pub(super) unchanged: Vec<bool>,
    /// Each ray's training image.
    pub(super) view: Vec<u32>,
    /// Each ray's pixel in its image (`y · width + x`).
    pub(super) pixel: Vec<u32>,
    /// Each ray's `(group slot, ray)` in the ray pool, when the step draws from one.
    pub(super) pooled: Vec<(u32, u32)>,
}

impl StepRays {
    /// Empties every list.
    pub(super) fn clear(&mut self) {
        self.rays.clear();
        self.targets.clear();
        self.backgrounds.clear();
        self.behind.clear();
        self.unchanged.clear();
        self.view.clear();
        self.pixel.clear();
        self.pooled.clear();
    }
}

/// The rays of slot `s` among a step's `n` rays: whole pixels of `k` rays each
/// ([`TrainConfig::rays_per_pixel`]; a pixel's rays are scored together), split as
/// [`crate::slots::slot_range`] splits the pixels.
pub(super) fn slot_rays(n: usize, k: usize, s: usize) -> std::ops::Range<usize> {
    let pixels = crate::slots::slot_range(n / k, s);
    pixels.start * k..pixels.end * k
}

/// Kept samples a chunk of the fused step holds at least (it takes whole rays, so it ends with
/// the rest of its last ray). Counting kept samples, not evaluated ones, makes a chunk's rays,
/// and so the order in which its sums round, independent of [`RAY_SEGMENT`]. Small enough
/// that a chunk's activations (~1 KiB a sample) stay in L1/L2 between its forward and
/// backward: the MLPs run 1.6× faster on 64-row batches than on 16 384-row ones
/// (BENCHMARKS.md, "The training step: fused per chunk of rays").
pub const CHUNK_SAMPLES: usize = 128;

/// Samples of each evaluated segment of a training ray. A ray's densities are evaluated only
/// up to the end of the segment in which it stops (opaque, or at the frozen tail; at the photo
/// tail, whose stop is known from `t` alone, up to the stop), so a shorter segment evaluates
/// fewer samples past the stop and costs more calls; which samples are kept,
/// and every bit of the step, do not depend on it (test
/// `a_step_has_the_same_bits_whatever_the_segment_length`). 32: docs/DECISIONS.md, "The frozen
/// tail".
pub const RAY_SEGMENT: usize = 32;

/// What a ray's segment callback tells [`march_in_segments`].
pub(super) enum Flow {
    /// March on.
    Go,
    /// The ray stopped (opaque, or at the frozen tail).
    Stop,
    /// The ray stopped before sample `i` (at the photo tail): the samples from `i` on are
    /// dropped unevaluated (the callback has no rows of them).
    StopBefore(usize),
    /// Keep the samples up to index `i` and march the rest of the ray at the coarse stride
    /// from the end of sample `i`: the samples after `i` are dropped (the callback drops its
    /// own rows of them). [`TrainConfig::frozen_coarse`].
    Coarsen(usize),
}

/// Marches `r` through `occ` segment by segment (`len` samples each), appending
/// each segment's samples to `t` and `delta` and handing `segment` the new samples' index range
/// (with the arrays so far); stops after a segment for which it returns [`Flow::Stop`], at the
/// end of the ray's span, or at the grid's sample budget. `strides`: lattice steps a sample
/// stands for outside the grid's pinned cells ([`OccupancyGrid::march_segment`]), before and
/// after a [`Flow::Coarsen`], where the field is the frozen background; a grid without pins
/// has no frozen part and marches every step. The segments concatenate to exactly the samples of marching the
/// whole ray (at the coarse stride from the sample the callback names): which samples a ray
/// takes does not depend on `len`. The training step's rays and the ray pool's
/// ([`super::pool`]) march this way.
pub(super) fn march_in_segments(
    occ: &OccupancyGrid,
    r: &Ray,
    (stride, coarse_stride): (u32, u32),
    len: usize,
    t: &mut Vec<f32>,
    delta: &mut Vec<f32>,
    mut segment: impl FnMut(&[f32], &[f32], std::ops::Range<usize>) -> Flow,
) {
    let Some(span) = occ.span(r.origin, r.dir) else { return };
    let max = occ.config().max_samples;
    let (stride, coarse_stride) = if occ.is_pinned() { (stride, coarse_stride) } else { (1, 1) };
    let (mut next, mut taken, mut stride) = (0, 0u32, stride);
    loop {
        let s0 = t.len();
        let room = len.max(1).min(max.saturating_sub(taken) as usize);
        next = occ.march_segment(r.origin, r.dir, span, next..span.steps, room, stride, t, delta);
        let count = t.len() - s0;
        if count == 0 {
            break;
        }
        taken += count as u32;
        match segment(t, delta, s0..s0 + count) {
            Flow::Go => {}
            Flow::Stop => break,
            Flow::StopBefore(i) => {
                t.truncate(i);
                delta.truncate(i);
                break;
            }
            Flow::Coarsen(i) => {
                // Sample i stands for the lattice steps [k, k + run) around its midpoint
                // t = near + (k + run/2)·dt, δ = run·dt: the march resumes at k + run.
                let dt = occ.step_size();
                next = ((t[i] - span.near + 0.5 * delta[i]) / dt).round() as u32;
                taken -= (t.len() - i - 1) as u32;
                t.truncate(i + 1);
                delta.truncate(i + 1);
                stride = stride.max(coarse_stride);
            }
        }
        if next >= span.steps || taken >= max {
            break;
        }
    }
}

/// Where `r` leaves the bounding box of the region its model is frozen outside
/// ([`FrozenOutside::region_bounds`]): beyond it a training ray may stop at the frozen tail
/// ([`TrainConfig::frozen_tail`]) or the photo tail ([`TrainConfig::photo_tail`]); 0 for a ray
/// that misses the region, `None` when the model has no region.
fn region_exit<M: Model>(x: &StepInputs<M>, r: &Ray) -> Option<f32> {
    let b = x.model.frozen_outside().and_then(|f| f.region_bounds())?;
    Some(b.intersect(r.origin, r.dir).map_or(0.0, |(_, exit)| exit))
}

/// Whether the photo tail applies to ray `ray` ([`TrainConfig::photo_tail`] on and the ray's
/// background colour known).
fn has_photo<M: Model>(x: &StepInputs<M>, rays: &StepRays, ray: usize) -> bool {
    x.cfg.photo_tail && rays.behind.get(ray).is_some_and(|b| !b[0].is_nan())
}

/// How a training ray of the fused step ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Tail {
    /// At its opaque point or the end of its span (the ray's background colour behind it).
    None,
    /// At the frozen tail: its last sample's colour stands for the light behind.
    Frozen,
    /// At the photo tail: the light behind read off its pixel's background image.
    Photo,
}

/// Below this frozen-background transmittance at the photo tail's start, the background image
/// says too little about the light behind: the ray's last sample's colour stands for it, as
/// at the frozen tail.
const PHOTO_TAIL_MIN_T: f32 = 0.1;

/// A pixel's colour against its target: `rgb` the mean colour of its `n` rays from `first`
/// (one, or [`TrainConfig::pixel_rays`]; they share target, view and gain), seen through its
/// image's gain when gains are learned (adding the gain's gradient into `d_gain`). The pixel
/// stands for `n` of the step's rays: its squared error joins `loss` `n` times and, as the
/// mean over the channels, `errors` once per ray. Returns dL/dC of each of its rays (Eq. 4,
/// averaged over the step's rays; with `n` rays each carries `1/n` of the mean's gradient).
#[allow(clippy::too_many_arguments)]
fn score_pixel<M: Model>(
    x: &StepInputs<M>,
    rays: &StepRays,
    first: usize,
    n: usize,
    rgb: [f32; 3],
    loss: &mut f64,
    errors: &mut Vec<f32>,
    d_gain: &mut [[f32; 3]],
) -> [f32; 3] {
    let scale = 2.0 * n as f32 / (3 * x.cfg.rays_per_step) as f32;
    let target = rays.targets[first];
    let (err, d_mean) = match x.gains.get(rays.view[first] as usize) {
        Some(&g) => gained_error(rgb, target, g, scale, &mut d_gain[rays.view[first] as usize]),
        None => {
            let err: [f32; 3] = std::array::from_fn(|i| rgb[i] - target[i]);
            (err, err.map(|e| e * scale))
        }
    };
    let sq: f32 = err.iter().map(|e| e * e).sum();
    errors.extend(std::iter::repeat_n(sq / 3.0, n));
    *loss += n as f64 * err.iter().map(|e| (e * e) as f64).sum::<f64>();
    // x / 1 is x exactly: one ray per pixel keeps its gradient's bits.
    d_mean.map(|d| d / n as f32)
}

/// Ray `ray`'s weights of the β penalty (0 on a changed ray) and of the β entropy, each per ray
/// and averaged over the step's rays.
fn beta_weights<M: Model>(x: &StepInputs<M>, rays: &StepRays, ray: usize) -> (f32, f32) {
    let (cfg, n) = (x.cfg, x.cfg.rays_per_step as f32);
    let unchanged = if rays.unchanged[ray] { cfg.beta.unchanged } else { 0.0 };
    (unchanged / n, x.entropy / n)
}

/// One slot's share of a fused step: its chunk's buffers, reused from step to step.
pub(super) struct Worker<C> {
    chunk: C,
    marched: PackedSamples,
    positions: Vec<Vec3>,
    dirs: Vec<Vec3>,
    sigma: Vec<f32>,
    keep: Vec<u32>,
    kept: Vec<(u32, u32)>,
    /// Per ray of the chunk: where it stopped ([`TrainConfig::frozen_tail`], [`TrainConfig::photo_tail`]).
    tails: Vec<Tail>,
    /// The frozen background's own σ and colour of the chunk's kept rows (the photo tail).
    frozen_sigma: Vec<f32>,
    frozen_rgb: Vec<[f32; 3]>,
    rgb: Vec<[f32; 3]>,
    /// Per ray of the chunk: its composite, and the dL/dC its pixel's score gives it.
    composites: Vec<RayComposite>,
    d_colours: Vec<[f32; 3]>,
    d_sigma: Vec<f32>,
    d_rgb: Vec<[f32; 3]>,
    scratch: Vec<f32>,
    /// This step's summed squared error, marched and kept samples.
    pub(super) loss: f64,
    pub(super) n_marched: usize,
    pub(super) n_kept: usize,
    /// This step's gradient of each training image's log-gain (empty without learned gains).
    pub(super) d_gain: Vec<[f32; 3]>,
    /// Each of the slot's rays' squared colour error, mean over the channels (the error map's input).
    pub(super) ray_errors: Vec<f32>,
    /// The pooled path's per-unit buffers.
    units: UnitScratch,
    /// Samples of each evaluated segment of a ray ([`RAY_SEGMENT`]).
    pub(super) segment: usize,
}

/// [`UnitScratch::row`] of a run outside the region (no row of the model's).
const OUTSIDE: u32 = u32::MAX;

/// A chunk's pooled rays unit by unit ([`Worker::run_pooled`]): each ray's units up to its
/// opaque point, and per kept row the background's values handed to the model.
#[derive(Default)]
struct UnitScratch {
    frozen_s: Vec<f32>,
    frozen_c: Vec<[f32; 3]>,
    sigma: Vec<f32>,
    delta: Vec<f32>,
    t: Vec<f32>,
    rgb: Vec<[f32; 3]>,
    /// Each unit's kept row, or [`OUTSIDE`] for a run.
    row: Vec<u32>,
    d_sigma: Vec<f32>,
    d_rgb: Vec<[f32; 3]>,
    beta: Vec<f32>,
    d_beta: Vec<f32>,
}

impl<C: Default> Default for Worker<C> {
    fn default() -> Self {
        Worker {
            chunk: C::default(),
            marched: PackedSamples::default(),
            positions: Vec::new(),
            dirs: Vec::new(),
            sigma: Vec::new(),
            keep: Vec::new(),
            kept: Vec::new(),
            tails: Vec::new(),
            frozen_sigma: Vec::new(),
            frozen_rgb: Vec::new(),
            rgb: Vec::new(),
            composites: Vec::new(),
            d_colours: Vec::new(),
            d_sigma: Vec::new(),
            d_rgb: Vec::new(),
            scratch: Vec::new(),
            loss: 0.0,
            n_marched: 0,
            n_kept: 0,
            d_gain: Vec::new(),
            ray_errors: Vec::new(),
            units: UnitScratch::default(),
            segment: RAY_SEGMENT,
        }
    }
}

/// What a slot's chunks read: the model and its parameters, the grid, the settings.
pub(super) struct StepInputs<'a, M: Model> {
    pub(super) isa: Isa,
    pub(super) model: &'a M,
    pub(super) params: &'a M::Params,
    pub(super) occupancy: &'a OccupancyGrid,
    pub(super) cfg: &'a TrainConfig,
    /// This step's β entropy weight (0 before [`BetaRegulariser::entropy_from`]).
    pub(super) entropy: f32,
    /// Each training image's gain (empty: images taken as they are; [`crate::train::gains`]).
    pub(super) gains: &'a [[f32; 3]],
    /// The near-camera gradient scaling's distance ([`super::trainer::Trainer::near_distance`];
    /// 0: off).
    pub(super) near_distance: f32,
}

impl<C> Worker<C> {
    /// Runs the slot's `rays` chunk by chunk into `slot`.
    pub(super) fn run<M: Model<Chunk = C>>(
        &mut self,
        x: &StepInputs<M>,
        rays: &StepRays,
        range: std::ops::Range<usize>,
        slot: &mut M::Slot,
    ) {
        self.begin_run(x, slot);
        // A chunk ends after a whole pixel's rays (they are scored together).
        let per_pixel = x.cfg.rays_per_pixel();
        let mut first = range.start;
        for i in range.clone() {
            self.add_ray(x, &rays.rays[i], has_photo(x, rays, i));
            let pixel_done = (i + 1 - range.start).is_multiple_of(per_pixel);
            if (self.keep.len() >= CHUNK_SAMPLES && pixel_done) || i + 1 == range.end {
                self.run_chunk(x, rays, first..i + 1, slot);
                self.begin_chunk();
                first = i + 1;
            }
        }
    }

    /// [`Worker::run`] for rays drawn from the ray pool ([`super::pool`]): each ray's runs
    /// outside the change region are single units whose light and transmittance the pool
    /// holds, and only its samples inside the region go through the model, with the
    /// background's values handed in ([`FrozenOutside`]).
    pub(super) fn run_pooled<M: Model<Chunk = C>>(
        &mut self,
        x: &StepInputs<M>,
        split: &dyn FrozenOutside<M::Params, C>,
        pool: &RayPool,
        rays: &StepRays,
        range: std::ops::Range<usize>,
        slot: &mut M::Slot,
    ) {
        self.begin_run(x, slot);
        let mut first = range.start;
        for i in range.clone() {
            let (g, k) = rays.pooled[i];
            let group = pool.group(g);
            let r = &rays.rays[i];
            for u in group.units_of(k as usize).iter().filter(|u| u.inside) {
                self.positions.push(r.at(u.t));
                self.units.frozen_s.push(u.s);
            }
            self.n_marched += group.rays[k as usize].marched as usize;
            if self.positions.len() >= CHUNK_SAMPLES || i + 1 == range.end {
                self.run_pooled_chunk(x, split, pool, rays, first..i + 1, slot);
                self.begin_chunk();
                first = i + 1;
            }
        }
    }

    /// A chunk of pooled rays: the density of their inside samples, each ray's units walked to
    /// its opaque point, the colours of the kept samples, compositing, loss, and back into
    /// `slot` (the runs' derivatives are dropped: nothing trainable made them).
    fn run_pooled_chunk<M: Model<Chunk = C>>(
        &mut self,
        x: &StepInputs<M>,
        split: &dyn FrozenOutside<M::Params, C>,
        pool: &RayPool,
        rays: &StepRays,
        range: std::ops::Range<usize>,
        slot: &mut M::Slot,
    ) {
        let (cfg, u) = (x.cfg, &mut self.units);
        let n = self.positions.len();
        self.sigma.resize(n, 0.0);
        if n > 0 {
            split.chunk_density_over(x.isa, x.params, &self.positions, &u.frozen_s, &mut self.sigma, &mut self.chunk);
        }
        for v in [&mut u.sigma, &mut u.delta, &mut u.t] {
            v.clear();
        }
        u.rgb.clear();
        u.row.clear();
        u.frozen_c.clear();
        let mut row = 0;
        for i in range.clone() {
            let (g, k) = rays.pooled[i];
            let start = u.sigma.len() as u32;
            let mut transmittance = 1.0f32;
            for unit in pool.group(g).units_of(k as usize) {
                if is_opaque(transmittance) {
                    // Past the opaque point: the ray's later inside rows are not composited.
                    row += unit.inside as usize;
                    continue;
                }
                let sigma = if unit.inside {
                    u.row.push(self.keep.len() as u32);
                    u.rgb.push([0.0; 3]); // the model's colour, below
                    self.keep.push(row as u32);
                    self.dirs.push(rays.rays[i].dir);
                    u.frozen_c.push(unit.c);
                    row += 1;
                    self.sigma[row - 1]
                } else {
                    u.row.push(OUTSIDE);
                    u.rgb.push(unit.c);
                    unit.s
                };
                transmittance *= transmitted(sigma, unit.delta);
                u.sigma.push(sigma);
                u.delta.push(unit.delta);
                u.t.push(unit.t);
            }
            self.kept.push((start, u.sigma.len() as u32 - start));
        }
        let k = self.keep.len();
        self.n_kept += k;
        self.rgb.resize(k, [0.0; 3]);
        if k > 0 {
            split.chunk_colour_over(
                x.isa,
                x.params,
                &self.keep,
                &self.dirs,
                &u.frozen_c,
                &mut self.rgb,
                &mut self.chunk,
            );
        }
        for (c, &kr) in u.rgb.iter_mut().zip(&u.row) {
            if kr != OUTSIDE {
                *c = self.rgb[kr as usize];
            }
        }
        self.d_sigma.clear();
        self.d_sigma.resize(k, 0.0);
        self.d_rgb.clear();
        self.d_rgb.resize(k, [0.0; 3]);
        let mut beta = match cfg.beta.is_on() && k > 0 {
            true => x.model.chunk_beta(&mut self.chunk),
            false => None,
        };
        for (ray, &(s0, count)) in range.zip(&self.kept) {
            let r = s0 as usize..(s0 + count) as usize;
            let (sigma, delta, t) = (&u.sigma[r.clone()], &u.delta[r.clone()], &u.t[r.clone()]);
            let c = composite_ray(sigma, delta, t, &u.rgb[r.clone()], rays.backgrounds[ray]);
            let d_colour = score_pixel(x, rays, ray, 1, c.rgb, &mut self.loss, &mut self.ray_errors, &mut self.d_gain);
            u.d_sigma.resize(count as usize, 0.0);
            u.d_rgb.resize(count as usize, [0.0; 3]);
            composite_ray_backward(sigma, delta, &u.rgb[r.clone()], &c, d_colour, &mut u.d_sigma, &mut u.d_rgb);
            if x.near_distance > 0.0 {
                scale_near_gradients(t, x.near_distance, &mut u.d_sigma, &mut u.d_rgb);
            }
            let rows = &u.row[r.clone()];
            for (j, &kr) in rows.iter().enumerate().filter(|(_, &kr)| kr != OUTSIDE) {
                self.d_sigma[kr as usize] = u.d_sigma[j];
                self.d_rgb[kr as usize] = u.d_rgb[j];
            }
            if let Some((beta, d_beta)) = &mut beta {
                let (unchanged, entropy) = beta_weights(x, rays, ray);
                if unchanged > 0.0 || entropy > 0.0 {
                    u.beta.clear();
                    u.beta.extend(rows.iter().map(|&kr| if kr == OUTSIDE { 0.0 } else { beta[kr as usize] }));
                    u.d_beta.clear();
                    u.d_beta.resize(rows.len(), 0.0);
                    beta_terms(sigma, delta, &u.beta, unchanged, entropy, &mut u.d_beta);
                    for (&kr, &d) in rows.iter().zip(&u.d_beta).filter(|(&kr, _)| kr != OUTSIDE) {
                        d_beta[kr as usize] += d;
                    }
                }
            }
        }
        if k > 0 {
            x.model.chunk_backward(x.isa, x.params, &mut self.chunk, &self.d_sigma, &self.d_rgb, slot);
        }
    }

    /// Starts the slot's share of a step: no loss, samples or gain gradients yet, an empty chunk.
    fn begin_run<M: Model<Chunk = C>>(&mut self, x: &StepInputs<M>, slot: &mut M::Slot) {
        (self.loss, self.n_marched, self.n_kept) = (0.0, 0, 0);
        self.d_gain.clear();
        self.d_gain.resize(x.gains.len(), [0.0; 3]);
        self.ray_errors.clear();
        x.model.begin_slot(slot);
        self.begin_chunk();
    }

    /// Empties the chunk's buffers.
    fn begin_chunk(&mut self) {
        self.marched.clear();
        self.positions.clear();
        self.dirs.clear();
        self.sigma.clear();
        self.keep.clear();
        self.kept.clear();
        self.tails.clear();
        self.units.frozen_s.clear();
    }

    /// Adds a ray to the chunk: marches it segment by segment ([`Worker::segment`] samples),
    /// evaluates each segment's densities as the chunk's next rows, and stops at
    /// the segment in which the ray turns opaque (`T < 1e-4`): the samples behind it would be
    /// dropped unseen by compositing (nerfacc's early stop). Keeps the ray's samples up to its
    /// opaque point. The samples are exactly those of marching the whole ray.
    ///
    /// With [`TrainConfig::frozen_tail`] `τ > 0` and a model that is frozen outside a region,
    /// the ray also stops at its first sample beyond the region's bounding box whose
    /// transmittance has fallen below `τ`: the rest of the ray is the frozen field, and
    /// [`Worker::run_chunk`] lets that last sample's colour stand for its light.
    ///
    /// With the photo tail (`photo`) the ray stops before its first sample beyond the region's
    /// bounding box instead; that sample and the segment's later ones are not evaluated.
    fn add_ray<M: Model<Chunk = C>>(&mut self, x: &StepInputs<M>, r: &Ray, photo: bool) {
        let m = &mut self.marched;
        let start = m.t.len();
        let first_kept = self.keep.len() as u32;
        let mut acc = RayAccumulator::new();
        let (cfg, occ, len) = (x.cfg, x.occupancy, self.segment);
        // Past the region's box: the photo tail's stop, or where the frozen tail may start.
        let exit = region_exit(x, r);
        let photo = exit.filter(|_| photo);
        let tail = exit.filter(|_| cfg.frozen_tail > 0.0).unwrap_or(f32::INFINITY);
        let strides = (cfg.frozen_stride, cfg.frozen_coarse_stride);
        // Past the tail's start, below this transmittance the ray goes on at the coarse stride.
        let mut coarse_below = if cfg.frozen_coarse_stride > cfg.frozen_stride { cfg.frozen_coarse } else { 0.0 };
        let mut tailed = false;
        let mut photoed = false;
        let (positions, dirs, sigma, keep, chunk) =
            (&mut self.positions, &mut self.dirs, &mut self.sigma, &mut self.keep, &mut self.chunk);
        march_in_segments(occ, r, strides, len, &mut m.t, &mut m.delta, |t, delta, seg| {
            // The photo tail's stop is known before any density: the first sample beyond the
            // box. The samples from it on are neither evaluated nor kept.
            let cut = photo.and_then(|exit| seg.clone().find(|&i| t[i] > exit)).unwrap_or(seg.end);
            let evaluated = seg.start..cut;
            for &t in &t[evaluated.clone()] {
                positions.push(r.at(t));
                dirs.push(r.dir);
            }
            sigma.resize(cut, 0.0);
            if cut > seg.start {
                x.model.chunk_density(
                    x.isa,
                    x.params,
                    seg.start,
                    &positions[evaluated.clone()],
                    &mut sigma[evaluated.clone()],
                    chunk,
                );
            }
            for i in evaluated {
                if acc.is_opaque() || tailed {
                    break;
                }
                acc.push(sigma[i], delta[i], 0.0, [0.0; 3]);
                keep.push(i as u32);
                let past = !acc.is_opaque() && t[i] > tail;
                tailed = past && acc.transmittance() < cfg.frozen_tail;
                if past && !tailed && acc.transmittance() < coarse_below {
                    coarse_below = 0.0;
                    positions.truncate(i + 1);
                    dirs.truncate(i + 1);
                    sigma.truncate(i + 1);
                    return Flow::Coarsen(i);
                }
            }
            let stopped = acc.is_opaque() || tailed;
            if cut < seg.end {
                photoed = !stopped;
                Flow::StopBefore(cut)
            } else if stopped {
                Flow::Stop
            } else {
                Flow::Go
            }
        });
        m.rays.push((start as u32, (m.t.len() - start) as u32));
        self.kept.push((first_kept, self.keep.len() as u32 - first_kept));
        self.tails.push(match (tailed, photoed) {
            (true, _) => Tail::Frozen,
            (_, true) => Tail::Photo,
            _ => Tail::None,
        });
    }

    /// The rest of a chunk whose rays [`Worker::add_ray`] evaluated: colours of the kept
    /// samples, compositing and loss, and back through everything into `slot`.
    fn run_chunk<M: Model<Chunk = C>>(
        &mut self,
        x: &StepInputs<M>,
        rays: &StepRays,
        range: std::ops::Range<usize>,
        slot: &mut M::Slot,
    ) {
        let (cfg, m) = (x.cfg, &mut self.marched);
        self.n_marched += m.len();
        let k = self.keep.len();
        self.n_kept += k;
        for v in [&mut m.t, &mut m.delta, &mut self.sigma] {
            crate::mlp::keep_rows(v, 1, &self.keep);
            v.truncate(k);
        }
        crate::mlp::keep_rows(&mut self.dirs, 1, &self.keep);
        self.dirs.truncate(k);
        self.rgb.resize(k, [0.0; 3]);
        if k > 0 {
            x.model.chunk_colour(x.isa, x.params, &self.keep, &self.dirs, &mut self.rgb, &mut self.chunk);
        }
        if let (Some(split), true) = (x.model.frozen_outside(), self.tails.contains(&Tail::Photo)) {
            split.chunk_frozen(&self.chunk, &mut self.frozen_sigma, &mut self.frozen_rgb);
        }
        // Composite, loss, and back through compositing, ray by ray.
        self.d_sigma.resize(k, 0.0);
        self.d_rgb.resize(k, [0.0; 3]);
        let mut beta = match cfg.beta.is_on() && k > 0 {
            true => x.model.chunk_beta(&mut self.chunk),
            false => None,
        };
        // Each ray composited (Eq. 2); a pixel's rays are scored together, as the mean colour
        // of its footprint ([`TrainConfig::pixel_rays`]), each taking the same dL/dC.
        self.composites.clear();
        for ((ray, &(s0, count)), &tail) in range.clone().zip(&self.kept).zip(&self.tails) {
            let r = s0 as usize..(s0 + count) as usize;
            // A ray stopped at the frozen tail: its last sample's colour (a constant here, as the
            // background colour is) stands for the frozen field's light behind it. At the photo
            // tail: what the background image leaves after the frozen field's own light in front.
            let behind = match tail {
                Tail::Frozen => self.rgb[r.end - 1],
                Tail::None => rays.backgrounds[ray],
                Tail::Photo => {
                    let bg = composite_ray(
                        &self.frozen_sigma[r.clone()],
                        &m.delta[r.clone()],
                        &m.t[r.clone()],
                        &self.frozen_rgb[r.clone()],
                        [0.0; 3],
                    );
                    let photo = rays.behind[ray];
                    // C = C_mix + T_mix · C_behind with C_photo = C_bg + T_bg · C_behind: a ray
                    // the mix leaves as the background predicts its photo, bit for bit up to rounding.
                    match bg.transmittance >= PHOTO_TAIL_MIN_T {
                        true => std::array::from_fn(|c| (photo[c] - bg.rgb[c]) / bg.transmittance),
                        false if count > 0 => self.rgb[r.end - 1],
                        false => photo,
                    }
                }
            };
            self.composites.push(composite_ray(
                &self.sigma[r.clone()],
                &m.delta[r.clone()],
                &m.t[r.clone()],
                &self.rgb[r],
                behind,
            ));
        }
        let per_pixel = cfg.rays_per_pixel();
        self.d_colours.clear();
        for (pixel, group) in self.composites.chunks(per_pixel).enumerate() {
            let first_ray = range.start + pixel * per_pixel;
            let mean: [f32; 3] =
                std::array::from_fn(|c| group.iter().map(|g| g.rgb[c]).sum::<f32>() / group.len() as f32);
            let d = score_pixel(
                x,
                rays,
                first_ray,
                group.len(),
                mean,
                &mut self.loss,
                &mut self.ray_errors,
                &mut self.d_gain,
            );
            self.d_colours.extend(std::iter::repeat_n(d, group.len()));
        }
        for (((i, &(s0, count)), c), &d_colour) in
            self.kept.iter().enumerate().zip(&self.composites).zip(&self.d_colours)
        {
            let ray = range.start + i;
            let r = s0 as usize..(s0 + count) as usize;
            let (sigma, delta, t) = (&self.sigma[r.clone()], &m.delta[r.clone()], &m.t[r.clone()]);
            let (d_s, d_c) = (&mut self.d_sigma[r.clone()], &mut self.d_rgb[r.clone()]);
            composite_ray_backward(sigma, delta, &self.rgb[r.clone()], c, d_colour, d_s, d_c);
            if cfg.distortion > 0.0 {
                let weight = cfg.distortion / cfg.rays_per_step as f32;
                distortion_backward(sigma, delta, t, weight, d_s, &mut self.scratch);
            }
            if let Some((beta, d_beta)) = &mut beta {
                let (unchanged, entropy) = beta_weights(x, rays, ray);
                if unchanged > 0.0 || entropy > 0.0 {
                    beta_terms(sigma, delta, &beta[r.clone()], unchanged, entropy, &mut d_beta[r.clone()]);
                }
            }
            if x.near_distance > 0.0 {
                scale_near_gradients(t, x.near_distance, d_s, d_c);
            }
        }
        if k > 0 {
            x.model.chunk_backward(x.isa, x.params, &mut self.chunk, &self.d_sigma, &self.d_rgb, slot);
        }
    }
}
