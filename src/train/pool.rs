//! The ray pool of a residual model's scene phase ([`TrainConfig::ray_pool`]).
//!
//! Outside its change region a residual model is its frozen background, whatever its
//! parameters ([`FrozenOutside`]), and its occupancy grid is frozen there
//! ([`crate::geometry::OccupancyGrid::freeze_outside_pins`]) with the region's cells pinned
//! occupied: a training ray marches the same samples at every step, and those outside the
//! region have the same density and colour at every step. Evaluating them at every step is
//! most of a step's cost (the background runs on ~180 samples a ray, the residual and the Mixnet
//! on the few inside the region; docs/DECISIONS.md, "Where a residual step's time goes").
//!
//! So the trainer evaluates a ray's background once and draws it several times. A pooled ray
//! keeps, in order along it:
//! - each **run** of consecutive samples outside the region, composited into one unit: its
//!   transmittance `T_run` (stored as the density `−ln T_run` of a unit step) and its colour
//!   `C_run / (1 − T_run)`, so compositing the unit gives the run's light and transmittance
//!   (the same value as compositing its samples, up to rounding);
//! - each sample **inside** the region with its distance, step and the background's raw
//!   density and pre-sigmoid colour there (the mix needs them; the background is not
//!   evaluated again).
//!
//! A ray is kept up to the point where the transmittance of its runs alone is opaque
//! ([`crate::render::composite::is_opaque`]): the samples inside can only lower the
//! transmittance further, so compositing at any parameters stops before that point.
//!
//! Each step adds one **group**: its own rays of the focus pixels (the changed pixels, drawn
//! fresh and used by that step only) and `(rays_per_step − focus) / reuse` rays of the reach
//! pixels (the pixels whose ray crosses the region), drawn as the trainer draws them. The step
//! takes its group's focus rays and draws the rest uniformly from the reach rays of the groups
//! of the last [`POOL_STEPS`] steps; the first step starts with [`POOL_START_STEPS`] steps'
//! worth of reach rays. A reach ray is then drawn `reuse` times on average. Group `j`'s rays
//! come from `Rng::stream(seed ^ POOL_KEY, j)`, so the pool at step `s` is a function of the
//! seed and `s` alone: a run resumed from a checkpoint refills it and continues bit-exactly,
//! and the groups are filled in [`SLOTS`] fixed parts, the same bits on any thread count.
//!
//! Measured on the dev scenes it is off by default: a reused ray teaches less than a fresh one,
//! and at the same training time fewer fresh rays per step (`--rays 512`) give better depth
//! (docs/DECISIONS.md, "The ray pool").

use super::step::{march_in_segments, Flow, StepRays, RAY_SEGMENT};
use super::trainer::{draw_pixel, is_unchanged, ray_through, TrainConfig};
use crate::data::View;
use crate::field::model::FrozenOutside;
use crate::field::FieldChunk;
use crate::geometry::camera::Ray;
use crate::render::composite::{is_opaque, transmitted, RayAccumulator};
use crate::render::OccupancyGrid;
use crate::rng::Rng;
use crate::simd::Isa;
use crate::slots::{slot_range, SLOTS};
use glam::Vec3;
use rayon::prelude::*;

/// Steps a group of fresh rays stays in the pool.
pub const POOL_STEPS: u64 = 128;

/// Steps' worth of rays the pool holds at step 0.
pub const POOL_START_STEPS: u64 = 4;

/// Mixed into the seed of the pool's ray streams (apart from the steps' own streams).
const POOL_KEY: u64 = 0x9001_c0de;

/// One unit along a pooled ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Unit {
    /// Distance along the ray: the sample's, or the middle of a run.
    pub t: f32,
    /// The sample's step; 1 for a run.
    pub delta: f32,
    /// Inside: the background's raw density. A run: its density over a unit step, `−ln T_run`.
    pub s: f32,
    /// Inside: the background's pre-sigmoid colour. A run: its activated colour.
    pub c: [f32; 3],
    /// Whether this is a sample inside the region (else a run outside it).
    pub inside: bool,
}

/// A pooled ray: where it comes from, what it must see, and its units.
#[derive(Clone, Copy, Debug)]
pub(super) struct PooledRay {
    pub ray: Ray,
    pub target: [f32; 3],
    pub view: u32,
    pub pixel: u32,
    pub unchanged: bool,
    /// `(start, count)` of its units in its group.
    pub units: (u32, u32),
    /// Samples the grid let through up to its cut (for the step's statistics).
    pub marched: u32,
}

