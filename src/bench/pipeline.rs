//! The pipeline as a user runs it: full fused training steps (march, density, early stop,
//! colour, compositing, backward, grid scatter, Adam, occupancy updates amortised) of a NeRF and
//! of a residual model on the synthetic workspace, threshold-depth views through the robot's
//! library call, and occupancy-grid updates.

use super::report::{PipelineFigures, Stat};
use super::{time_reps, BenchOptions, Progress};
use crate::data::{Dataset, LoadOptions};
use crate::encoding::HashGridConfig;
use crate::field::mix::{DensityMix, MixKind};
use crate::field::mixnet::{default_mixnet_grid, MixnetEncoding};
use crate::field::residual::ResidualConfig;
use crate::field::NerfConfig;
use crate::geometry::{Intrinsics, OccupancyGrid, Pose};
use crate::io::LoadedModel;
use crate::onboard::{DepthKind, DepthMethod, DepthRenderer, DepthRequest};
use crate::rng::Rng;
use crate::train::trainer::{train_nerf, train_residual, StepStats, TrainConfig};
use std::path::Path;

/// A trained model whose depth rendering `rnerf bench --model M --data D` times in place of
/// the bench's own short-trained one — those are still foggy, so their depth rays march far
/// (BENCHMARKS.md, "Depth rendering"). Its kind picks the figures: a NeRF
/// `render_depth_ms_200` and `render_depth_ms_640x480`, a residual model the same with
/// `_residual`.
pub struct TrainedView {
    /// The model, as loaded.
    pub model: LoadedModel,
    /// The first test view of `D`, as the dataset gives it.
    pub intrinsics: Intrinsics,
    /// Its pose.
    pub pose: Pose,
}

/// `k` rescaled to `width` pixels across; with `height`, the rescaled image cropped (or
/// extended) about its centre to that many rows — a depth camera's 640×480 from a square view.
pub fn resized(k: Intrinsics, width: u32, height: Option<u32>) -> Intrinsics {
    let s = width as f32 / k.width as f32;
    let scaled = ((k.height as f32 * s).round() as u32).max(1);
    let height = height.unwrap_or(scaled);
    let shift = 0.5 * (height as f32 - scaled as f32);
    Intrinsics { width, height, fx: k.fx * s, fy: k.fy * s, cx: k.cx * s, cy: k.cy * s + shift, ..k }
}

impl TrainedView {
    /// Loads `model` and the first test view of `data` (errors name the file).
    pub fn load(model: &Path, data: &Path) -> Result<TrainedView, String> {
        let loaded = crate::io::load_model(model)?;
        let opts = LoadOptions { ground_truth: false, ..Default::default() };
        let test = Dataset::load(data, "test", &opts).map_err(|e| e.to_string())?;
        let view = test.views.first().ok_or_else(|| format!("{}: the test split has no views", data.display()))?;
        Ok(TrainedView { model: loaded, intrinsics: view.intrinsics, pose: view.pose })
    }

    /// The figure its 200-pixel view is timed under.
    pub fn figure(&self) -> &'static str {
        match self.model {
            LoadedModel::Nerf(_) => "render_depth_ms_200",
            LoadedModel::Residual(_) => "render_depth_ms_200_residual",
        }
    }
}

