//! Fuzzes the image loaders: colour PNG/JPEG, mask and depth EXR decoding of any bytes.
//! Run: `cargo +nightly fuzz run image_decode fuzz/seeds/image_decode`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use residual_nerf::data::images;

fuzz_target!(|data: &[u8]| {
    let _ = images::decode_rgb(data, [1.0; 3]);
    let _ = images::decode_mask(data);
    let _ = images::decode_depth_exr(data);
});
