//! The sampling sized in metres: a NeRF's march step and its hash grids' finest cells follow
//! its scene box (the step is the box diagonal / [`OccupancyConfig::steps_per_diagonal`], the
//! finest cell the box's side / [`HashGridConfig::finest_resolution`]), so in a larger room the
//! glass would be sampled more coarsely at the same settings. These functions keep the box's
//! defaults where they are fine enough and refine them where the box is larger than the dev
//! set's workspace (3.3 × 3.3 × 2.17 m), so the glass is sampled as finely, in metres, in any
//! room: at most [`MAX_STEP`] a step, [`FIELD_CELL`] the field's finest cell and
//! [`MIXNET_CELL`] the Mixnet's. Positions are in metres (`metres_per_unit` converts a json's
//! units on loading). Measured in docs/DECISIONS.md, "The sampling sized in metres": in a box
//! 1.5 times wider, 25 scene views, the box-relative sampling lost the residual's glass.

use crate::encoding::hashgrid::HashGridConfig;
use crate::geometry::occupancy::OccupancyConfig;
use crate::geometry::Aabb;

/// The longest march step, metres: the dev box's (its diagonal 5.147 m / 1024 steps = 5.03 mm),
/// rounded up so that box keeps its 1024 steps.
pub const MAX_STEP: f32 = 0.0051;

/// The NeRF field's (background, residual, Dex-NeRF) finest hash-grid cell along the box's
/// longest side, metres: the dev box's 3.3 m / 2048 = 1.61 mm, rounded up.
pub const FIELD_CELL: f32 = 0.00165;

/// The Mixnet's finest hash-grid cell along the box's longest side, metres: the dev box's
/// 3.3 m / 512 = 6.45 mm, rounded up.
pub const MIXNET_CELL: f32 = 0.0066;

/// `cfg` with at least as many steps per diagonal as a step of [`MAX_STEP`] needs in `aabb`,
/// and at least as many samples per ray allowed.
pub fn occupancy_for_box(cfg: OccupancyConfig, aabb: &Aabb) -> OccupancyConfig {
    let steps = cells_across(aabb.size().length(), MAX_STEP).max(cfg.steps_per_diagonal);
    let max_samples = cfg.max_samples.max(steps);
    OccupancyConfig { steps_per_diagonal: steps, max_samples, ..cfg }
}

/// `grid` with its finest cell at most `cell` metres along `aabb`'s longest side.
pub fn grid_for_box(grid: HashGridConfig, aabb: &Aabb, cell: f32) -> HashGridConfig {
    let finest = cells_across(aabb.size().max_element(), cell).max(grid.finest_resolution);
    HashGridConfig { finest_resolution: finest, ..grid }
}

/// The Mixnet's default grid ([`crate::field::mixnet::default_mixnet_grid`]) sized for `aabb`.
pub fn mixnet_grid_for_box(aabb: &Aabb) -> HashGridConfig {
    grid_for_box(crate::field::mixnet::default_mixnet_grid(), aabb, MIXNET_CELL)
}

/// Cells of `cell` metres across `length` metres, rounded up (at most 2^20, the hash grid's
/// limit; a box that long is not a workspace).
fn cells_across(length: f32, cell: f32) -> u32 {
    (length / cell).ceil().clamp(1.0, (1u32 << 20) as f32) as u32
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn dev_box(scale: f32) -> Aabb {
        let (lo, hi) = (Vec3::new(-1.65, -1.65, -0.72), Vec3::new(1.65, 1.65, 1.45));
        let c = 0.5 * (lo + hi);
        Aabb { min: c + scale * (lo - c), max: c + scale * (hi - c) }
    }

    #[test]
    fn the_dev_box_keeps_the_defaults_and_a_smaller_box_its_finer_ones() {
        for scale in [1.0, 0.5, 0.1] {
            let b = dev_box(scale);
            assert_eq!(occupancy_for_box(OccupancyConfig::default(), &b), OccupancyConfig::default());
            assert_eq!(grid_for_box(HashGridConfig::default(), &b, FIELD_CELL), HashGridConfig::default());
            assert_eq!(mixnet_grid_for_box(&b), crate::field::mixnet::default_mixnet_grid());
        }
    }

    #[test]
    fn a_larger_box_is_sampled_as_finely_in_metres() {
        for scale in [1.2, 1.5, 2.0, 3.0] {
            let b = dev_box(scale);
            let occ = occupancy_for_box(OccupancyConfig::default(), &b);
            let step = b.size().length() / occ.steps_per_diagonal as f32;
            assert!(step <= MAX_STEP && step > 0.98 * MAX_STEP, "{scale}: step {step}");
            assert!(occ.max_samples >= occ.steps_per_diagonal);
            let g = grid_for_box(HashGridConfig::default(), &b, FIELD_CELL);
            let cell = b.size().max_element() / g.finest_resolution as f32;
            assert!(cell <= FIELD_CELL && cell > 0.99 * FIELD_CELL, "{scale}: cell {cell}");
            let m = mixnet_grid_for_box(&b);
            assert!(b.size().max_element() / m.finest_resolution as f32 <= MIXNET_CELL);
            assert_eq!((g.levels, g.log2_table_size, g.base_resolution), (16, 17, 16), "only the finest level moves");
        }
    }
}