/// The rays one step added.
#[derive(Default)]
pub(super) struct Group {
    id: Option<u64>,
    /// Its first rays are this many fresh rays of the focus pixels.
    focus: usize,
    pub rays: Vec<PooledRay>,
    pub units: Vec<Unit>,
}

impl Group {
    /// The units of ray `i`.
    pub fn units_of(&self, i: usize) -> &[Unit] {
        let (s, n) = self.rays[i].units;
        &self.units[s as usize..(s + n) as usize]
    }
}

/// The pool: [`POOL_STEPS`] + the first step's groups at most, group `j` in slot `j mod` that.
pub(super) struct RayPool {
    /// Fresh rays of the focus pixels in each step's group (drawn by that step only).
    focus: usize,
    /// Rays of the reach pixels in each group (drawn from the pool).
    reach: usize,
    start_groups: u64,
    groups: Vec<Group>,
    fillers: Vec<Filler>,
}

impl RayPool {
    /// A pool for steps of `rays_per_step` rays, the first `focused` of them from the focus
    /// pixels (always fresh), each of the rest drawn `reuse` times on average.
    pub fn new(rays_per_step: usize, focused: usize, reuse: u32) -> RayPool {
        let rest = rays_per_step.saturating_sub(focused);
        let reach = (rest / reuse.max(1) as usize).max(1);
        let start_groups = (POOL_START_STEPS as usize * rest).div_ceil(reach) as u64;
        let slots = (POOL_STEPS + start_groups) as usize;
        RayPool {
            focus: focused.min(rays_per_step),
            reach,
            start_groups,
            groups: (0..slots).map(|_| Group::default()).collect(),
            fillers: (0..SLOTS).map(|_| Filler::default()).collect(),
        }
    }

    /// The ids of the groups in the pool at `step` (the last one is `step`'s own).
    fn window(&self, step: u32) -> std::ops::Range<u64> {
        let hi = self.start_groups + step as u64 + 1;
        hi.saturating_sub(self.groups.len() as u64)..hi
    }

    /// Fills every group of `step`'s window that is not in the pool yet (at a fresh start the
    /// first groups, at a resumed one all of them, else the step's new group).
    pub fn refresh<P, C>(&mut self, step: u32, x: &PoolInputs<P, C>) {
        let n = self.groups.len() as u64;
        for id in self.window(step) {
            let slot = (id % n) as usize;
            if self.groups[slot].id != Some(id) {
                self.fill(slot, id, x);
            }
        }
    }

    /// `step`'s `count` rays into `rays` (cleared): its own group's focus rays, then the rest
    /// drawn uniformly from the reach rays of the window's groups; each with its pool index
    /// (`(group slot, ray)`), ray, target, view, pixel and β flag, and a colour behind it from
    /// `background` (called in ray order after the draws).
    pub fn take(
        &self,
        step: u32,
        count: usize,
        rng: &mut Rng,
        rays: &mut StepRays,
        mut background: impl FnMut(&mut Rng) -> [f32; 3],
    ) {
        let w = self.window(step);
        let n = self.groups.len() as u64;
        let own = ((w.end - 1) % n) as u32;
        let focus = self.groups[own as usize].focus;
        let total = (w.end - w.start) * self.reach as u64;
        rays.clear();
        rays.pooled.extend((0..focus.min(count) as u32).map(|i| (own, i)));
        rays.pooled.extend((0..count.saturating_sub(focus)).map(|_| {
            let u = rng.below(total);
            let slot = ((w.start + u / self.reach as u64) % n) as u32;
            (slot, (self.groups[slot as usize].focus as u64 + u % self.reach as u64) as u32)
        }));
        for &(g, k) in &rays.pooled {
            let r = &self.groups[g as usize].rays[k as usize];
            rays.rays.push(r.ray);
            rays.targets.push(r.target);
            rays.view.push(r.view);
            rays.pixel.push(r.pixel);
            rays.unchanged.push(r.unchanged);
            rays.backgrounds.push(background(rng));
            rays.behind.push([f32::NAN; 3]);
        }
    }

    /// Group slot `slot`.
    pub fn group(&self, slot: u32) -> &Group {
        &self.groups[slot as usize]
    }

