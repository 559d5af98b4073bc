//! Rendering whole views of a trained [`Nerf`] into caller buffers, with a reusable
//! [`ViewRenderer`] (no allocation per frame once its buffers have grown).
//!
//! A view is cut into tiles of whole rows, each marched and evaluated by one thread start to
//! finish. Rays are marched in **segments** so work stops where the answer is known:
//! - [`ViewRenderer::depth`] — threshold depth only: evaluates only σ (the density networks'
//!   first outputs, [`Model::chunk_density_only`], a chunk at a time on the worker's thread)
//!   and stops each ray at its first solid sample (the robot's hot path), 2 samples per round;
//!   with a coarse start ([`ViewRenderer::set_coarse_start`], the onboard default) in passes,
//!   every other row and column first (every 4th or 8th on finer views, so that the first
//!   pass's pixels lie within [`COARSE_SPACING`] of each other), then each further pass's rays
//!   started just before the depth their neighbours found;
//! - [`ViewRenderer::full`] — colour, expected depth and threshold depth (and β): the training
//!   step's chunk path a chunk at a time on the worker's thread — σ of every marched sample,
//!   colour and β only of the samples a ray composites (before it turns opaque, `T < 1e-4`, as
//!   in training) — each ray stopped once it is opaque and its threshold hit found; segments
//!   of 16 samples doubling to 128.
//!
//! Outputs are **z-depth** (distance along the camera's viewing axis, in the dataset's unit —
//! metres for ours), row-major from the top-left, NaN for a hole (no solid sample). Segmented
//! marching visits exactly the samples of one-shot marching, so results equal compositing the
//! whole ray (tested).

use super::composite::{transmitted, RayAccumulator, EARLY_STOP_TRANSMITTANCE};
use super::depth::{DensityThreshold, DepthMethod};
use super::{pixel_ray, Intrinsics, OccupancyGrid, Pose, Ray, RaySpan};
use crate::field::model::Model;
use crate::field::residual::{ResidualField, ResidualModel};
use crate::field::{Nerf, NerfField};
use crate::simd::Isa;
use glam::Vec3;
use rayon::prelude::*;
use std::sync::Mutex;

/// Pixels per tile: the rays one worker marches together (rounded to whole image rows). Small
/// enough that a round's encodings and activations stay in L2, large enough to batch the MLP.
const TILE_PIXELS: usize = 1024;
/// Samples per ray per round of the depth-only path. Rays stop at their first solid sample,
/// and every sample a round marches past it is evaluated for nothing: at the onboard solid
/// fraction a dev table-top ray's hit is its 4th–5th marched sample, so 4 per round evaluated
/// 6.6 samples a ray and 2 evaluate 5.2 (docs/DECISIONS.md, "Depth-only rounds of two
/// samples"); a tile keeps the batch large.
pub const DEPTH_SEGMENT: usize = 2;
/// Samples per evaluation on a worker's thread (both paths): encodings and activations of this
/// many stay in L1/L2.
const CHUNK: usize = 256;
/// The widest angle (radians) between neighbouring pixels of a coarse start's first pass
/// ([`ViewRenderer::set_coarse_spacing`]): two pixels of the dev cameras (focal length 277.8 px,
/// 3.6 mrad a pixel), the spacing the coarse start was scored at against the ground truth. A
/// 200×200 dev view renders in two passes (every other row and column first); the same cameras
/// at 640×480 (1.1 mrad a pixel) in three (every fourth, then every other, then the rest). What
/// a coarse start can miss is a solid narrower than this angle in front of all its neighbours'
/// surfaces (3.6 mm at 0.5 m), whatever the camera's resolution (docs/DECISIONS.md, "The
/// robot's depth in passes").
pub const COARSE_SPACING: f32 = 2.0 / 277.8;
/// First segment length of the full path; doubles per round up to [`MAX_SEGMENT`].
const FIRST_SEGMENT: usize = 16;
const MAX_SEGMENT: usize = 128;
/// The most lattice steps one sample of the colour tail stands for
/// ([`ViewRenderer::set_colour_tail`]).
pub const COLOUR_TAIL_MAX_STRIDE: u32 = 16;
/// The colour tail's reach of `rnerf eval` and `rnerf render` (`--colour-tail`): on the dev
/// models their colour pass takes 0.43–0.62× the time at 0.4 and its PSNR moves by 0.008–0.013
/// dB (docs/DECISIONS.md, "The colour tail").
pub const COLOUR_TAIL: f32 = 0.4;

