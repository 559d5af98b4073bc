//! The **change region** of a residual model: the cells of a regular grid over the scene box
//! (the occupancy grid's cells, or cells a whole number of times finer) where the scene may
//! differ from the background. Outside it the residual field *is* the frozen background: β = 0
//! there, so the mix returns the background's density and colour bit for bit and neither the
//! residual nor the Mixnet gets a gradient from it. The region is voted from the training
//! images' change maps ([`crate::train::prior`]); inside it the trainer keeps the occupancy
//! grid's cells marchable (every grid cell holding a cell of the region), so a glass standing
//! where the background had empty air is sampled from the first step on.

use super::Aabb;
use glam::Vec3;

/// The finest region a model file holds, 512³ cells (a 16-MiB bit set;
/// [`crate::train::prior::PriorConfig::region_subdivide`] stops there).
pub const MAX_RESOLUTION: u32 = 512;

/// A set of cells of a `resolution³` grid over `aabb` (cell `x + r·(y + r·z)`, x fastest, as
/// the occupancy grid, or a grid a whole number of times finer:
/// [`crate::train::prior::PriorConfig::region_subdivide`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ChangeRegion {
    aabb: Aabb,
    resolution: u32,
    bits: Vec<u64>,
}

impl ChangeRegion {
    /// An empty region.
    pub fn empty(aabb: Aabb, resolution: u32) -> ChangeRegion {
        assert!((1..=1024).contains(&resolution), "region: resolution must be 1..=1024");
        let n = (resolution as usize).pow(3);
        ChangeRegion { aabb, resolution, bits: vec![0; n.div_ceil(64)] }
    }

    /// The region holding `cells` (indices below `resolution³`; others are refused).
    pub fn from_cells(aabb: Aabb, resolution: u32, cells: &[u32]) -> Result<ChangeRegion, String> {
        let mut r = ChangeRegion::empty(aabb, resolution);
        let n = r.n_cells();
        for &c in cells {
            if c as usize >= n {
                return Err(format!("region cell {c} is outside the {resolution}^3 grid"));
            }
            r.insert(c as usize);
        }
        Ok(r)
    }

    /// The scene box.
    pub fn aabb(&self) -> &Aabb {
        &self.aabb
    }

    /// Cells per axis.
    pub fn resolution(&self) -> u32 {
        self.resolution
    }

    /// Cells of the grid.
    pub fn n_cells(&self) -> usize {
        (self.resolution as usize).pow(3)
    }

    /// Adds cell `i`.
    pub fn insert(&mut self, i: usize) {
        self.bits[i / 64] |= 1 << (i % 64);
    }

    /// Whether cell `i` is in the region.
    #[inline]
    pub fn has_cell(&self, i: usize) -> bool {
        self.bits[i / 64] >> (i % 64) & 1 == 1
    }

    /// The cell of the grid holding world point `p`, in the region or not (`None` outside the
    /// box).
    #[inline]
    pub fn cell_at(&self, p: Vec3) -> Option<usize> {
        let u = self.aabb.to_unit(p) * self.resolution as f32;
        if !(u.x >= 0.0 && u.y >= 0.0 && u.z >= 0.0) {
            return None;
        }
        let r = self.resolution;
        let (x, y, z) = (u.x as u32, u.y as u32, u.z as u32);
        (x < r && y < r && z < r).then(|| (x + r * (y + r * z)) as usize)
    }

    /// Whether world point `p` lies in a cell of the region (points outside the box never do).
    #[inline]
    pub fn contains(&self, p: Vec3) -> bool {
        self.cell_at(p).is_some_and(|i| self.has_cell(i))
    }

    /// The region's cells in increasing order.
    pub fn cells(&self) -> Vec<u32> {
        super::set_bits(&self.bits, self.n_cells())
    }

    /// Number of cells in the region.
    pub fn count(&self) -> usize {
        self.bits.iter().map(|w| w.count_ones() as usize).sum()
    }

    /// The region grown by `cells` cells along each axis (a cube neighbourhood).
    pub fn dilated(&self, cells: u32) -> ChangeRegion {
        let r = self.resolution as i64;
        let k = cells as i64;
        let mut out = ChangeRegion::empty(self.aabb, self.resolution);
        for i in self.cells() {
            let i = i as i64;
            let (x, y, z) = (i % r, (i / r) % r, i / (r * r));
            for dz in -k..=k {
                for dy in -k..=k {
                    for dx in -k..=k {
                        let (a, b, c) = (x + dx, y + dy, z + dz);
                        if (0..r).contains(&a) && (0..r).contains(&b) && (0..r).contains(&c) {
                            out.insert((a + r * (b + r * c)) as usize);
                        }
                    }
                }
            }
        }
        out
    }

    /// The region on the coarser grid of `resolution` cells per axis over the same box: every
    /// coarse cell holding a cell of this region. `None` unless `resolution` divides this
    /// region's (a region voted finer than its occupancy grid is pinned this way).
    pub fn coarsened(&self, resolution: u32) -> Option<ChangeRegion> {
        if resolution == 0 || !self.resolution.is_multiple_of(resolution) {
            return None;
        }
        let (r, k) = (self.resolution, self.resolution / resolution);
        let mut out = ChangeRegion::empty(self.aabb, resolution);
        for i in self.cells() {
            let (x, y, z) = (i % r / k, i / r % r / k, i / (r * r) / k);
            out.insert((x + resolution * (y + resolution * z)) as usize);
        }
        Some(out)
    }

