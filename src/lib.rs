//! # residual-nerf
//!
//! A pure-CPU implementation of Residual-NeRF (background NeRF + residual NeRF + Mixnet) for
//! depth of transparent objects, built on hand-vectorised kernels (AVX2+FMA+F16C, NEON) with
//! scalar twins, dispatched at run time.
//!
//! On the robot: load a model once, render depth for each camera pose into your own buffer
//! ([`onboard::DepthRenderer`]; z or range in metres, NaN holes). Here the model is trained
//! in a few steps on a synthesised workspace; a robot loads its file with
//! [`onboard::DepthRenderer::load`]. When objects appear, the scene phase runs on board from the
//! images in memory ([`train::scene::train_scene`]: the background's prior, the start at the
//! background, the residual's training) and hands its model to [`onboard::DepthRenderer::new`].
//!
//! ```
//! use residual_nerf::data::workspace;
//! use residual_nerf::encoding::HashGridConfig;
//! use residual_nerf::field::NerfConfig;
//! use residual_nerf::io::LoadedModel;
//! use residual_nerf::onboard::{DepthKind, DepthMethod, DepthRenderer, DepthRequest};
//! use residual_nerf::render::{DensityThreshold, Intrinsics, Pose};
//! use residual_nerf::simd::Isa;
//! use residual_nerf::train::trainer::{train_nerf, TrainConfig};
//!
//! let scene = workspace::workspace(16, 6, 0.0, false); // posed images, a box around them
//! let field = NerfConfig { grid: HashGridConfig { log2_table_size: 12, ..Default::default() }, aabb: scene.aabb };
//! let mut cfg = TrainConfig::with_steps(20);
//! cfg.rays_per_step = 256;
//! let nerf = train_nerf(Isa::detect(), &scene.views, field, &cfg, 0, |_| {})?;
//!
//! let mut camera = DepthRenderer::new(LoadedModel::Nerf(Box::new(nerf))).with_threads(2)?;
//! let k = Intrinsics::from_fov_x(32, 24, 0.9);
//! let pose = Pose::look_at([1.0, -1.0, 1.0].into(), workspace::TARGET);
//! let mut depth = vec![0.0f32; 32 * 24]; // allocated once, reused every frame
//! let request = DepthRequest { method: DepthMethod::Threshold(DensityThreshold::Sigma(1.0)), kind: DepthKind::Z };
//! camera.depth(&k, &pose, request, &mut depth)?;
//! assert!(depth.iter().all(|z| z.is_nan() || *z > 0.0)); // metres along the viewing axis
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! The data flow (see `ARCHITECTURE.md`): positions → [`encoding::HashGrid`] (fp16 table) →
//! density [`mlp::Mlp`] → σ and geometry features; directions → [`encoding::sh4`] → colour
//! MLP → RGB; compositing → loss → backward through the same kernels → [`train::Adam`].
//! The kernels are usable on their own:
//!
//! ```
//! use residual_nerf::encoding::{HashGrid, HashGridConfig, HashGridParams};
//! use residual_nerf::mlp::{Activation, Mlp, MlpConfig, MlpContext};
//! use residual_nerf::{rng::Rng, simd::Isa};
//!
//! let isa = Isa::detect(); // the best SIMD level this CPU has
//! let grid = HashGrid::new(HashGridConfig { log2_table_size: 14, ..Default::default() });
//! let mut rng = Rng::new(0);
//! let table = HashGridParams::init(&grid, &mut rng);
//! let positions = [[0.5f32, 0.25, 0.75]; 3];
//! let mut features = vec![0.0; positions.len() * grid.output_width()];
//! grid.forward(isa, &table.table, &positions, &mut features);
//!
//! let density = Mlp::<64>::new(MlpConfig {
//!     input: 32, output: 16, hidden_layers: 1,
//!     hidden_activation: Activation::Relu, output_activation: Activation::None,
//! });
//! let weights = density.init_params(&mut rng);
//! let mut ctx = MlpContext::default();
//! density.forward(isa, &weights, &features, positions.len(), &mut ctx);
//! let sigma = ctx.output()[0].exp(); // σ = trunc_exp(raw density) of the first sample
//! assert!(sigma.is_finite() && sigma > 0.0);
//! ```

pub mod app;
pub mod bench;
pub mod cli;
pub mod compare;
pub mod data;
pub mod encoding;
pub mod error;
pub mod eval;
pub mod field;
pub mod files;
pub mod geometry;
pub mod io;
pub mod memory;
pub mod mlp;
pub mod onboard;
pub mod render;
pub mod rng;
pub mod simd;
pub mod slots;
pub mod train;

/// What a backward pass does with parameter gradients (tiny-cuda-nn's contract).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum GradientMode {
    /// Compute no parameter gradients (a frozen network, e.g. Residual-NeRF's background).
    Ignore,
    /// Replace the gradient buffer's contents.
    Overwrite,
    /// Add to the gradient buffer's contents.
    Accumulate,
}
