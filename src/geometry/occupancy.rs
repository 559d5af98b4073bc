//! Occupancy grid and ray marching (DESIGN §2.5).
//!
//! `R³` cells (R = 128 by default) over the scene box hold the optical thickness of one
//! minimum step, `σ·δ_min`, of the field sampled inside the cell. A cell is **occupied** when
//! its value exceeds `min(0.01, mean)` (Instant-NGP's rule); marching visits only occupied
//! cells, jumping across empty ones to their far boundary.
//!
//! Updates ([`OccupancyGrid::update`], every 16 training steps): during warm-up every cell is
//! evaluated, afterwards ¼ of the cells at random plus ¼ chosen among the occupied ones; each
//! at a jittered point of the cell; `cell = max(old · 0.95, new)`. The field is seen only
//! through a density callback (nerfacc's design), so the grid serves plain and residual
//! fields alike.
//!
//! Marching ([`OccupancyGrid::march`]): constant steps `δ_min = diag / steps_per_diagonal`
//! from the entry into the box, samples at step midpoints inside occupied cells, at most
//! `max_samples` per ray. Samples are packed: one `(start, count)` per ray into flat arrays.
//! Empty space is crossed cell by cell (3-D DDA), and a block of [`BLOCK`]³ cells that is
//! empty as a whole in one jump — the same cells and boundary times, fewer steps.

use super::Aabb;
use crate::rng::Rng;
use glam::Vec3;

/// Occupancy-grid settings.
#[derive(Clone, Debug, PartialEq)]
pub struct OccupancyConfig {
    /// Cells per axis. Defaults to 128.
    pub resolution: u32,
    /// Marching steps across the box diagonal (`δ_min = diag / steps`). Defaults to 1024.
    pub steps_per_diagonal: u32,
    /// Most samples per ray. Defaults to 1024.
    pub max_samples: u32,
    /// Steps whose updates evaluate every cell. Defaults to 256.
    pub warmup_steps: u32,
    /// Decay of a cell's value per update. Defaults to 0.95.
    pub decay: f32,
    /// Marching starts at least this far from the ray origin (dataset units; metres for
    /// ours), so no density can grow right in front of a camera (floaters). Defaults to 0.1.
    pub near: f32,
}

impl Default for OccupancyConfig {
    fn default() -> Self {
        OccupancyConfig {
            resolution: 128,
            steps_per_diagonal: 1024,
            max_samples: 1024,
            warmup_steps: 256,
            decay: 0.95,
            near: 0.1,
        }
    }
}

/// Samples of a batch of rays, packed: ray `r` owns `rays[r] = (start, count)` of the flat arrays.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PackedSamples {
    /// `(start, count)` per ray.
    pub rays: Vec<(u32, u32)>,
    /// Sample distance along the ray (midpoint of its step).
    pub t: Vec<f32>,
    /// Step length.
    pub delta: Vec<f32>,
}

impl PackedSamples {
    /// Total samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Removes everything, keeping capacity.
    pub fn clear(&mut self) {
        self.rays.clear();
        self.t.clear();
        self.delta.clear();
    }
}

/// Entry and exit distance of a ray through the scene box, and its marching lattice: step
/// `k` covers `[near + k·δ, near + (k+1)·δ)`, its sample sits at the midpoint.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RaySpan {
    /// Entry (≥ 0).
    pub near: f32,
    /// Exit.
    pub far: f32,
    /// Lattice steps starting before `far`.
    pub steps: u32,
}

impl RaySpan {
    /// A ray that misses the box (no steps).
    pub const EMPTY: RaySpan = RaySpan { near: 0.0, far: 0.0, steps: 0 };
}

/// How far before the DDA's entry time (in lattice steps) marching resumes after crossing
/// empty cells: the crossing times are sums, so they carry rounding error, and the cell a
/// step's midpoint falls in (`floor(q0 + t·dq)`) is the one that decides.
const RESUME_SLACK: f32 = 0.01;

/// Cells per edge of a coarse block: a block bit says whether any of its `BLOCK³` cells is
/// occupied, so marching crosses empty blocks (most of a room's air) in one step.
pub const BLOCK: u32 = 4;

