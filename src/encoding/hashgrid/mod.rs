//! Multiresolution hash-grid encoding (Instant-NGP; DESIGN §2.1).
//!
//! `L` levels of `F = 2` features. Level `l` has resolution
//! `N_l = floor(N_min · b^l)` with `b = exp((ln N_max − ln N_min) / (L − 1))`; a position
//! `x ∈ [0,1]³` (the unit cube of the scene box) scales to `p = x · N_l`, whose cell corner
//! `⌊p⌋` (clamped to `N_l − 1`, so `x = 1` lies in the last cell) and fraction `w = p − ⌊p⌋`
//! give the 8 corners and trilinear weights. A level whose `(N_l+1)³ ≤ T` is indexed densely,
//! `i = x + y(N_l+1) + z(N_l+1)²`; the others use the spatial hash
//! `h = (x·1 ⊕ y·2654435761 ⊕ z·805459861) mod T`. Points outside the cube encode to zeros.
//!
//! **Storage.** Each table entry is a pair of fp16 features packed into one `u32` (feature 0
//! in the low half), so a corner is one 4-byte gather; the optimiser keeps an fp32 master copy
//! (see [`HashGridParams`]) and rewrites the fp16 mirror after each step.
//!
//! **Layout of the encoding.** `out[s · W + 2l + f]`: sample-major rows of
//! `W = `[`HashGrid::output_width`] floats — `2L` features padded with zeros to a multiple of
//! 16, the input layout of the density MLP (whose SIMD tiles are 16 wide).
//!
//! **Forward/backward contract.** The encoding is linear in its parameters, so its forward
//! context is just its input positions: [`HashGrid::backward_params`] recomputes corner indices
//! and weights (cheaper than storing 1 KiB per sample). Backward runs one level per task: each
//! level owns a disjoint slice of the gradient, so it needs no atomics and sums in sample order
//! whatever the thread count.
//!
//! Kernels: [`scalar`] is the specification; `avx2`, `avx512` (the forward, 16 lanes; the
//! same bits as `avx2`) and `neon` compute the same values (FMA may change the last bits) and
//! are compared against it in `tests/simd_vs_scalar.rs`.

use crate::rng::Rng;
use crate::simd::{CpuLevel, Isa};
use crate::GradientMode;
use rayon::prelude::*;

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;
#[cfg(target_arch = "aarch64")]
mod neon;
pub mod scalar;

/// Features per level (fixed: one fp16 pair per table entry).
pub const FEATURES_PER_LEVEL: usize = 2;
/// Multiplier of the y coordinate in the spatial hash (Instant-NGP).
pub const PRIME_Y: u32 = 2_654_435_761;
/// Multiplier of the z coordinate in the spatial hash (Instant-NGP).
pub const PRIME_Z: u32 = 805_459_861;
/// Samples converted to structure-of-arrays and pushed through all levels at once.
pub(crate) const CHUNK: usize = 256;

/// Hash-grid hyper-parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HashGridConfig {
    /// Number of levels `L`. Defaults to 16.
    pub levels: usize,
    /// log2 of the per-level table size `T`. Defaults to 17, chosen by measured quality per
    /// second on the dev scenes (docs/DECISIONS.md, "The engine"; Instant-NGP's NeRF setting is 19).
    pub log2_table_size: u32,
    /// Coarsest resolution `N_min`. Defaults to 16.
    pub base_resolution: u32,
    /// Finest resolution `N_max`. Defaults to 2048.
    pub finest_resolution: u32,
}

impl Default for HashGridConfig {
    fn default() -> Self {
        HashGridConfig { levels: 16, log2_table_size: 17, base_resolution: 16, finest_resolution: 2048 }
    }
}

/// Where one level lives in the table and how it is indexed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LevelInfo {
    /// Grid resolution `N_l` (cells per axis).
    pub resolution: u32,
    /// First entry of this level in the table.
    pub offset: usize,
    /// Entries in this level: `(N_l+1)³` when dense, else `T`.
    pub size: usize,
    /// Dense (`true`) or hashed indexing.
    pub dense: bool,
}

