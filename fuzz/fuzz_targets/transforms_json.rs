//! Fuzzes the transforms-json parser (any bytes as the json's contents).
//! Run: `cargo +nightly fuzz run transforms_json fuzz/seeds/transforms_json`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    // Parsed transforms or a list of problems, never a panic.
    let _ = residual_nerf::data::transforms::parse_transforms(data, std::path::Path::new("fuzz/transforms.json"));
});
