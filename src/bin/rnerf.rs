//! `rnerf`: the command-line face of residual-nerf (DESIGN §4).

use residual_nerf::bench::{self, BenchOptions};
use residual_nerf::simd::Isa;
use std::process::ExitCode;

const USAGE: &str = "usage: rnerf <command> [options]

commands:
  bench [--json] [--reps N] [--log2t N] [--threads N]
        throughput of the hot kernels on this machine (one JSON object with --json)
  demo  [--steps N] [--threads N] [--seed S]
        fit the hash grid + MLPs to a synthesised 3-D field (until the NeRF pipeline lands)
  help  this text

environment: RNERF_CPU_LEVEL=scalar|avx2|neon lowers the SIMD level (never raises it)";

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
    let mut parser = lexopt::Parser::from_env();
    let command = match parser.next().map_err(|e| e.to_string())? {
        Some(lexopt::Arg::Value(v)) => v.into_string().map_err(|_| "command is not valid UTF-8".to_string())?,
        Some(lexopt::Arg::Long("help")) | Some(lexopt::Arg::Short('h')) | None => {
            println!("{USAGE}");
            return Ok(());
        }
        Some(other) => return Err(format!("expected a command before {}\n{USAGE}", describe(&other))),
    };
    match command.as_str() {
        "bench" => cmd_bench(&mut parser),
        "demo" => cmd_demo(&mut parser),
        "help" => {
            println!("{USAGE}");
            Ok(())
        }
        other => Err(format!("unknown command '{other}' (try 'rnerf help')")),
    }
}

fn describe(arg: &lexopt::Arg) -> String {
    match arg {
        lexopt::Arg::Short(c) => format!("'-{c}'"),
        lexopt::Arg::Long(l) => format!("'--{l}'"),
        lexopt::Arg::Value(v) => format!("'{}'", v.to_string_lossy()),
    }
}

/// Parses the value of `--name` as a `T`, naming the flag in the error.
fn value<T: std::str::FromStr>(parser: &mut lexopt::Parser, name: &str) -> Result<T, String> {
    let raw = parser.value().map_err(|e| format!("--{name}: {e}"))?;
    let s = raw.to_string_lossy();
    s.parse().map_err(|_| format!("--{name}: '{s}' is not a valid value"))
}

fn set_threads(threads: Option<usize>) -> Result<(), String> {
    if let Some(n) = threads {
        if n == 0 {
            return Err("--threads: must be at least 1".into());
        }
        rayon::ThreadPoolBuilder::new().num_threads(n).build_global().map_err(|e| format!("--threads: {e}"))?;
    }
    Ok(())
}

fn cmd_bench(parser: &mut lexopt::Parser) -> Result<(), String> {
    let mut opts = BenchOptions::default();
    let mut json = false;
    let mut threads = None;
    while let Some(arg) = parser.next().map_err(|e| e.to_string())? {
        match arg {
            lexopt::Arg::Long("json") => json = true,
            lexopt::Arg::Long("reps") => opts.reps = value(parser, "reps")?,
            lexopt::Arg::Long("log2t") => opts.log2_table_size = value(parser, "log2t")?,
            lexopt::Arg::Long("threads") => threads = Some(value(parser, "threads")?),
            other => return Err(format!("bench: unexpected argument {}", describe(&other))),
        }
    }
    if opts.reps == 0 {
        return Err("--reps: must be at least 1".into());
    }
    if !(4..=26).contains(&opts.log2_table_size) {
        return Err(format!("--log2t: {} is outside 4..=26", opts.log2_table_size));
    }
    set_threads(threads)?;
    opts.isa = Isa::detect();
    let report = bench::run(&opts);
    if json {
        println!("{}", report.to_json());
    } else {
        print!("{}", report.to_table());
    }
    Ok(())
}

fn cmd_demo(parser: &mut lexopt::Parser) -> Result<(), String> {
    let mut cfg = residual_nerf::demo::FieldFitConfig::default();
    let mut threads = None;
    while let Some(arg) = parser.next().map_err(|e| e.to_string())? {
        match arg {
            lexopt::Arg::Long("steps") => cfg.steps = value(parser, "steps")?,
            lexopt::Arg::Long("seed") => cfg.seed = value(parser, "seed")?,
            lexopt::Arg::Long("threads") => threads = Some(value(parser, "threads")?),
            other => return Err(format!("demo: unexpected argument {}", describe(&other))),
        }
    }
    set_threads(threads)?;
    let report = residual_nerf::demo::fit_field(&cfg, Isa::detect(), |line| eprintln!("{line}"));
    println!("{report}");
    Ok(())
}