/// The colour tail a colour pass takes when none is asked for: [`COLOUR_TAIL`] with threshold
/// depth, 0 (every step) with expected depth, whose depth comes from that pass. `rnerf eval`,
/// `rnerf render` and the onboard [`crate::onboard::DepthRenderer`] all default to it.
pub fn default_colour_tail(depth: DepthMethod) -> f32 {
    match depth {
        DepthMethod::Threshold(_) => COLOUR_TAIL,
        DepthMethod::Expected => 0.0,
    }
}

/// A view's camera, pose and depth threshold.
type View<'a> = (&'a Intrinsics, &'a Pose, DensityThreshold);

/// Per-ray marching state.
#[derive(Clone, Copy)]
struct RayState {
    ray: Ray,
    span: RaySpan,
    /// Next lattice step to march.
    next: u32,
    taken: u32,
    hit: Option<f32>,
    /// Transmittance after the samples evaluated so far (the full path's opaque test: the
    /// product of the same factors the accumulator takes, ahead of their colours).
    transmittance: f32,
    acc: RayAccumulator,
}

/// Caller buffers of [`ViewRenderer::full`] (each `width × height`, or empty to skip it).
pub struct FullOutputs<'a> {
    /// Composited colour.
    pub rgb: &'a mut [[f32; 3]],
    /// Expected depth `Σ w t` as z (paper Eq. 3; never a hole).
    pub expected_z: &'a mut [f32],
    /// Threshold depth as z, NaN for holes.
    pub threshold_z: &'a mut [f32],
    /// β composited like a colour (`Σ w β`; residual models: where the scene changed).
    pub beta: &'a mut [f32],
}

impl<'a> FullOutputs<'a> {
    /// Splits off the first `len` pixels of every (non-empty) buffer.
    fn take_front(&mut self, len: usize) -> FullOutputs<'a> {
        fn front<'b, T>(buf: &mut &'b mut [T], len: usize) -> &'b mut [T] {
            if buf.is_empty() {
                return &mut [];
            }
            let (head, tail) = std::mem::take(buf).split_at_mut(len);
            *buf = tail;
            head
        }
        FullOutputs {
            rgb: front(&mut self.rgb, len),
            expected_z: front(&mut self.expected_z, len),
            threshold_z: front(&mut self.threshold_z, len),
            beta: front(&mut self.beta, len),
        }
    }
}

/// One worker's buffers: the rays of its current tile and the samples of one round.
struct Worker<M: Model> {
    states: Vec<RayState>,
    active: Vec<u32>,
    seg: Vec<(u32, u32)>,
    t: Vec<f32>,
    delta: Vec<f32>,
    positions: Vec<Vec3>,
    sigma: Vec<f32>,
    /// Of the current chunk of the full path: the composited rows, their directions, rays and
    /// transmitted shares (`e^{−σδ}`, computed once for the opaque test and the compositing),
    /// and their colours.
    keep: Vec<u32>,
    kept_dirs: Vec<Vec3>,
    kept_ray: Vec<u32>,
    kept_share: Vec<f32>,
    rgb: Vec<[f32; 3]>,
    beta_acc: Vec<f32>,
    /// The depth-only path's scratch and the full path's chunk, apart: one path's smaller
    /// buffers would otherwise drop the other's, and each frame after a switch would allocate.
    chunk: M::Chunk,
    full_chunk: M::Chunk,
}

impl<M: Model> Default for Worker<M> {
    fn default() -> Self {
        Worker {
            states: Vec::new(),
            active: Vec::new(),
            seg: Vec::new(),
            t: Vec::new(),
            delta: Vec::new(),
            positions: Vec::new(),
            sigma: Vec::new(),
            keep: Vec::new(),
            kept_dirs: Vec::new(),
            kept_ray: Vec::new(),
            kept_share: Vec::new(),
            rgb: Vec::new(),
            beta_acc: Vec::new(),
            chunk: M::Chunk::default(),
            full_chunk: M::Chunk::default(),
        }
    }
}

