//! The NeRF trainer: each step draws random rays from all training views, marches them
//! through the occupancy grid, runs the field, composites (Eq. 2), takes the MSE (Eq. 4),
//! back-propagates through compositing, activations, field and grid, and steps Adam. Every
//! [`TrainConfig::occupancy_interval`] steps the occupancy grid is refreshed through the
//! field's density-only path.
//!
//! Determinism: ray sampling draws from `Rng::stream(seed, step)`, marching and compositing
//! are per ray in ray order, the field reduces in fixed slots — same seed, same bits on any
//! thread count.

pub use crate::field::Nerf;
use crate::field::{FieldContext, NerfConfig, NerfField, NerfGrads};
use crate::mlp::Activation;
use crate::render::{
    composite_ray, composite_ray_backward, pixel_ray, Intrinsics, OccupancyConfig, OccupancyGrid, PackedSamples, Pose,
    Ray, RayAccumulator,
};
use crate::rng::Rng;
use crate::simd::Isa;
use crate::train::slots::{slot_range, SLOTS};
use crate::train::{Adam, AdamConfig, LrSchedule};
use crate::GradientMode;
use glam::Vec3;
use rayon::prelude::*;
use std::time::Instant;

/// One posed training image with linear RGB values in [0, 1], row-major from the top-left.
#[derive(Clone, Debug)]
pub struct View {
    /// Camera intrinsics.
    pub intrinsics: Intrinsics,
    /// Camera-to-world pose.
    pub pose: Pose,
    /// `width × height` colours.
    pub rgb: Vec<[f32; 3]>,
}

/// Trainer settings.
#[derive(Clone, Debug)]
pub struct TrainConfig {
    /// Optimiser steps. Defaults to 2000.
    pub steps: u32,
    /// Rays per step. Defaults to 4096.
    pub rays_per_step: usize,
    /// Learning rate against step. Defaults to 1e-2, decaying ×0.33 from 60% of the steps every 15%.
    pub schedule: LrSchedule,
    /// Steps between occupancy-grid updates. Defaults to 16.
    pub occupancy_interval: u32,
    /// Occupancy grid and marching. Defaults to [`OccupancyConfig::default`].
    pub occupancy: OccupancyConfig,
    /// Colour behind the scene where rays leave the box (C's background term). Defaults to black.
    pub background: [f32; 3],
    /// Seed of initialisation and sampling. Defaults to 0.
    pub seed: u64,
}

impl TrainConfig {
    /// Defaults for `steps` steps (the schedule scales with it).
    pub fn with_steps(steps: u32) -> TrainConfig {
        TrainConfig {
            steps,
            rays_per_step: 4096,
            schedule: LrSchedule {
                base: 1e-2,
                warmup_steps: 0,
                decay_start: steps * 3 / 5,
                decay_interval: (steps * 3 / 20).max(1),
                decay_factor: 0.33,
            },
            occupancy_interval: 16,
            occupancy: OccupancyConfig::default(),
            background: [0.0; 3],
            seed: 0,
        }
    }
}

impl Default for TrainConfig {
    fn default() -> Self {
        TrainConfig::with_steps(2000)
    }
}

/// Progress of one logged step.
#[derive(Clone, Copy, Debug)]
pub struct StepStats {
    /// Step index (0-based).
    pub step: u32,
    /// MSE over the step's rays.
    pub loss: f32,
    /// Mean samples per ray that reached the field's full forward and backward.
    pub samples_per_ray: f32,
    /// Mean samples per ray the occupancy grid let through (before dropping those behind
    /// the opaque point).
    pub marched_per_ray: f32,
    /// Seconds since training began.
    pub seconds: f64,
    /// Fraction of occupied cells.
    pub occupancy: f64,
}

