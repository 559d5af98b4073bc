//! `rnerf eval`: a model against a split's images and ground-truth depth (DESIGN §2.6).

use super::Progress;
use crate::cli::Rendering;
use crate::data::{Dataset, LoadOptions};
use crate::eval::{crop_box, mse, psnr, CropRule, DepthErrors, DepthReport, NEAR_LIMIT};
use crate::field::model::Model;
use crate::io::{load_model, LoadedModel};
use crate::render::view::Scene;
use crate::render::DepthMethod;
use crate::render::{FullOutputs, ViewRenderer};
use crate::simd::Isa;
use serde_json::json;
use std::path::Path;

/// Metrics of one model on one split.
#[derive(Clone, Debug)]
pub struct EvalReport {
    /// Depth errors over all scored pixels (z-depth, metres).
    pub depth: DepthErrors,
    /// The same prediction inside each frame's own crop, scored on the object mask, the near
    /// crop (< `--limit`, default 1.5 m) and the crop without the object ([`DepthReport`]).
    pub regions: DepthReport,
    /// Mean per-image PSNR (dB); NaN for a depth-only evaluation.
    pub psnr: f64,
    /// Whether only threshold depth was rendered (no colour pass, no PSNR).
    pub depth_only: bool,
    /// The depth-only path's solid fraction (0: every occupied cell marched).
    pub solid_fraction: f32,
    /// The depth-only path's coarse start (`None`: every ray marched from the box).
    pub coarse_start: Option<u32>,
    /// The colour pass's colour tail (0: every lattice step; [`ViewRenderer::set_colour_tail`];
    /// left out of the JSON of a depth-only evaluation, which has no colour pass).
    pub colour_tail: f32,
    /// Frames evaluated.
    pub frames: usize,
    /// Frames that had ground-truth depth.
    pub frames_with_depth: usize,
}

impl EvalReport {
    /// The `--json` object.
    pub fn to_json(&self, depth: DepthMethod) -> serde_json::Value {
        let num = |x: f64| if x.is_finite() { json!(x) } else { json!(null) };
        // A setting as it was typed: the f64 of the f32's shortest decimal (0.4, not 0.4000000059604645).
        let setting = |x: f32| json!(x.to_string().parse::<f64>().unwrap_or(f64::NAN));
        let method = match depth {
            DepthMethod::Expected => "expected".to_string(),
            DepthMethod::Threshold(crate::render::DensityThreshold::Sigma(m)) => format!("threshold sigma>={m}"),
            DepthMethod::Threshold(crate::render::DensityThreshold::Raw(s)) => format!("threshold raw>={s}"),
        };
        json!({
            "mae": num(self.depth.mae()), "rmse": num(self.depth.rmse()), "hole_rate": num(self.depth.hole_rate()),
            "psnr": num(self.psnr), "frames": self.frames, "frames_with_depth": self.frames_with_depth,
            "pixels": self.depth.pixels, "holes": self.depth.holes, "depth_kind": "z", "depth_unit": "m",
            "depth_method": method, "depth_only": self.depth_only, "solid_fraction": setting(self.solid_fraction),
            "coarse_start": self.coarse_start,
            "colour_tail": if self.depth_only { json!(null) } else { setting(self.colour_tail) },
            "regions": self.regions.to_json(),
        })
    }
}

/// What [`evaluate`] renders and how it scores it (`rnerf eval`'s flags).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EvalOptions {
    /// The depth scored (`--depth`, `--m`, `--m-raw`).
    pub depth: DepthMethod,
    /// The scoring crop of the whole-frame figures (`--crop`).
    pub crop: CropRule,
    /// Score only ground truth nearer than this (`--limit`, metres).
    pub limit: Option<f32>,
    /// Colour behind the scene (the dataset loader's).
    pub background: [f32; 3],
    /// Threshold depth alone through the depth-only path ([`ViewRenderer::depth`]: the same
    /// depths as the full pass, every occupied cell marched, σ only, each ray stopped at its
    /// first solid sample), no colour and no PSNR (`--depth-only`); needs a threshold `depth`.
    pub depth_only: bool,
    /// With `depth_only`: skip the occupied cells whose occupancy value stayed below
    /// `solid_fraction · m · δ`, as the onboard renderer does
    /// ([`crate::onboard::DepthRenderer::solid_fraction`]; `--solid-fraction F`), so what a
    /// robot gets is scored; 0 marches every occupied cell (the full pass's depths).
    pub solid_fraction: f32,
    /// With `depth_only`: render every other row and column first (every 4th or 8th on finer
    /// views, [`ViewRenderer::set_coarse_spacing`]) and start the other rays this many lattice
    /// steps before their neighbours' depth, as the onboard renderer does
    /// ([`ViewRenderer::set_coarse_start`]; `--coarse-start N`); `None` marches every ray from
    /// the box.
    pub coarse_start: Option<u32>,
    /// Without `depth_only`: the colour pass's colour tail
    /// ([`ViewRenderer::set_colour_tail`]; `--colour-tail R`, 0 for off): the same threshold
    /// depths, colour within its quadrature error.
    pub colour_tail: f32,
}

