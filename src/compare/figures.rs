//! Pictures of a comparison: depth images side by side and training-speed curves, drawn
//! straight into RGB buffers (a 3×5 pixel font for the labels; no plotting dependency).

use image::{Rgb, RgbImage};

/// A colour for curves and labels.
pub type Colour = [u8; 3];

const WHITE: Colour = [255, 255, 255];
const BLACK: Colour = [0, 0, 0];
const GREY: Colour = [200, 200, 200];
const RED: Colour = [230, 40, 40];
/// The object mask's outline on depth sheets.
const OUTLINE: Colour = [255, 60, 255];

/// 3×5 glyphs, one row per byte (bit 2 = left column).
fn glyph(c: char) -> [u8; 5] {
    match c.to_ascii_uppercase() {
        '0' => [7, 5, 5, 5, 7],
        '1' => [2, 6, 2, 2, 7],
        '2' => [7, 1, 7, 4, 7],
        '3' => [7, 1, 7, 1, 7],
        '4' => [5, 5, 7, 1, 1],
        '5' => [7, 4, 7, 1, 7],
        '6' => [7, 4, 7, 5, 7],
        '7' => [7, 1, 1, 1, 1],
        '8' => [7, 5, 7, 5, 7],
        '9' => [7, 5, 7, 1, 7],
        'A' => [2, 5, 7, 5, 5],
        'B' => [6, 5, 6, 5, 6],
        'C' => [3, 4, 4, 4, 3],
        'D' => [6, 5, 5, 5, 6],
        'E' => [7, 4, 6, 4, 7],
        'F' => [7, 4, 6, 4, 4],
        'G' => [3, 4, 5, 5, 3],
        'H' => [5, 5, 7, 5, 5],
        'I' => [7, 2, 2, 2, 7],
        'J' => [1, 1, 1, 5, 2],
        'K' => [5, 5, 6, 5, 5],
        'L' => [4, 4, 4, 4, 7],
        'M' => [5, 7, 7, 5, 5],
        'N' => [6, 5, 5, 5, 5],
        'O' => [2, 5, 5, 5, 2],
        'P' => [6, 5, 6, 4, 4],
        'Q' => [2, 5, 5, 6, 3],
        'R' => [6, 5, 6, 5, 5],
        'S' => [3, 4, 2, 1, 6],
        'T' => [7, 2, 2, 2, 2],
        'U' => [5, 5, 5, 5, 7],
        'V' => [5, 5, 5, 5, 2],
        'W' => [5, 5, 7, 7, 5],
        'X' => [5, 5, 2, 5, 5],
        'Y' => [5, 5, 2, 2, 2],
        'Z' => [7, 1, 2, 4, 7],
        '.' => [0, 0, 0, 0, 2],
        '-' => [0, 0, 7, 0, 0],
        '(' => [1, 2, 2, 2, 1],
        ')' => [4, 2, 2, 2, 4],
        '/' => [1, 1, 2, 4, 4],
        ':' => [0, 2, 0, 2, 0],
        '%' => [5, 1, 2, 4, 5],
        '=' => [0, 7, 0, 7, 0],
        '_' => [0, 0, 0, 0, 7],
        _ => [0; 5],
    }
}

/// Text scale: each font pixel is 2×2.
const SCALE: u32 = 2;
/// Horizontal advance of one character (pixels).
pub const CHAR_W: u32 = 4 * SCALE;
/// Height of a text line (pixels).
pub const CHAR_H: u32 = 5 * SCALE;

fn put(img: &mut RgbImage, x: i64, y: i64, c: Colour) {
    if x >= 0 && y >= 0 && (x as u32) < img.width() && (y as u32) < img.height() {
        img.put_pixel(x as u32, y as u32, Rgb(c));
    }
}

/// Draws `text` with its top-left corner at (x, y).
pub fn text(img: &mut RgbImage, x: i64, y: i64, s: &str, c: Colour) {
    for (i, ch) in s.chars().enumerate() {
        let g = glyph(ch);
        for (row, bits) in g.iter().enumerate() {
            for col in 0..3 {
                if bits & (4 >> col) != 0 {
                    for dy in 0..SCALE as i64 {
                        for dx in 0..SCALE as i64 {
                            let px = x + (i as u32 * CHAR_W) as i64 + col as i64 * SCALE as i64 + dx;
                            put(img, px, y + row as i64 * SCALE as i64 + dy, c);
                        }
                    }
                }
            }
        }
    }
}