/// Measures every pipeline figure; also returns the Mixnet's share of the NeRF networks'
/// forward + backward multiply-adds per sample (for the residual's kernel bound).
pub(super) fn measure(
    opts: &BenchOptions,
    trained: Vec<TrainedView>,
    progress: &mut Progress,
) -> (PipelineFigures, f64) {
    let (isa, reps) = (opts.isa, opts.reps.max(1));
    // Training on the synthetic workspace at the default model size (random background
    // colours, as `rnerf train` trains images without alpha), measured over the last quarter
    // of a short run; then a residual model (Mixnet, own grid) over that background on the
    // workspace with the glass sphere.
    progress.start("NeRF training steps");
    let scene = crate::data::workspace::workspace(64, 30, 0.0, false);
    let field = NerfConfig {
        grid: HashGridConfig { log2_table_size: opts.log2_table_size, ..Default::default() },
        aabb: scene.aabb,
    };
    let cfg = TrainConfig::with_steps(opts.scaled(120.0).max(8) as u32);
    let rates = |log: &[StepStats]| -> (Stat, Stat) {
        let w: Vec<&[StepStats]> = log[log.len() * 3 / 4..].windows(2).collect();
        let dt = |w: &[StepStats]| w[1].seconds - w[0].seconds;
        let rays = cfg.rays_per_step as f64;
        (
            Stat::of(w.iter().map(|w| w[1].samples_per_ray as f64 * rays / dt(w)).collect()),
            Stat::of(w.iter().map(|w| rays / dt(w)).collect()),
        )
    };
    let mut log = Vec::new();
    let nerf = train_nerf(isa, &scene.views, field.clone(), &cfg, 1, |s| log.push(s)).expect("the bench scene trains");
    let (train_samples_per_s, train_rays_per_s) = rates(&log);
    progress.start("residual training steps");
    let glass = crate::data::workspace::workspace(64, 30, 0.0, true);
    let config = ResidualConfig {
        residual: field,
        kind: MixKind::Mixnet(DensityMix::Raw),
        mixnet: MixnetEncoding::Own(default_mixnet_grid()),
    };
    let residual_cfg = TrainConfig { steps: opts.scaled(60.0).max(8) as u32, ..cfg.clone() };
    let mut log = Vec::new();
    let residual = train_residual(isa, nerf.clone(), &glass.views, config, &residual_cfg, 1, |s| log.push(s))
        .expect("the bench scene trains");
    let (train_residual_samples_per_s, train_residual_rays_per_s) = rates(&log);
    let nets = nerf.field.networks();
    let mixnet_mac_share = residual.field.mixnet().mlp().fwd_bwd_macs_per_sample() as f64
        / (nets.0.fwd_bwd_macs_per_sample() + nets.1.fwd_bwd_macs_per_sample()) as f64;

    // Threshold depth (σ ≥ 10/m, depth-only path) of one view of each model, 200 pixels wide
    // and 640×480 (a depth camera's size), through the robot's library call: `DepthRenderer`
    // with its defaults (thinned grid), on this pool.
    progress.start("depth views");
    let k = Intrinsics::from_fov_x(200, 200, 50f32.to_radians());
    let pose = scene.views[0].pose;
    let request = DepthRequest { method: DepthMethod::default(), kind: DepthKind::Z };
    let mut nerf_view = TrainedView { model: LoadedModel::Nerf(Box::new(nerf.clone())), intrinsics: k, pose };
    let mut residual_view = TrainedView { model: LoadedModel::Residual(Box::new(residual)), intrinsics: k, pose };
    for t in trained {
        match t.model {
            LoadedModel::Nerf(_) => nerf_view = t,
            LoadedModel::Residual(_) => residual_view = t,
        }
    }
    let depth_ms = |s: TrainedView| {
        let mut camera = DepthRenderer::new(s.model);
        let mut time = |k: Intrinsics| {
            let mut z = vec![0f32; (k.width * k.height) as usize];
            let v = time_reps(reps, || camera.depth(&k, &s.pose, request, &mut z).expect("a valid camera and buffer"));
            Stat::of(v.iter().map(|s| s * 1e3).collect())
        };
        (time(resized(s.intrinsics, 200, None)), time(resized(s.intrinsics, 640, Some(480))))
    };
    let (render_depth_ms_200, render_depth_ms_640x480) = depth_ms(nerf_view);
    let (render_depth_ms_200_residual, render_depth_ms_640x480_residual) = depth_ms(residual_view);

    // Occupancy-grid updates of the NeRF at the default 128³: a warm-up update evaluates every
    // cell, a later one ¼ random + ¼ occupied cells (DESIGN §2.5), all through the
    // density-only path on all threads.
    progress.start("occupancy updates");
    let mut occ = OccupancyGrid::new(nerf.field.config().aabb, Default::default());
    let mut ctx = Default::default();
    let mut orng = Rng::new(11);
    let mut update_ms = |step: u32| {
        let v = time_reps(reps, || {
            occ.update(step, &mut orng, |p, sigma| {
                crate::field::model::Model::density(&nerf.field, isa, &nerf.params, p, sigma, &mut ctx)
            })
        });
        Stat::of(v.iter().map(|s| s * 1e3).collect())
    };
    let occupancy_update_ms_warmup = update_ms(0);
    let occupancy_update_ms = update_ms(u32::MAX);

    let figures = PipelineFigures {
        train_samples_per_s,
        train_rays_per_s,
        train_residual_samples_per_s,
        train_residual_rays_per_s,
        render_depth_ms_200,
        render_depth_ms_200_residual,
        render_depth_ms_640x480,
        render_depth_ms_640x480_residual,
        occupancy_update_ms_warmup,
        occupancy_update_ms,
    };
    (figures, mixnet_mac_share)
}