/// The grid: per-cell optical thickness and the occupancy bitfield.
#[derive(Clone, Debug)]
pub struct OccupancyGrid {
    config: OccupancyConfig,
    aabb: Aabb,
    values: Vec<f32>,
    bits: Vec<u64>,
    /// One bit per block of [`BLOCK`]³ cells (x fastest): any cell in it occupied.
    blocks: Vec<u64>,
    step_size: f32,
    /// Cells kept occupied whatever their value ([`OccupancyGrid::pin`]).
    pinned: Option<Vec<u64>>,
    /// Whether the cells outside the pinned ones are frozen ([`OccupancyGrid::freeze_outside_pins`]).
    frozen: bool,
}

impl OccupancyGrid {
    /// A grid over `aabb` with every cell occupied (training starts by looking everywhere).
    pub fn new(aabb: Aabb, config: OccupancyConfig) -> OccupancyGrid {
        assert!(config.resolution >= 1 && config.resolution <= 1024, "occupancy: resolution must be 1..=1024");
        assert!(aabb.size().min_element() > 0.0 && aabb.size().is_finite(), "occupancy: empty or infinite scene box");
        let n = (config.resolution as usize).pow(3);
        let step_size = aabb.size().length() / config.steps_per_diagonal.max(1) as f32;
        let mut bits = vec![!0u64; n.div_ceil(64)];
        if !n.is_multiple_of(64) {
            // Only the first n bits stand for cells.
            *bits.last_mut().unwrap() = (1u64 << (n % 64)) - 1;
        }
        let mut g = OccupancyGrid {
            values: vec![f32::MAX; n],
            bits,
            blocks: Vec::new(),
            aabb,
            step_size,
            config,
            pinned: None,
            frozen: false,
        };
        g.rebuild_blocks();
        g
    }

    /// The scene box.
    pub fn aabb(&self) -> &Aabb {
        &self.aabb
    }

    /// The marching step `δ_min`.
    pub fn step_size(&self) -> f32 {
        self.step_size
    }

    /// Number of cells.
    pub fn cells(&self) -> usize {
        self.values.len()
    }

    /// Fraction of cells marked occupied.
    pub fn occupancy(&self) -> f64 {
        let set: u64 = self.bits.iter().map(|w| w.count_ones() as u64).sum();
        set as f64 / self.values.len() as f64
    }

    /// Index of the cell holding unit-cube point `u` (clamped into the grid).
    fn cell_of(&self, u: Vec3) -> usize {
        self.index_of_cell(floor3(u * self.config.resolution as f32))
    }

    /// Whether the cell holding world point `p` is occupied.
    pub fn is_occupied(&self, p: Vec3) -> bool {
        let i = self.cell_of(self.aabb.to_unit(p));
        self.bits[i / 64] >> (i % 64) & 1 == 1
    }

    /// One update (see the module docs). `density` fills `sigma[i]` with σ at world points
    /// `points[i]`; it is called with batches of cells. `step` is the training step (for the
    /// warm-up), `rng` draws the cells and jitter.
    pub fn update(&mut self, step: u32, rng: &mut Rng, mut density: impl FnMut(&[Vec3], &mut [f32])) {
        let n = self.values.len();
        let r = self.config.resolution;
        let cells: Vec<u32> = if let (true, Some(p)) = (self.frozen, &self.pinned) {
            super::set_bits(p, n)
        } else if step < self.config.warmup_steps {
            (0..n as u32).collect()
        } else {
            let occupied = super::set_bits(&self.bits, n);
            let mut c: Vec<u32> = (0..n / 4).map(|_| rng.below(n as u64) as u32).collect();
            if !occupied.is_empty() {
                c.extend((0..n / 4).map(|_| occupied[rng.below(occupied.len() as u64) as usize]));
            }
            c
        };
        const BATCH: usize = 1 << 14;
        let mut points = Vec::with_capacity(BATCH);
        let mut sigma = vec![0f32; BATCH];
        let cell_size = self.aabb.size() / r as f32;
        // Each drawn cell's optical thickness, in draw order.
        let mut drawn = Vec::with_capacity(cells.len());
        for chunk in cells.chunks(BATCH) {
            points.clear();
            for &i in chunk {
                let (x, y, z) = (i % r, (i / r) % r, i / (r * r));
                let jitter = Vec3::new(rng.f32(), rng.f32(), rng.f32());
                points.push(self.aabb.min + (Vec3::new(x as f32, y as f32, z as f32) + jitter) * cell_size);
            }
            density(&points, &mut sigma[..chunk.len()]);
            drawn.extend(sigma[..chunk.len()].iter().map(|&s| {
                if s.is_finite() {
                    s.max(0.0) * self.step_size
                } else {
                    0.0
                }
            }));
        }
        let refresh = |old: &mut f32, new: f32| {
            let decayed = if *old == f32::MAX { 0.0 } else { *old * self.config.decay };
            *old = if new.is_finite() { decayed.max(new) } else { decayed };
        };
        if self.frozen {
            // The pinned cells' values only (what `keep_solid` reads; each drawn once); every
            // bit stays: the frozen cells keep theirs, the pinned ones are set.
            for (&i, &v) in cells.iter().zip(&drawn) {
                refresh(&mut self.values[i as usize], v);
            }
            return;
        }
        // A cell drawn more than once keeps its largest thickness; one not drawn only decays.
        let mut fresh = vec![f32::NEG_INFINITY; n];
        for (&i, &v) in cells.iter().zip(&drawn) {
            fresh[i as usize] = fresh[i as usize].max(v);
        }
        for (old, &new) in self.values.iter_mut().zip(&fresh) {
            refresh(old, new);
        }
        self.rebuild_bits();
    }

