//! Fuzzes the model-file reader (any bytes as a .safetensors file).
//! Run: `cargo +nightly fuzz run model_file fuzz/seeds/model_file`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = residual_nerf::io::nerf_from_bytes(data);
});