/// Reusable buffers for rendering views of a model `M` (a [`NerfField`] by default): one
/// worker per thread of the pool it runs on.
///
/// A view is cut into tiles of whole rows (`TILE_PIXELS`); each thread takes the next tile
/// and marches, evaluates and composites it on its own, so everything a round touches stays in
/// its core's cache. Tiles do not depend on the thread count, and neither do the results.
pub struct ViewRenderer<M: Model = NerfField> {
    workers: Vec<Worker<M>>,
    /// The pixels of the pass being rendered, in output order, and the z-depth each one's ray
    /// may start marching from (empty: every ray from the box; see [`ViewRenderer::set_coarse_start`]).
    pixels: Vec<u32>,
    starts: Vec<f32>,
    /// A pass's threshold depths in `pixels` order, before they are scattered to the view.
    pass_z: Vec<f32>,
    /// Lattice steps of slack before the start a coarse pass sets ([`ViewRenderer::set_coarse_start`]).
    coarse_margin: Option<u32>,
    /// The widest angle between the first pass's pixels ([`ViewRenderer::set_coarse_spacing`]).
    coarse_spacing: f32,
    /// Samples per ray per round of the depth-only path ([`ViewRenderer::set_depth_round`]).
    depth_round: usize,
    /// Transmittance below which a ray of the full path stops compositing
    /// ([`ViewRenderer::set_early_stop`]).
    stop: f32,
    /// What stands for the light a ray stopped early would still gather.
    fill: StopFill,
    /// The colour tail's reach, 0 for off ([`ViewRenderer::set_colour_tail`]).
    colour_tail: f32,
}

/// What stands for the light a ray of [`ViewRenderer::full`] would still gather after its early
/// stop ([`ViewRenderer::set_early_stop`]), `T` of its colour at most.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum StopFill {
    /// The background colour, as for a ray that leaves the scene: every channel within `T` of
    /// compositing the whole ray.
    #[default]
    Background,
    /// The colour the ray has gathered so far, `C / (1 − T)`: the rest of a thick, leaky surface
    /// taken to look like its front. Exact when the samples behind the stop share the colour of
    /// those before it (a surface of one colour), within `T ·` the spread of the ray's colours
    /// otherwise; for renders read against a tolerance (the background prior's).
    RayColour,
}

impl<M: Model> Default for ViewRenderer<M> {
    fn default() -> Self {
        ViewRenderer {
            workers: Vec::new(),
            pixels: Vec::new(),
            starts: Vec::new(),
            pass_z: Vec::new(),
            coarse_margin: None,
            coarse_spacing: COARSE_SPACING,
            depth_round: DEPTH_SEGMENT,
            stop: EARLY_STOP_TRANSMITTANCE,
            fill: StopFill::Background,
            colour_tail: 0.0,
        }
    }
}

/// What is rendered: a model, its parameters and its occupancy grid.
pub struct Scene<'a, M: Model> {
    /// The field.
    pub model: &'a M,
    /// Its parameters.
    pub params: &'a M::Params,
    /// Where it is worth sampling.
    pub occupancy: &'a OccupancyGrid,
}

impl<M: Model> Scene<'_, M> {
    /// The same model and parameters over `grid` instead of the scene's own grid (`None`: its
    /// own), e.g. one thinned by [`OccupancyGrid::keep_solid`].
    pub fn with_grid<'b>(&'b self, grid: Option<&'b OccupancyGrid>) -> Scene<'b, M> {
        Scene { model: self.model, params: self.params, occupancy: grid.unwrap_or(self.occupancy) }
    }
}

impl<'a> From<&'a Nerf> for Scene<'a, NerfField> {
    fn from(n: &'a Nerf) -> Self {
        Scene { model: &n.field, params: &n.params, occupancy: &n.occupancy }
    }
}

impl<'a> From<&'a ResidualModel> for Scene<'a, ResidualField> {
    fn from(m: &'a ResidualModel) -> Self {
        Scene { model: &m.field, params: &m.params, occupancy: &m.occupancy }
    }
}

impl<M: Model> ViewRenderer<M> {
    /// An empty renderer (buffers grow on first use).
    pub fn new() -> ViewRenderer<M> {
        ViewRenderer::default()
    }