    /// Draws group `id`'s rays (the focus rays of its step, none for the first step's extra
    /// groups, then the reach rays) and evaluates their background, in [`SLOTS`] parts.
    fn fill<P, C>(&mut self, slot: usize, id: u64, x: &PoolInputs<P, C>) {
        let mut rng = Rng::stream(x.cfg.seed ^ POOL_KEY, id);
        let focus = if id >= self.start_groups { self.focus } else { 0 };
        let f = focus + self.reach;
        let drawn: Vec<(u32, u32, Ray)> = (0..f)
            .map(|r| {
                let (v, p) = draw_pixel(x.views, x.cfg.focus.as_ref(), focus, 0, r, &mut rng, None);
                (v, p, ray_through(&x.views[v as usize], p, x.cfg.pixel_jitter, &mut rng))
            })
            .collect();
        self.fillers.par_iter_mut().enumerate().for_each(|(s, filler)| {
            filler.rays.clear();
            filler.units.clear();
            for &(v, p, ray) in &drawn[slot_range(f, s)] {
                filler.add(x, v, p, ray);
            }
        });
        let g = &mut self.groups[slot];
        g.rays.clear();
        g.units.clear();
        for filler in &self.fillers {
            let offset = g.units.len() as u32;
            g.rays.extend(filler.rays.iter().map(|r| PooledRay { units: (r.units.0 + offset, r.units.1), ..*r }));
            g.units.extend_from_slice(&filler.units);
        }
        g.focus = focus;
        g.id = Some(id);
    }
}

/// What filling a group reads.
pub(super) struct PoolInputs<'a, P, C> {
    pub isa: Isa,
    pub split: &'a dyn FrozenOutside<P, C>,
    pub occupancy: &'a OccupancyGrid,
    pub views: &'a [View],
    pub cfg: &'a TrainConfig,
    /// Per view, the bitset of the pixels the β penalty spares.
    pub changed: &'a [Vec<u64>],
}

/// One part's scratch and output while a group fills.
#[derive(Default)]
struct Filler {
    chunk: FieldChunk,
    t: Vec<f32>,
    delta: Vec<f32>,
    positions: Vec<Vec3>,
    raw: Vec<f32>,
    keep: Vec<u32>,
    /// Whether each kept sample is inside the region.
    inside: Vec<bool>,
    dirs: Vec<Vec3>,
    rgb_raw: Vec<[f32; 3]>,
    rays: Vec<PooledRay>,
    units: Vec<Unit>,
}

impl Filler {
    /// Marches `ray` (of view `v`, pixel `p`) as the step does ([`march_in_segments`]),
    /// evaluates the background's density on each segment and stops once the transmittance of
    /// the samples outside the region is opaque ([`is_opaque`]); then the background's colour
    /// of the kept samples, and the ray's units.
    fn add<P, C>(&mut self, x: &PoolInputs<P, C>, v: u32, p: u32, ray: Ray) {
        let split = x.split;
        let bg = split.frozen();
        for b in [&mut self.t, &mut self.delta, &mut self.raw] {
            b.clear();
        }
        self.positions.clear();
        self.keep.clear();
        self.inside.clear();
        let mut t_out = 1.0f32;
        let (positions, raw, keep, inside, chunk) =
            (&mut self.positions, &mut self.raw, &mut self.keep, &mut self.inside, &mut self.chunk);
        let (occ, stride) = (x.occupancy, x.cfg.frozen_stride);
        march_in_segments(occ, &ray, (stride, stride), RAY_SEGMENT, &mut self.t, &mut self.delta, |t, delta, seg| {
            positions.extend(t[seg.clone()].iter().map(|&t| ray.at(t)));
            raw.resize(seg.end, 0.0);
            bg.field.chunk_density(x.isa, &bg.params, seg.start, &positions[seg.clone()], &mut raw[seg.clone()], chunk);
            for i in seg {
                if is_opaque(t_out) {
                    break;
                }
                let is_in = split.is_inside(positions[i]);
                keep.push(i as u32);
                inside.push(is_in);
                if !is_in {
                    t_out *= transmitted(split.outside(raw[i], [0.0; 3]).0, delta[i]);
                }
            }
            if is_opaque(t_out) {
                Flow::Stop
            } else {
                Flow::Go
            }
        });
        let marched = self.t.len() as u32;
        let k = self.keep.len();
        self.rgb_raw.resize(k, [0.0; 3]);
        if k > 0 {
            bg.field.chunk_keep(&mut self.chunk, &self.keep);
            self.dirs.clear();
            self.dirs.resize(k, ray.dir);
            bg.field.chunk_colour(x.isa, &bg.params, &self.dirs, &mut self.rgb_raw, &mut self.chunk);
        }
        let start = self.units.len();
        let mut run: Option<(RayAccumulator, f32, f32)> = None;
        for (j, &i) in self.keep.iter().enumerate() {
            let i = i as usize;
            let (t, delta, s, c) = (self.t[i], self.delta[i], self.raw[i], self.rgb_raw[j]);
            if self.inside[j] {
                flush_run(run.take(), &mut self.units);
                self.units.push(Unit { t, delta, s, c, inside: true });
            } else {
                let (sigma, rgb) = split.outside(s, c);
                let r = run.get_or_insert((RayAccumulator::new(), t, t));
                r.0.push(sigma, delta, t, rgb);
                r.2 = t;
            }
        }
        flush_run(run, &mut self.units);
        self.rays.push(PooledRay {
            ray,
            target: x.views[v as usize].rgb[p as usize],
            view: v,
            pixel: p,
            unchanged: is_unchanged(x.changed, v, p),
            units: (start as u32, (self.units.len() - start) as u32),
            marched,
        });
    }
}