impl LevelInfo {
    /// Table index (within the level) of grid vertex `(x, y, z)`.
    #[inline(always)]
    pub fn index(&self, x: u32, y: u32, z: u32) -> u32 {
        if self.dense {
            let s = self.resolution + 1;
            x + y * s + z * s * s
        } else {
            (x ^ y.wrapping_mul(PRIME_Y) ^ z.wrapping_mul(PRIME_Z)) & (self.size as u32 - 1)
        }
    }
}

/// The encoding's geometry (levels and table layout) and its kernels. Parameters live
/// outside, in a [`HashGridParams`] or the caller's own flat buffers.
#[derive(Clone, Debug)]
pub struct HashGrid {
    config: HashGridConfig,
    levels: Vec<LevelInfo>,
    entries: usize,
    stride: usize,
}

impl HashGrid {
    /// Lays out the levels of `config`. Panics on a configuration no table could hold
    /// (0 levels, `log2_table_size` outside 4..=26, resolutions 0 or decreasing).
    pub fn new(config: HashGridConfig) -> HashGrid {
        assert!(config.levels >= 1 && config.levels <= 32, "hash grid: levels must be 1..=32");
        assert!((4..=26).contains(&config.log2_table_size), "hash grid: log2_table_size must be 4..=26");
        assert!(
            config.base_resolution >= 1 && config.finest_resolution >= config.base_resolution,
            "hash grid: need 1 <= base_resolution <= finest_resolution"
        );
        assert!(config.finest_resolution <= 1 << 20, "hash grid: finest_resolution too large");
        let t = 1usize << config.log2_table_size;
        let n_min = config.base_resolution as f64;
        let n_max = config.finest_resolution as f64;
        let b = if config.levels > 1 { ((n_max.ln() - n_min.ln()) / (config.levels - 1) as f64).exp() } else { 1.0 };
        let mut offset = 0;
        let levels = (0..config.levels)
            .map(|l| {
                // The tiny epsilon keeps exact powers (e.g. N_max itself) from flooring one below.
                let resolution = ((n_min * b.powi(l as i32)) * (1.0 + 1e-12)).floor().max(1.0) as u32;
                let dense_size = (resolution as usize + 1).pow(3);
                let (size, dense) = if dense_size <= t { (dense_size, true) } else { (t, false) };
                let info = LevelInfo { resolution, offset, size, dense };
                offset += size;
                info
            })
            .collect();
        let stride = (FEATURES_PER_LEVEL * config.levels).div_ceil(16) * 16;
        HashGrid { config, levels, entries: offset, stride }
    }

    /// The configuration this grid was built from.
    pub fn config(&self) -> &HashGridConfig {
        &self.config
    }

    /// Per-level layout.
    pub fn levels(&self) -> &[LevelInfo] {
        &self.levels
    }

    /// Table entries over all levels (each entry holds 2 features).
    pub fn entries(&self) -> usize {
        self.entries
    }

    /// Trainable parameters (`2 · entries`).
    pub fn n_params(&self) -> usize {
        FEATURES_PER_LEVEL * self.entries
    }

    /// Features per sample (`2L`).
    pub fn features(&self) -> usize {
        FEATURES_PER_LEVEL * self.levels.len()
    }

    /// Floats per encoded row: `2L` padded to a multiple of 16 (padding is written as zero).
    pub fn output_width(&self) -> usize {
        self.stride
    }

