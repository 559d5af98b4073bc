//! Rendering: volume compositing along rays (DESIGN §2.2). Cameras, rays, the occupancy grid
//! and marching, and depth extraction join this module with issue #3.

pub mod composite;

pub use composite::{
    composite_ray, composite_ray_backward, weights_from_density, RayComposite, EARLY_STOP_TRANSMITTANCE,
};