/// Appends a run of outside samples (its accumulator, first and last `t`) as one unit; a run
/// that lets all light through is dropped.
fn flush_run(run: Option<(RayAccumulator, f32, f32)>, units: &mut Vec<Unit>) {
    let Some((acc, t0, t1)) = run else { return };
    let r = acc.finish([0.0; 3]);
    let alpha = 1.0 - r.transmittance;
    if alpha <= 0.0 {
        return;
    }
    units.push(Unit {
        t: 0.5 * (t0 + t1),
        delta: 1.0,
        s: -r.transmittance.ln(),
        c: r.rgb.map(|c| c / alpha),
        inside: false,
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::encoding::HashGridConfig;
    use crate::field::mix::{DensityMix, MixKind};
    use crate::field::mixnet::MixnetEncoding;
    use crate::field::model::Model;
    use crate::field::residual::{ResidualConfig, ResidualField};
    use crate::field::{Nerf, NerfConfig, NerfField};
    use crate::geometry::ChangeRegion;
    use crate::render::OccupancyConfig;
    use crate::slots::SLOTS;
    use crate::train::prior::BackgroundColours;
    use crate::train::step::{StepInputs, Worker};
    use crate::train::trainer::Focus;
    use std::sync::Arc;

    /// A random background and residual over the tabletop scene, a change region of 4³ cells at
    /// its centre, β penalty on, and 128 rays drawn from a pool refreshed twice; `check` gets
    /// the step's inputs, the rays and a function running them (pooled for `None`, fresh with
    /// segments of `Some(n)` samples; with a configuration) to the step's loss, kept samples and
    /// gradients per group; and a function giving each ray's colour under the background
    /// alone (the frozen NeRF marched over the same samples to its opaque point, over the ray's
    /// background colour).
    #[allow(clippy::type_complexity)]
    fn frozen_outside_step(
        check: impl FnOnce(
            &StepRays,
            &dyn Fn(Option<usize>, &TrainConfig, &StepRays) -> (f64, usize, Vec<Vec<f32>>),
            &TrainConfig,
            &dyn Fn(&StepRays) -> Vec<[f32; 3]>,
        ),
    ) {
        let isa = Isa::detect();
        let scene = crate::data::synth::tabletop(24, 4, 0.0);
        let aabb = scene.aabb;
        let grid = HashGridConfig { levels: 6, log2_table_size: 10, base_resolution: 4, finest_resolution: 64 };
        let mut rng = Rng::new(3);
        let bg_field = NerfField::new(NerfConfig { grid, aabb });
        let mut bg_params = bg_field.init_params(&mut rng);
        bg_params.grid.master.iter_mut().for_each(|v| *v = rng.uniform(-1.0, 1.0));
        bg_params.grid.sync_mirror();
        let occ_cfg = OccupancyConfig { resolution: 8, steps_per_diagonal: 128, ..Default::default() };
        let bg_grid = OccupancyGrid::new(aabb, occ_cfg.clone());
        let bg = Nerf { field: bg_field, params: bg_params, occupancy: bg_grid.clone() };
        let cells: Vec<u32> =
            (2..6).flat_map(|z| (2..6).flat_map(move |y| (2..6).map(move |x| x + 8 * (y + 8 * z)))).collect();
        let region = ChangeRegion::from_cells(aabb, 8, &cells).unwrap();
        let config = ResidualConfig {
            residual: NerfConfig { grid, aabb },
            kind: MixKind::Mixnet(DensityMix::Raw),
            mixnet: MixnetEncoding::Shared,
        };
        let field = ResidualField::new(bg, config).with_region(region.clone());
        let mut params = field.init_params(&mut rng);
        params.residual.grid.master.iter_mut().for_each(|v| *v = rng.uniform(-1.0, 1.0));
        params.residual.grid.sync_mirror();
        let last = *field.mixnet().mlp().layers().last().unwrap();
        let w = params.mixnet.mlp.weights_mut();
        for k in 0..last.k_real {
            w[last.offset + k * last.o] = rng.uniform(-0.3, 0.3);
        }
        params.mixnet.mlp.sync();
        let mut occupancy = bg_grid;
        occupancy.pin(&region);
        occupancy.freeze_outside_pins();

        let views = &scene.views;
        let pixels: Vec<(u32, u32)> = (0..views.len() as u32).flat_map(|v| (0..24 * 24).map(move |p| (v, p))).collect();
        let mut cfg = TrainConfig::with_steps(10);
        cfg.rays_per_step = 128;
        cfg.occupancy = occ_cfg;
        // The frozen tail's coarse part off whatever its default; the tests that want it turn it on.
        cfg.frozen_coarse = 0.0;
        cfg.beta.unchanged = 0.5;
        cfg.focus = Some(Focus {
            share: 0.25,
            pixels: Arc::new(pixels.iter().copied().filter(|&(_, p)| p % 7 == 0).collect()),
            reach: Some(Arc::new(pixels)),
            spared: None,
        });
        let changed: Vec<Vec<u64>> = views.iter().map(|_| vec![0x5555_5555_5555_5555; 24 * 24 / 64 + 1]).collect();
        let split = field.frozen_outside().expect("a residual model with a region is frozen outside it");
        let mut pool = RayPool::new(cfg.rays_per_step, 32, 4);
        let x = PoolInputs { isa, split, occupancy: &occupancy, views, cfg: &cfg, changed: &changed };
        pool.refresh(0, &x);
        pool.refresh(1, &x);
        let mut rays = StepRays::default();
        pool.take(1, cfg.rays_per_step, &mut Rng::new(5), &mut rays, |_| [0.3, 0.5, 0.7]);
        assert!(rays.unchanged.iter().any(|&u| u) && rays.unchanged.iter().any(|&u| !u));
        let run = |fresh: Option<usize>, cfg: &TrainConfig, rays: &StepRays| {
            let inputs = StepInputs {
                isa,
                model: &field,
                params: &params,
                occupancy: &occupancy,
                cfg,
                entropy: 0.1,
                gains: &[],
                near_distance: 0.0,
            };
            let mut workers: Vec<Worker<_>> = (0..SLOTS).map(|_| Worker::default()).collect();
            workers.iter_mut().for_each(|w| w.segment = fresh.unwrap_or(RAY_SEGMENT));
            let mut slots: Vec<_> = (0..SLOTS).map(|_| Default::default()).collect();
            for (s, (w, slot)) in workers.iter_mut().zip(slots.iter_mut()).enumerate() {
                let range = crate::train::step::slot_rays(rays.rays.len(), cfg.rays_per_pixel(), s);
                match fresh {
                    None => w.run_pooled(&inputs, split, &pool, rays, range, slot),
                    Some(_) => w.run(&inputs, rays, range, slot),
                }
            }
            let mut grads = field.zero_grads();
            field.finish_step(isa, &slots, &mut grads);
            let loss: f64 = workers.iter().map(|w| w.loss).sum();
            let kept: usize = workers.iter().map(|w| w.n_kept).sum();
            let mut p = params.clone();
            let g: Vec<Vec<f32>> = field.groups(&mut p, &grads).iter().map(|g| g.grad.to_vec()).collect();
            (loss, kept, g)
        };
        let background_light = |rays: &StepRays| -> Vec<[f32; 3]> {
            let nerf = split.frozen();
            let mut chunk = Default::default();
            let (mut t, mut delta) = (Vec::new(), Vec::new());
            rays.rays
                .iter()
                .zip(&rays.backgrounds)
                .map(|(r, &bg)| {
                    t.clear();
                    delta.clear();
                    crate::train::step::march_in_segments(
                        &occupancy,
                        r,
                        (1, 1),
                        1 << 20,
                        &mut t,
                        &mut delta,
                        |_, _, _| crate::train::step::Flow::Go,
                    );
                    let positions: Vec<Vec3> = t.iter().map(|&t| r.at(t)).collect();
                    let mut sigma = vec![0.0; t.len()];
                    let mut rgb = vec![[0.0; 3]; t.len()];
                    if !t.is_empty() {
                        Model::chunk_density(&nerf.field, isa, &nerf.params, 0, &positions, &mut sigma, &mut chunk);
                        let keep: Vec<u32> = (0..t.len() as u32).collect();
                        let dirs = vec![r.dir; t.len()];
                        Model::chunk_colour(&nerf.field, isa, &nerf.params, &keep, &dirs, &mut rgb, &mut chunk);
                    }
                    crate::render::composite::composite_ray(&sigma, &delta, &t, &rgb, bg).rgb
                })
                .collect()
        };
        check(&rays, &run, &cfg, &background_light);
    }

    /// A pooled step's loss and gradients are those of marching the same rays fresh: the runs
    /// outside the region composited once and the background's values handed in change only
    /// the rounding.
    #[test]
    fn a_pooled_step_has_the_loss_and_gradients_of_the_same_rays_marched_fresh() {
        frozen_outside_step(|rays, run, cfg, _| {
            let (loss_p, kept_p, grads_p) = run(None, cfg, rays);
            let (loss_f, kept_f, grads_f) = run(Some(RAY_SEGMENT), cfg, rays);
            assert!(kept_p > 0 && kept_p < kept_f, "pooled rays run only their inside samples ({kept_p} of {kept_f})");
            assert!((loss_p - loss_f).abs() <= 1e-5 * loss_f, "loss {loss_p} pooled, {loss_f} fresh");
            for (i, (p, f)) in grads_p.iter().zip(&grads_f).enumerate() {
                let scale = f.iter().fold(0f32, |m, v| m.max(v.abs()));
                assert!(scale > 0.0 || i == 3, "group {i} has a gradient");
                for (j, (a, b)) in p.iter().zip(f).enumerate() {
                    assert!((a - b).abs() <= 1e-3 * scale, "group {i}[{j}]: pooled {a}, fresh {b} (scale {scale})");
                }
            }
        });
    }

    /// Per gradient group, an approximate step's gradient against the exact step's: the cosine
    /// between them and the relative error `|a − e| / |e|`; `None` for a group the exact step
    /// leaves without a gradient (the approximate step must leave it so too). `what` names
    /// the approximation in the messages.
    fn group_agreement(approx: &[Vec<f32>], exact: &[Vec<f32>], what: &str) -> Vec<Option<(f64, f64)>> {
        let dot = |a: &[f32], b: &[f32]| a.iter().zip(b).map(|(x, y)| *x as f64 * *y as f64).sum::<f64>();
        let groups = approx.iter().zip(exact).enumerate();
        groups
            .map(|(i, (a, e))| {
                let (aa, ee, ae) = (dot(a, a), dot(e, e), dot(a, e));
                if ee == 0.0 {
                    assert_eq!(aa, 0.0, "{what}: group {i} gains a gradient");
                    return None;
                }
                Some((ae / (aa * ee).sqrt(), ((aa - 2.0 * ae + ee) / ee).max(0.0).sqrt()))
            })
            .collect()
    }

    /// The frozen tail stops rays beyond the region early and perturbs the step by no more
    /// than the light it stops marching: the loss moves by less than τ of itself, the loss and
    /// every group's gradient come closer to the exact step as τ shrinks, and at τ = 0.1 each
    /// gradient keeps its direction; at τ = 0 the tail is off, bit for bit. (The random background here lets light through slowly,
    /// so the tail starts biting at τ ≈ 0.1; a trained one turns opaque within a few cells.)
    #[test]
    fn the_frozen_tail_stops_rays_past_the_region_and_keeps_the_gradients() {
        frozen_outside_step(|rays, run, cfg, _| {
            let exact = run(Some(RAY_SEGMENT), cfg, rays);
            let mut off = cfg.clone();
            off.frozen_tail = 0.0;
            assert_eq!(run(Some(RAY_SEGMENT), &off, rays), exact, "τ = 0 marches every ray to its opaque point");
            let (loss_f, kept_f, grads_f) = &exact;
            let mut last: Option<(usize, f64, Vec<f64>)> = None;
            for tau in [0.5f32, 0.3, 0.2, 0.1] {
                let mut tail = cfg.clone();
                tail.frozen_tail = tau;
                let (loss_t, kept_t, grads_t) = run(Some(RAY_SEGMENT), &tail, rays);
                assert!(kept_t < *kept_f, "τ = {tau} keeps fewer samples ({kept_t} of {kept_f})");
                let dl = (loss_t - loss_f).abs() / loss_f;
                assert!(dl < tau as f64, "τ = {tau}: loss {loss_t} with the tail, {loss_f} without");
                let mut errors = Vec::new();
                for (i, agreement) in group_agreement(&grads_t, grads_f, &format!("τ = {tau}")).into_iter().enumerate()
                {
                    let Some((cos, error)) = agreement else { continue };
                    assert!(tau > 0.1 || cos > 0.9, "τ = {tau}: group {i}'s gradient turns (cos {cos})");
                    errors.push(error);
                }
                if let Some((kept_l, dl_l, errors_l)) = &last {
                    assert!(kept_t >= *kept_l, "a smaller τ keeps more samples ({kept_t} < {kept_l})");
                    assert!(dl <= *dl_l, "a smaller τ comes closer to the exact loss ({dl} > {dl_l})");
                    for (e, l) in errors.iter().zip(errors_l) {
                        assert!(*e <= l * 1.01, "a smaller τ comes closer to the exact gradient ({e} > {l})");
                    }
                }
                last = Some((kept_t, dl, errors));
            }
        });
    }

    /// The photo tail is exact when the photo is the background's own light: with each ray's
    /// background image colour set to the background NeRF's render of that ray, stopping the
    /// rays where they leave the region and reading the light behind off that colour gives the
    /// loss and gradients of marching every ray to its opaque point (rounding apart), with
    /// fewer samples kept; without colours, or with the switch off, the step is the marched one
    /// bit for bit.
    #[test]
    fn the_photo_tail_reads_the_light_behind_off_the_background_image() {
        frozen_outside_step(|rays, run, cfg, background_light| {
            let mut exact_cfg = cfg.clone();
            exact_cfg.frozen_tail = 0.0;
            let exact = run(Some(RAY_SEGMENT), &exact_cfg, rays);
            let mut photo_cfg = exact_cfg.clone();
            photo_cfg.photo_tail = true;
            let mut with_photo = rays.clone();
            // Through 16-bit colours, as training holds them.
            let light = BackgroundColours::new(&[background_light(rays)]);
            with_photo.behind = (0..rays.rays.len()).map(|i| light.get(0, i)).collect();
            let (loss, kept, grads) = run(Some(RAY_SEGMENT), &photo_cfg, &with_photo);
            assert!(kept < exact.1, "the photo tail keeps fewer samples ({kept} of {})", exact.1);
            assert!((loss - exact.0).abs() < 1e-4 * exact.0, "loss {loss} with the photo tail, {} marched", exact.0);
            for (i, agreement) in group_agreement(&grads, &exact.2, "photo tail").into_iter().enumerate() {
                let Some((cos, error)) = agreement else { continue };
                assert!(cos > 0.9999 && error < 1e-2, "group {i}: cos {cos}, relative error {error}");
            }
            // Without background colours (or with the switch off) nothing changes, bit for bit.
            assert_eq!(run(Some(RAY_SEGMENT), &photo_cfg, rays), exact, "no photo: the step is the marched one");
            let mut off = exact_cfg.clone();
            off.photo_tail = false;
            assert_eq!(run(Some(RAY_SEGMENT), &off, &with_photo), exact, "switch off: the step is the marched one");
        });
    }

    /// The segment length is a cost, not a result: marching a ray in segments of 1, 7, 32 or
    /// 500 samples keeps the same samples, puts the same rays in each chunk (chunks close on
    /// kept samples) and gives the same loss and gradients bit for bit, with the frozen tail
    /// on (rays stop mid-segment) and off (rays run to their opaque point), and with the photo
    /// tail (rays stop before the first sample past the region's box, which is not evaluated).
    #[test]
    fn a_step_has_the_same_bits_whatever_the_segment_length() {
        frozen_outside_step(|plain, run, cfg, background_light| {
            let mut with_photo = plain.clone();
            let light = BackgroundColours::new(&[background_light(plain)]);
            with_photo.behind = (0..plain.rays.len()).map(|i| light.get(0, i)).collect();
            for (tau, coarse, photo) in
                [(0.0f32, 0.0f32, false), (0.3, 0.0, false), (0.05, 0.5, false), (0.0, 0.0, true)]
            {
                let mut c = cfg.clone();
                c.frozen_tail = tau;
                (c.frozen_coarse, c.frozen_coarse_stride) = (coarse, 4);
                c.photo_tail = photo;
                let rays = if photo { &with_photo } else { plain };
                let reference = run(Some(RAY_SEGMENT), &c, rays);
                assert!(reference.1 > 0 && reference.2.iter().any(|g| g.iter().any(|&v| v != 0.0)));
                if coarse > 0.0 {
                    let mut fine = c.clone();
                    fine.frozen_coarse = 0.0;
                    let kept_fine = run(Some(RAY_SEGMENT), &fine, rays).1;
                    assert!(reference.1 < kept_fine, "the coarse part bites ({} of {kept_fine} kept)", reference.1);
                }
                for segment in [1, 7, 500] {
                    let step = run(Some(segment), &c, rays);
                    assert!(
                        step == reference,
                        "τ = {tau}, coarse below {coarse}, photo tail {photo}: segments of {segment} change the step"
                    );
                }
            }
        });
    }

    /// The frozen tail's coarse part ([`TrainConfig::frozen_coarse`]): past the region, once a
    /// ray's transmittance is below T its frozen samples stand for N lattice steps each. It
    /// keeps fewer samples, more so at a larger T or N; at N = 1 it is off, bit for bit; it
    /// moves the loss by less than T of itself (the light still to come when it starts), and
    /// no group's gradient turns. (This random background lets light through slowly, so the
    /// coarse part covers much of each ray here.)
    #[test]
    fn the_frozen_tails_coarse_part_keeps_fewer_samples_and_moves_the_step_by_less_than_its_light() {
        frozen_outside_step(|rays, run, cfg, _| {
            let mut fine = cfg.clone();
            fine.frozen_tail = 0.01;
            let exact = run(Some(RAY_SEGMENT), &fine, rays);
            let with = |below: f32, stride: u32| {
                let mut c = fine.clone();
                (c.frozen_coarse, c.frozen_coarse_stride) = (below, stride);
                run(Some(RAY_SEGMENT), &c, rays)
            };
            assert!(with(0.5, 1) == exact, "a stride of 1 is every step");
            let (loss_f, kept_f, grads_f) = &exact;
            let mut kept = Vec::new();
            for (below, stride) in [(0.3f32, 2u32), (0.3, 4), (0.5, 4)] {
                let (loss_c, kept_c, grads_c) = with(below, stride);
                assert!(kept_c < *kept_f, "{below},{stride} keeps fewer samples ({kept_c} of {kept_f})");
                let dl = (loss_c - loss_f).abs() / loss_f;
                assert!(dl < below as f64, "{below},{stride}: loss {loss_c} coarse, {loss_f} fine");
                let what = format!("{below},{stride}");
                for (i, agreement) in group_agreement(&grads_c, grads_f, &what).into_iter().enumerate() {
                    let Some((cos, _)) = agreement else { continue };
                    assert!(cos > 0.9, "{what}: group {i}'s gradient turns (cos {cos})");
                }
                kept.push(kept_c);
            }
            assert!(kept[1] < kept[0] && kept[2] < kept[1], "a larger stride or T keeps fewer samples ({kept:?})");
        });
    }

    /// A pixel scored by the mean of its rays ([`TrainConfig::pixel_rays`]): three rays through
    /// the same point make the step of that one ray — the same loss per ray, and gradients
    /// whose thirds add up to the one ray's (rounding apart) — with the β terms on.
    #[test]
    fn a_pixel_of_three_identical_rays_makes_the_step_of_one() {
        frozen_outside_step(|rays, run, cfg, _| {
            let one = run(Some(RAY_SEGMENT), cfg, rays);
            let mut three = StepRays::default();
            for i in 0..rays.rays.len() {
                for _ in 0..3 {
                    three.rays.push(rays.rays[i]);
                    three.targets.push(rays.targets[i]);
                    three.backgrounds.push(rays.backgrounds[i]);
                    three.unchanged.push(rays.unchanged[i]);
                    three.view.push(rays.view[i]);
                    three.pixel.push(rays.pixel[i]);
                }
            }
            let mut c = cfg.clone();
            c.pixel_rays = 3;
            c.rays_per_step = 3 * cfg.rays_per_step;
            let (loss, kept, grads) = run(Some(RAY_SEGMENT), &c, &three);
            assert_eq!(kept, 3 * one.1);
            assert!((loss - 3.0 * one.0).abs() <= 1e-6 * loss, "loss {loss} against 3 × {}", one.0);
            for (i, (g, f)) in grads.iter().zip(&one.2).enumerate() {
                let scale = f.iter().fold(0f32, |m, v| m.max(v.abs()));
                for (j, (a, b)) in g.iter().zip(f).enumerate() {
                    assert!((a - b).abs() <= 1e-5 * scale, "group {i}[{j}]: three rays {a}, one {b} (scale {scale})");
                }
            }
        });
    }
}