    /// Samples each ray marches per round of [`ViewRenderer::depth`] (default
    /// [`DEPTH_SEGMENT`], at least 1). Only the speed depends on it: every round continues
    /// where the last stopped, so the depths are the same bits for any value (tested).
    pub fn set_depth_round(&mut self, samples: usize) {
        self.depth_round = samples.max(1);
    }

    /// Transmittance below which a ray of [`ViewRenderer::full`] stops compositing (default
    /// [`EARLY_STOP_TRANSMITTANCE`], 1e-4; clamped to `[1e-4, 0.5]`, NaN taken as the
    /// default). A ray stopped at transmittance `T` takes `fill` for the light it would still
    /// gather (at most `T` of its colour): with [`StopFill::Background`] every colour channel
    /// moves by less than `stop`; threshold depth is the same bits with either (tested). For
    /// renders read against a tolerance far above it (the background prior's change maps).
    pub fn set_early_stop(&mut self, stop: f32, fill: StopFill) {
        self.stop = if stop.is_nan() { EARLY_STOP_TRANSMITTANCE } else { stop.clamp(EARLY_STOP_TRANSMITTANCE, 0.5) };
        self.fill = fill;
    }

    /// The colour tail of [`ViewRenderer::full`] (`reach > 0`; default 0, off): once a ray has
    /// its threshold hit, each further round marches it with one sample for a run of up to
    /// `⌊reach / T⌋` occupied lattice steps ([`COLOUR_TAIL_MAX_STRIDE`] at most), `T` the ray's
    /// transmittance at the round's start, at the run's middle with `δ` the run's length
    /// ([`OccupancyGrid::march_segment`]; the pinned cells of a residual model's change region
    /// keep every step). A sample's colour weight is at most `T`, so the fewer, longer steps
    /// go where what is left of the ray can move its colour least: behind a leaky surface the
    /// ray's light is gathered from far fewer samples. Threshold depth is the same bits (the
    /// hit comes before the tail; tested); colour and expected depth move by the quadrature
    /// error of the merged steps. NaN or negative: off.
    pub fn set_colour_tail(&mut self, reach: f32) {
        self.colour_tail = if reach > 0.0 { reach } else { 0.0 };
    }

    /// `Some(margin)`: [`ViewRenderer::depth`] renders in passes. The first renders the pixels
    /// of even rows and columns (and the last row and column) as usual; the second starts each
    /// other pixel's ray `margin` lattice steps before the nearest threshold hit of the first
    /// pass's pixels around it (the two, or four, that enclose it), read as the same z-depth on
    /// its own ray, and marches from there; next to a first-pass hole it marches from the box.
    /// On views finer than [`ViewRenderer::set_coarse_spacing`]'s angle the first pass takes
    /// every 4th (8th, …) row and column, and each further pass halves the stride by the same
    /// rule. A pixel's depth is the same bits as without it whenever its ray
    /// has no solid sample before that start: everywhere on surfaces smooth at the scale of
    /// the first pass's spacing, since a pixel between two others on a plane lies between
    /// their depths. What it can miss is a solid narrower than that spacing standing in front
    /// of all of them (a wire or an edge-on sheet along a row or column the first pass skips). The rays of the second pass skip the
    /// empty air and most of the occupied cell in front of their surface. `None` (the
    /// default): every ray marches from where it enters the box.
    pub fn set_coarse_start(&mut self, margin: Option<u32>) {
        self.coarse_margin = margin;
    }

    /// The widest angle (radians) between the pixels of a coarse start's first pass (default
    /// [`COARSE_SPACING`]): the first pass renders every `s`-th row and column, `s` the largest
    /// power of two whose `s` pixels span at most this angle at the image centre (2 at least),
    /// and each further pass halves `s`, starting its rays at the depth of the last passes'
    /// pixels that enclose them (the rule of [`ViewRenderer::set_coarse_start`] at each
    /// stride). 0: always two passes.
    pub fn set_coarse_spacing(&mut self, radians: f32) {
        self.coarse_spacing = if radians.is_nan() { COARSE_SPACING } else { radians.max(0.0) };
    }

