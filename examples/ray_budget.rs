//! Where a NeRF's samples go along the rays of a capture: samples marched and kept per ray
//! (kept: before the ray turns opaque, T < 1e-4, as training and rendering stop), how many it
//! takes for the transmittance to fall below 0.99, 0.3, 0.1, 0.05 and 0.01 (where a residual's
//! training ray past the change region may stop: `--frozen-tail`), the optical thickness `σδ` of the
//! kept samples and the share of the colour weight each carries, and the kept samples by
//! distance from the camera. A field whose surfaces are sharp spends few samples per ray; one
//! whose light leaks through its surfaces spends them on the leak.
//!
//! ```text
//! cargo run --release --example ray_budget -- MODEL DATA_DIR [EVERY_VIEW [EVERY_PIXEL]]
//! cargo run --release --example ray_budget -- bg.safetensors DEV/glass_up 7 10
//! ```
//!
//! The rays are those of every `EVERY_VIEW`-th training view (default 7), every
//! `EVERY_PIXEL`-th pixel in each direction (default 10), marched through the model's own
//! occupancy grid.

use residual_nerf::data::dataset::{Dataset, LoadOptions};
use residual_nerf::field::model::Model;
use residual_nerf::render::{pixel_ray, PackedSamples};
use std::path::Path;

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [model, data, rest @ ..] = &args[..] else {
        return Err("usage: ray_budget MODEL DATA_DIR [EVERY_VIEW [EVERY_PIXEL]]".into());
    };
    let every = |i: usize, default: usize| -> Result<usize, String> {
        rest.get(i).map_or(Ok(default), |s| s.parse().ok().filter(|&n| n > 0).ok_or(format!("'{s}' is not a count")))
    };
    let (every_view, every_pixel) = (every(0, 7)?, every(1, 10)?);
    let isa = residual_nerf::simd::Isa::detect();
    let nerf = residual_nerf::io::model::load_nerf(Path::new(model))?;
    let opts = LoadOptions { ground_truth: false, ..Default::default() };
    let views = Dataset::load(Path::new(data), "train", &opts).map_err(|e| e.to_string())?.views;
    let occ = &nerf.occupancy;
    const BINS: [f64; 5] = [1e-3, 1e-2, 0.1, 1.0, f64::INFINITY];
    const LADDER: [f64; 5] = [0.99, 0.3, 0.1, 0.05, 0.01];
    let (mut rays, mut marched, mut kept, mut before) = (0usize, 0usize, 0usize, [0usize; 5]);
    let (mut count, mut weight) = ([0usize; 5], [0f64; 5]);
    let mut by_distance = [0usize; 8];
    let (mut samples, mut positions, mut sigma, mut ctx) =
        (PackedSamples::default(), Vec::new(), Vec::new(), Default::default());
    for v in views.iter().step_by(every_view) {
        for j in (0..v.intrinsics.height).step_by(every_pixel) {
            for i in (0..v.intrinsics.width).step_by(every_pixel) {
                let r = pixel_ray(&v.intrinsics, &v.pose, i, j);
                samples.clear();
                occ.march(r.origin, r.dir, &mut samples);
                positions.clear();
                positions.extend(samples.t.iter().map(|&t| r.at(t)));
                sigma.resize(positions.len(), 0.0);
                Model::density(&nerf.field, isa, &nerf.params, &positions, &mut sigma, &mut ctx);
                rays += 1;
                marched += positions.len();
                let mut t = 1f64;
                for (k, (&s, &delta)) in sigma.iter().zip(&samples.delta).enumerate() {
                    if t < 1e-4 {
                        break;
                    }
                    kept += 1;
                    for (n, &level) in before.iter_mut().zip(&LADDER) {
                        *n += (t >= level) as usize;
                    }
                    let thickness = s.max(0.0) as f64 * delta as f64;
                    let b = BINS.iter().position(|&x| thickness < x).expect("the last bin is unbounded");
                    let alpha = 1.0 - (-thickness).exp();
                    count[b] += 1;
                    weight[b] += t * alpha;
                    by_distance[((samples.t[k] / 0.5) as usize).min(7)] += 1;
                    t *= 1.0 - alpha;
                }
            }
        }
    }
    let per_ray = |n: usize| n as f64 / rays.max(1) as f64;
    println!("{rays} rays from {} of {} views of {data}", views.len().div_ceil(every_view), views.len());
    println!("per ray: {:.1} marched, {:.1} kept", per_ray(marched), per_ray(kept));
    let ladder: Vec<String> =
        LADDER.iter().zip(&before).map(|(level, &n)| format!("{:.1} before T < {level}", per_ray(n))).collect();
    println!("per ray: {}", ladder.join(", "));
    println!("kept samples by σδ (< 1e-3, < 1e-2, < 0.1, < 1, ≥ 1): per ray, share of the colour weight");
    for (b, label) in ["< 1e-3", "< 1e-2", "< 0.1", "< 1", ">= 1"].iter().enumerate() {
        println!("  σδ {label:7} {:6.1} {:5.1}%", per_ray(count[b]), 100.0 * weight[b] / rays.max(1) as f64);
    }
    let d: Vec<String> = by_distance.iter().map(|&n| format!("{:.1}", per_ray(n))).collect();
    println!("kept per ray by distance, 0.5 m bins from the camera (the last: ≥ 3.5 m): {}", d.join(" "));
    Ok(())
}
