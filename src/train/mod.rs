//! Training: the optimiser and its learning-rate schedule (the trainer loop and batch
//! sampling join them with the NeRF pipeline).

pub mod adam;
pub mod slots;

pub use adam::{Adam, AdamConfig, LrSchedule};
