//! Fuzzes the COLMAP sparse-model parsers (any bytes as `cameras`, `images` or `points3D`, text
//! and binary).
//! Run: `cargo +nightly fuzz run colmap_model fuzz/seeds/colmap_model`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use residual_nerf::data::colmap;

fuzz_target!(|data: &[u8]| {
    // Parsed records or a one-line error, never a panic.
    let _ = colmap::cameras_txt(data);
    let _ = colmap::images_txt(data);
    let _ = colmap::points_txt(data);
    let _ = colmap::cameras_bin(data);
    let _ = colmap::images_bin(data);
    let _ = colmap::points_bin(data);
});
