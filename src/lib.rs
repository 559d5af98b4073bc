//! # residual-nerf
//!
//! A pure-CPU implementation of Residual-NeRF (background NeRF + residual NeRF + Mixnet) for
//! depth of transparent objects, built on hand-vectorised kernels (AVX2+FMA+F16C, NEON) with
//! scalar twins, dispatched at run time.
//!
//! The data flow (see `ARCHITECTURE.md`): positions → [`encoding::HashGrid`] (fp16 table) →
//! density [`mlp::Mlp`] → σ and geometry features; directions → [`encoding::sh4`] → colour
//! MLP → RGB; compositing → loss → backward through the same kernels → [`train::Adam`].
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
pub mod eval;
pub mod field;
pub mod io;
pub mod mlp;
pub mod render;
pub mod rng;
pub mod simd;
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