    /// Freezes every cell outside the pinned ones: [`OccupancyGrid::update`] then refreshes the
    /// pinned cells' values only and leaves every bit as it is. For a grid taken from a frozen
    /// background whose field changes only inside the pinned region (a warm-started residual
    /// model: outside its change region the mixed field is the background bit for bit, so the
    /// background's grid already holds its occupancy there). An update then costs the region's
    /// cells, not the room's (docs/DECISIONS.md, "Where a residual step's time goes").
    pub fn freeze_outside_pins(&mut self) {
        assert!(self.pinned.is_some(), "occupancy: only a grid with pinned cells can freeze the rest");
        self.frozen = true;
    }

    /// Raises each pinned cell's value to the largest `σ·δ_min` at the centres of a
    /// `per_edge³` lattice inside it, if that is larger (values never drop; no bit changes).
    /// For the end of a residual model's training: a refresh draws one point per cell, so a
    /// briefly trained model's values under-report surfaces thinner than a cell, and the
    /// renderers that skip cells by value ([`Self::keep_solid`]) lose them. `density` as in
    /// [`Self::update`]. No-op on a grid without pins.
    pub fn settle_pinned(&mut self, per_edge: u32, mut density: impl FnMut(&[Vec3], &mut [f32])) {
        let Some(p) = &self.pinned else { return };
        let cells = super::set_bits(p, self.values.len());
        let r = self.config.resolution;
        let cell_size = self.aabb.size() / r as f32;
        let per_cell = (per_edge * per_edge * per_edge) as usize;
        let lattice: Vec<Vec3> = (0..per_cell as u32)
            .map(|j| {
                let (x, y, z) = (j % per_edge, j / per_edge % per_edge, j / (per_edge * per_edge));
                (Vec3::new(x as f32, y as f32, z as f32) + 0.5) / per_edge as f32
            })
            .collect();
        let batch = ((1usize << 14) / per_cell).max(1);
        let (mut points, mut sigma) = (Vec::with_capacity(batch * per_cell), vec![0f32; batch * per_cell]);
        for chunk in cells.chunks(batch) {
            points.clear();
            for &i in chunk {
                let corner = Vec3::new((i % r) as f32, (i / r % r) as f32, (i / (r * r)) as f32);
                points.extend(lattice.iter().map(|&u| self.aabb.min + (corner + u) * cell_size));
            }
            let sigma = &mut sigma[..points.len()];
            density(&points, sigma);
            for (&i, s) in chunk.iter().zip(sigma.chunks(per_cell)) {
                let densest = s.iter().filter(|v| v.is_finite()).fold(0f32, |a, &v| a.max(v));
                let v = &mut self.values[i as usize];
                *v = v.max(densest * self.step_size);
            }
        }
    }

    /// Whether the cells outside the pinned ones are frozen.
    pub fn is_frozen_outside_pins(&self) -> bool {
        self.frozen
    }

