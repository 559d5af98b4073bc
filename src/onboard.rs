//! The robot-facing API: load a trained model once, then render depth — and, when asked,
//! colour and β — for any camera pose and intrinsics into the caller's buffers. After the
//! first frame of a given size nothing is allocated per frame; the thread count is the
//! caller's ([`DepthRenderer::with_threads`]); the depth convention is part of the request
//! ([`DepthKind`]: z or range, metres, NaN holes). Errors carry an [`ErrorKind`] to act on
//! (bad input, unsupported or corrupt model file, I/O) and a one-line message.
//!
//! ```no_run
//! use residual_nerf::onboard::{DepthKind, DepthMethod, DepthRenderer, DepthRequest};
//! use residual_nerf::render::{Intrinsics, Pose};
//!
//! let mut cam = DepthRenderer::load("workspace.safetensors".as_ref())?.with_threads(2)?;
//! let k = Intrinsics::from_fov_x(640, 480, 0.9);
//! let pose = Pose::look_at([0.0, -0.6, 0.5].into(), [0.0, 0.0, 0.05].into());
//! let mut depth = vec![0.0f32; 640 * 480];
//! let request = DepthRequest { method: DepthMethod::default(), kind: DepthKind::Z };
//! cam.depth(&k, &pose, request, &mut depth)?; // metres along the viewing axis, NaN = hole
//! # Ok::<(), residual_nerf::onboard::Error>(())
//! ```

use crate::field::residual::ResidualField;
use crate::field::NerfField;
use crate::io::{load_model, LoadedModel};
use crate::render::view::{default_colour_tail, Scene};
pub use crate::render::view::{COARSE_SPACING, COLOUR_TAIL};
use crate::render::{pixel_ray, Aabb, FullOutputs, Intrinsics, OccupancyGrid, Pose, ViewRenderer};
use crate::simd::Isa;
use std::path::Path;

pub use crate::error::{Error, ErrorKind};
pub use crate::render::{DensityThreshold, DepthKind, DepthMethod};

/// A depth request: method and convention.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct DepthRequest {
    /// How depth is read off a ray.
    pub method: DepthMethod,
    /// What the values measure.
    pub kind: DepthKind,
}

/// Optional outputs of [`DepthRenderer::render`] beside depth; each `width × height`.
#[derive(Default)]
pub struct Extras<'a> {
    /// Composited linear RGB in [0, 1], over [`DepthRenderer::background`].
    pub rgb: Option<&'a mut [[f32; 3]]>,
    /// β composited like a colour: where the scene differs from the background (0 for a
    /// plain NeRF).
    pub beta: Option<&'a mut [f32]>,
}

/// Threshold depth at σ ≥ m marches only over cells whose occupancy value showed at least
/// this fraction of m ([`OccupancyGrid::keep_solid`]) by default; see
/// [`DepthRenderer::solid_fraction`] for the trade. ½: on the seven dev models (background,
/// Dex-NeRF and Residual-NeRF on three scenes) it is 1.4–2.4× faster than ¼ and scores as well
/// against the ground truth — crop MAE lower on every model, object MAE within +7% / −16%
/// (`rnerf eval --depth-only --solid-fraction F`; docs/DECISIONS.md, "The onboard renderer's
/// solid fraction"). A residual model settles its change region's cell values at the end of
/// training, so a briefly trained one keeps its glass at ½; a plain NeRF trained far short of
/// the defaults has an under-sampled grid and loses surfaces at ½: render it with
/// `solid_fraction(0.25)` or `exact(true)`.
pub const SOLID_FRACTION: f32 = 0.5;

/// Threshold depth renders every other row and column first (every 4th or 8th on views finer
/// than the dev cameras', [`COARSE_SPACING`]) and starts the other rays this many lattice
/// steps before the nearest depth of those around them ([`ViewRenderer::set_coarse_start`]),
/// by default; see [`DepthRenderer::coarse_start`] for the trade. 1: the step of the lattice
/// (a neighbour's hit sample lies up to a step past its surface, and a pixel between its
/// neighbours on a plane or a concave surface lies no nearer than the nearest of them). On the
/// dev models a 200×200 view takes 0.52–0.77× the time of marching every ray from the box, and
/// 1.0–1.4% of its pixels move, each farther, where a solid thinner than two pixels (mostly a
/// speck of fog) or a bump of more than a step over one pixel stood in front of the surface;
/// the depth scores as well against the ground truth as marching from the box or a margin of 2
/// (docs/DECISIONS.md, "The robot's depth in passes"; `coarse_start(Some(2))` is the setting
/// with a step of slack). At 640×480 three passes take 0.71–0.87× the time of two.
pub const COARSE_MARGIN: u32 = 1;

