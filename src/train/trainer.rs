//! The NeRF trainer: each step draws random rays from all training views, marches them
//! through the occupancy grid, runs the field, composites (Eq. 2), takes the MSE (Eq. 4),
//! back-propagates through compositing, activations, field and grid, and steps Adam. Every
//! [`TrainConfig::occupancy_interval`] steps the occupancy grid is refreshed through the
//! field's density-only path.
//!
//! Determinism: ray sampling draws from `Rng::stream(seed, step)`, marching and compositing
//! are per ray in ray order, the field reduces in fixed slots — same seed, same bits on any
//! thread count.

use crate::field::residual::{ResidualConfig, ResidualField, ResidualModel};
pub use crate::field::Nerf;
use crate::field::{NerfConfig, NerfField};
use crate::render::distortion::distortion_backward;
use crate::render::{
    composite_ray, composite_ray_backward, pixel_ray, Aabb, Intrinsics, OccupancyConfig, OccupancyGrid, PackedSamples,
    Pose, Ray, RayAccumulator,
};
use crate::rng::Rng;
use crate::simd::Isa;
use crate::train::model::Model;
use crate::train::slots::{slot_range, SLOTS};
use crate::train::{Adam, AdamConfig, LrSchedule};
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
    /// Draw each training ray's background colour uniformly at random instead (targets
    /// unchanged): transmittance left at the end of a ray then costs loss, so the field must
    /// make every surface opaque. Right for images without alpha (every pixel shows a surface);
    /// `rnerf train` turns it on for such datasets. Defaults to false.
    pub random_background: bool,
    /// Seed of initialisation and sampling. Defaults to 0.
    pub seed: u64,
    /// Weight λ of the distortion loss (per ray, scene units; [`crate::render::distortion`]).
    /// Defaults to [`DISTORTION`].
    pub distortion: f32,
    /// Distance (scene units) within which each sample's gradients are scaled down by
    /// `(t / d)²` (Philip & Deschaintre 2023, "Floaters No More"): density right in front of a
    /// training camera, which only that camera sees, learns slower than the scene. 0 turns it
    /// off. Defaults to [`NEAR_GRADIENT_DISTANCE`].
    pub near_gradient_distance: f32,
}

/// Default of [`TrainConfig::near_gradient_distance`] (chosen by measured depth; README).
pub const NEAR_GRADIENT_DISTANCE: f32 = 0.0;

/// Default weight of the distortion loss: off — on the dev background it did not improve depth
/// at the weights tried (README, "Decisions").
pub const DISTORTION: f32 = 0.0;

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
            random_background: false,
            seed: 0,
            distortion: DISTORTION,
            near_gradient_distance: NEAR_GRADIENT_DISTANCE,
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
    /// Seconds of training so far (time spent in the observer excluded).
    pub seconds: f64,
    /// Fraction of occupied cells.
    pub occupancy: f64,
}

/// Scales each sample's gradients by `min(1, (t / distance)²)` ([`TrainConfig::near_gradient_distance`]).
pub fn scale_near_gradients(t: &[f32], distance: f32, d_sigma: &mut [f32], d_rgb: &mut [[f32; 3]]) {
    let inv = 1.0 / distance;
    for ((ds, dc), &t) in d_sigma.iter_mut().zip(d_rgb.iter_mut()).zip(t) {
        let k = (t * inv).min(1.0).powi(2);
        *ds *= k;
        *dc = dc.map(|v| v * k);
    }
}

