//! Datasets: the scene synthesiser (and, with issue #3, the NeRF-synthetic loaders).

pub mod synth;