    /// Threshold z-depth of every pixel into `z` (`width × height`), NaN for holes.
    pub fn depth(
        &mut self,
        isa: Isa,
        scene: &Scene<'_, M>,
        k: &Intrinsics,
        pose: &Pose,
        m: DensityThreshold,
        z: &mut [f32],
    ) {
        let n = (k.width * k.height) as usize;
        assert_eq!(z.len(), n, "render: depth buffer is not width × height");
        let Some(margin) = self.coarse_margin else {
            self.all_pixels(n);
            let out = FullOutputs { rgb: &mut [], expected_z: &mut [], threshold_z: z, beta: &mut [] };
            self.run(isa, scene, k, pose, [0.0; 3], m, false, 0.0, out);
            return;
        };
        let (w, h) = (k.width as usize, k.height as usize);
        // On the lattice of stride `s`: a multiple of s, or the last row or column (so every
        // pixel between two of its rows or columns has one on each side).
        let on = |i: usize, len: usize, s: usize| i.is_multiple_of(s) || i + 1 == len;
        let mut s = coarse_stride(k, self.coarse_spacing);
        self.pixels.clear();
        self.starts.clear();
        for y in (0..h).filter(|&y| on(y, h, s)) {
            self.pixels.extend((0..w).filter(|&x| on(x, w, s)).map(|x| (y * w + x) as u32));
        }
        self.pass(isa, scene, (k, pose, m), 0.0, z);
        let slack = margin as f32 * scene.occupancy.step_size();
        while s > 1 {
            // The pixels of the lattice of stride s / 2 not on that of s, each started at the
            // pixels of s that enclose it: its own row or column where that is on s, else the
            // ones half a stride either side (the last where that is past the edge).
            let half = s / 2;
            let around =
                |i: usize, len: usize| if on(i, len, s) { [i, i] } else { [i - half, (i + half).min(len - 1)] };
            self.pixels.clear();
            self.starts.clear();
            for y in (0..h).filter(|&y| on(y, h, half)) {
                for x in (0..w).filter(|&x| on(x, w, half) && !(on(x, w, s) && on(y, h, s))) {
                    // The nearest of their depths; a hole (NaN) among them counts as −∞: no
                    // bound, march from the box.
                    let zs = around(y, h).into_iter().flat_map(|yy| around(x, w).map(|xx| z[yy * w + xx]));
                    let near = zs.map(|d| if d.is_nan() { f32::NEG_INFINITY } else { d }).fold(f32::INFINITY, f32::min);
                    self.pixels.push((y * w + x) as u32);
                    self.starts.push(near);
                }
            }
            self.pass(isa, scene, (k, pose, m), slack, z);
            s = half;
        }
    }

    /// Renders the depth of `self.pixels` in the view `(k, pose)` at threshold `m` (starting at
    /// `self.starts`, `slack` before them) and writes each into its place in the view's `z`.
    fn pass(&mut self, isa: Isa, scene: &Scene<'_, M>, view: View<'_>, slack: f32, z: &mut [f32]) {
        let (k, pose, m) = view;
        let mut pass_z = std::mem::take(&mut self.pass_z);
        pass_z.resize(self.pixels.len(), 0.0);
        let out = FullOutputs { rgb: &mut [], expected_z: &mut [], threshold_z: &mut pass_z, beta: &mut [] };
        self.run(isa, scene, k, pose, [0.0; 3], m, false, slack, out);
        for (&p, &d) in self.pixels.iter().zip(&pass_z) {
            z[p as usize] = d;
        }
        self.pass_z = pass_z;
    }

    /// Every pixel of an `n`-pixel view in order, each ray marched from the box.
    fn all_pixels(&mut self, n: usize) {
        self.pixels.clear();
        self.pixels.extend(0..n as u32);
        self.starts.clear();
    }

    /// Colour (over `background`), expected and threshold z-depth of every pixel.
    pub fn full(
        &mut self,
        isa: Isa,
        scene: &Scene<'_, M>,
        k: &Intrinsics,
        pose: &Pose,
        background: [f32; 3],
        m: DensityThreshold,
        out: FullOutputs<'_>,
    ) {
        let n = (k.width * k.height) as usize;
        for (len, what) in [
            (out.rgb.len(), "rgb"),
            (out.expected_z.len(), "expected"),
            (out.threshold_z.len(), "threshold"),
            (out.beta.len(), "beta"),
        ] {
            assert!(len == n || len == 0, "render: {what} buffer is not width × height");
        }
        self.all_pixels(n);
        self.run(isa, scene, k, pose, background, m, true, 0.0, out);
    }

