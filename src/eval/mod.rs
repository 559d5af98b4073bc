//! Evaluation (paper Eqs. 7–8, DESIGN §2.6): depth MAE / RMSE in metres and the hole rate
//! inside a crop, and PSNR of RGB.
//!
//! Protocol: pixels inside the crop whose ground truth is a finite positive depth (and, when a
//! limit is given, nearer than it — the authors used 1.5 m) are scored. A hole (NaN
//! prediction) counts with `D̂ = 0`, i.e. its error is the ground-truth depth, as in the
//! authors' code; the hole rate is reported beside. Metrics accumulate over all frames of a
//! split (pixel-weighted), so one frame's crop size weighs as its pixel count.
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
}

impl DepthErrors {
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
                let hole = !pred[p].is_finite();
                let e = if hole { d as f64 } else { (pred[p] - d) as f64 };
                self.abs_sum += e.abs();
                self.sq_sum += e * e;
                self.pixels += 1;
                self.holes += hole as u64;
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