/// A loaded model (plain NeRF or residual) and the reusable buffers to render it.
pub struct DepthRenderer {
    model: LoadedModel,
    nerf: ViewRenderer<NerfField>,
    residual: ViewRenderer<ResidualField>,
    pool: Option<rayon::ThreadPool>,
    isa: Isa,
    /// The occupancy grid thinned for the last threshold asked for, keyed by the solid
    /// fraction and the threshold's σ (built once per pair).
    solid: Option<((f32, f32), OccupancyGrid)>,
    solid_fraction: f32,
    /// The last intrinsics that passed [`Intrinsics::check`] (the lens's check is the costly
    /// part): a robot renders one camera frame after frame, so the check runs once per camera,
    /// not per frame.
    checked_camera: Option<Intrinsics>,
    /// The colour tail of the full pass; `None`: [`default_colour_tail`] of the request's
    /// depth method ([`DepthRenderer::colour_tail`]).
    colour_tail: Option<f32>,
    /// Colour behind the scene for [`Extras::rgb`]. Defaults to white.
    pub background: [f32; 3],
}

impl DepthRenderer {
    /// Loads a model file (either kind); errors name the file.
    pub fn load(path: &Path) -> Result<DepthRenderer, Error> {
        Ok(DepthRenderer::new(load_model(path)?))
    }

    /// Wraps a model already in memory. Renders on the global rayon pool at the best CPU
    /// level this machine has.
    pub fn new(model: LoadedModel) -> DepthRenderer {
        DepthRenderer {
            model,
            nerf: ViewRenderer::new(),
            residual: ViewRenderer::new(),
            pool: None,
            isa: Isa::detect(),
            solid: None,
            solid_fraction: SOLID_FRACTION,
            checked_camera: None,
            colour_tail: None,
            background: [1.0; 3],
        }
        .coarse_start(Some(COARSE_MARGIN))
    }

    /// `true`: threshold depth marches every occupied cell of every ray from where it enters
    /// the box, as training and evaluation do (the same bits as [`ViewRenderer::depth`];
    /// `solid_fraction(0.0)` and `coarse_start(None)`), and colour, β and expected depth take
    /// every lattice step (the colour tail off: the same bits as [`ViewRenderer::full`]);
    /// `false` (the default): `solid_fraction(SOLID_FRACTION)`,
    /// `coarse_start(Some(COARSE_MARGIN))` and the default colour tail.
    pub fn exact(mut self, exact: bool) -> DepthRenderer {
        let margin;
        (self.solid_fraction, margin, self.colour_tail) = match exact {
            true => (0.0, None, Some(0.0)),
            false => (SOLID_FRACTION, Some(COARSE_MARGIN), None),
        };
        self.coarse_start(margin)
    }

    /// The colour tail of a frame that asks for colour or β ([`Extras`]): behind a ray's
    /// threshold hit, one sample for a run of up to `⌊reach / T⌋` occupied lattice steps
    /// ([`ViewRenderer::set_colour_tail`]). Threshold depth is the same bits with or without
    /// it; colour moves by the quadrature error of the merged steps (on the dev models 0.003–
    /// 0.015 dB of PSNR at the default [`COLOUR_TAIL`], 0.49–0.74× the time of a 200×200
    /// colour frame; docs/DECISIONS.md, "The colour tail"). 0: every step. By default [`COLOUR_TAIL`] with
    /// threshold depth, and every step with expected depth, whose depth comes from the same
    /// pass; a value set here holds for both.
    pub fn colour_tail(mut self, reach: f32) -> Result<DepthRenderer, Error> {
        if !(reach.is_finite() && reach >= 0.0) {
            return Err(Error::bad_input(format!("colour tail {reach} is not a number >= 0")));
        }
        self.colour_tail = Some(reach);
        Ok(self)
    }

