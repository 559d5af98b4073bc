//! Command-line parsing for `rnerf` (DESIGN §4), kept in the library so it is tested and
//! fuzzed like any other parser of untrusted input. Parsing never panics: every problem is a
//! one-line [`CliError`] naming the flag.

use std::ffi::OsString;
use std::fmt;

/// Usage text printed by `rnerf help`.
pub const USAGE: &str = "usage: rnerf <command> [options]

commands:
  demo  [--steps N] [--threads N] [--seed S]
        fit the hash grid + MLP to a synthesised 3-D field and report held-out PSNR
        (becomes the Residual-NeRF demo once the rendering pipeline lands)
  bench [--json] [--reps N] [--log2t N] [--threads N]
        throughput of the hot kernels on this machine (one JSON object with --json)
  help  this text

environment: RNERF_CPU_LEVEL=scalar|avx2|neon lowers the SIMD level (never raises it)";

/// A parsed command line.
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    /// `rnerf demo`.
    Demo {
        /// Training steps (`--steps`).
        steps: Option<u32>,
        /// Seed (`--seed`).
        seed: Option<u64>,
        /// Worker threads (`--threads`); all cores when absent.
        threads: Option<usize>,
    },
    /// `rnerf bench`.
    Bench {
        /// One JSON object instead of a table (`--json`).
        json: bool,
        /// Repetitions per figure (`--reps`).
        reps: Option<usize>,
        /// Hash-grid table size (`--log2t`).
        log2t: Option<u32>,
        /// Worker threads (`--threads`).
        threads: Option<usize>,
    },
    /// `rnerf help`, `-h`, `--help` or no arguments.
    Help,
}

/// A command-line error: one line saying what is wrong and where.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CliError(pub String);

impl fmt::Display for CliError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for CliError {}

fn err(msg: impl Into<String>) -> CliError {
    CliError(msg.into())
}

/// Parses the arguments after the program name.
pub fn parse(args: impl IntoIterator<Item = OsString>) -> Result<Command, CliError> {
    use lexopt::Arg::{Long, Short, Value};
    let mut p = lexopt::Parser::from_args(args);
    let command = match p.next().map_err(|e| err(e.to_string()))? {
        None | Some(Long("help")) | Some(Short('h')) => return Ok(Command::Help),
        Some(Value(v)) => {
            v.into_string().map_err(|v| err(format!("command '{}' is not valid UTF-8", v.to_string_lossy())))?
        }
        Some(other) => return Err(err(format!("expected a command before {} (try 'rnerf help')", describe(&other)))),
    };
    match command.as_str() {
        "help" => Ok(Command::Help),
        "demo" => {
            let (mut steps, mut seed, mut threads) = (None, None, None);
            while let Some(arg) = p.next().map_err(|e| err(e.to_string()))? {
                match arg {
                    Long("steps") => steps = Some(positive(&mut p, "steps")?),
                    Long("seed") => seed = Some(number(&mut p, "seed")?),
                    Long("threads") => threads = Some(positive(&mut p, "threads")?),
                    other => return Err(err(format!("demo: unexpected argument {}", describe(&other)))),
                }
            }
            Ok(Command::Demo { steps, seed, threads })
        }
        "bench" => {
            let (mut json, mut reps, mut log2t, mut threads) = (false, None, None, None);
            while let Some(arg) = p.next().map_err(|e| err(e.to_string()))? {
                match arg {
                    Long("json") => json = true,
                    Long("reps") => reps = Some(positive(&mut p, "reps")?),
                    Long("log2t") => {
                        let v: u32 = number(&mut p, "log2t")?;
                        if !(4..=26).contains(&v) {
                            return Err(err(format!("--log2t: {v} is outside 4..=26")));
                        }
                        log2t = Some(v);
                    }
                    Long("threads") => threads = Some(positive(&mut p, "threads")?),
                    other => return Err(err(format!("bench: unexpected argument {}", describe(&other)))),
                }
            }
            Ok(Command::Bench { json, reps, log2t, threads })
        }
        other => Err(err(format!("unknown command '{other}' (try 'rnerf help')"))),
    }
}

fn describe(arg: &lexopt::Arg) -> String {
    match arg {
        lexopt::Arg::Short(c) => format!("'-{c}'"),
        lexopt::Arg::Long(l) => format!("'--{l}'"),
        lexopt::Arg::Value(v) => format!("'{}'", v.to_string_lossy()),
    }
}

/// The value of `--name` parsed as a `T`, naming the flag in the error.
fn number<T: std::str::FromStr>(p: &mut lexopt::Parser, name: &str) -> Result<T, CliError> {
    let raw = p.value().map_err(|e| err(format!("--{name}: {e}")))?;
    let s = raw.to_string_lossy();
    s.parse().map_err(|_| err(format!("--{name}: '{s}' is not a valid value")))
}

/// Like [`number`], and at least 1.
fn positive<T: std::str::FromStr + PartialOrd + From<u8>>(p: &mut lexopt::Parser, name: &str) -> Result<T, CliError> {
    let v: T = number(p, name)?;
    if v < T::from(1) {
        return Err(err(format!("--{name}: must be at least 1")));
    }
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(s: &str) -> Vec<OsString> {
        s.split_whitespace().map(OsString::from).collect()
    }

    #[test]
    fn parses_commands_and_rejects_bad_values() {
        assert_eq!(parse(args("")), Ok(Command::Help));
        assert_eq!(parse(args("--help")), Ok(Command::Help));
        assert_eq!(
            parse(args("bench --json --reps 3 --log2t 15")),
            Ok(Command::Bench { json: true, reps: Some(3), log2t: Some(15), threads: None })
        );
        assert_eq!(
            parse(args("demo --steps=20 --threads 1")),
            Ok(Command::Demo { steps: Some(20), seed: None, threads: Some(1) })
        );
        for (bad, needle) in [
            ("bench --log2t 40", "--log2t: 40 is outside"),
            ("bench --reps 0", "--reps: must be at least 1"),
            ("bench --reps many", "--reps: 'many' is not a valid value"),
            ("demo --threads", "--threads"),
            ("demo --frobnicate", "unexpected argument '--frobnicate'"),
            ("trian", "unknown command 'trian'"),
            ("--json", "expected a command"),
        ] {
            let e = parse(args(bad)).unwrap_err();
            assert!(e.0.contains(needle), "{bad}: {e}");
            assert!(!e.0.contains('\n'), "{bad}: error must be one line: {e}");
        }
    }
}
