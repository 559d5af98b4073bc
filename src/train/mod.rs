//! Training: the optimiser, its learning-rate schedule, thread-independent gradient slots and
//! the NeRF trainer loop.

pub mod adam;
pub mod slots;
pub mod trainer;

pub use adam::{Adam, AdamConfig, LrSchedule};