    /// Whether the grid has pinned cells ([`OccupancyGrid::pin`]).
    pub fn is_pinned(&self) -> bool {
        self.pinned.is_some()
    }

    /// Keeps `region`'s cells occupied from now on, whatever the field's density there (a
    /// residual model's change region: where a new object may stand in what was empty air, so
    /// the residual must be sampled before it has any density). Pins carry over clones and
    /// updates, not model files: a residual model re-pins its region on loading. A region
    /// voted on a finer grid (its resolution a multiple of this grid's) pins every cell holding
    /// one of its cells ([`super::ChangeRegion::coarsened`]).
    pub fn pin(&mut self, region: &super::ChangeRegion) {
        let coarse = region.coarsened(self.config.resolution).filter(|_| *region.aabb() == self.aabb);
        let Some(coarse) = coarse else {
            panic!("occupancy: the pinned region's grid differs from the occupancy grid")
        };
        let p = coarse.bits().to_vec();
        for (b, q) in self.bits.iter_mut().zip(&p) {
            *b |= q;
        }
        self.pinned = Some(p);
        self.rebuild_blocks();
    }

    /// Marks cells whose value passes the optical-thickness rule `σ·δ > min(0.01, mean)`, and
    /// the pinned cells.
    fn rebuild_bits(&mut self) {
        let n = self.values.len();
        let mean = self.values.iter().map(|&v| v as f64).sum::<f64>() / n as f64;
        let threshold = (0.01f64).min(mean) as f32;
        self.bits.fill(0);
        for (i, &v) in self.values.iter().enumerate() {
            if v > threshold {
                self.bits[i / 64] |= 1 << (i % 64);
            }
        }
        if let Some(p) = &self.pinned {
            for (b, q) in self.bits.iter_mut().zip(p) {
                *b |= q;
            }
        }
        self.rebuild_blocks();
    }

    /// Re-derives the block bits from the cell bits.
    fn rebuild_blocks(&mut self) {
        let r = self.config.resolution;
        let br = r.div_ceil(BLOCK);
        self.blocks.clear();
        self.blocks.resize(((br * br * br) as usize).div_ceil(64), 0);
        for z in 0..r {
            for y in 0..r {
                for x in 0..r {
                    let i = (x + r * (y + r * z)) as usize;
                    if self.bits[i / 64] >> (i % 64) & 1 == 1 {
                        let b = (x / BLOCK + br * (y / BLOCK + br * (z / BLOCK))) as usize;
                        self.blocks[b / 64] |= 1 << (b % 64);
                    }
                }
            }
        }
    }

    /// For threshold depth at σ ≥ `min_sigma`: a copy in which a cell stays occupied only if
    /// its value (the largest `σ·δ_min` seen at its sampled points, decayed) also reaches
    /// `fraction · min_sigma · δ_min`, so cells that never showed a density near the threshold
    /// are marched over without evaluating the field (the onboard renderer's solid fraction,
    /// `rnerf eval --solid-fraction`, the prior's depth renders). An approximation: a cell's
    /// value is sampled, not its true maximum.
    pub fn keep_solid(&self, fraction: f32, min_sigma: f32) -> OccupancyGrid {
        let min_value = fraction * min_sigma * self.step_size;
        let mut g = self.clone();
        for (i, &v) in self.values.iter().enumerate() {
            if v < min_value {
                g.bits[i / 64] &= !(1u64 << (i % 64));
            }
        }
        g.rebuild_blocks();
        g
    }

    /// The settings.
    pub fn config(&self) -> &OccupancyConfig {
        &self.config
    }

    /// Per-cell optical thickness `σ·δ_min` (x fastest; `f32::MAX` for cells never evaluated).
    pub fn values(&self) -> &[f32] {
        &self.values
    }

    /// A grid restored from saved [`OccupancyGrid::values`] (the bitfield is rebuilt by the
    /// same rule, so it equals the saved grid's).
    pub fn from_values(aabb: Aabb, config: OccupancyConfig, values: Vec<f32>) -> OccupancyGrid {
        let mut g = OccupancyGrid::new(aabb, config);
        assert_eq!(values.len(), g.values.len(), "occupancy: saved values do not match the resolution");
        if values.iter().any(|&v| v != f32::MAX) {
            g.values = values;
            g.rebuild_bits();
        }
        g
    }

