//! Training: the optimiser, its learning-rate schedule, thread-independent gradient slots and
//! the trainer loop over any [`crate::field::model::Model`] (a NeRF, or a residual model).

pub mod adam;
pub mod beta;
pub mod error_map;
pub mod field_fit;
pub mod gains;
pub mod lift;
pub mod pixel_filter;
mod pool;
pub mod prior;
pub mod register;
pub mod scene;
pub mod sizing;
mod step;
pub mod trainer;

pub use adam::{Adam, AdamConfig, LrSchedule};
