//! Rendering: cameras and rays, volume compositing along rays (DESIGN §2.2). The occupancy
//! grid, marching and depth extraction join this module with issue #3.

pub mod camera;
pub mod composite;

pub use camera::{pixel_ray, Intrinsics, Pose, Ray};
pub use composite::{
    composite_ray, composite_ray_backward, weights_from_density, RayComposite, EARLY_STOP_TRANSMITTANCE,
};
