//! Image inputs: colour (PNG 8/16-bit, JPEG; gray, RGB, RGBA), masks (8-bit gray PNG) and
//! depth (single-channel float EXR). The header is read and the size checked before anything
//! is decoded, so a decompression bomb costs nothing. Decoders are pure functions of the bytes
//! (fuzzed); errors are strings the loader puts next to the file, frame and field.

use std::io::Cursor;

/// Largest accepted image side in pixels (as for `w`/`h` in the json).
pub use super::transforms::MAX_SIDE;
/// Largest accepted image area in pixels (64 MP): decoding stops before allocating more.
pub const MAX_PIXELS: u64 = 1 << 26;

/// A decoded colour image: values in [0, 1], row-major from the top-left.
#[derive(Clone, Debug, PartialEq)]
pub struct Rgb {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width × height` colours.
    pub pixels: Vec<[f32; 3]>,
    /// Whether the file had an alpha channel (composited over the given background).
    pub had_alpha: bool,
}

fn check_size(width: u32, height: u32) -> Result<(), String> {
    if width == 0 || height == 0 {
        return Err(format!("empty image ({width}x{height})"));
    }
    if width > MAX_SIDE || height > MAX_SIDE || width as u64 * height as u64 > MAX_PIXELS {
        return Err(format!("image header says {width}x{height}, beyond the {MAX_SIDE}-pixel side / 64-MP limit"));
    }
    Ok(())
}

/// A reader of `bytes`; `limited` sets the decoding limits (header reads need none).
fn reader(bytes: &[u8], limited: bool) -> Result<image::ImageReader<Cursor<&[u8]>>, String> {
    let mut r = image::ImageReader::new(Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| format!("cannot read image: {e}"))?;
    if r.format().is_none() {
        return Err("not an image (no PNG or JPEG signature)".into());
    }
    if !limited {
        r.no_limits();
        return Ok(r);
    }
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_SIDE);
    limits.max_image_height = Some(MAX_SIDE);
    limits.max_alloc = Some(MAX_PIXELS * 16);
    r.limits(limits);
    Ok(r)
}

/// Width and height from the header alone.
pub fn dimensions(bytes: &[u8]) -> Result<(u32, u32), String> {
    let (w, h) = reader(bytes, false)?.into_dimensions().map_err(|e| format!("cannot read image header: {e}"))?;
    check_size(w, h)?;
    Ok((w, h))
}

/// Decodes a colour image (16-bit kept at full precision), compositing any alpha over `background`.
pub fn decode_rgb(bytes: &[u8], background: [f32; 3]) -> Result<Rgb, String> {
    let (width, height) = dimensions(bytes)?;
    let img = reader(bytes, true)?.decode().map_err(|e| format!("corrupt image: {e}"))?;
    let had_alpha = img.color().has_alpha();
    let rgba = img.to_rgba32f();
    let pixels = rgba
        .pixels()
        .map(|p| {
            let a = p.0[3].clamp(0.0, 1.0);
            std::array::from_fn(|k| p.0[k].clamp(0.0, 1.0) * a + background[k] * (1.0 - a))
        })
        .collect();
    Ok(Rgb { width, height, pixels, had_alpha })
}

/// Decodes a mask: a pixel is set where its (first channel's) value is at least half scale.
pub fn decode_mask(bytes: &[u8]) -> Result<(u32, u32, Vec<bool>), String> {
    let (w, h) = dimensions(bytes)?;
    let img = reader(bytes, true)?.decode().map_err(|e| format!("corrupt mask: {e}"))?;
    let gray = img.to_luma32f();
    Ok((w, h, gray.pixels().map(|p| p.0[0] >= 0.5).collect()))
}

/// Decodes a single-channel depth EXR (channel `Y`, `Z`, `R`, `depth` or the only one), any
/// sample type, as f32. Returns `(width, height, values)`; values are as stored (not checked).
pub fn decode_depth_exr(bytes: &[u8]) -> Result<(u32, u32, Vec<f32>), String> {
    use exr::prelude::*;
    let meta = exr::meta::MetaData::read_from_buffered(Cursor::new(bytes), false)
        .map_err(|e| format!("not a readable EXR: {e}"))?;
    let header = meta.headers.first().ok_or("EXR has no layers")?;
    let size = header.layer_size;
    let (w, h) = (u32::try_from(size.width()).unwrap_or(u32::MAX), u32::try_from(size.height()).unwrap_or(u32::MAX));
    check_size(w, h)?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .non_parallel()
        .from_buffered(Cursor::new(bytes))
        .map_err(|e| format!("corrupt EXR: {e}"))?;
    let channels = &image.layer_data.channel_data.list;
    let pick = ["Y", "Z", "R", "depth", "V"]
        .iter()
        .find_map(|n| channels.iter().find(|c| c.name.to_string() == *n))
        .or(if channels.len() == 1 { channels.first() } else { None })
        .ok_or_else(|| {
            let names: Vec<String> = channels.iter().map(|c| c.name.to_string()).collect();
            format!("no depth channel (Y, Z, R or depth) among {names:?}")
        })?;
    let values: Vec<f32> = pick.sample_data.values_as_f32().collect();
    if values.len() != w as usize * h as usize {
        return Err(format!("EXR holds {} samples for {w}x{h}", values.len()));
    }
    Ok((w, h, values))
}
