//! Geometry every layer shares: the scene box ([`Aabb`]: the field's encodings, the occupancy
//! grid, the change region, the datasets), cameras ([`camera`]: intrinsics, poses, pixel
//! rays, depth conventions; [`distortion`]: lens models) and two cell sets over the box: the
//! occupancy grid ([`occupancy`]: where the field has something, and marching rays through
//! it) and a residual model's change region ([`region`]). A trained model carries both, the
//! trainer refreshes the grid and the renderer marches it, so they live here, below all three.

pub mod camera;
pub mod distortion;
pub mod occupancy;
pub mod region;

pub use camera::{image_ray, pixel_ray, DepthKind, Intrinsics, Pose, Ray};
pub use distortion::Distortion;
use glam::Vec3;
pub use occupancy::{OccupancyConfig, OccupancyGrid, PackedSamples, RaySpan};
pub use region::ChangeRegion;

/// The scene's axis-aligned bounding box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Minimum corner.
    pub min: Vec3,
    /// Maximum corner.
    pub max: Vec3,
}

impl Aabb {
    /// Size along each axis.
    pub fn size(&self) -> Vec3 {
        self.max - self.min
    }

    /// `p` mapped to the unit cube of the box.
    pub fn to_unit(&self, p: Vec3) -> Vec3 {
        (p - self.min) / self.size()
    }

    /// Entry and exit distances of a ray (unit `dir`), clipped to `t ≥ 0`; `None` if it misses.
    pub fn intersect(&self, origin: Vec3, dir: Vec3) -> Option<(f32, f32)> {
        let inv = dir.recip();
        let a = (self.min - origin) * inv;
        let b = (self.max - origin) * inv;
        // NaN (0 · ∞ for an axis-parallel ray on a face) is treated as "no constraint".
        let lo = a.min(b);
        let hi = a.max(b);
        let near = [lo.x, lo.y, lo.z].into_iter().filter(|v| !v.is_nan()).fold(0.0f32, f32::max);
        let far = [hi.x, hi.y, hi.z].into_iter().filter(|v| !v.is_nan()).fold(f32::INFINITY, f32::min);
        (near < far).then_some((near, far))
    }
}

/// The indices below `n` of the set bits of a bitset (bit `i` of word `i / 64`), in increasing
/// order: the cells of a cell set (the occupancy grid's occupied or pinned cells, a region's).
pub(crate) fn set_bits(bits: &[u64], n: usize) -> Vec<u32> {
    let mut out = Vec::new();
    for (w, &word) in bits.iter().enumerate() {
        let mut rest = word;
        while rest != 0 {
            let i = w * 64 + rest.trailing_zeros() as usize;
            if i >= n {
                return out;
            }
            out.push(i as u32);
            rest &= rest - 1;
        }
    }
    out
}