    /// Hands the tiles of `self.pixels` (outputs in their order) out to one worker per thread
    /// of the current rayon pool; a ray with a start in `self.starts` marches from `slack`
    /// before it.
    #[allow(clippy::too_many_arguments)]
    fn run(
        &mut self,
        isa: Isa,
        scene: &Scene<'_, M>,
        k: &Intrinsics,
        pose: &Pose,
        background: [f32; 3],
        m: DensityThreshold,
        full: bool,
        slack: f32,
        out: FullOutputs<'_>,
    ) {
        let n = self.pixels.len();
        let tile = (TILE_PIXELS / k.width as usize).max(1) * k.width as usize;
        let first = if full { FIRST_SEGMENT } else { self.depth_round };
        let compositing = (self.stop, self.fill, self.colour_tail);
        let threads = rayon::current_num_threads().clamp(1, n.div_ceil(tile).max(1));
        if self.workers.len() < threads {
            self.workers.resize_with(threads, Worker::default);
        }
        let queue = Mutex::new((0usize, out));
        let next_tile = || {
            let mut q = queue.lock().unwrap_or_else(|e| e.into_inner());
            let (start, rest) = &mut *q;
            let s = *start;
            let len = tile.min(n - s);
            *start += len;
            (len > 0).then(|| (s..s + len, rest.take_front(len)))
        };
        let (pixels, starts) = (&self.pixels, &self.starts);
        self.workers[..threads].par_iter_mut().for_each(|w| {
            while let Some((range, out)) = next_tile() {
                let start = (starts.len() == n).then(|| (&starts[range.clone()], slack));
                w.run_tile(isa, scene, k, pose, &pixels[range], start, m, full, first, compositing, background, out);
            }
        });
    }
}

/// The stride of a coarse start's first pass over the view `k` ([`ViewRenderer::set_coarse_spacing`]):
/// the largest power of two, at least 2 and below the image's longer side, whose pixels span at
/// most `spacing` radians at the image centre.
pub fn coarse_stride(k: &Intrinsics, spacing: f32) -> usize {
    let pixel = 1.0 / k.fx.min(k.fy);
    let longest = k.width.max(k.height) as usize;
    let mut s = 2;
    while 2 * s < longest && (2 * s) as f32 * pixel <= spacing {
        s *= 2;
    }
    s
}

