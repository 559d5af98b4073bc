//! Evaluation (paper Eqs. 7–8, DESIGN §2.6): depth MAE / RMSE in metres, the hole rate and
//! the gross-error rates inside a crop and on the object mask, and PSNR of RGB.
//!
//! Protocol: pixels inside the crop whose ground truth is a finite positive depth (and, when a
//! limit is given, nearer than it — the authors used 1.5 m) are scored. A hole (NaN
//! prediction) counts with `D̂ = 0`, i.e. its error is the ground-truth depth, as in the
//! authors' code; the hole rate is reported beside. Metrics accumulate over all frames of a
//! split (pixel-weighted), so one frame's crop size weighs as its pixel count.
//!
//! [`DepthReport`] scores one prediction four ways: the whole crop (the paper's figure), the
//! **near crop** (ground truth < [`NEAR_LIMIT`], the paper's protocol, which drops the far
//! walls that otherwise carry most of the squared error), the **object** (the frame's mask:
//! the glass itself) and the **crop without the object** (where the background is unchanged).
//! Beside MAE and RMSE each region counts the share within 1 cm and 2.5 cm, **see-through**
//! pixels (a finite prediction more than [`GROSS_ERROR`] behind the truth: the depth of what
//! lies behind the glass) and **floaters** (more than [`GROSS_ERROR`] in front of it).
//! PSNR is `−10 log10(MSE)` per image over all pixels and channels, averaged over images
//! (the NeRF papers' convention).

/// Which pixels of a frame are scored.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CropRule {
    /// The frame's own `crop` (full image when it has none).
    Frame,
    /// A centred square of this half-size (pixels), clipped to the image (authors: 150 of 800).
    Centre(u32),
    /// The whole image.
    Full,
}

/// The `[x0, y0, x1, y1)` box a rule gives for a `width × height` frame with `frame_crop`.
pub fn crop_box(rule: CropRule, width: u32, height: u32, frame_crop: Option<[u32; 4]>) -> [u32; 4] {
    match rule {
        CropRule::Frame => frame_crop.unwrap_or([0, 0, width, height]),
        CropRule::Full => [0, 0, width, height],
        CropRule::Centre(h) => {
            let (cx, cy) = (width / 2, height / 2);
            [cx.saturating_sub(h), cy.saturating_sub(h), (cx + h).min(width), (cy + h).min(height)]
        }
    }
}

/// Ground truth at or beyond this depth (m) is left out of the near crop (the paper's 1.5 m).
pub const NEAR_LIMIT: f32 = 1.5;

/// A finite prediction this far (m) behind the truth is see-through, this far in front of it a
/// floater.
pub const GROSS_ERROR: f32 = 0.02;

/// Running depth error sums (f64) over any number of frames.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DepthErrors {
    /// Σ |D̂ − D| (m).
    pub abs_sum: f64,
    /// Σ (D̂ − D)² (m²).
    pub sq_sum: f64,
    /// Pixels scored.
    pub pixels: u64,
    /// Scored pixels whose prediction was a hole.
    pub holes: u64,
    /// Scored pixels with a finite prediction within 1 cm of the truth.
    pub within_1cm: u64,
    /// Scored pixels with a finite prediction within 2.5 cm of the truth.
    pub within_2_5cm: u64,
    /// Scored pixels whose finite prediction lies more than [`GROSS_ERROR`] behind the truth.
    pub see_through: u64,
    /// Scored pixels whose finite prediction lies more than [`GROSS_ERROR`] in front of the truth.
    pub floaters: u64,
}

impl DepthErrors {
    /// Scores one pixel: prediction `pred` (NaN = hole) against finite positive truth `d`.
    #[inline]
    pub fn add_pixel(&mut self, pred: f32, d: f32) {
        let hole = !pred.is_finite();
        let e = if hole { d as f64 } else { (pred - d) as f64 };
        self.abs_sum += e.abs();
        self.sq_sum += e * e;
        self.pixels += 1;
        self.holes += hole as u64;
        if !hole {
            self.within_1cm += (e.abs() <= 0.01) as u64;
            self.within_2_5cm += (e.abs() <= 0.025) as u64;
            self.see_through += (e > GROSS_ERROR as f64) as u64;
            self.floaters += (e < -(GROSS_ERROR as f64)) as u64;
        }
    }

