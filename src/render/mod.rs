//! Rendering: cameras and rays, the occupancy grid and marching (DESIGN §2.5), volume
//! compositing along rays (§2.2), depth extraction (Eq. 3, Dex-NeRF; §2.4), and whole views
//! into caller buffers ([`view`]).

pub mod composite;
pub mod depth;
pub mod distortion;
pub mod occupancy;
pub mod view;

pub use crate::geometry::{pixel_ray, Aabb, DepthKind, Intrinsics, Pose, Ray};
pub use composite::{
    composite_ray, composite_ray_backward, weights_from_density, RayAccumulator, RayComposite, EARLY_STOP_TRANSMITTANCE,
};
pub use depth::{expected_depth, threshold_depth, DensityThreshold, DepthMethod};
pub use occupancy::{OccupancyConfig, OccupancyGrid, PackedSamples, RaySpan};
pub use view::{FullOutputs, RenderedView, ViewRenderer};