    /// Marches one ray (unit `dir`), appending its samples to `out` (and its `(start, count)`).
    pub fn march(&self, origin: Vec3, dir: Vec3, out: &mut PackedSamples) {
        let start = out.t.len() as u32;
        if let Some(span) = self.span(origin, dir) {
            self.march_segment(
                origin,
                dir,
                span,
                0..span.steps,
                self.config.max_samples as usize,
                1,
                &mut out.t,
                &mut out.delta,
            );
        }
        out.rays.push((start, out.t.len() as u32 - start));
    }

    /// Where a ray (unit `dir`) is inside the box; `None` when it misses.
    pub fn span(&self, origin: Vec3, dir: Vec3) -> Option<RaySpan> {
        let (near, far) = self.aabb.intersect(origin, dir)?;
        let near = near.max(self.config.near);
        let steps = ((far - near) / self.step_size).ceil().min(u32::MAX as f32) as u32;
        (near < far).then_some(RaySpan { near, far, steps })
    }

    /// Appends the samples of the occupied lattice steps among `steps` (a range of the span's
    /// lattice), at most `max`, to `ts`/`deltas`; returns the step to continue from
    /// (`≥ steps.end` once the range is done). Segments concatenate to exactly
    /// [`Self::march`]'s samples, and a sample's `t` depends only on its step.
    ///
    /// `stride > 1`: outside the pinned cells (a residual model's change region; everywhere on
    /// a grid without pins) one sample stands for a run of up to `stride` consecutive occupied
    /// steps, at the run's middle with `δ = run · step`. Runs end before an empty or a pinned
    /// step, so the samples cover the same lattice steps as with `stride = 1` (the same `Σ δ`)
    /// and those inside the pinned cells are the same samples. `stride = 1`: every step.
    #[allow(clippy::too_many_arguments)]
    pub fn march_segment(
        &self,
        origin: Vec3,
        dir: Vec3,
        span: RaySpan,
        steps: std::ops::Range<u32>,
        max: usize,
        stride: u32,
        ts: &mut Vec<f32>,
        deltas: &mut Vec<f32>,
    ) -> u32 {
        let pins = self.pinned.as_deref();
        let bit = |bits: &[u64], i: usize| bits[i / 64] >> (i % 64) & 1 == 1;
        let res = self.config.resolution as i32;
        let r = res as f32;
        let dt = self.step_size;
        let near = span.near;
        // Grid coordinates are affine in t: q(t) = q0 + t·dq.
        let to_grid = self.aabb.size().recip() * r;
        let (q0, dq) = ((origin - self.aabb.min) * to_grid, dir * to_grid);
        let (mut k, end) = (steps.start, steps.end);
        let mut taken = 0;
        while k < end && taken < max {
            let mid = near + (k as f32 + 0.5) * dt;
            let c = floor3(q0 + mid * dq);
            let i = self.index_of_cell(c);
            if bit(&self.bits, i) {
                let mut run = 1;
                if stride > 1 && pins.is_none_or(|p| !bit(p, i)) {
                    while run < stride && k + run < end {
                        let i = self.index_of_cell(floor3(q0 + (near + ((k + run) as f32 + 0.5) * dt) * dq));
                        if !bit(&self.bits, i) || pins.is_some_and(|p| bit(p, i)) {
                            break;
                        }
                        run += 1;
                    }
                }
                if run == 1 {
                    ts.push(mid);
                    deltas.push(dt);
                } else {
                    ts.push(near + (k as f32 + 0.5 * run as f32) * dt);
                    deltas.push(dt * run as f32);
                }
                taken += 1;
                k += run;
            } else {
                // Walk the cells after this empty one (3-D DDA) to the next occupied one, then
                // resume at the first step whose midpoint lies past the entry into it, less
                // RESUME_SLACK: the DDA's summed crossing times can land a few ulps late, and
                // a midpoint that close to the entry is checked above by its own cell rather
                // than skipped (when that cell is empty, the next pass moves on by one step).
                let entry = self.next_occupied(q0, dq, c, res, span.far);
                let past = floor1(((entry - near) / dt - 0.5 - RESUME_SLACK).min(end as f32)) + 1.0;
                k = (past.max(0.0) as u32).max(k + 1);
            }
        }
        k
    }