/// Reusable buffers of one step.
#[derive(Default)]
struct StepBuffers {
    rays: Vec<Ray>,
    targets: Vec<[f32; 3]>,
    marched: PackedSamples,
    marched_pos: Vec<Vec3>,
    marched_dirs: Vec<Vec3>,
    samples: PackedSamples,
    positions: Vec<Vec3>,
    dirs: Vec<Vec3>,
    raw: Vec<f32>,
    rgb_raw: Vec<[f32; 3]>,
    sigma: Vec<f32>,
    rgb: Vec<[f32; 3]>,
    d_raw: Vec<f32>,
    d_rgb_raw: Vec<[f32; 3]>,
    ctx: FieldContext,
}

/// Marches `rays` into `out` (packed in ray order) and fills per-sample positions and directions.
pub fn march_rays(
    occ: &OccupancyGrid,
    rays: &[Ray],
    out: &mut PackedSamples,
    positions: &mut Vec<Vec3>,
    dirs: &mut Vec<Vec3>,
) {
    out.clear();
    for r in rays {
        occ.march(r.origin, r.dir, out);
    }
    positions.clear();
    dirs.clear();
    for (r, &(start, count)) in rays.iter().zip(&out.rays) {
        for &t in &out.t[start as usize..(start + count) as usize] {
            positions.push(r.at(t));
            dirs.push(r.dir);
        }
    }
}

/// Copies each ray's samples of `marched` up to its opaque point — the samples
/// [`composite_ray`] uses, given raw densities `raw` — into `out`, `positions`, `dirs`.
fn keep_until_opaque(
    marched: &PackedSamples,
    marched_pos: &[Vec3],
    marched_dirs: &[Vec3],
    raw: &[f32],
    out: &mut PackedSamples,
    positions: &mut Vec<Vec3>,
    dirs: &mut Vec<Vec3>,
) {
    out.clear();
    positions.clear();
    dirs.clear();
    for &(s0, count) in &marched.rays {
        let start = out.t.len() as u32;
        let mut acc = RayAccumulator::new();
        for i in s0 as usize..(s0 + count) as usize {
            if acc.is_opaque() {
                break;
            }
            acc.push(Activation::TruncExp.forward(raw[i]), marched.delta[i], 0.0, [0.0; 3]);
            out.t.push(marched.t[i]);
            out.delta.push(marched.delta[i]);
            positions.push(marched_pos[i]);
            dirs.push(marched_dirs[i]);
        }
        out.rays.push((start, out.t.len() as u32 - start));
    }
}

/// σ = trunc_exp(s) and c = sigmoid(c′), element-wise into caller buffers.
fn activate(raw: &[f32], rgb_raw: &[[f32; 3]], sigma: &mut [f32], rgb: &mut [[f32; 3]]) {
    for (o, &s) in sigma.iter_mut().zip(raw) {
        *o = Activation::TruncExp.forward(s);
    }
    for (o, c) in rgb.iter_mut().zip(rgb_raw) {
        *o = c.map(|v| Activation::Sigmoid.forward(v));
    }
}

/// A group of consecutive rays and the contiguous range of their samples.
struct RayGroup {
    rays: std::ops::Range<usize>,
    samples: std::ops::Range<usize>,
}

/// Cuts the packed rays into [`SLOTS`] groups of consecutive rays (boundaries depend only on
/// the ray count, so the work split is the same on any thread count).
fn ray_groups(rays: &[(u32, u32)]) -> Vec<RayGroup> {
    (0..SLOTS)
        .map(|g| {
            let r = slot_range(rays.len(), g);
            let first = rays.get(r.start).map_or(0, |x| x.0 as usize);
            let last = if r.is_empty() { first } else { (rays[r.end - 1].0 + rays[r.end - 1].1) as usize };
            RayGroup { samples: first..last, rays: r }
        })
        .collect()
}

/// Disjoint mutable slices of `buf` for each group's sample range (ranges are consecutive).
fn split_at_bounds<'a, T>(buf: &'a mut [T], groups: &[RayGroup]) -> Vec<&'a mut [T]> {
    let mut parts = Vec::with_capacity(groups.len());
    let mut rest = buf;
    let mut at = 0;
    for g in groups {
        let (_, tail) = rest.split_at_mut(g.samples.start - at);
        let (head, tail) = tail.split_at_mut(g.samples.len());
        parts.push(head);
        rest = tail;
        at = g.samples.end;
    }
    parts
}

