//! `rnerf`: the command-line face of residual-nerf (DESIGN §4). Parsing lives in
//! [`residual_nerf::cli`]; this file only runs the parsed command.

use residual_nerf::bench::{self, BenchOptions};
use residual_nerf::cli::{self, Command};
use residual_nerf::demo::{fit_field, FieldFitConfig};
use residual_nerf::simd::Isa;
use std::process::ExitCode;

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("rnerf: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run() -> Result<(), String> {
    match cli::parse(std::env::args_os().skip(1)).map_err(|e| e.to_string())? {
        Command::Help => println!("{}", cli::USAGE),
        Command::Bench { json, reps, log2t, threads } => {
            set_threads(threads)?;
            let defaults = BenchOptions::default();
            let opts = BenchOptions {
                reps: reps.unwrap_or(defaults.reps),
                log2_table_size: log2t.unwrap_or(defaults.log2_table_size),
                ..defaults
            };
            let report = bench::run(&opts);
            if json {
                println!("{}", report.to_json());
            } else {
                print!("{}", report.to_table());
            }
        }
        Command::Demo { steps, seed, threads } => {
            set_threads(threads)?;
            let defaults = FieldFitConfig::default();
            let cfg = FieldFitConfig {
                steps: steps.unwrap_or(defaults.steps),
                seed: seed.unwrap_or(defaults.seed),
                ..defaults
            };
            eprintln!("rnerf demo: fitting a synthesised 3-D field ({} steps, cpu level {})", cfg.steps, Isa::detect());
            let report = fit_field(&cfg, Isa::detect(), |line| eprintln!("{line}"));
            println!("{report}");
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