    /// The sums of `self` and `other` (pixel-weighted pooling).
    pub fn merged(&self, o: &DepthErrors) -> DepthErrors {
        DepthErrors {
            abs_sum: self.abs_sum + o.abs_sum,
            sq_sum: self.sq_sum + o.sq_sum,
            pixels: self.pixels + o.pixels,
            holes: self.holes + o.holes,
            within_1cm: self.within_1cm + o.within_1cm,
            within_2_5cm: self.within_2_5cm + o.within_2_5cm,
            see_through: self.see_through + o.see_through,
            floaters: self.floaters + o.floaters,
        }
    }

    /// Share of scored pixels within 1 cm.
    pub fn within_1cm_rate(&self) -> f64 {
        self.within_1cm as f64 / self.pixels as f64
    }

    /// Share of scored pixels within 2.5 cm.
    pub fn within_2_5cm_rate(&self) -> f64 {
        self.within_2_5cm as f64 / self.pixels as f64
    }

    /// Share of scored pixels that are see-through.
    pub fn see_through_rate(&self) -> f64 {
        self.see_through as f64 / self.pixels as f64
    }

    /// Share of scored pixels that are floaters.
    pub fn floater_rate(&self) -> f64 {
        self.floaters as f64 / self.pixels as f64
    }

    /// Every figure as a JSON object (NaN as null).
    pub fn to_json(&self) -> serde_json::Value {
        let num = |x: f64| if x.is_finite() { serde_json::json!(x) } else { serde_json::Value::Null };
        serde_json::json!({
            "mae": num(self.mae()), "rmse": num(self.rmse()), "hole_rate": num(self.hole_rate()),
            "within_1cm": num(self.within_1cm_rate()), "within_2_5cm": num(self.within_2_5cm_rate()),
            "see_through": num(self.see_through_rate()), "floaters": num(self.floater_rate()),
            "pixels": self.pixels, "holes": self.holes,
        })
    }

    /// Adds a frame: `pred` and `truth` are z-depth per pixel (`width` per row, NaN = hole /
    /// no ground truth), scored inside `crop` and, with `limit`, where `truth < limit`.
    pub fn add_frame(&mut self, pred: &[f32], truth: &[f32], width: u32, crop: [u32; 4], limit: Option<f32>) {
        assert_eq!(pred.len(), truth.len(), "eval: prediction and ground truth differ in size");
        for y in crop[1]..crop[3] {
            for x in crop[0]..crop[2] {
                let p = (y * width + x) as usize;
                let d = truth[p];
                if !(d.is_finite() && d > 0.0) || limit.is_some_and(|l| d >= l) {
                    continue;
                }
                self.add_pixel(pred[p], d);
            }
        }
    }

    /// Mean absolute error (m); NaN when nothing was scored.
    pub fn mae(&self) -> f64 {
        self.abs_sum / self.pixels as f64
    }

    /// Root mean squared error (m); NaN when nothing was scored.
    pub fn rmse(&self) -> f64 {
        (self.sq_sum / self.pixels as f64).sqrt()
    }

    /// Fraction of scored pixels that were holes.
    pub fn hole_rate(&self) -> f64 {
        self.holes as f64 / self.pixels as f64
    }
}

/// One prediction scored over the regions of the module docs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DepthReport {
    /// The whole crop (the paper's figure; the authors' code, holes as 0).
    pub crop: DepthErrors,
    /// The crop where the truth is nearer than the near limit (the paper's protocol).
    pub near: DepthErrors,
    /// The object mask (empty for frames without a mask).
    pub object: DepthErrors,
    /// The crop without the object mask.
    pub rest: DepthErrors,
}

