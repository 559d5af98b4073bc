//! Rendering whole views of a trained [`Nerf`] into caller buffers, with a reusable
//! [`ViewRenderer`] (no allocation per frame once its buffers have grown).
//!
//! Rays are marched in **segments** (16 samples, doubling to 128) so work stops where the
//! answer is known:
//! - [`ViewRenderer::depth`] — threshold depth only: evaluates only the density network and
//!   stops each ray at its first solid sample (the robot's hot path);
//! - [`ViewRenderer::full`] — colour, expected depth and threshold depth: the full field,
//!   each ray stopped once it is opaque (`T < 1e-4`, as in training) and its threshold hit found.
//!
//! Outputs are **z-depth** (distance along the camera's viewing axis, in the dataset's unit —
//! metres for ours), row-major from the top-left, NaN for a hole (no solid sample). Segmented
//! marching visits exactly the samples of one-shot marching, so results equal compositing the
//! whole ray (tested).

use super::composite::RayAccumulator;
use super::depth::DensityThreshold;
use super::occupancy::RaySpan;
use super::OccupancyGrid;
use super::{pixel_ray, Intrinsics, Pose, Ray};
use crate::field::{Nerf, NerfField};
use crate::simd::Isa;
use crate::train::model::Model;
use glam::Vec3;

/// Rays per chunk (bounds the sample buffers).
const CHUNK_RAYS: usize = 8192;
/// First segment length; doubles per round up to [`MAX_SEGMENT`].
const FIRST_SEGMENT: usize = 16;
const MAX_SEGMENT: usize = 128;

