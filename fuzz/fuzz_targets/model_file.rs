//! Fuzzes the model-file readers (any bytes as a .safetensors file): either kind of model,
//! and a training checkpoint.
//! Run: `cargo +nightly fuzz run model_file fuzz/seeds/model_file`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = residual_nerf::io::model_from_bytes(data);
    let _ = residual_nerf::io::checkpoint_from_bytes(data);
});