impl<M: Model> Worker<M> {
    /// Marches and evaluates pixels `pixels` to completion and writes their outputs; `first`
    /// samples per ray in the first round (the full path doubles it each round). With
    /// `start = (z, slack)` a pixel's ray marches from the lattice step before `slack` ahead
    /// of where it reaches z-depth `z[i]` (from the box where that is −∞ or before it).
    #[allow(clippy::too_many_arguments)]
    fn run_tile(
        &mut self,
        isa: Isa,
        scene: &Scene<'_, M>,
        k: &Intrinsics,
        pose: &Pose,
        pixels: &[u32],
        start: Option<(&[f32], f32)>,
        m: DensityThreshold,
        full: bool,
        first: usize,
        (stop, fill, tail): (f32, StopFill, f32),
        background: [f32; 3],
        out: FullOutputs<'_>,
    ) {
        let occ = scene.occupancy;
        let max_samples = occ.config().max_samples;
        let min_sigma = m.min_sigma();
        self.states.clear();
        self.active.clear();
        self.beta_acc.clear();
        self.beta_acc.resize(pixels.len(), 0.0);
        let dt = occ.step_size();
        for (i, &p) in pixels.iter().enumerate() {
            let ray = pixel_ray(k, pose, p % k.width, p / k.width);
            let span = occ.span(ray.origin, ray.dir).unwrap_or(RaySpan::EMPTY);
            // The lattice step whose sample lies `slack` before the start, if that is inside
            // the span; marching from it visits the same samples as from the box, less those
            // before it.
            let next = start.map_or(0, |(z, slack)| {
                let from = (ray.z_to_range(z[i]) - slack - span.near) / dt;
                if from > 0.0 {
                    (from.floor() as u32).min(span.steps)
                } else {
                    0
                }
            });
            if next < span.steps {
                self.active.push(self.states.len() as u32);
            }
            self.states.push(RayState {
                ray,
                span,
                next,
                taken: 0,
                hit: None,
                transmittance: 1.0,
                acc: RayAccumulator::new(),
            });
        }
        let mut segment = first;
        while !self.active.is_empty() {
            self.seg.clear();
            self.t.clear();
            self.delta.clear();
            self.positions.clear();
            for &r in &self.active {
                let s = &mut self.states[r as usize];
                let start = self.t.len();
                let room = segment.min(max_samples.saturating_sub(s.taken) as usize);
                let (o, d) = (s.ray.origin, s.ray.dir);
                let stride = match s.hit {
                    Some(_) if full && tail > 0.0 => ((tail / s.transmittance) as u32).clamp(1, COLOUR_TAIL_MAX_STRIDE),
                    _ => 1,
                };
                s.next =
                    occ.march_segment(o, d, s.span, s.next..s.span.steps, room, stride, &mut self.t, &mut self.delta);
                let count = self.t.len() - start;
                s.taken += count as u32;
                self.seg.push((start as u32, count as u32));
                for &t in &self.t[start..] {
                    self.positions.push(s.ray.at(t));
                }
            }
            let n = self.t.len();
            self.sigma.resize(n, 0.0);
            if full {
                self.composite_round(isa, scene, min_sigma, stop);
            } else {
                // On this thread, a chunk at a time, density networks' first outputs only.
                for (p, s) in self.positions.chunks(CHUNK).zip(self.sigma.chunks_mut(CHUNK)) {
                    scene.model.chunk_density_only(isa, scene.params, p, Some(min_sigma), s, &mut self.chunk);
                }
            }
            let (states, t, sigma, seg) = (&mut self.states, &self.t, &self.sigma, &self.seg);
            let mut i = 0;
            self.active.retain(|&r| {
                let s = &mut states[r as usize];
                let (start, count) = seg[i];
                i += 1;
                if !full && s.hit.is_none() {
                    // The full path found its hits while compositing.
                    let j = (start as usize..(start + count) as usize).find(|&j| sigma[j] >= min_sigma);
                    s.hit = j.map(|j| t[j]);
                }
                let finished = if full { s.transmittance < stop && s.hit.is_some() } else { s.hit.is_some() };
                let exhausted = s.next >= s.span.steps || s.taken >= max_samples || count == 0;
                !(finished || exhausted)
            });
            if full {
                segment = (segment * 2).min(MAX_SEGMENT);
            }
        }
        for (i, s) in self.states.iter().enumerate() {
            if !out.threshold_z.is_empty() {
                out.threshold_z[i] = s.hit.map_or(f32::NAN, |t| s.ray.range_to_z(t));
            }
            if !full {
                continue;
            }
            let c = match fill {
                // Stopped early: the light still to come looks like the light so far.
                StopFill::RayColour if s.transmittance < stop => {
                    let mut c = s.acc.finish([0.0; 3]);
                    let gathered = 1.0 - c.transmittance;
                    c.rgb = c.rgb.map(|v| v / gathered);
                    c
                }
                _ => s.acc.finish(background),
            };
            if !out.rgb.is_empty() {
                out.rgb[i] = c.rgb;
            }
            if !out.expected_z.is_empty() {
                out.expected_z[i] = s.ray.range_to_z(c.depth);
            }
            if !out.beta.is_empty() {
                out.beta[i] = self.beta_acc[i];
            }
        }
    }
}

