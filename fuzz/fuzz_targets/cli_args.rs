//! Fuzzes `rnerf`'s argument parser: NUL-separated arguments, any bytes.
//! Run: `cargo +nightly fuzz run cli_args fuzz/seeds/cli_args` (from the repository root).
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::ffi::OsString;
use std::os::unix::ffi::OsStringExt;

fuzz_target!(|data: &[u8]| {
    let args = data.split(|&b| b == 0).map(|a| OsString::from_vec(a.to_vec()));
    // An error or a command, never a panic.
    let _ = residual_nerf::cli::parse(args);
});