/// Reusable buffers of one step.
#[derive(Default)]
struct StepBuffers {
    rays: Vec<Ray>,
    targets: Vec<[f32; 3]>,
    backgrounds: Vec<[f32; 3]>,
    marched: PackedSamples,
    marched_pos: Vec<Vec3>,
    marched_dirs: Vec<Vec3>,
    samples: PackedSamples,
    positions: Vec<Vec3>,
    dirs: Vec<Vec3>,
    sigma: Vec<f32>,
    rgb: Vec<[f32; 3]>,
    d_sigma: Vec<f32>,
    d_rgb: Vec<[f32; 3]>,
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
/// [`composite_ray`] uses, given densities `sigma` — into `out`, `positions`, `dirs`.
fn keep_until_opaque(
    marched: &PackedSamples,
    marched_pos: &[Vec3],
    marched_dirs: &[Vec3],
    sigma: &[f32],
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
            acc.push(sigma[i], marched.delta[i], 0.0, [0.0; 3]);
            out.t.push(marched.t[i]);
            out.delta.push(marched.delta[i]);
            positions.push(marched_pos[i]);
            dirs.push(marched_dirs[i]);
        }
        out.rays.push((start, out.t.len() as u32 - start));
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

/// Trains a NeRF of `field_config` on `views`; `log` receives stats every `log_every` steps
/// (0: never).
pub fn train_nerf(
    isa: Isa,
    views: &[View],
    field_config: NerfConfig,
    cfg: &TrainConfig,
    log_every: u32,
    log: impl FnMut(StepStats),
) -> Nerf {
    let aabb = field_config.aabb;
    let field = NerfField::new(field_config);
    let mut log = log;
    let (params, occupancy) = train_model(isa, &field, aabb, views, cfg, log_every, |s, _, _| log(s));
    Nerf { field, params, occupancy }
}

/// Trains a residual model (residual NeRF + Mixnet over the frozen `background`) on the scene
/// `views`; the occupancy grid covers the mixed field.
pub fn train_residual(
    isa: Isa,
    background: Nerf,
    views: &[View],
    config: ResidualConfig,
    cfg: &TrainConfig,
    log_every: u32,
    log: impl FnMut(StepStats),
) -> ResidualModel {
    let aabb = config.residual.aabb;
    let field = ResidualField::new(background, config);
    let mut log = log;
    let (params, occupancy) = train_model(isa, &field, aabb, views, cfg, log_every, |s, _, _| log(s));
    ResidualModel { field, params, occupancy }
}

/// Trains `model` on `views` inside `aabb` from fresh parameters (seeded by `cfg.seed`);
/// returns the parameters and the occupancy grid. `observe` receives the stats, parameters and
/// occupancy grid after every `log_every`-th step and the last (0: never); the training clock
/// ([`StepStats::seconds`]) stops while it runs, so an observer that evaluates the model (the
/// speed curves of `rnerf compare`) does not count as training time.
pub fn train_model<M: Model>(
    isa: Isa,
    model: &M,
    aabb: Aabb,
    views: &[View],
    cfg: &TrainConfig,
    log_every: u32,
    mut observe: impl FnMut(StepStats, &M::Params, &OccupancyGrid),
) -> (M::Params, OccupancyGrid) {
    assert!(!views.is_empty(), "train: no training views");
    // Denormals are ~100× slower on x86; every thread of the pool flushes them while training.
    let modes: Vec<u64> = rayon::broadcast(|_| crate::simd::fpmode::flush_denormals());
    let main_mode = crate::simd::fpmode::flush_denormals();
    let mut rng = Rng::new(cfg.seed);
    let mut params = model.init_params(&mut rng);
    let mut occupancy = OccupancyGrid::new(aabb, cfg.occupancy.clone());
    let mut grads = model.zero_grads();
    let mut adams: Vec<Adam> = model
        .groups(&mut params, &grads)
        .iter()
        .map(|g| Adam::new(g.master.len(), AdamConfig { l2: g.l2, ..Default::default() }))
        .collect();
    model.after_step(&mut params);
    let mut buf = StepBuffers::default();
    let mut ctx = M::Context::default();
    let start = Instant::now();
    let mut observing = std::time::Duration::ZERO;
    for step in 0..cfg.steps {
        if step % cfg.occupancy_interval.max(1) == 0 {
            let mut orng = Rng::stream(cfg.seed ^ 0x0CC, step as u64);
            occupancy.update(step, &mut orng, |pts, sigma| model.density(isa, &params, pts, sigma, &mut ctx));
        }
        // 1. Rays: uniform over all pixels of all views.
        let mut srng = Rng::stream(cfg.seed, step as u64);
        buf.rays.clear();
        buf.targets.clear();
        buf.backgrounds.clear();
        for _ in 0..cfg.rays_per_step {
            let v = &views[srng.below(views.len() as u64) as usize];
            let (w, h) = (v.intrinsics.width, v.intrinsics.height);
            let p = srng.below(w as u64 * h as u64) as u32;
            buf.rays.push(pixel_ray(&v.intrinsics, &v.pose, p % w, p / w));
            buf.targets.push(v.rgb[p as usize]);
            buf.backgrounds.push(match cfg.random_background {
                true => std::array::from_fn(|_| srng.uniform(0.0, 1.0)),
                false => cfg.background,
            });
        }
        // 2. March; drop the samples behind each ray's opaque point (T < 1e-4): a density-only
        //    pass finds them; compositing ignores them anyway, so the result is unchanged and
        //    the full forward/backward runs on the samples that matter (nerfacc's early stop).
        march_rays(&occupancy, &buf.rays, &mut buf.marched, &mut buf.marched_pos, &mut buf.marched_dirs);
        let marched = buf.marched.len();
        buf.sigma.resize(marched, 0.0);
        model.density(isa, &params, &buf.marched_pos, &mut buf.sigma, &mut ctx);
        keep_until_opaque(
            &buf.marched,
            &buf.marched_pos,
            &buf.marched_dirs,
            &buf.sigma,
            &mut buf.samples,
            &mut buf.positions,
            &mut buf.dirs,
        );
        // 3. Forward: activated density and colour per sample.
        let n = buf.positions.len();
        buf.sigma.resize(n, 0.0);
        buf.rgb.resize(n, [0.0; 3]);
        model.forward(isa, &params, &buf.positions, &buf.dirs, &mut buf.sigma, &mut buf.rgb, &mut ctx);
        // 4. Composite, loss, and back through compositing. Rays are processed in SLOTS fixed
        //    groups whose samples are contiguous, each group writing its own slices of the
        //    step buffers (no per-ray allocation).
        buf.d_sigma.resize(n, 0.0);
        buf.d_rgb.resize(n, [0.0; 3]);
        let scale = 2.0 / (3 * cfg.rays_per_step) as f32;
        let (samples, sigma, rgb, targets) = (&buf.samples, &buf.sigma, &buf.rgb, &buf.targets);
        let backgrounds = &buf.backgrounds;
        let groups = ray_groups(&samples.rays);
        let d_sigma_parts = split_at_bounds(&mut buf.d_sigma, &groups);
        let d_rgb_parts = split_at_bounds(&mut buf.d_rgb, &groups);
        let losses: Vec<f64> = groups
            .par_iter()
            .zip(d_sigma_parts)
            .zip(d_rgb_parts)
            .map(|((g, d_s), d_c)| {
                let mut loss = 0.0f64;
                let mut scratch = Vec::new();
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
                        backgrounds[ray],
                    );
                    let err: [f32; 3] = std::array::from_fn(|k| c.rgb[k] - targets[ray][k]);
                    loss += err.iter().map(|e| (e * e) as f64).sum::<f64>();
                    composite_ray_backward(
                        &sigma[r.clone()],
                        &samples.delta[r.clone()],
                        &rgb[r.clone()],
                        &c,
                        err.map(|e| e * scale),
                        &mut d_s[local.clone()],
                        &mut d_c[local.clone()],
                    );
                    if cfg.distortion > 0.0 {
                        distortion_backward(
                            &sigma[r.clone()],
                            &samples.delta[r.clone()],
                            &samples.t[r.clone()],
                            cfg.distortion / cfg.rays_per_step as f32,
                            &mut d_s[local.clone()],
                            &mut scratch,
                        );
                    }
                    if cfg.near_gradient_distance > 0.0 {
                        let (ds, dc) = (&mut d_s[local.clone()], &mut d_c[local]);
                        scale_near_gradients(&samples.t[r], cfg.near_gradient_distance, ds, dc);
                    }
                }
                loss
            })
            .collect();
        let loss: f64 = losses.iter().sum();
        // 5. Backward through the model, 6. Adam on every parameter group.
        model.backward(isa, &params, &mut ctx, &buf.d_sigma, &buf.d_rgb, &mut grads);
        let lr = cfg.schedule.lr(step);
        for (adam, g) in adams.iter_mut().zip(model.groups(&mut params, &grads)) {
            adam.step(isa, lr, g.master, g.grad, g.mirror);
        }
        model.after_step(&mut params);
        if log_every > 0 && ((step + 1) % log_every == 0 || step + 1 == cfg.steps) {
            let stats = StepStats {
                step,
                loss: (loss / (3 * cfg.rays_per_step) as f64) as f32,
                samples_per_ray: n as f32 / cfg.rays_per_step as f32,
                marched_per_ray: marched as f32 / cfg.rays_per_step as f32,
                seconds: (start.elapsed() - observing).as_secs_f64(),
                occupancy: occupancy.occupancy(),
            };
            let t = Instant::now();
            observe(stats, &params, &occupancy);
            observing += t.elapsed();
        }
    }
    rayon::broadcast(|ctx| crate::simd::fpmode::restore(modes[ctx.index()]));
    crate::simd::fpmode::restore(main_mode);
    (params, occupancy)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn near_gradients_scale_quadratically_up_to_the_distance() {
        let t = [0.05, 0.1, 0.2, 0.5];
        let mut ds = [1.0, 2.0, 1.0, 1.0];
        let mut dc = [[1.0; 3], [1.0; 3], [-2.0; 3], [1.0; 3]];
        scale_near_gradients(&t, 0.2, &mut ds, &mut dc);
        assert_eq!(ds, [0.0625, 0.5, 1.0, 1.0]);
        assert_eq!(dc, [[0.0625; 3], [0.25; 3], [-2.0; 3], [1.0; 3]]);
    }
}
