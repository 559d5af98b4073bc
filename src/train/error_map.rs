//! Sampling rays by the training error (Instant-NGP's error map), an improvement of plain
//! NeRF training that needs no background: a share of each step's rays is drawn where the
//! model's colours are still wrong instead of uniformly.
//!
//! Every training image is cut into tiles of [`TILE`]×[`TILE`] pixels (the last row and column
//! of tiles cut at the image's edge). Each tile holds a running estimate of the squared colour
//! error of rays through it (the mean over the three channels, before any learned gain): after
//! every step each ray's error `e` moves its tile's value `v` to `v + EMA·(e − v)`, in ray
//! order ([`record`]). Tiles start at [`INITIAL`], above any error a colour in [0, 1] can have,
//! so the error-drawn rays visit every tile once before they concentrate (new items at top
//! priority, as in prioritised replay). The drawn rays choose a tile with probability
//! proportional to its value, then a pixel of it uniformly ([`ErrorSampler`]); the loss is not
//! reweighted (Instant-NGP does not either): the map moves effort to the hard pixels, which is
//! the point. A step skipped for a non-finite value records nothing.

use crate::data::View;
use crate::rng::Rng;

/// Tile edge in pixels.
pub const TILE: u32 = 8;

/// Weight of a new error in a tile's running estimate.
pub const EMA: f32 = 0.5;

/// A tile's value before any ray crossed it.
pub const INITIAL: f32 = 1.0;

/// Share of each step's rays drawn by the error map where a method turns it on (Dex-NeRF's
/// variant `dex-error-map`; docs/DECISIONS.md, "Baselines").
pub const ERROR_MAP_SHARE: f32 = 0.5;

/// The tiles of a run's training views: tile `t` of view `v` is `offsets[v] + tx + ty·cols[v]`.
#[derive(Clone, Debug, PartialEq)]
pub struct TileLayout {
    offsets: Vec<usize>,
    cols: Vec<u32>,
    sizes: Vec<(u32, u32)>,
}

impl TileLayout {
    /// The tiles of `views`.
    pub fn new(views: &[View]) -> TileLayout {
        let mut offsets = Vec::with_capacity(views.len() + 1);
        let (mut cols, mut sizes) = (Vec::new(), Vec::new());
        let mut n = 0usize;
        for v in views {
            let (w, h) = (v.intrinsics.width, v.intrinsics.height);
            offsets.push(n);
            cols.push(w.div_ceil(TILE));
            sizes.push((w, h));
            n += w.div_ceil(TILE) as usize * h.div_ceil(TILE) as usize;
        }
        offsets.push(n);
        TileLayout { offsets, cols, sizes }
    }

    /// Tiles in all views.
    pub fn len(&self) -> usize {
        *self.offsets.last().expect("offsets end with the total")
    }

    /// Whether there are no tiles.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The tile holding `pixel` (`y · width + x`) of view `view`.
    pub fn tile_of(&self, view: u32, pixel: u32) -> usize {
        let v = view as usize;
        let w = self.sizes[v].0;
        let (x, y) = (pixel % w, pixel / w);
        self.offsets[v] + (x / TILE + y / TILE * self.cols[v]) as usize
    }

    /// A pixel of tile `tile` drawn uniformly, as `(view, pixel)`.
    pub fn draw_pixel(&self, tile: usize, rng: &mut Rng) -> (u32, u32) {
        let v = self.offsets.partition_point(|&o| o <= tile) - 1;
        let (w, h) = self.sizes[v];
        let local = (tile - self.offsets[v]) as u32;
        let (x0, y0) = (local % self.cols[v] * TILE, local / self.cols[v] * TILE);
        let x = x0 + rng.below(TILE.min(w - x0) as u64) as u32;
        let y = y0 + rng.below(TILE.min(h - y0) as u64) as u32;
        (v as u32, y * w + x)
    }

    /// The starting values of a map over these tiles.
    pub fn initial_values(&self) -> Vec<f32> {
        vec![INITIAL; self.len()]
    }
}

/// Moves tile `tile`'s value towards a ray's squared error `err` (its mean over the channels).
#[inline]
pub fn record(values: &mut [f32], tile: usize, err: f32) {
    let v = &mut values[tile];
    *v += EMA * (err - *v);
}

/// Draws tiles with probability proportional to their value (a cumulative sum, rebuilt for
/// each step's draws).
#[derive(Clone, Debug, Default)]
pub struct ErrorSampler {
    cdf: Vec<f64>,
}

impl ErrorSampler {
    /// Prepares draws from `values` (non-negative; all zero draws uniformly).
    pub fn rebuild(&mut self, values: &[f32]) {
        self.cdf.clear();
        let mut sum = 0.0f64;
        for &v in values {
            sum += v.max(0.0) as f64;
            self.cdf.push(sum);
        }
    }

    /// One tile.
    pub fn draw(&self, rng: &mut Rng) -> usize {
        let n = self.cdf.len();
        let total = self.cdf.last().copied().unwrap_or(0.0);
        if total <= 0.0 || !total.is_finite() {
            return rng.below(n as u64) as usize;
        }
        let u = (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64) * total;
        self.cdf.partition_point(|&c| c <= u).min(n - 1)
    }
}