    /// Where the ray `q0 + t·dq` (grid coordinates) enters the first occupied cell after cell
    /// `c` (Amanatides–Woo stepping); `f32::INFINITY` when it leaves the grid, or passes `far`,
    /// first.
    fn next_occupied(&self, q0: Vec3, dq: Vec3, c: Vec3, res: i32, far: f32) -> f32 {
        let mut cell = [c.x as i32, c.y as i32, c.z as i32];
        let mut t_next = [0.0f32; 3];
        let mut t_cell = [0.0f32; 3];
        let mut step = [0i32; 3];
        for a in 0..3 {
            cell[a] = cell[a].clamp(0, res - 1);
            if dq[a] > 0.0 {
                (step[a], t_cell[a]) = (1, dq[a].recip());
                t_next[a] = (cell[a] as f32 + 1.0 - q0[a]) * t_cell[a];
            } else if dq[a] < 0.0 {
                (step[a], t_cell[a]) = (-1, -dq[a].recip());
                t_next[a] = (q0[a] - cell[a] as f32) * t_cell[a];
            } else {
                t_next[a] = f32::INFINITY;
            }
        }
        let stride = [1, res as usize, (res * res) as usize];
        let br = (res as u32).div_ceil(BLOCK) as usize;
        let block = |cell: &[i32; 3]| {
            let b = cell.map(|c| c as usize / BLOCK as usize);
            let b = b[0] + br * (b[1] + br * b[2]);
            self.blocks[b / 64] >> (b % 64) & 1 == 1
        };
        let mut i = cell[0] as usize + stride[1] * cell[1] as usize + stride[2] * cell[2] as usize;
        loop {
            let a = if t_next[0] < t_next[1] {
                if t_next[0] < t_next[2] {
                    0
                } else {
                    2
                }
            } else if t_next[1] < t_next[2] {
                1
            } else {
                2
            };
            let t = t_next[a];
            cell[a] += step[a];
            if !(0..res).contains(&cell[a]) || t >= far {
                return f32::INFINITY;
            }
            i = if step[a] > 0 { i + stride[a] } else { i - stride[a] };
            t_next[a] += t_cell[a];
            if self.bits[i / 64] >> (i % 64) & 1 == 1 {
                return t;
            }
            if !block(&cell) {
                // Every cell of this block is empty: take, per axis, the crossings that stay
                // inside it (the same additions as the steps above, so the same times), up to
                // the first crossing that leaves it, which the loop then takes as usual.
                let mut t_exit = f32::INFINITY;
                for a in 0..3 {
                    let inside = match step[a] {
                        1 => ((cell[a] as u32 / BLOCK + 1) * BLOCK).min(res as u32) as i32 - 1 - cell[a],
                        -1 => cell[a] - (cell[a] as u32 / BLOCK * BLOCK) as i32,
                        _ => continue,
                    };
                    let mut tl = t_next[a];
                    for _ in 0..inside {
                        tl += t_cell[a];
                    }
                    t_exit = t_exit.min(tl);
                }
                for a in 0..3 {
                    while t_next[a] < t_exit {
                        cell[a] += step[a];
                        t_next[a] += t_cell[a];
                    }
                }
                i = cell[0] as usize + stride[1] * cell[1] as usize + stride[2] * cell[2] as usize;
            }
        }
    }

    /// Index of the cell at (floored) grid coordinates `c`, clamped into the grid.
    #[inline]
    fn index_of_cell(&self, c: Vec3) -> usize {
        let r = self.config.resolution;
        let c = c.clamp(Vec3::ZERO, Vec3::splat((r - 1) as f32)).as_uvec3();
        (c.x + r * (c.y + r * c.z)) as usize
    }
}

/// `x.floor()` without a libm call (the build's baseline has no `roundss`): exact for
/// |x| < 2³¹; NaN gives 0 (every caller clamps into the grid).
#[inline]
fn floor1(x: f32) -> f32 {
    let f = x as i32 as f32;
    if f > x {
        f - 1.0
    } else {
        f
    }
}

#[inline]
fn floor3(v: Vec3) -> Vec3 {
    Vec3::new(floor1(v.x), floor1(v.y), floor1(v.z))
}