    /// The region on the grid `k` times finer over the same box: every cell split into its k³
    /// children (the inverse of [`Self::coarsened`]).
    pub fn subdivided(&self, k: u32) -> ChangeRegion {
        let (r, f) = (self.resolution, self.resolution * k);
        let mut out = ChangeRegion::empty(self.aabb, f);
        for i in self.cells() {
            let (x, y, z) = (i % r * k, i / r % r * k, i / (r * r) * k);
            for j in 0..k * k * k {
                out.insert(((x + j % k) + f * ((y + j / k % k) + f * (z + j / (k * k)))) as usize);
            }
        }
        out
    }

    /// The smallest box holding every cell of the region; `None` when it is empty.
    pub fn bounds(&self) -> Option<Aabb> {
        let r = self.resolution as usize;
        let cell = self.aabb.size() / self.resolution as f32;
        let (mut lo, mut hi) = ([usize::MAX; 3], [0usize; 3]);
        for i in self.cells() {
            let c = [i as usize % r, (i as usize / r) % r, i as usize / (r * r)];
            for a in 0..3 {
                lo[a] = lo[a].min(c[a]);
                hi[a] = hi[a].max(c[a] + 1);
            }
        }
        let corner = |c: [usize; 3]| self.aabb.min + Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32) * cell;
        (lo[0] != usize::MAX).then(|| Aabb { min: corner(lo), max: corner(hi) })
    }

    /// The region's volume (scene units cubed).
    pub fn volume(&self) -> f64 {
        let cell = self.aabb.size() / self.resolution as f32;
        self.count() as f64 * (cell.x * cell.y * cell.z) as f64
    }

    /// One bit per cell (`i / 64`, bit `i % 64`), in the occupancy grid's layout.
    pub fn bits(&self) -> &[u64] {
        &self.bits
    }

    /// Centre of cell `i` in world coordinates.
    pub fn cell_centre(&self, i: usize) -> Vec3 {
        let r = self.resolution as usize;
        let (x, y, z) = (i % r, (i / r) % r, i / (r * r));
        let cell = self.aabb.size() / self.resolution as f32;
        self.aabb.min + (Vec3::new(x as f32, y as f32, z as f32) + 0.5) * cell
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_box() -> Aabb {
        Aabb { min: Vec3::ZERO, max: Vec3::ONE }
    }

    #[test]
    fn bounds_are_the_box_of_its_cells() {
        assert_eq!(ChangeRegion::empty(unit_box(), 4).bounds(), None);
        // Cells (1, 2, 3) and (2, 0, 3) of a 4³ grid over the unit cube.
        let r = ChangeRegion::from_cells(unit_box(), 4, &[1 + 4 * (2 + 4 * 3), 2 + 4 * (4 * 3)]).unwrap();
        let b = r.bounds().unwrap();
        assert_eq!(b.min, Vec3::new(0.25, 0.0, 0.75));
        assert_eq!(b.max, Vec3::new(0.75, 0.75, 1.0));
        for c in r.cells() {
            let p = r.cell_centre(c as usize);
            assert!(p.cmpge(b.min).all() && p.cmple(b.max).all());
        }
    }

    #[test]
    fn contains_the_points_of_its_cells_only() {
        let r = ChangeRegion::from_cells(unit_box(), 4, &[1 + 4 * (2 + 4 * 3)]).unwrap();
        assert!(r.contains(Vec3::new(0.3, 0.6, 0.9)));
        assert!(!r.contains(Vec3::new(0.2, 0.6, 0.9)));
        assert!(!r.contains(Vec3::new(0.3, 0.6, 1.1)));
        assert!(!r.contains(Vec3::new(f32::NAN, 0.6, 0.9)));
        assert_eq!(r.cells(), vec![1 + 4 * (2 + 4 * 3)]);
        assert!(r.contains(r.cell_centre(1 + 4 * (2 + 4 * 3))));
    }

    #[test]
    fn coarsened_holds_every_cell_in_its_parent() {
        // Cells (0, 0, 0), (1, 1, 1), (5, 2, 7) of an 8³ grid: parents (0, 0, 0) twice and (2, 1, 3) of 4³.
        let r = ChangeRegion::from_cells(unit_box(), 8, &[0, 1 + 8 * (1 + 8), 5 + 8 * (2 + 8 * 7)]).unwrap();
        let c = r.coarsened(4).unwrap();
        assert_eq!(c.cells(), vec![0, 2 + 4 * (1 + 4 * 3)]);
        for i in r.cells() {
            assert!(c.contains(r.cell_centre(i as usize)));
        }
        assert_eq!(r.coarsened(8).unwrap(), r);
        assert!(r.coarsened(3).is_none() && r.coarsened(0).is_none());
        // Subdivided, each cell becomes its 8 children, which coarsen back to it.
        let f = c.subdivided(2);
        assert_eq!((f.resolution(), f.count()), (8, 16));
        assert_eq!(f.coarsened(4).unwrap(), c);
        assert!(f.cells().iter().all(|&i| c.contains(f.cell_centre(i as usize))));
    }

    #[test]
    fn dilation_grows_a_cell_into_a_clipped_cube() {
        let r = ChangeRegion::from_cells(unit_box(), 8, &[0, 4 + 8 * (4 + 8 * 4)]).unwrap();
        assert_eq!(r.dilated(1).count(), 8 + 27);
        assert!(ChangeRegion::from_cells(unit_box(), 2, &[8]).is_err());
    }
}
