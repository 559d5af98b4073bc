//! What `rnerf bench` reports: each figure a named field of a typed struct (its name is its
//! JSON key and its row in BENCHMARKS.md), the kernels' and the pipeline's figures as
//! measured, the derived ones (roofline bounds and ratios) computed from their medians, and
//! the report's JSON object and table.

/// Median and spread of one figure.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stat {
    /// Median over repetitions.
    pub median: f64,
    /// Smallest repetition.
    pub min: f64,
    /// Largest repetition.
    pub max: f64,
}

impl Stat {
    /// Median, min and max of repetitions (at least one).
    pub fn of(mut v: Vec<f64>) -> Stat {
        assert!(!v.is_empty(), "a figure needs at least one repetition");
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let median = if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) };
        Stat { median, min: v[0], max: v[n - 1] }
    }

    /// A figure computed once (no spread).
    pub fn exact(v: f64) -> Stat {
        Stat { median: v, min: v, max: v }
    }
}

/// A field of a figures struct: measured ([`Stat`]), measured on some levels only
/// (`Option<Stat>`), or derived (`f64`, NaN when an input is missing).
pub trait Figure {
    /// The figure as a statistic, `None` if not measured.
    fn stat(&self) -> Option<Stat>;
}

impl Figure for Stat {
    fn stat(&self) -> Option<Stat> {
        Some(*self)
    }
}

impl Figure for Option<Stat> {
    fn stat(&self) -> Option<Stat> {
        *self
    }
}

impl Figure for f64 {
    fn stat(&self) -> Option<Stat> {
        Some(Stat::exact(*self))
    }
}

