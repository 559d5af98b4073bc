//! Datasets: the NeRF-synthetic layout on disk ([`Dataset::load`]; DESIGN §3) and the scene
//! synthesiser ([`synth`]) the crate's tests and demo use instead of files.
//!
//! - [`transforms`]: the json (pure parsing, every problem collected).
//! - [`images`]: PNG/JPEG colour, mask PNGs, depth EXRs (size checked before decoding).
//! - [`dataset`]: a split → posed [`View`]s plus ground truth.
//! - [`error`]: errors naming the file, frame and field.
//! - [`workspace`]: the synthetic robot workspace with a glass object (background and scene sets).
//! - [`colmap`]: COLMAP sparse models in and out (`rnerf import colmap`).

pub mod colmap;
pub mod dataset;
pub mod error;
pub mod images;
pub mod synth;
pub mod transforms;
pub mod view;
pub mod workspace;

pub use dataset::{aabb_from_cameras, AabbSource, Dataset, FrameInfo, LoadOptions};
pub use error::{DataError, DataReport};
pub use transforms::{DepthKind, FrameType};
pub use view::View;

/// `n` evenly spaced items of `items` (indices `⌊i · len / n⌋`; all of them when `n ≥ len`): the
/// views a robot in a hurry takes (`--scene-views`).
pub fn evenly_spaced<T: Clone>(items: &[T], n: usize) -> Vec<T> {
    if n >= items.len() {
        return items.to_vec();
    }
    (0..n).map(|i| items[i * items.len() / n].clone()).collect()
}
