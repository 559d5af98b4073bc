//! Rendering: cameras and rays, volume compositing along rays (DESIGN §2.2). The occupancy
//! grid and marching join this module with issue #3; depth extraction (Eq. 3, Dex-NeRF) is here.

pub mod camera;
pub mod composite;
pub mod depth;
pub mod occupancy;

pub use camera::{pixel_ray, Intrinsics, Pose, Ray};
pub use composite::{
    composite_ray, composite_ray_backward, weights_from_density, RayComposite, EARLY_STOP_TRANSMITTANCE,
};
pub use depth::{expected_depth, threshold_depth, DensityThreshold, DepthMethod};
pub use occupancy::{Aabb, OccupancyConfig, OccupancyGrid, PackedSamples};