/// Declares a struct of figures and, from the same lines, the one list of their names and
/// units ([`KernelFigures::each`] …) that the JSON and the table are written from.
macro_rules! figures {
    ($(#[doc = $sdoc:literal])* $name:ident { $( $(#[doc = $doc:literal])* $field:ident : $ty:ty = $unit:literal, )* }) => {
        $(#[doc = $sdoc])*
        #[derive(Clone, Debug, PartialEq)]
        pub struct $name { $( $(#[doc = $doc])* pub $field: $ty, )* }

        impl $name {
            /// Each figure, in the order measured: its name (the JSON key), unit and value.
            pub fn each(&self) -> Vec<(&'static str, &'static str, Option<Stat>)> {
                vec![$((stringify!($field), $unit, Figure::stat(&self.$field))),*]
            }
        }
    };
}

figures! {
    /// The kernels alone and the machine's limits, measured in the same run
    /// ([`super::kernels`]).
    KernelFigures {
        /// fp32 FMA loop, one thread.
        fma_peak_gflops_1t: Stat = "GFLOP/s",
        /// fp32 FMA loop, all threads.
        fma_peak_gflops: Stat = "GFLOP/s",
        /// The AMX tile unit's bf16 loop, one thread (AMX level only).
        tile_peak_gflops_1t: Option<Stat> = "GFLOP/s",
        /// The NeRF's two networks, fused forward + backward, one thread.
        mlp_fwd_bwd_gflops_1t: Stat = "GFLOP/s",
        /// The same in samples.
        mlp_fwd_bwd_samples_per_s_1t: Stat = "samples/s",
        /// The same on all threads.
        mlp_fwd_bwd_gflops: Stat = "GFLOP/s",
        /// The same in samples, all threads.
        mlp_fwd_bwd_samples_per_s: Stat = "samples/s",
        /// Hash-grid forward, ray-coherent samples, one thread.
        hash_grid_fwd_ns_per_sample_1t: Stat = "ns/sample",
        /// Hash-grid backward (level-major feature gradients, as training runs it), one thread.
        hash_grid_bwd_ns_per_sample_1t: Stat = "ns/sample",
        /// Hash-grid forward, all threads.
        hash_grid_fwd_ns_per_sample: Stat = "ns/sample",
        /// Hash-grid backward, all threads.
        hash_grid_bwd_ns_per_sample: Stat = "ns/sample",
        /// Hash-grid backward from row-major feature gradients, all threads.
        hash_grid_bwd_row_major_ns_per_sample: Stat = "ns/sample",
        /// A bare random-gather loop over a table of the grid's size, one thread.
        gather_limit_ns_per_sample_1t: Stat = "ns/sample",
        /// The Mixnet's own grid (8 levels, 2^15 entries), forward, all threads.
        mixnet_grid_fwd_ns_per_sample: Stat = "ns/sample",
        /// Its backward, all threads.
        mixnet_grid_bwd_ns_per_sample: Stat = "ns/sample",
        /// Adam over the grid's parameters with the fp16 mirror, one thread.
        adam_ns_per_param_1t: Stat = "ns/param",
        /// The same, all threads.
        adam_ns_per_param: Stat = "ns/param",
    }
}

figures! {
    /// The pipeline: fused training steps, depth views and occupancy updates
    /// ([`super::pipeline`]).
    PipelineFigures {
        /// NeRF training samples per second (the last quarter of a short run).
        train_samples_per_s: Stat = "samples/s",
        /// NeRF training rays per second.
        train_rays_per_s: Stat = "rays/s",
        /// Residual training samples per second.
        train_residual_samples_per_s: Stat = "samples/s",
        /// Residual training rays per second.
        train_residual_rays_per_s: Stat = "rays/s",
        /// One 200-pixel-wide threshold-depth view of a NeRF (the robot's library call).
        render_depth_ms_200: Stat = "ms",
        /// The same of a residual model.
        render_depth_ms_200_residual: Stat = "ms",
        /// One 640×480 threshold-depth view of the NeRF (a depth camera's size).
        render_depth_ms_640x480: Stat = "ms",
        /// The same of the residual model.
        render_depth_ms_640x480_residual: Stat = "ms",
        /// An occupancy-grid update of the warm-up (every cell).
        occupancy_update_ms_warmup: Stat = "ms",
        /// A later update (¼ random + ¼ occupied cells).
        occupancy_update_ms: Stat = "ms",
    }
}

figures! {
    /// Training time to quality on a captured background and scene ([`super::quality`],
    /// `rnerf bench --background-data BG --scene S`); each one measurement, absent without
    /// those flags (and the background's three when it never reached the PSNR).
    QualityFigures {
        /// The background's training seconds until its test PSNR first reached 28 dB.
        background_seconds_to_28db: Option<Stat> = "s",
        /// The same in steps (a multiple of the curve's 100).
        background_steps_to_28db: Option<Stat> = "steps",
        /// Its test PSNR there.
        background_test_psnr_at_28db: Option<Stat> = "dB",
        /// The scene prior's seconds (change maps, region, registration) before training.
        scene_prior_seconds: Option<Stat> = "s",
        /// The default Residual-NeRF's training seconds until its object-mask MAE is within 5%
        /// of its final one.
        scene_seconds_to_quality: Option<Stat> = "s",
        /// The same in steps.
        scene_steps_to_quality: Option<Stat> = "steps",
        /// Its whole training's seconds.
        scene_seconds: Option<Stat> = "s",
        /// Its final object-mask MAE of threshold depth.
        scene_final_object_mae_m: Option<Stat> = "m",
    }
}

impl QualityFigures {
    /// None measured (a bench run without a dataset pair).
    pub fn none() -> QualityFigures {
        QualityFigures {
            background_seconds_to_28db: None,
            background_steps_to_28db: None,
            background_test_psnr_at_28db: None,
            scene_prior_seconds: None,
            scene_seconds_to_quality: None,
            scene_steps_to_quality: None,
            scene_seconds: None,
            scene_final_object_mae_m: None,
        }
    }
}

figures! {
    /// Bounds and ratios computed from the medians of the measured figures.
    DerivedFigures {
        /// One training sample's three kernels (grid forward, MLP forward + backward, grid
        /// backward) at their all-thread rates: the pipeline's own roofline.
        train_kernel_bound_samples_per_s: f64 = "samples/s",
        /// A residual training sample's kernels: the background's forward, the residual's full
        /// pass and the Mixnet's.
        train_residual_kernel_bound_samples_per_s: f64 = "samples/s",
        /// The MLP's one-thread rate against the FMA peak.
        mlp_fraction_of_fma_peak_1t: f64 = "ratio",
        /// Against the unit the level runs the MLP's products on (the tile unit at AMX).
        mlp_fraction_of_level_peak_1t: f64 = "ratio",
        /// All threads over one thread.
        mlp_thread_scaling: f64 = "ratio",
        /// NeRF training against its kernel bound.
        train_fraction_of_kernel_bound: f64 = "ratio",
        /// Residual training against its kernel bound.
        train_residual_fraction_of_kernel_bound: f64 = "ratio",
        /// Grid forward + backward over the bare gather, one thread.
        hash_grid_fwd_bwd_over_gather_limit_1t: f64 = "ratio",
    }
}

impl DerivedFigures {
    /// The derived figures. `mixnet_mac_share`: the Mixnet's network against the NeRF's two,
    /// in executed forward + backward multiply-adds per sample (its 32 → 32 → 1 network costed
    /// by that share of the measured MLP rate).
    pub fn of(k: &KernelFigures, p: &PipelineFigures, mixnet_mac_share: f64) -> DerivedFigures {
        let mlp_ns = 1e9 / k.mlp_fwd_bwd_samples_per_s.median;
        let (grid_fwd, grid_bwd) = (k.hash_grid_fwd_ns_per_sample.median, k.hash_grid_bwd_ns_per_sample.median);
        let mixnet_ns =
            k.mixnet_grid_fwd_ns_per_sample.median + k.mixnet_grid_bwd_ns_per_sample.median + mlp_ns * mixnet_mac_share;
        let bound = 1e9 / (mlp_ns + grid_fwd + grid_bwd);
        // The background's forward: its grid forward and its networks' forward, ⅓ of their
        // forward + backward FLOPs.
        let residual_bound = 1e9 / (grid_fwd + mlp_ns / 3.0 + mlp_ns + grid_fwd + grid_bwd + mixnet_ns);
        let level_peak = k.tile_peak_gflops_1t.unwrap_or(k.fma_peak_gflops_1t).median;
        DerivedFigures {
            train_kernel_bound_samples_per_s: bound,
            train_residual_kernel_bound_samples_per_s: residual_bound,
            mlp_fraction_of_fma_peak_1t: k.mlp_fwd_bwd_gflops_1t.median / k.fma_peak_gflops_1t.median,
            mlp_fraction_of_level_peak_1t: k.mlp_fwd_bwd_gflops_1t.median / level_peak,
            mlp_thread_scaling: k.mlp_fwd_bwd_gflops.median / k.mlp_fwd_bwd_gflops_1t.median,
            train_fraction_of_kernel_bound: p.train_samples_per_s.median / bound,
            train_residual_fraction_of_kernel_bound: p.train_residual_samples_per_s.median / residual_bound,
            hash_grid_fwd_bwd_over_gather_limit_1t: (k.hash_grid_fwd_ns_per_sample_1t.median
                + k.hash_grid_bwd_ns_per_sample_1t.median)
                / k.gather_limit_ns_per_sample_1t.median,
        }
    }
}

/// All figures of one run.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchReport {
    /// CPU level the kernels ran at.
    pub cpu_level: String,
    /// Threads of the rayon pool ("all threads").
    pub threads: usize,
    /// log2 table size of the grid figures.
    pub log2_table_size: u32,
    /// The kernels and the machine's limits.
    pub kernels: KernelFigures,
    /// The pipeline.
    pub pipeline: PipelineFigures,
    /// Bounds and ratios.
    pub derived: DerivedFigures,
    /// Time to quality on a dataset pair (none measured without one).
    pub quality: QualityFigures,
}

impl BenchReport {
    /// Every measured figure, in order: (name, unit, statistic).
    pub fn each(&self) -> Vec<(&'static str, &'static str, Stat)> {
        let all = (self.kernels.each().into_iter().chain(self.pipeline.each()).chain(self.derived.each()))
            .chain(self.quality.each());
        all.filter_map(|(name, unit, s)| Some((name, unit, s?))).collect()
    }

    /// One JSON object: every figure's median under its name, plus `spread` ([min, max]).
    pub fn to_json(&self) -> serde_json::Value {
        let mut o = serde_json::Map::new();
        o.insert("cpu_level".into(), self.cpu_level.clone().into());
        o.insert("threads".into(), self.threads.into());
        o.insert("log2_table_size".into(), self.log2_table_size.into());
        let mut spread = serde_json::Map::new();
        for (name, _, s) in self.each() {
            o.insert(name.into(), round4(s.median).into());
            spread.insert(name.into(), serde_json::json!([round4(s.min), round4(s.max)]));
        }
        o.insert("spread".into(), spread.into());
        serde_json::Value::Object(o)
    }

    /// A human-readable table.
    pub fn to_table(&self) -> String {
        let mut s = format!(
            "cpu level {}, {} threads, hash grid log2T={}\n",
            self.cpu_level, self.threads, self.log2_table_size
        );
        for (name, unit, st) in self.each() {
            s += &format!("{name:<44} {:>12.3} [{:>10.3} .. {:>10.3}] {unit}\n", st.median, st.min, st.max);
        }
        s
    }
}

/// Four significant digits.
fn round4(x: f64) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    let mag = 10f64.powi(3 - x.abs().log10().floor() as i32);
    (x * mag).round() / mag
}