    /// Encodes `positions` (unit-cube coordinates) into `out` (`positions.len() ×
    /// output_width()`, see the module docs for the layout). One thread; call it per batch chunk.
    pub fn forward(&self, isa: Isa, table: &[u32], positions: &[[f32; 3]], out: &mut [f32]) {
        self.check(table.len(), positions.len(), out.len());
        let width = self.output_width();
        let mut soa = Soa::default();
        for (c, pos) in positions.chunks(CHUNK).enumerate() {
            soa.fill(pos);
            let out = &mut out[c * CHUNK * width..(c * CHUNK + pos.len()) * width];
            for (l, level) in self.levels.iter().enumerate() {
                let t = &table[level.offset..level.offset + level.size];
                let out = &mut out[2 * l..];
                match isa.level() {
                    #[cfg(target_arch = "x86_64")]
                    CpuLevel::Avx2 => avx2::forward_level(isa, level, t, &soa, pos.len(), out, width),
                    #[cfg(target_arch = "x86_64")]
                    CpuLevel::Avx512 | CpuLevel::Amx => {
                        avx512::forward_level(isa, level, t, &soa, pos.len(), out, width)
                    }
                    #[cfg(target_arch = "aarch64")]
                    CpuLevel::Neon => neon::forward_level(isa, level, t, &soa, pos.len(), out, width),
                    _ => scalar::forward_level(level, t, &soa, pos.len(), out, width),
                }
            }
            if width > self.features() {
                out.chunks_mut(width).for_each(|row| row[self.features()..].fill(0.0));
            }
        }
    }

    /// Encodes a large batch on the rayon pool (chunks of `CHUNK` samples; the result does
    /// not depend on the thread count).
    pub fn forward_par(&self, isa: Isa, table: &[u32], positions: &[[f32; 3]], out: &mut [f32]) {
        self.check(table.len(), positions.len(), out.len());
        let width = self.output_width();
        positions
            .par_chunks(4 * CHUNK)
            .zip(out.par_chunks_mut(4 * CHUNK * width))
            .for_each(|(p, o)| self.forward(isa, table, p, o));
    }

    /// dL/d(parameters) from dL/d(encoding) `d_out` (`positions.len() × output_width()`; padding
    /// columns ignored), written into
    /// `grads` (`n_params()` floats, entry-major pairs like the table) per `mode`.
    /// Runs one level per rayon task: deterministic and free of atomics.
    pub fn backward_params(
        &self,
        isa: Isa,
        positions: &[[f32; 3]],
        d_out: &[f32],
        grads: &mut [f32],
        mode: GradientMode,
    ) {
        self.check(self.entries, positions.len(), d_out.len());
        let width = self.output_width();
        self.scatter(isa, grads, mode, |l, each| {
            if !positions.is_empty() {
                each(positions, &d_out[2 * l..], width)
            }
        });
    }

    /// [`HashGrid::backward_params`] of a batch held in parts in the level-major layout
    /// ([`FeatureLevels`], e.g. one per slot of the fused training step), scattered part by
    /// part in the order given — the same sums as one concatenated batch. Each level's task
    /// streams 8 bytes of gradient per sample instead of a 64-byte line of the row-major
    /// layout.
    pub fn backward_params_levels(&self, isa: Isa, parts: &[&FeatureLevels], grads: &mut [f32], mode: GradientMode) {
        // A part that never received a sample has no level buffers yet.
        let parts: Vec<&FeatureLevels> = parts.iter().copied().filter(|p| !p.unit.is_empty()).collect();
        for part in &parts {
            assert_eq!(part.levels.len(), self.levels.len(), "hash grid: feature gradient has the wrong level count");
            assert!(
                part.levels.iter().all(|d| d.len() == 2 * part.unit.len()),
                "hash grid: feature gradient is not 2 floats per sample and level"
            );
        }
        self.scatter(isa, grads, mode, |l, each| {
            for part in &parts {
                each(&part.unit, &part.levels[l], 2);
            }
        });
    }