impl<M: Model> Worker<M> {
    /// The full path's work on one round's samples, [`CHUNK`] at a time on this thread (the
    /// training step's chunk path): σ of every sample, the threshold hit, and colour (and β)
    /// only of the samples a ray composites — those before it turns opaque (`T < 1e-4`); the
    /// samples a segment marched past that point cost their density alone. The opaque point
    /// is found from σ alone (each ray's `transmittance` multiplies the factors the accumulator
    /// then takes), so the composited samples are those of compositing the whole ray.
    fn composite_round(&mut self, isa: Isa, scene: &Scene<'_, M>, min_sigma: f32, stop: f32) {
        let n = self.t.len();
        // The round's samples, ray after ray: the ray (index into `states`) of each.
        let mut owner =
            self.active.iter().zip(&self.seg).flat_map(|(&r, &(_, count))| std::iter::repeat_n(r, count as usize));
        let mut from = 0;
        while from < n {
            let to = (from + CHUNK).min(n);
            let chunk = &mut self.full_chunk;
            scene.model.chunk_density(
                isa,
                scene.params,
                0,
                &self.positions[from..to],
                &mut self.sigma[from..to],
                chunk,
            );
            self.keep.clear();
            self.kept_dirs.clear();
            self.kept_ray.clear();
            self.kept_share.clear();
            for j in from..to {
                let r = owner.next().expect("every sample belongs to a ray");
                let s = &mut self.states[r as usize];
                let sigma = self.sigma[j];
                if s.hit.is_none() && sigma >= min_sigma {
                    s.hit = Some(self.t[j]);
                }
                let opaque = s.transmittance < stop;
                if !opaque {
                    let share = transmitted(sigma, self.delta[j]);
                    s.transmittance *= share;
                    self.keep.push((j - from) as u32);
                    self.kept_dirs.push(s.ray.dir);
                    self.kept_ray.push(r);
                    self.kept_share.push(share);
                }
            }
            let k = self.keep.len();
            self.rgb.resize(k, [0.0; 3]);
            if k > 0 {
                scene.model.chunk_colour(isa, scene.params, &self.keep, &self.kept_dirs, &mut self.rgb, chunk);
            }
            let beta = scene.model.chunk_beta(chunk).map(|(b, _)| b);
            for (i, (&row, &r)) in self.keep.iter().zip(&self.kept_ray).enumerate() {
                let s = &mut self.states[r as usize];
                let w = s.acc.push_kept(self.kept_share[i], self.t[from + row as usize], self.rgb[i]);
                if let Some(b) = beta {
                    self.beta_acc[r as usize] += w * b[i];
                }
            }
            from = to;
        }
    }
}

/// A rendered view (allocating convenience over [`ViewRenderer::full`]).
#[derive(Clone, Debug)]
pub struct RenderedView {
    /// Colour per pixel.
    pub rgb: Vec<[f32; 3]>,
    /// Expected z-depth per pixel.
    pub expected_z: Vec<f32>,
    /// Threshold z-depth per pixel, NaN for holes.
    pub threshold_z: Vec<f32>,
    /// β per pixel (zero for a plain NeRF).
    pub beta: Vec<f32>,
}

impl Nerf {
    /// Renders colour, expected and threshold z-depth of one view (allocates; for repeated
    /// rendering keep a [`ViewRenderer`]).
    pub fn render(
        &self,
        isa: Isa,
        k: &Intrinsics,
        pose: &Pose,
        background: [f32; 3],
        m: DensityThreshold,
    ) -> RenderedView {
        render_view(isa, &Scene::from(self), k, pose, background, m)
    }
}

/// Renders colour, expected and threshold z-depth and β of one view of `scene` (allocates).
pub fn render_view<M: Model>(
    isa: Isa,
    scene: &Scene<'_, M>,
    k: &Intrinsics,
    pose: &Pose,
    background: [f32; 3],
    m: DensityThreshold,
) -> RenderedView {
    ViewRenderer::<M>::new().render(isa, scene, k, pose, background, m)
}

impl<M: Model> ViewRenderer<M> {
    /// [`ViewRenderer::full`] into newly allocated images (the renderer's buffers are reused).
    pub fn render(
        &mut self,
        isa: Isa,
        scene: &Scene<'_, M>,
        k: &Intrinsics,
        pose: &Pose,
        background: [f32; 3],
        m: DensityThreshold,
    ) -> RenderedView {
        let n = (k.width * k.height) as usize;
        let mut v = RenderedView {
            rgb: vec![[0.0; 3]; n],
            expected_z: vec![0.0; n],
            threshold_z: vec![0.0; n],
            beta: vec![0.0; n],
        };
        let out = FullOutputs {
            rgb: &mut v.rgb,
            expected_z: &mut v.expected_z,
            threshold_z: &mut v.threshold_z,
            beta: &mut v.beta,
        };
        self.full(isa, scene, k, pose, background, m, out);
        v
    }
}