    /// `Some(margin)`: threshold depth renders the pixels of every other row and column
    /// first, then starts each other ray `margin` lattice steps before the nearest depth
    /// among the first pass's pixels around it ([`ViewRenderer::set_coarse_start`]); on a
    /// view whose pixels are finer than a quarter of [`COARSE_SPACING`] (640×480 through the dev
    /// cameras' lens) the first pass takes every 4th (8th, …) row and column and each
    /// further pass halves the stride by the same rule. Such a ray skips the air and most of the
    /// occupied cell in front of its surface; its depth is the same as marching from the box
    /// unless a solid stands before that start, which on a surface smooth over the first
    /// pass's spacing it cannot: what it misses is a solid narrower than that spacing (7.2
    /// mrad, 3.6 mm at 0.5 m) in front of all its neighbours' surfaces (a speck of fog, or a
    /// wire along a row or column the first pass skips; such a pixel reads the surface
    /// behind). `None`: every ray from the box. Default [`COARSE_MARGIN`]; colour, β and
    /// expected depth ignore it.
    pub fn coarse_start(mut self, margin: Option<u32>) -> DepthRenderer {
        self.nerf.set_coarse_start(margin);
        self.residual.set_coarse_start(margin);
        self
    }

    /// The widest angle (radians) between the pixels of the coarse start's first pass
    /// (default [`COARSE_SPACING`], 7.2 mrad; [`ViewRenderer::set_coarse_spacing`]): a solid
    /// narrower than it in front of all its neighbours can be missed. 0 keeps every other row
    /// and column at any resolution (what can be missed is then two pixels wide; a 640×480
    /// view through the dev cameras' lens took 1.15–1.41× the default's time that way,
    /// docs/DECISIONS.md, "The first pass's spacing"); NaN is the default.
    pub fn coarse_spacing(mut self, radians: f32) -> DepthRenderer {
        self.nerf.set_coarse_spacing(radians);
        self.residual.set_coarse_spacing(radians);
        self
    }

    /// Threshold depth at σ ≥ m skips the occupied cells whose occupancy value (the largest
    /// σ·δ training saw there) stayed below `fraction · m · δ`. 0 marches every occupied
    /// cell (exact); larger values are faster and miss more: a cell's value is a sampled
    /// estimate, so a surface inside a cell can be denser than training saw. Measured on the
    /// dev models in BENCHMARKS.md ("Depth rendering on trained models"); the default is [`SOLID_FRACTION`].
    pub fn solid_fraction(mut self, fraction: f32) -> Result<DepthRenderer, Error> {
        if !(fraction.is_finite() && fraction >= 0.0) {
            return Err(Error::bad_input(format!("solid fraction {fraction} is not a number >= 0")));
        }
        self.solid_fraction = fraction;
        Ok(self)
    }

    /// Renders on a pool of its own with `threads` threads (1 keeps all work on the calling
    /// thread's pool worker; results are the same bits for any count).
    pub fn with_threads(mut self, threads: usize) -> Result<DepthRenderer, Error> {
        if threads == 0 {
            return Err(Error::bad_input("threads: must be at least 1"));
        }
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(|i| format!("rnerf-render-{i}"))
            .build()
            .map_err(|e| Error::new(ErrorKind::Io, format!("threads: cannot start {threads} threads: {e}")))?;
        self.pool = Some(pool);
        Ok(self)
    }

    /// The model.
    pub fn model(&self) -> &LoadedModel {
        &self.model
    }

    /// The scene box (world frame, metres).
    pub fn scene_box(&self) -> Aabb {
        match &self.model {
            LoadedModel::Nerf(n) => n.field.config().aabb,
            LoadedModel::Residual(r) => r.field.residual().config().aabb,
        }
    }

    /// Depth of every pixel of the camera `k` at `pose` (camera-to-world, OpenGL camera) into
    /// `depth` (`width × height`, row-major from the top-left). Threshold depth evaluates only
    /// the density network and stops each ray at its first solid sample.
    pub fn depth(
        &mut self,
        k: &Intrinsics,
        pose: &Pose,
        request: DepthRequest,
        depth: &mut [f32],
    ) -> Result<(), Error> {
        self.render(k, pose, request, depth, Extras::default())
    }