/// Trains a NeRF on `views` inside `aabb`; `log` receives stats every `log_every` steps (0: never).
pub fn train_nerf(
    isa: Isa,
    views: &[View],
    field_config: NerfConfig,
    cfg: &TrainConfig,
    log_every: u32,
    mut log: impl FnMut(StepStats),
) -> Nerf {
    assert!(!views.is_empty(), "train: no training views");
    // Denormals are ~100× slower on x86; every thread of the pool flushes them while training.
    let modes: Vec<u64> = rayon::broadcast(|_| crate::simd::fpmode::flush_denormals());
    let main_mode = crate::simd::fpmode::flush_denormals();
    let field = NerfField::new(field_config);
    let mut rng = Rng::new(cfg.seed);
    let mut params = field.init_params(&mut rng);
    let mut occupancy = OccupancyGrid::new(field.config().aabb, cfg.occupancy.clone());
    let mut grads: NerfGrads = field.zero_grads();
    let mut adam_grid = Adam::new(grads.grid.len(), AdamConfig::default());
    let mut adam_density = Adam::new(grads.density.len(), AdamConfig { l2: 1e-6, ..Default::default() });
    let mut adam_colour = Adam::new(grads.colour.len(), AdamConfig { l2: 1e-6, ..Default::default() });
    let mut buf = StepBuffers::default();
    let mut occ_ctx = FieldContext::default();
    let start = Instant::now();
    for step in 0..cfg.steps {
        if step % cfg.occupancy_interval.max(1) == 0 {
            let mut orng = Rng::stream(cfg.seed ^ 0x0CC, step as u64);
            occupancy.update(step, &mut orng, |pts, sigma| {
                field.density(isa, &params, pts, sigma, &mut occ_ctx);
                sigma.iter_mut().for_each(|s| *s = Activation::TruncExp.forward(*s));
            });
        }
        // 1. Rays: uniform over all pixels of all views.
        let mut srng = Rng::stream(cfg.seed, step as u64);
        buf.rays.clear();
        buf.targets.clear();
        for _ in 0..cfg.rays_per_step {
            let v = &views[srng.below(views.len() as u64) as usize];
            let (w, h) = (v.intrinsics.width, v.intrinsics.height);
            let p = srng.below(w as u64 * h as u64) as u32;
            buf.rays.push(pixel_ray(&v.intrinsics, &v.pose, p % w, p / w));
            buf.targets.push(v.rgb[p as usize]);
        }
        // 2. March, 3. field forward.
        march_rays(&occupancy, &buf.rays, &mut buf.marched, &mut buf.marched_pos, &mut buf.marched_dirs);
        let marched = buf.marched.len();
        // 2b. Drop the samples behind each ray's opaque point (T < 1e-4): a density-only pass
        //     finds them; compositing ignores them anyway, so the result is unchanged and the
        //     full forward/backward runs on the samples that matter (nerfacc's early stop).
        buf.raw.resize(marched, 0.0);
        if marched > 0 {
            field.density(isa, &params, &buf.marched_pos, &mut buf.raw, &mut buf.ctx);
        }
        keep_until_opaque(
            &buf.marched,
            &buf.marched_pos,
            &buf.marched_dirs,
            &buf.raw,
            &mut buf.samples,
            &mut buf.positions,
            &mut buf.dirs,
        );
        let n = buf.positions.len();
        buf.raw.resize(n, 0.0);
        buf.rgb_raw.resize(n, [0.0; 3]);
        field.forward(isa, &params, &buf.positions, &buf.dirs, &mut buf.raw, &mut buf.rgb_raw, &mut buf.ctx);
        // 4. Activate, composite, loss, and back through compositing and the activations.
        //    Rays are processed in SLOTS fixed groups whose samples are contiguous, each group
        //    writing its own slices of the step buffers (no per-ray allocation).
        buf.sigma.resize(n, 0.0);
        buf.rgb.resize(n, [0.0; 3]);
        activate(&buf.raw, &buf.rgb_raw, &mut buf.sigma, &mut buf.rgb);
        buf.d_raw.resize(n, 0.0);
        buf.d_rgb_raw.resize(n, [0.0; 3]);
        let scale = 2.0 / (3 * cfg.rays_per_step) as f32;
        let (samples, sigma, rgb, targets) = (&buf.samples, &buf.sigma, &buf.rgb, &buf.targets);
        let groups = ray_groups(&samples.rays);
        let d_raw_parts = split_at_bounds(&mut buf.d_raw, &groups);
        let d_rgb_parts = split_at_bounds(&mut buf.d_rgb_raw, &groups);
        let losses: Vec<f64> = groups
            .par_iter()
            .zip(d_raw_parts)
            .zip(d_rgb_parts)
            .map(|((g, d_s), d_c)| {
                let mut loss = 0.0f64;
                let base = g.samples.start;
                for ray in g.rays.clone() {
                    let (s0, cnt) = samples.rays[ray];
                    let r = s0 as usize..(s0 + cnt) as usize;
                    let local = r.start - base..r.end - base;
                    let c = composite_ray(
                        &sigma[r.clone()],
                        &samples.delta[r.clone()],
                        &samples.t[r.clone()],
                        &rgb[r.clone()],
                        cfg.background,
                    );
                    let err: [f32; 3] = std::array::from_fn(|k| c.rgb[k] - targets[ray][k]);
                    loss += err.iter().map(|e| (e * e) as f64).sum::<f64>();
                    let (ds, dc) = (&mut d_s[local.clone()], &mut d_c[local]);
                    composite_ray_backward(
                        &sigma[r.clone()],
                        &samples.delta[r.clone()],
                        &rgb[r.clone()],
                        &c,
                        err.map(|e| e * scale),
                        ds,
                        dc,
                    );
                    // dL/ds = dL/dσ · trunc_exp′, dL/dc′ = dL/dc · sigmoid′ (both from the outputs).
                    for ((g, &sg), (gc, col)) in ds.iter_mut().zip(&sigma[r.clone()]).zip(dc.iter_mut().zip(&rgb[r])) {
                        *g *= Activation::TruncExp.derivative_from_output(sg);
                        for k in 0..3 {
                            gc[k] *= Activation::Sigmoid.derivative_from_output(col[k]);
                        }
                    }
                }
                loss
            })
            .collect();
        let loss: f64 = losses.iter().sum();
        // 5. Field backward, 6. Adam.
        field.backward(isa, &params, &mut buf.ctx, &buf.d_raw, &buf.d_rgb_raw, &mut grads, GradientMode::Overwrite);
        let lr = cfg.schedule.lr(step);
        let half: &mut [u16] = bytemuck::cast_slice_mut(&mut params.grid.table);
        adam_grid.step(isa, lr, &mut params.grid.master, &grads.grid, Some(half));
        adam_density.step(isa, lr, params.density.weights_mut(), &grads.density, None);
        params.density.sync();
        adam_colour.step(isa, lr, params.colour.weights_mut(), &grads.colour, None);
        params.colour.sync();
        if log_every > 0 && ((step + 1) % log_every == 0 || step + 1 == cfg.steps) {
            log(StepStats {
                step,
                loss: (loss / (3 * cfg.rays_per_step) as f64) as f32,
                samples_per_ray: n as f32 / cfg.rays_per_step as f32,
                marched_per_ray: marched as f32 / cfg.rays_per_step as f32,
                seconds: start.elapsed().as_secs_f64(),
                occupancy: occupancy.occupancy(),
            });
        }
    }
    rayon::broadcast(|ctx| crate::simd::fpmode::restore(modes[ctx.index()]));
    crate::simd::fpmode::restore(main_mode);
    Nerf { field, params, occupancy }
}
