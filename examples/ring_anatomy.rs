//! What makes a residual model's threshold depth see the glass a pixel too wide: at the hit of
//! every floater in the 1-px ring around the object mask (a near-crop pixel outside the mask,
//! next to it, whose threshold depth is nearer than the truth by 2 cm), the three parts of the
//! mix at that point — the background's σ, the residual's σ and the Mixnet's β (0 outside the
//! change region) — binned by β, beside the same at the hits on the object mask. With raw
//! mixing the mixed log-density is `(1−β)·ln σ_bg + β·ln σ_res`, so a ring hit is either the
//! background's own density (β ≈ 0), the residual's (β ≈ 1), or a blend of the two.
//!
//! ```text
//! cargo run --release --example ring_anatomy -- RESIDUAL_MODEL SCENE_DIR
//! ```

use glam::Vec3;
use residual_nerf::data::dataset::{Dataset, LoadOptions};
use residual_nerf::eval::NEAR_LIMIT;
use residual_nerf::field::mix::{mix_forward, MixInput};
use residual_nerf::field::mixnet::{MixnetContext, MixnetEncoding};
use residual_nerf::field::residual::ResidualModel;
use residual_nerf::field::FieldContext;
use residual_nerf::geometry::camera::pixel_ray;
use residual_nerf::io::{load_model, LoadedModel};
use residual_nerf::render::view::Scene;
use residual_nerf::render::{DensityThreshold, ViewRenderer};
use residual_nerf::simd::Isa;
use std::path::Path;

/// β bins' upper edges.
const BINS: [f32; 5] = [0.01, 0.1, 0.5, 0.9, 1.0];

/// The three parts of the mix at each point, and the mixed σ they give: (ln σ_bg, ln σ_res, β,
/// σ). β is 0 outside the change region, where the field is the background's.
fn parts(isa: Isa, model: &ResidualModel, points: &[Vec3]) -> Vec<(f32, f32, f32, f32)> {
    let f = &model.field;
    let n = points.len();
    let (mut s_bg, mut s_res, mut logit) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let bg = &f.background;
    bg.field.density(isa, &bg.params, points, &mut s_bg, &mut FieldContext::default());
    f.residual().density(isa, &model.params.residual, points, &mut s_res, &mut FieldContext::default());
    f.mixnet().forward(isa, &model.params.mixnet, points, None, &mut logit, &mut MixnetContext::default());
    (0..n)
        .map(|i| {
            let inside = f.region().is_none_or(|r| r.contains(points[i]));
            let m = if inside { logit[i] } else { f32::NEG_INFINITY };
            let x = MixInput { s_bg: s_bg[i], c_bg: [0.0; 3], s_res: s_res[i], c_res: [0.0; 3], m };
            let out = mix_forward(f.kind(), &x);
            (s_bg[i], s_res[i], out.beta, out.sigma)
        })
        .collect()
}

fn median(mut v: Vec<f32>) -> f32 {
    if v.is_empty() {
        return f32::NAN;
    }
    v.sort_by(f32::total_cmp);
    v[v.len() / 2]
}

/// The mix's parts at `hits` (the threshold hits of one kind of pixel, world points), by β.
fn report(isa: Isa, model: &ResidualModel, name: &str, hits: &[Vec3]) {
    let p = parts(isa, model, hits);
    let mut betas: Vec<f32> = p.iter().map(|x| x.2).collect();
    betas.sort_by(f32::total_cmp);
    let q = |f: f64| betas.get(((betas.len() as f64 - 1.0) * f) as usize).copied().unwrap_or(f32::NAN);
    println!(
        "{name}: {} hits; β at the 10th / 50th / 90th percentile and the largest: {:.3} / {:.3} / {:.3} / {:.3}",
        p.len(),
        q(0.1),
        q(0.5),
        q(0.9),
        q(1.0)
    );
    println!("| β | share of the hits | median σ_bg (1/m) | median σ_res (1/m) | median mixed σ (1/m) |");
    println!("|---|---|---|---|---|");
    let mut lo = -1.0;
    for &hi in &BINS {
        let bin: Vec<_> = p.iter().filter(|x| x.2 > lo && x.2 <= hi).collect();
        lo = hi;
        if bin.is_empty() {
            continue;
        }
        let m = |k: fn(&(f32, f32, f32, f32)) -> f32| median(bin.iter().map(|x| k(x)).collect());
        println!(
            "| ≤ {hi} | {:.1}% | {:.3} | {:.3} | {:.3} |",
            100.0 * bin.len() as f64 / p.len().max(1) as f64,
            m(|x| x.0.exp()),
            m(|x| x.1.exp()),
            m(|x| x.3),
        );
    }
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [model, dir] = &args[..] else { return Err("usage: ring_anatomy RESIDUAL_MODEL SCENE_DIR".into()) };
    let isa = Isa::detect();
    let test = Dataset::load(Path::new(dir), "test", &LoadOptions::default()).map_err(|e| format!("{dir}: {e}"))?;
    let LoadedModel::Residual(model) = load_model(Path::new(model)).map_err(|e| e.to_string())? else {
        return Err(format!("{model}: not a residual model"));
    };
    if model.field.mixnet_encoding() == MixnetEncoding::Shared || model.field.solid_background().is_some() {
        return Err("ring_anatomy: a Mixnet on the residual's features or colour-only mixing is not supported".into());
    }
    let scene = Scene::from(&*model);
    let mut renderer = ViewRenderer::new();
    let (mut ring, mut object) = (Vec::new(), Vec::new());
    for (v, f) in test.views.iter().zip(&test.frames) {
        let k = &v.intrinsics;
        let (Some(truth), Some(crop), Some(mask)) = (&f.depth, f.crop, f.mask.as_deref()) else { continue };
        let (w, h) = (k.width as usize, k.height as usize);
        let mut z = vec![0.0; w * h];
        renderer.depth(isa, &scene, k, &v.pose, DensityThreshold::Sigma(10.0), &mut z);
        for y in crop[1] as usize..crop[3] as usize {
            for x in crop[0] as usize..crop[2] as usize {
                let p = y * w + x;
                let t = truth[p];
                if !(t.is_finite() && t > 0.0 && t < NEAR_LIMIT && z[p].is_finite()) {
                    continue;
                }
                let ray = pixel_ray(k, &v.pose, x as u32, y as u32);
                let point = ray.at(ray.z_to_range(z[p]));
                if mask[p] {
                    object.push(point);
                    continue;
                }
                let next = (y.saturating_sub(1)..(y + 2).min(h))
                    .any(|yy| (x.saturating_sub(1)..(x + 2).min(w)).any(|xx| mask[yy * w + xx]));
                if next && z[p] < t - 0.02 {
                    ring.push(point);
                }
            }
        }
    }
    report(isa, &model, "floaters of the 1-px ring", &ring);
    report(isa, &model, "hits on the object mask", &object);
    Ok(())
}