    /// Per level (one rayon task each): zero the level's gradient slice if `mode` overwrites,
    /// then scatter every `(positions, d, stride)` batch `parts` hands out for that level
    /// (`d[i · stride + f]`: sample i's gradient of feature f at that level).
    fn scatter(
        &self,
        isa: Isa,
        grads: &mut [f32],
        mode: GradientMode,
        parts: impl Fn(usize, &mut dyn FnMut(&[[f32; 3]], &[f32], usize)) + Sync,
    ) {
        assert_eq!(grads.len(), self.n_params(), "hash grid: gradient buffer has the wrong length");
        if mode == GradientMode::Ignore {
            return;
        }
        let mut slices = Vec::with_capacity(self.levels.len());
        let mut rest = grads;
        for level in &self.levels {
            let (head, tail) = rest.split_at_mut(FEATURES_PER_LEVEL * level.size);
            slices.push(head);
            rest = tail;
        }
        slices.into_par_iter().enumerate().for_each(|(l, g)| {
            if mode == GradientMode::Overwrite {
                g.fill(0.0);
            }
            let level = &self.levels[l];
            let mut soa = Soa::default();
            parts(l, &mut |positions, d_out, stride| {
                for (c, pos) in positions.chunks(CHUNK).enumerate() {
                    soa.fill(pos);
                    let d = &d_out[c * CHUNK * stride..];
                    match isa.level() {
                        #[cfg(target_arch = "x86_64")]
                        CpuLevel::Avx2 | CpuLevel::Avx512 | CpuLevel::Amx => {
                            avx2::backward_level(isa, level, g, &soa, pos.len(), d, stride)
                        }
                        #[cfg(target_arch = "aarch64")]
                        CpuLevel::Neon => neon::backward_level(isa, level, g, &soa, pos.len(), d, stride),
                        _ => scalar::backward_level(level, g, &soa, pos.len(), d, stride),
                    }
                }
            });
        });
    }

    /// dL/d(position) (unit-cube coordinates) from dL/d(encoding), written into `d_pos`.
    /// Positions outside the cube (zero features) get zero gradient. Scalar: positional
    /// gradients are not on the NeRF's hot path.
    pub fn backward_positions(&self, table: &[u32], positions: &[[f32; 3]], d_out: &[f32], d_pos: &mut [[f32; 3]]) {
        self.check(table.len(), positions.len(), d_out.len());
        assert_eq!(d_pos.len(), positions.len(), "hash grid: d_pos has the wrong length");
        let width = self.output_width();
        for (s, (p, dp)) in positions.iter().zip(d_pos.iter_mut()).enumerate() {
            *dp = [0.0; 3];
            for (l, level) in self.levels.iter().enumerate() {
                let t = &table[level.offset..level.offset + level.size];
                let g = [d_out[s * width + 2 * l], d_out[s * width + 2 * l + 1]];
                let d = scalar::position_gradient(level, t, *p, g);
                for k in 0..3 {
                    dp[k] += d[k];
                }
            }
        }
    }

    fn check(&self, table_len: usize, n: usize, out_len: usize) {
        assert_eq!(table_len, self.entries, "hash grid: table has {table_len} entries, grid needs {}", self.entries);
        assert_eq!(out_len, n * self.output_width(), "hash grid: encoding buffer must hold n × output_width() floats");
    }
}

/// dL/d(encoding) of a batch in the level-major layout the fused training step gathers: the
/// samples' unit positions and, per level, their 2 feature gradients in sample order.
#[derive(Clone, Debug, Default)]
pub struct FeatureLevels {
    /// Unit-cube positions.
    pub unit: Vec<[f32; 3]>,
    /// Per level: `2 × unit.len()` gradients.
    pub levels: Vec<Vec<f32>>,
}

impl FeatureLevels {
    /// Empties the batch, keeping its buffers.
    pub fn clear(&mut self) {
        self.unit.clear();
        self.levels.iter_mut().for_each(Vec::clear);
    }