    /// [`DepthRenderer::depth`] plus the `extras` asked for, from one pass over the field.
    pub fn render(
        &mut self,
        k: &Intrinsics,
        pose: &Pose,
        request: DepthRequest,
        depth: &mut [f32],
        extras: Extras<'_>,
    ) -> Result<(), Error> {
        let n = k.width as usize * k.height as usize;
        let sized = |len: usize, what: &str| match len == n {
            true => Ok(()),
            false => Err(Error::bad_input(format!(
                "{what} buffer holds {len} values, the camera has {}x{} = {n}",
                k.width, k.height
            ))),
        };
        sized(depth.len(), "depth")?;
        if let Some(rgb) = &extras.rgb {
            sized(rgb.len(), "rgb")?;
        }
        if let Some(beta) = &extras.beta {
            sized(beta.len(), "beta")?;
        }
        if self.checked_camera != Some(*k) {
            k.check().map_err(Error::bad_input)?;
            self.checked_camera = Some(*k);
        }
        pose.check().map_err(Error::bad_input)?;
        let (isa, background) = (self.isa, self.background);
        let depth_only = extras.rgb.is_none() && extras.beta.is_none();
        let fast = match request.method {
            DepthMethod::Threshold(m) if depth_only && self.solid_fraction > 0.0 => Some(m.min_sigma()),
            _ => None,
        };
        let fraction = self.solid_fraction;
        let tail = self.colour_tail.unwrap_or_else(|| default_colour_tail(request.method));
        self.nerf.set_colour_tail(tail);
        self.residual.set_colour_tail(tail);
        let DepthRenderer { model, nerf, residual, pool, solid, .. } = self;
        let model = &*model;
        let occupancy = match model {
            LoadedModel::Nerf(m) => &m.occupancy,
            LoadedModel::Residual(m) => &m.occupancy,
        };
        let grid = match fast {
            Some(min_sigma) => {
                if solid.as_ref().is_none_or(|(key, _)| *key != (fraction, min_sigma)) {
                    *solid = Some(((fraction, min_sigma), occupancy.keep_solid(fraction, min_sigma)));
                }
                &solid.as_ref().expect("built above").1
            }
            None => occupancy,
        };
        let job = || match model {
            LoadedModel::Nerf(m) => {
                let scene = Scene { model: &m.field, params: &m.params, occupancy: grid };
                draw(isa, nerf, &scene, k, pose, request, background, depth, extras)
            }
            LoadedModel::Residual(m) => {
                let scene = Scene { model: &m.field, params: &m.params, occupancy: grid };
                draw(isa, residual, &scene, k, pose, request, background, depth, extras)
            }
        };
        match pool {
            Some(p) => p.install(job),
            None => job(),
        }
        if request.kind == DepthKind::Range {
            for (p, d) in depth.iter_mut().enumerate() {
                let ray = pixel_ray(k, pose, p as u32 % k.width, p as u32 / k.width);
                *d = ray.z_to_range(*d);
            }
        }
        Ok(())
    }
}

/// One frame into the caller's buffers: the depth-only path when only threshold depth is
/// asked for, the full one otherwise.
#[allow(clippy::too_many_arguments)]
fn draw<M: crate::field::model::Model>(
    isa: Isa,
    renderer: &mut ViewRenderer<M>,
    scene: &Scene<'_, M>,
    k: &Intrinsics,
    pose: &Pose,
    request: DepthRequest,
    background: [f32; 3],
    depth: &mut [f32],
    extras: Extras<'_>,
) {
    let (m, expected) = (request.method.threshold(), request.method == DepthMethod::Expected);
    if !expected && extras.rgb.is_none() && extras.beta.is_none() {
        renderer.depth(isa, scene, k, pose, m, depth);
        return;
    }
    let (threshold_z, expected_z): (&mut [f32], &mut [f32]) =
        if expected { (&mut [], depth) } else { (depth, &mut []) };
    let out = FullOutputs {
        rgb: extras.rgb.unwrap_or(&mut []),
        expected_z,
        threshold_z,
        beta: extras.beta.unwrap_or(&mut []),
    };
    renderer.full(isa, scene, k, pose, background, m, out);
}
