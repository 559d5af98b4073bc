//! A posed training image: what the datasets and synthesisers produce and the trainer reads.

use crate::geometry::{Intrinsics, Pose};

/// One posed training image with linear RGB values in [0, 1], row-major from the top-left.
#[derive(Clone, Debug)]
pub struct View {
    /// Camera intrinsics.
    pub intrinsics: Intrinsics,
    /// Camera-to-world pose.
    pub pose: Pose,
    /// `width × height` colours.
    pub rgb: Vec<[f32; 3]>,
}