/// A 2-pixel-wide line from (x0, y0) to (x1, y1).
fn line(img: &mut RgbImage, (x0, y0): (f64, f64), (x1, y1): (f64, f64), c: Colour) {
    let n = ((x1 - x0).abs().max((y1 - y0).abs()).ceil() as usize).max(1);
    for i in 0..=n {
        let f = i as f64 / n as f64;
        let (x, y) = ((x0 + (x1 - x0) * f).round() as i64, (y0 + (y1 - y0) * f).round() as i64);
        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            put(img, x + dx, y + dy, c);
        }
    }
}

fn rect(img: &mut RgbImage, x0: i64, y0: i64, x1: i64, y1: i64, c: Colour) {
    for x in x0..=x1 {
        put(img, x, y0, c);
        put(img, x, y1, c);
    }
    for y in y0..=y1 {
        put(img, x0, y, c);
        put(img, x1, y, c);
    }
}

/// One panel of a depth sheet.
pub enum Panel<'a> {
    /// z-depth (metres, NaN = hole, drawn black), coloured over the sheet's depth range.
    Depth(&'a [f32]),
    /// Values in [0, 1] in gray (β maps).
    Gray(&'a [f32]),
    /// |depth − truth| from white (0) to red (≥ [`ERROR_SCALE`]); holes (NaN depth where the
    /// truth is finite) black, pixels without truth grey.
    Error {
        /// z-depth (metres, NaN = hole).
        depth: &'a [f32],
        /// True z-depth (metres, NaN = none).
        truth: &'a [f32],
    },
}

/// Depth error at which an [`Panel::Error`] pixel is fully red (metres).
pub const ERROR_SCALE: f32 = 0.10;

fn error_colour(depth: f32, truth: f32) -> Colour {
    if !truth.is_finite() {
        return GREY;
    }
    if !depth.is_finite() {
        return BLACK;
    }
    let f = ((depth - truth).abs() / ERROR_SCALE).min(1.0);
    let fade = (255.0 * (1.0 - f)).round() as u8;
    [255, fade, fade]
}

/// The magnified pixels (in a `pw × ph` panel) inside `mask` whose neighbour is outside it or
/// off the image: a one-pixel outline at any zoom.
fn mask_outline(mask: &[bool], width: u32, zoom: u32, pw: u32, ph: u32) -> Vec<(u32, u32)> {
    let inside = |x: i64, y: i64| {
        x >= 0
            && y >= 0
            && (x as u32) < pw
            && (y as u32) < ph
            && mask[((y as u32 / zoom) * width + x as u32 / zoom) as usize]
    };
    let mut edge = Vec::new();
    for y in 0..ph as i64 {
        for x in 0..pw as i64 {
            if inside(x, y) && !(inside(x - 1, y) && inside(x + 1, y) && inside(x, y - 1) && inside(x, y + 1)) {
                edge.push((x as u32, y as u32));
            }
        }
    }
    edge
}

/// Labelled `width × height` panels side by side, the scoring `crop` outlined in red and the
/// object `mask` (when given) in magenta on each; depth panels share the colour range
/// `[near, far]` (viridis, near = dark). Small images are magnified (nearest pixel) to at least
/// 160 pixels wide, so labels fit and pixels show.
pub fn depth_sheet(
    panels: &[(&str, Panel<'_>)],
    width: u32,
    height: u32,
    crop: [u32; 4],
    mask: Option<&[bool]>,
    near: f32,
    far: f32,
) -> RgbImage {
    let zoom = 160u32.div_ceil(width.max(1)).max(1);
    let (pw, ph) = (width * zoom, height * zoom);
    let top = CHAR_H + 6;
    let gap = 4;
    let mut img = RgbImage::from_pixel((panels.len() as u32 * (pw + gap)).max(1), ph + top, Rgb(WHITE));
    let outline = mask.map_or_else(Vec::new, |m| mask_outline(m, width, zoom, pw, ph));
    for (k, (label, panel)) in panels.iter().enumerate() {
        let x0 = k as u32 * (pw + gap);
        text(&mut img, x0 as i64 + 2, 3, label, BLACK);
        for y in 0..ph {
            for x in 0..pw {
                let p = ((y / zoom) * width + x / zoom) as usize;
                let c = match panel {
                    Panel::Depth(d) => crate::files::export::depth_colour(d[p], near, far),
                    Panel::Gray(v) => [(v[p].clamp(0.0, 1.0) * 255.0).round() as u8; 3],
                    Panel::Error { depth, truth } => error_colour(depth[p], truth[p]),
                };
                img.put_pixel(x0 + x, top + y, Rgb(c));
            }
        }
        for &(x, y) in &outline {
            img.put_pixel(x0 + x, top + y, Rgb(OUTLINE));
        }
        if crop[2] > crop[0] && crop[3] > crop[1] && (crop[2] - crop[0], crop[3] - crop[1]) != (width, height) {
            let (cx0, cy0) = ((x0 + crop[0] * zoom) as i64, (top + crop[1] * zoom) as i64);
            let (cx1, cy1) = ((x0 + crop[2] * zoom - 1) as i64, (top + crop[3] * zoom - 1) as i64);
            rect(&mut img, cx0, cy0, cx1, cy1, RED);
        }
    }
    img
}

/// One curve of a plot.
pub struct Series<'a> {
    /// Legend label.
    pub label: &'a str,
    /// Line colour.
    pub colour: Colour,
    /// Points (x, y).
    pub points: Vec<(f64, f64)>,
}

/// A tick step giving about 5 ticks over `[0, max]`.
fn tick_step(max: f64) -> f64 {
    let raw = (max / 5.0).max(1e-12);
    let mag = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 2.5, 5.0, 10.0].iter().map(|f| f * mag).find(|&s| s >= raw).unwrap_or(10.0 * mag)
}

fn tick_label(v: f64, step: f64) -> String {
    let decimals = (0..6)
        .find(|&d| {
            let s = step * 10f64.powi(d);
            (s - s.round()).abs() < 1e-6
        })
        .unwrap_or(6) as usize;
    format!("{v:.decimals$}")
}

/// A line plot `w × h` of `series` over x, y ≥ 0 with axes, ticks, title and legend.
pub fn plot(title: &str, x_label: &str, series: &[Series<'_>], w: u32, h: u32) -> RgbImage {
    let mut img = RgbImage::from_pixel(w, h, Rgb(WHITE));
    let (left, right, top, bottom) = (56.0, 12.0, 2.0 * CHAR_H as f64 + 10.0, CHAR_H as f64 * 2.0 + 14.0);
    let (pw, ph) = (w as f64 - left - right, h as f64 - top - bottom);
    let finite = |v: f64| v.is_finite();
    let x_max = series.iter().flat_map(|s| s.points.iter().map(|p| p.0)).filter(|&v| finite(v)).fold(0.0, f64::max);
    let y_max = series.iter().flat_map(|s| s.points.iter().map(|p| p.1)).filter(|&v| finite(v)).fold(0.0, f64::max);
    let (xs, ys) = (tick_step(x_max), tick_step(y_max));
    let (x_top, y_top) = ((x_max / xs).ceil().max(1.0) * xs, (y_max / ys).ceil().max(1.0) * ys);
    let to_px = |x: f64, y: f64| (left + x / x_top * pw, top + ph - y / y_top * ph);
    text(&mut img, left as i64, 4, title, BLACK);
    // Grid and ticks.
    let mut v = 0.0;
    while v <= y_top + ys * 0.01 {
        let (_, py) = to_px(0.0, v);
        for x in left as i64..(left + pw) as i64 {
            put(&mut img, x, py.round() as i64, GREY);
        }
        let s = tick_label(v, ys);
        text(&mut img, left as i64 - 4 - (s.len() as u32 * CHAR_W) as i64, py as i64 - CHAR_H as i64 / 2, &s, BLACK);
        v += ys;
    }
    let mut v = 0.0;
    while v <= x_top + xs * 0.01 {
        let (px, _) = to_px(v, 0.0);
        for y in top as i64..(top + ph) as i64 {
            put(&mut img, px.round() as i64, y, GREY);
        }
        let s = tick_label(v, xs);
        text(&mut img, px as i64 - (s.len() as u32 * CHAR_W / 2) as i64, (top + ph) as i64 + 4, &s, BLACK);
        v += xs;
    }
    rect(&mut img, left as i64, top as i64, (left + pw) as i64, (top + ph) as i64, BLACK);
    let xl_w = x_label.len() as u32 * CHAR_W;
    text(&mut img, (left + pw / 2.0) as i64 - xl_w as i64 / 2, (top + ph) as i64 + CHAR_H as i64 + 8, x_label, BLACK);
    // Curves, then the legend on top.
    for s in series {
        let pts: Vec<(f64, f64)> =
            s.points.iter().filter(|p| finite(p.0) && finite(p.1)).map(|&(x, y)| to_px(x, y)).collect();
        for pair in pts.windows(2) {
            line(&mut img, pair[0], pair[1], s.colour);
        }
    }
    for (i, s) in series.iter().enumerate() {
        let y = top as i64 + 6 + i as i64 * (CHAR_H as i64 + 4);
        let x = (left + pw) as i64 - 8 - (s.label.len() as u32 * CHAR_W) as i64 - 18;
        for dy in 0..CHAR_H as i64 {
            for dx in 0..12 {
                put(&mut img, x + dx, y + dy, s.colour);
            }
        }
        text(&mut img, x + 16, y, s.label, BLACK);
    }
    img
}

/// Images of equal size in a grid of `columns`.
pub fn grid(images: &[RgbImage], columns: usize) -> RgbImage {
    let (w, h) = images.first().map_or((1, 1), |i| (i.width(), i.height()));
    let rows = images.len().div_ceil(columns.max(1)) as u32;
    let mut out = RgbImage::from_pixel(w * columns as u32, h * rows.max(1), Rgb(WHITE));
    for (k, im) in images.iter().enumerate() {
        let (x0, y0) = ((k % columns) as u32 * w, (k / columns) as u32 * h);
        for (x, y, p) in im.enumerate_pixels() {
            if x < w && y < h {
                out.put_pixel(x0 + x, y0 + y, *p);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round_and_cover_the_range() {
        assert_eq!(tick_step(1.0), 0.2);
        assert_eq!(tick_step(900.0), 200.0);
        assert_eq!(tick_step(0.07), 0.02);
        assert_eq!(tick_label(0.4, 0.2), "0.4");
        assert_eq!(tick_label(0.25, 0.25), "0.25");
        assert_eq!(tick_label(400.0, 200.0), "400");
    }

    #[test]
    fn a_plot_draws_its_curve_in_its_colour() {
        let s = Series { label: "A", colour: [10, 200, 30], points: vec![(0.0, 1.0), (10.0, 0.5), (20.0, 0.2)] };
        let img = plot("RMSE", "STEP", &[s], 300, 200);
        let hits = img.pixels().filter(|p| p.0 == [10, 200, 30]).count();
        assert!(hits > 100, "curve pixels drawn: {hits}");
    }

    #[test]
    fn a_sheet_outlines_the_crop() {
        let d = vec![1.0f32; 200 * 200];
        let img = depth_sheet(&[("GT", Panel::Depth(&d))], 200, 200, [2, 2, 8, 8], None, 0.5, 1.5);
        let top = CHAR_H + 6;
        assert_eq!(img.get_pixel(2, top + 2).0, RED);
        assert_ne!(img.get_pixel(4, top + 4).0, RED);
        // A 16-pixel image is magnified ten times.
        let small = depth_sheet(&[("GT", Panel::Depth(&d[..256]))], 16, 16, [2, 2, 8, 8], None, 0.5, 1.5);
        assert_eq!(small.width(), 160 + 4);
        assert_eq!(small.get_pixel(20, top + 20).0, RED);
    }

    #[test]
    fn a_sheet_outlines_the_mask_and_colours_errors() {
        // 16×16, mask = the 4×4 square at (6..10, 6..10), magnified ten times.
        let mask: Vec<bool> = (0..256).map(|p| (6..10).contains(&(p % 16)) && (6..10).contains(&(p / 16))).collect();
        let truth = vec![1.0f32; 256];
        let mut depth = vec![1.0f32; 256];
        depth[0] = 1.0 + ERROR_SCALE; // fully red
        depth[1] = 1.0 + ERROR_SCALE / 2.0; // half way
        depth[2] = f32::NAN; // a hole
        let panels = [("GT", Panel::Depth(&truth)), ("err", Panel::Error { depth: &depth, truth: &truth })];
        let img = depth_sheet(&panels, 16, 16, [0, 0, 16, 16], Some(&mask), 0.5, 1.5);
        let top = CHAR_H + 6;
        let px = |panel: u32, x: u32, y: u32| img.get_pixel(panel * (160 + 4) + x, top + y).0;
        assert_eq!(px(0, 60, 75), OUTLINE, "the mask's left edge");
        assert_eq!(px(0, 99, 75), OUTLINE, "the mask's right edge");
        assert_ne!(px(0, 75, 75), OUTLINE, "inside the mask");
        assert_ne!(px(0, 59, 75), OUTLINE, "outside the mask");
        assert_eq!(px(1, 5, 5), [255, 0, 0]);
        assert_eq!(px(1, 15, 5), [255, 128, 128]);
        assert_eq!(px(1, 25, 5), BLACK);
        assert_eq!(px(1, 35, 5), WHITE, "no error");
    }
}
