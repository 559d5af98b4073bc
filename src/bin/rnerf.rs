//! `rnerf`: the command-line face of residual-nerf (DESIGN §4). Parsing lives in
//! [`residual_nerf::cli`], the commands in [`residual_nerf::app`]; this file only connects them.

use std::process::ExitCode;

fn main() -> ExitCode {
    let result = residual_nerf::cli::parse(std::env::args_os().skip(1))
        .map_err(|e| residual_nerf::app::Failure::from(e.to_string()))
        .and_then(residual_nerf::app::run);
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) => {
            eprintln!("rnerf: {}", f.message);
            ExitCode::from(f.code)
        }
    }
}
