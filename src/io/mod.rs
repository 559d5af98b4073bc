//! Files the crate writes and reads back: model files (safetensors), atomic writes,
//! depth and image exports ([`export`]).

pub mod atomic;
pub mod export;
pub mod model;

pub use atomic::write_atomic;
pub use model::{load_nerf, nerf_from_bytes, save_nerf};
