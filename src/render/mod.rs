//! Rendering: volume compositing along rays (§2.2), depth extraction (Eq. 3, Dex-NeRF; §2.4),
//! and whole views into caller buffers ([`view`]). Cameras, rays and the occupancy grid the
//! renderer marches (DESIGN §2.5) live in [`crate::geometry`] and are re-exported here.

pub mod composite;
pub mod depth;
pub mod distortion;
pub mod view;

pub use crate::geometry::{
    image_ray, pixel_ray, Aabb, DepthKind, Intrinsics, OccupancyConfig, OccupancyGrid, PackedSamples, Pose, Ray,
    RaySpan,
};
pub use composite::{
    composite_ray, composite_ray_backward, weights_from_density, RayAccumulator, RayComposite, EARLY_STOP_TRANSMITTANCE,
};
pub use depth::{expected_depth, threshold_depth, DensityThreshold, DepthMethod};
pub use view::{FullOutputs, RenderedView, StopFill, ViewRenderer};
