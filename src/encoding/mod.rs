//! Input encodings: the multiresolution hash grid for positions (DESIGN §2.1) and real
//! spherical harmonics for view directions.

pub mod hashgrid;
pub mod sh;

pub use hashgrid::{FeatureLevels, HashGrid, HashGridConfig, HashGridParams, LevelInfo};
pub use sh::{sh4, SH4_COEFFS};
