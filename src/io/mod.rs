//! Files the crate writes and reads back: model files (safetensors), atomic writes,
//! depth and image exports ([`export`]).

pub mod atomic;
pub mod export;
pub mod model;

pub use atomic::{read_limited, write_atomic};
pub use model::{load_model, load_nerf, model_from_bytes, nerf_from_bytes, save_nerf, save_residual, LoadedModel};
