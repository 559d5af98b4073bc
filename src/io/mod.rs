//! Files the crate writes and reads back: model files (safetensors), training checkpoints
//! (a model file plus the trainer's state), atomic writes, depth and image exports
//! ([`export`]).

pub mod atomic;
pub mod checkpoint;
pub mod export;
pub mod model;

pub use atomic::{read_limited, write_atomic};
pub use checkpoint::{checkpoint_from_bytes, load_checkpoint, save_checkpoint, views_fingerprint, Checkpoint};
pub use model::{
    load_model, load_nerf, model_from_bytes, nerf_from_bytes, save_model, save_nerf, save_residual, LoadedModel,
    ModelFile,
};
