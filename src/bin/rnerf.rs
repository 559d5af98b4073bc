//! `rnerf`: the command-line face of residual-nerf (DESIGN §4). Parsing lives in
//! [`residual_nerf::cli`], the commands in [`residual_nerf::app`]; this file only connects them.

use std::process::ExitCode;

fn main() -> ExitCode {
    let result = residual_nerf::cli::parse(std::env::args_os().skip(1))
        .map_err(|e| e.to_string())
        .and_then(residual_nerf::app::run);
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("rnerf: {e}");
            ExitCode::FAILURE
        }
    }
}