    /// Appends samples at `unit` with their row-major gradients `d_rows` of `grid`'s encoding
    /// (`unit.len()` rows of its output width).
    pub fn append(&mut self, grid: &HashGrid, unit: &[[f32; 3]], d_rows: &[f32]) {
        let width = grid.output_width();
        assert_eq!(d_rows.len(), unit.len() * width, "hash grid: feature gradient is not rows × width");
        self.unit.extend_from_slice(unit);
        self.levels.resize_with(grid.levels().len(), Vec::new);
        for (l, d) in self.levels.iter_mut().enumerate() {
            d.extend(d_rows.chunks_exact(width).flat_map(|row| [row[2 * l], row[2 * l + 1]]));
        }
    }
}

/// A chunk of positions as structure-of-arrays, padded with zeros to a multiple of 8 lanes.
pub(crate) struct Soa {
    pub x: [f32; CHUNK],
    pub y: [f32; CHUNK],
    pub z: [f32; CHUNK],
}

impl Default for Soa {
    fn default() -> Self {
        Soa { x: [0.0; CHUNK], y: [0.0; CHUNK], z: [0.0; CHUNK] }
    }
}

impl Soa {
    fn fill(&mut self, pos: &[[f32; 3]]) {
        debug_assert!(pos.len() <= CHUNK);
        for (i, p) in pos.iter().enumerate() {
            self.x[i] = p[0];
            self.y[i] = p[1];
            self.z[i] = p[2];
        }
        let padded = pos.len().div_ceil(8) * 8;
        for i in pos.len()..padded {
            self.x[i] = 0.0;
            self.y[i] = 0.0;
            self.z[i] = 0.0;
        }
    }
}

/// Trainable hash-grid parameters: the fp32 master copy the optimiser updates and the fp16
/// mirror (packed pairs) the kernels read. The mirror, gathered at random, lives in huge pages
/// where the OS offers them ([`crate::memory`]).
#[derive(Debug, PartialEq)]
pub struct HashGridParams {
    /// fp32 master weights, `2 · entries` floats (entry-major pairs).
    pub master: Vec<f32>,
    /// fp16 mirror: one `u32` per entry, feature 0 in the low 16 bits.
    pub table: Vec<u32>,
}

impl Clone for HashGridParams {
    fn clone(&self) -> Self {
        HashGridParams { master: self.master.clone(), table: crate::memory::copied_vec(&self.table) }
    }
}

impl HashGridParams {
    /// Instant-NGP's initialisation: uniform in [−1e-4, 1e-4].
    pub fn init(grid: &HashGrid, rng: &mut Rng) -> HashGridParams {
        let master: Vec<f32> = (0..grid.n_params()).map(|_| rng.uniform(-1e-4, 1e-4)).collect();
        Self::from_master(master)
    }

    /// Parameters from given master weights (the mirror is derived).
    pub fn from_master(master: Vec<f32>) -> HashGridParams {
        assert!(master.len().is_multiple_of(2), "hash grid parameters come in pairs");
        let mut p = HashGridParams { table: crate::memory::zeroed_vec(master.len() / 2), master };
        p.sync_mirror();
        p
    }

    /// Rewrites the fp16 mirror from the master copy (round to nearest even).
    pub fn sync_mirror(&mut self) {
        let half: &mut [half::f16] = bytemuck::cast_slice_mut(&mut self.table);
        half::slice::HalfFloatSliceExt::convert_from_f32_slice(half, &self.master);
    }

    /// The fp16 mirror as a slice of halves (feature-interleaved, like `master`).
    pub fn mirror_halves(&self) -> &[half::f16] {
        bytemuck::cast_slice(&self.table)
    }
}

/// Packs two features into one table entry (feature 0 low), rounding to nearest even.
pub fn pack_entry(f0: f32, f1: f32) -> u32 {
    half::f16::from_f32(f0).to_bits() as u32 | (half::f16::from_f32(f1).to_bits() as u32) << 16
}

/// Unpacks a table entry into its two features.
pub fn unpack_entry(e: u32) -> [f32; 2] {
    [half::f16::from_bits(e as u16).to_f32(), half::f16::from_bits((e >> 16) as u16).to_f32()]
}
