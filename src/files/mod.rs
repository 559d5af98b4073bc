//! Bytes to and from disk, below every layer that reads or writes a file: atomic writes and
//! size-bounded reads ([`atomic`]), and the depth and image encodings a robot stack or a person
//! reads ([`export`]). Model files and checkpoints, which know the fields and the trainer, are
//! [`crate::io`]'s; the dataset readers and the synthesisers' writers in [`crate::data`] and
//! the exports of `rnerf render` use these.

pub mod atomic;
pub mod export;

pub use atomic::{read_limited, write_atomic};