impl DepthReport {
    /// Adds a frame: `pred`, `truth` and `mask` (when the frame has one) per pixel, `width`
    /// per row; scored inside `crop`, the near region where `truth < near_limit`.
    pub fn add_frame(
        &mut self,
        pred: &[f32],
        truth: &[f32],
        mask: Option<&[bool]>,
        width: u32,
        crop: [u32; 4],
        near_limit: f32,
    ) {
        assert_eq!(pred.len(), truth.len(), "eval: prediction and ground truth differ in size");
        assert!(mask.is_none_or(|m| m.len() == pred.len()), "eval: mask and prediction differ in size");
        for y in crop[1]..crop[3] {
            for x in crop[0]..crop[2] {
                let p = (y * width + x) as usize;
                let d = truth[p];
                if !(d.is_finite() && d > 0.0) {
                    continue;
                }
                self.crop.add_pixel(pred[p], d);
                if d < near_limit {
                    self.near.add_pixel(pred[p], d);
                }
                match mask.is_some_and(|m| m[p]) {
                    true => self.object.add_pixel(pred[p], d),
                    false => self.rest.add_pixel(pred[p], d),
                }
            }
        }
    }

    /// The four regions as a JSON object.
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "crop": self.crop.to_json(), "near_crop": self.near.to_json(),
            "object": self.object.to_json(), "crop_without_object": self.rest.to_json(),
        })
    }
}

/// Chessboard distance, in pixels, of every pixel of a `w × h` image to the nearest pixel of
/// `mask` (0 on the mask; `u32::MAX / 2` everywhere when the mask is empty): two chamfer
/// passes. The analysis examples bin a near crop's pixels by it (`near_crop_bands`,
/// `far_floaters`).
pub fn mask_distance(mask: &[bool], w: usize, h: usize) -> Vec<u32> {
    assert_eq!(mask.len(), w * h, "eval: mask of {} pixels for a {w}x{h} image", mask.len());
    let mut d: Vec<u32> = mask.iter().map(|&m| if m { 0 } else { u32::MAX / 2 }).collect();
    let mut relax = |x: usize, y: usize, neighbours: [(i64, i64); 4]| {
        let mut v = d[y * w + x];
        for (dx, dy) in neighbours {
            let (nx, ny) = (x as i64 + dx, y as i64 + dy);
            if nx >= 0 && ny >= 0 && (nx as usize) < w && (ny as usize) < h {
                v = v.min(d[ny as usize * w + nx as usize] + 1);
            }
        }
        d[y * w + x] = v;
    };
    for y in 0..h {
        for x in 0..w {
            relax(x, y, [(-1, 0), (-1, -1), (0, -1), (1, -1)]);
        }
    }
    for y in (0..h).rev() {
        for x in (0..w).rev() {
            relax(x, y, [(1, 0), (1, 1), (0, 1), (-1, 1)]);
        }
    }
    d
}

/// Mean squared error of two images over all pixels and channels.
pub fn mse(pred: &[[f32; 3]], truth: &[[f32; 3]]) -> f64 {
    assert_eq!(pred.len(), truth.len(), "eval: images differ in size");
    let se: f64 =
        pred.iter().zip(truth).map(|(a, b)| (0..3).map(|k| ((a[k] - b[k]) as f64).powi(2)).sum::<f64>()).sum();
    se / (3 * pred.len()).max(1) as f64
}

/// PSNR (dB) of an MSE on [0, 1] values.
pub fn psnr(mse: f64) -> f64 {
    -10.0 * mse.log10()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against the brute-force chessboard distance on a mask of two blobs and a stray pixel.
    #[test]
    fn mask_distance_is_the_chessboard_distance_to_the_nearest_mask_pixel() {
        let (w, h) = (13, 9);
        let on = [(2, 2), (3, 2), (2, 3), (9, 6), (10, 6), (10, 7), (12, 0)];
        let mask: Vec<bool> = (0..w * h).map(|p| on.contains(&(p % w, p / w))).collect();
        let d = mask_distance(&mask, w, h);
        for p in 0..w * h {
            let (x, y) = ((p % w) as i64, (p / w) as i64);
            let brute = on.iter().map(|&(a, b)| (a as i64 - x).abs().max((b as i64 - y).abs())).min().unwrap();
            assert_eq!(d[p] as i64, brute, "pixel ({x}, {y})");
        }
        assert!(mask_distance(&[false; 6], 3, 2).iter().all(|&v| v == u32::MAX / 2));
    }
}
