//! What each `rnerf` command does (DESIGN §4): the binary parses with [`crate::cli`] and calls
//! [`run`]. Every error is one line naming the file, frame and field; nothing is written until
//! the inputs have been read and checked, and every file is written atomically.

mod compare;
mod eval;
mod progress;
mod render;
mod train;

pub use compare::{compare_and_write, demo_config, train_background, SceneData, DEMO};
pub use eval::{evaluate, EvalOptions, EvalReport};
pub use progress::Progress;
pub use train::checkpoint_path;

use crate::bench::{self, BenchOptions};
use crate::cli::Command;

/// Loads a dataset split for a command: the error as its one line, each warning printed as
/// `rnerf: warning: …` on stderr.
pub(crate) fn load_data(
    dir: &std::path::Path,
    split: &str,
    opts: &crate::data::LoadOptions,
) -> Result<crate::data::Dataset, String> {
    let data = crate::data::Dataset::load(dir, split, opts).map_err(|e| e.to_string())?;
    for w in &data.warnings {
        eprintln!("rnerf: warning: {w}");
    }
    Ok(data)
}

/// The renderer's trades as `rnerf eval` and `rnerf render` take them: the depth-only path's
/// onboard trades (`--solid-fraction F`, `--coarse-start N|off`) and the colour pass's colour
/// tail (`--colour-tail R|off`). Sets `renderer`'s coarse start and colour tail and returns the
/// scene's grid thinned to `solid_fraction` of `m` (`None` at 0: every occupied cell), for
/// [`Scene::with_grid`]. The first two apply to the depth-only path alone, the tail to the
/// colour pass alone (the depth-only path never reads it).
fn onboard_trades<M: crate::field::model::Model>(
    scene: &crate::render::view::Scene<'_, M>,
    m: crate::render::DensityThreshold,
    depth_only: bool,
    solid_fraction: f32,
    coarse_start: Option<u32>,
    colour_tail: f32,
    renderer: &mut crate::render::ViewRenderer<M>,
) -> Option<crate::geometry::occupancy::OccupancyGrid> {
    assert!(solid_fraction == 0.0 || depth_only, "a solid fraction applies to the depth-only path");
    assert!(coarse_start.is_none() || depth_only, "a coarse start applies to the depth-only path");
    renderer.set_coarse_start(coarse_start);
    renderer.set_colour_tail(colour_tail);
    (solid_fraction > 0.0).then(|| scene.occupancy.keep_solid(solid_fraction, m.min_sigma()))
}

/// A failed command: its one-line message and the process's exit code.
#[derive(Debug)]
pub struct Failure {
    /// One line naming the file, frame and field.
    pub message: String,
    /// 1 for errors; 128 + signal for an interrupted run.
    pub code: u8,
}

impl From<String> for Failure {
    fn from(message: String) -> Failure {
        Failure { message, code: 1 }
    }
}

impl From<crate::error::Error> for Failure {
    fn from(e: crate::error::Error) -> Failure {
        Failure { message: e.into(), code: 1 }
    }
}

/// Runs a parsed command.
pub fn run(command: Command) -> Result<(), Failure> {
    match command {
        Command::Help => println!("{}", crate::cli::USAGE),
        Command::ImportColmap(options) => {
            let r = crate::data::colmap::import(&options)?;
            for (path, n) in &r.written {
                println!("rnerf import: wrote {} ({n} frames)", path.display());
            }
            match &options.known_distance {
                Some((a, b, m)) => println!(
                    "rnerf import: scale from --known-distance ({a} to {b} is {m} m): 1 COLMAP unit = {:.6} m (metres_per_unit)",
                    r.metres_per_unit
                ),
                None => eprintln!(
                    "rnerf: warning: no --known-distance: COLMAP's unit is taken as a metre, so threshold depth (sigma per metre) and depth are in COLMAP's arbitrary unit"
                ),
            }
            if r.aabb.is_none() {
                eprintln!("rnerf: warning: the model has too few 3D points for a scene box; the loader derives one from the cameras");
            }
        }
        Command::Train(args) => {
            set_threads(args.threads)?;
            train::run(&args)?;
        }
        Command::Render { model, data, out, split, rendering, threads } => {
            set_threads(threads)?;
            render::run(&model, &data, &split, &rendering, &out)?;
        }
        Command::Eval { model, data, split, rendering, crop, limit, json, threads } => {
            set_threads(threads)?;
            eval::run(&model, &data, &split, &rendering, crop, limit, json)?;
        }
        Command::Bench { json, reps, log2t, threads, models, data, background_data, scene } => {
            set_threads(threads)?;
            let trained = match &data {
                Some(d) => models.iter().map(|m| bench::TrainedView::load(m, d)).collect::<Result<Vec<_>, _>>()?,
                None => Vec::new(),
            };
            for (i, t) in trained.iter().enumerate() {
                if trained[..i].iter().any(|u| u.figure() == t.figure()) {
                    return Err(format!("bench: two --model files would both time {}", t.figure()).into());
                }
            }
            let defaults = BenchOptions::default();
            let opts = BenchOptions {
                reps: reps.unwrap_or(defaults.reps),
                log2_table_size: log2t.unwrap_or(defaults.log2_table_size),
                ..defaults
            };
            // The datasets of the time-to-quality figures are read before anything runs.
            let quality = match (&background_data, &scene) {
                (Some(bg), Some(sc)) => Some(compare::QualityData::load(bg, sc, log2t)?),
                _ => None,
            };
            let mut report = bench::run(&opts, trained);
            if let Some(q) = &quality {
                report.quality = q.measure(opts.isa)?;
            }
            if json {
                println!("{}", report.to_json());
            } else {
                print!("{}", report.to_table());
            }
        }
        Command::Compare(args) => {
            set_threads(args.threads)?;
            compare::run(&args)?;
        }
        Command::Demo { out, steps, size, seed, threads } => {
            set_threads(threads)?;
            compare::demo(&out.unwrap_or_else(|| "rnerf-demo".into()), steps, size, seed)?;
        }
    }
    Ok(())
}

/// Sizes the global rayon pool (all cores when `None`).
fn set_threads(threads: Option<usize>) -> Result<(), String> {
    if let Some(n) = threads {
        rayon::ThreadPoolBuilder::new().num_threads(n).build_global().map_err(|e| format!("--threads: {e}"))?;
    }
    Ok(())
}

/// Checks that `path`'s directory exists (before any work whose result would go there).
fn check_output_file(path: &std::path::Path, flag: &str) -> Result<(), String> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => std::path::Path::new("."),
    };
    if !dir.is_dir() {
        return Err(format!("{}: {flag}: directory {} does not exist", path.display(), dir.display()));
    }
    if path.is_dir() {
        return Err(format!("{}: {flag}: is a directory, expected a file path", path.display()));
    }
    Ok(())
}