/// Per-ray marching state.
#[derive(Clone, Copy)]
struct RayState {
    ray: Ray,
    span: RaySpan,
    next_t: f32,
    taken: u32,
    hit: Option<f32>,
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

/// Reusable buffers for rendering views of a model `M` (a [`NerfField`] by default).
pub struct ViewRenderer<M: Model = NerfField> {
    states: Vec<RayState>,
    active: Vec<u32>,
    seg: Vec<(u32, u32)>,
    t: Vec<f32>,
    delta: Vec<f32>,
    positions: Vec<Vec3>,
    dirs: Vec<Vec3>,
    sigma: Vec<f32>,
    rgb: Vec<[f32; 3]>,
    beta: Vec<f32>,
    beta_acc: Vec<f32>,
    ctx: M::Context,
}

impl<M: Model> Default for ViewRenderer<M> {
    fn default() -> Self {
        ViewRenderer {
            states: Vec::new(),
            active: Vec::new(),
            seg: Vec::new(),
            t: Vec::new(),
            delta: Vec::new(),
            positions: Vec::new(),
            dirs: Vec::new(),
            sigma: Vec::new(),
            rgb: Vec::new(),
            beta: Vec::new(),
            beta_acc: Vec::new(),
            ctx: M::Context::default(),
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

impl<'a> From<&'a Nerf> for Scene<'a, NerfField> {
    fn from(n: &'a Nerf) -> Self {
        Scene { model: &n.field, params: &n.params, occupancy: &n.occupancy }
    }
}

impl<M: Model> ViewRenderer<M> {
    /// An empty renderer (buffers grow on first use).
    pub fn new() -> ViewRenderer<M> {
        ViewRenderer::default()
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
        for start in (0..n).step_by(CHUNK_RAYS) {
            let end = (start + CHUNK_RAYS).min(n);
            self.run_chunk(isa, scene, k, pose, start..end, m, false);
            for (o, s) in z[start..end].iter_mut().zip(&self.states) {
                *o = s.hit.map_or(f32::NAN, |t| s.ray.range_to_z(t));
            }
        }
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
        for start in (0..n).step_by(CHUNK_RAYS) {
            let end = (start + CHUNK_RAYS).min(n);
            self.run_chunk(isa, scene, k, pose, start..end, m, true);
            for (i, s) in self.states.iter().enumerate() {
                let p = start + i;
                let c = s.acc.finish(background);
                if !out.rgb.is_empty() {
                    out.rgb[p] = c.rgb;
                }
                if !out.expected_z.is_empty() {
                    out.expected_z[p] = s.ray.range_to_z(c.depth);
                }
                if !out.threshold_z.is_empty() {
                    out.threshold_z[p] = s.hit.map_or(f32::NAN, |t| s.ray.range_to_z(t));
                }
                if !out.beta.is_empty() {
                    out.beta[p] = self.beta_acc[i];
                }
            }
        }
    }

    /// Marches and evaluates pixels `pixels` to completion (`full`: colour too).
    #[allow(clippy::too_many_arguments)]
    fn run_chunk(
        &mut self,
        isa: Isa,
        scene: &Scene<'_, M>,
        k: &Intrinsics,
        pose: &Pose,
        pixels: std::ops::Range<usize>,
        m: DensityThreshold,
        full: bool,
    ) {
        let occ = scene.occupancy;
        let max_samples = occ.config().max_samples;
        let min_sigma = m.min_sigma();
        self.states.clear();
        self.active.clear();
        self.beta_acc.clear();
        self.beta_acc.resize(pixels.len(), 0.0);
        for p in pixels {
            let ray = pixel_ray(k, pose, p as u32 % k.width, p as u32 / k.width);
            let span = occ.span(ray.origin, ray.dir).unwrap_or(RaySpan { near: 0.0, far: 0.0 });
            if span.far > span.near {
                self.active.push(self.states.len() as u32);
            }
            self.states.push(RayState {
                ray,
                span,
                next_t: span.near,
                taken: 0,
                hit: None,
                acc: RayAccumulator::new(),
            });
        }
        let mut segment = FIRST_SEGMENT;
        while !self.active.is_empty() {
            self.seg.clear();
            self.t.clear();
            self.delta.clear();
            self.positions.clear();
            self.dirs.clear();
            for &r in &self.active {
                let s = &mut self.states[r as usize];
                let start = self.t.len();
                let room = segment.min((max_samples - s.taken) as usize);
                s.next_t =
                    occ.march_segment(s.ray.origin, s.ray.dir, s.span, s.next_t, room, &mut self.t, &mut self.delta);
                let count = self.t.len() - start;
                s.taken += count as u32;
                self.seg.push((start as u32, count as u32));
                for &t in &self.t[start..] {
                    self.positions.push(s.ray.at(t));
                    self.dirs.push(s.ray.dir);
                }
            }
            let n = self.t.len();
            self.sigma.resize(n, 0.0);
            if full && n > 0 {
                self.rgb.resize(n, [0.0; 3]);
                scene.model.forward(
                    isa,
                    scene.params,
                    &self.positions,
                    &self.dirs,
                    &mut self.sigma,
                    &mut self.rgb,
                    &mut self.ctx,
                );
                scene.model.betas(&self.ctx, &mut self.beta);
            } else if n > 0 {
                scene.model.density(isa, scene.params, &self.positions, &mut self.sigma, &mut self.ctx);
            }
            let states = &mut self.states;
            let beta_acc = &mut self.beta_acc;
            let (t, delta, sigma, rgb, beta, seg) =
                (&self.t, &self.delta, &self.sigma, &self.rgb, &self.beta, &self.seg);
            let mut i = 0;
            self.active.retain(|&r| {
                let s = &mut states[r as usize];
                let (start, count) = seg[i];
                i += 1;
                for j in start as usize..(start + count) as usize {
                    if s.hit.is_none() && sigma[j] >= min_sigma {
                        s.hit = Some(t[j]);
                    }
                    if !full {
                        if s.hit.is_some() {
                            break;
                        }
                    } else if !s.acc.is_opaque() {
                        let w = s.acc.push(sigma[j], delta[j], t[j], rgb[j]);
                        if !beta.is_empty() {
                            beta_acc[r as usize] += w * beta[j];
                        }
                    }
                }
                let finished = if full { s.acc.is_opaque() && s.hit.is_some() } else { s.hit.is_some() };
                let exhausted = s.next_t >= s.span.far || s.taken >= max_samples || count == 0;
                !(finished || exhausted)
            });
            segment = (segment * 2).min(MAX_SEGMENT);
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
