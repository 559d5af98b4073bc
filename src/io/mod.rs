//! The files of a trained model: model files (safetensors) and training checkpoints (a model
//! file plus the trainer's state). They are written through [`crate::files`]' atomic writes;
//! depth and image exports are [`crate::files::export`]'s.

pub mod checkpoint;
pub mod model;

pub use checkpoint::{checkpoint_from_bytes, load_checkpoint, save_checkpoint, views_fingerprint, Checkpoint};
pub use model::{
    load_model, load_nerf, model_from_bytes, nerf_from_bytes, save_model, save_nerf, save_residual, LoadedModel,
    ModelFile,
};