/// Renders every view of `data` and scores it.
pub fn evaluate<M: Model>(
    isa: Isa,
    scene: &Scene<'_, M>,
    data: &Dataset,
    opts: &EvalOptions,
    mut progress: impl FnMut(usize),
) -> EvalReport {
    let EvalOptions { depth, crop, limit, background, depth_only, solid_fraction, coarse_start, colour_tail } = *opts;
    assert!(!(depth_only && depth == DepthMethod::Expected), "eval: expected depth needs the colour pass");
    let m = depth.threshold();
    let mut renderer = ViewRenderer::<M>::new();
    let thinned = super::onboard_trades(scene, m, depth_only, solid_fraction, coarse_start, colour_tail, &mut renderer);
    let depth_scene = scene.with_grid(thinned.as_ref());
    let mut errors = DepthErrors::default();
    let mut regions = DepthReport::default();
    let (mut psnr_sum, mut with_depth) = (0.0, 0);
    let (mut rgb, mut expected, mut threshold) = (Vec::new(), Vec::new(), Vec::new());
    for (i, (v, f)) in data.views.iter().zip(&data.frames).enumerate() {
        let k = &v.intrinsics;
        let n = (k.width * k.height) as usize;
        threshold.resize(n, 0.0);
        if depth_only {
            renderer.depth(isa, &depth_scene, k, &v.pose, m, &mut threshold);
        } else {
            rgb.resize(n, [0.0; 3]);
            expected.resize(n, 0.0);
            let out =
                FullOutputs { rgb: &mut rgb, expected_z: &mut expected, threshold_z: &mut threshold, beta: &mut [] };
            renderer.full(isa, scene, k, &v.pose, background, m, out);
            psnr_sum += psnr(mse(&rgb, &v.rgb));
        }
        if let Some(gt) = &f.depth {
            let pred = if depth == DepthMethod::Expected { &expected } else { &threshold };
            errors.add_frame(pred, gt, k.width, crop_box(crop, k.width, k.height, f.crop), limit);
            let frame_crop = crop_box(CropRule::Frame, k.width, k.height, f.crop);
            regions.add_frame(pred, gt, f.mask.as_deref(), k.width, frame_crop, limit.unwrap_or(NEAR_LIMIT));
            with_depth += 1;
        }
        progress(i + 1);
    }
    EvalReport {
        depth: errors,
        regions,
        psnr: if depth_only { f64::NAN } else { psnr_sum / data.views.len() as f64 },
        depth_only,
        solid_fraction,
        coarse_start,
        colour_tail,
        frames: data.views.len(),
        frames_with_depth: with_depth,
    }
}

/// `rnerf eval`: loads the model and the split, renders them as `rendering` says, scores them
/// (`crop`, `limit`) and prints the report.
pub(super) fn run(
    model: &Path,
    data_dir: &Path,
    split: &str,
    rendering: &Rendering,
    crop: CropRule,
    limit: Option<f32>,
    json: bool,
) -> Result<(), String> {
    let model = load_model(model)?;
    let opts = LoadOptions::default();
    let data = crate::app::load_data(data_dir, split, &opts)?;
    let Rendering { depth, depth_only, solid_fraction, coarse_start, colour_tail } = *rendering;
    let eval = EvalOptions {
        depth,
        crop,
        limit,
        background: opts.background,
        depth_only,
        solid_fraction,
        coarse_start,
        colour_tail,
    };
    let mut progress = Progress::new("eval", data.views.len() as u64);
    let tick = |i: usize| progress.update(i as u64, "views rendered");
    let isa = Isa::detect();
    let report = match &model {
        LoadedModel::Nerf(n) => evaluate(isa, &Scene::from(&**n), &data, &eval, tick),
        LoadedModel::Residual(r) => evaluate(isa, &Scene::from(&**r), &data, &eval, tick),
    };
    if json {
        println!("{}", report.to_json(depth));
    } else {
        let d = &report.depth;
        let psnr = if depth_only { String::new() } else { format!("  PSNR {:.2} dB", report.psnr) };
        println!(
            "{} frames ({} with depth), {} scored pixels: depth MAE {:.4} m  RMSE {:.4} m  holes {:.2}%{psnr}",
            report.frames,
            report.frames_with_depth,
            d.pixels,
            d.mae(),
            d.rmse(),
            100.0 * d.hole_rate(),
        );
        let (o, n) = (&report.regions.object, &report.regions.near);
        if o.pixels > 0 {
            println!(
                "object mask: MAE {:.4} m  RMSE {:.4} m  holes {:.2}%  within 1 cm {:.1}%  within 2.5 cm {:.1}%  \
                 see-through {:.1}%  floaters {:.1}%",
                o.mae(),
                o.rmse(),
                100.0 * o.hole_rate(),
                100.0 * o.within_1cm_rate(),
                100.0 * o.within_2_5cm_rate(),
                100.0 * o.see_through_rate(),
                100.0 * o.floater_rate()
            );
        }
        println!("near crop: MAE {:.4} m  RMSE {:.4} m", n.mae(), n.rmse());
    }
    Ok(())
}
