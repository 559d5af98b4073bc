//! A robot's colour-and-depth frames through the onboard API, with the default colour tail
//! (`DepthRenderer::colour_tail`) and without it (every lattice step): the first VIEWS test
//! cameras of DATA_DIR, each rendered REPS times by the two renderers alternately (colour and
//! threshold depth from one pass); prints per view the median milliseconds of each, their PSNR
//! against the test image, and whether the threshold depth is the same bits.
//!
//! `cargo run --release --example colour_frames -- MODEL DATA_DIR [VIEWS [REPS]]`
//! (`RNERF_CPU_LEVEL=avx2` for the robots' level; run it alone, in its own autogroup.)

use residual_nerf::data::{Dataset, LoadOptions};
use residual_nerf::eval;
use residual_nerf::onboard::{DepthKind, DepthMethod, DepthRenderer, DepthRequest, Extras, COLOUR_TAIL};
use std::path::PathBuf;
use std::time::Instant;

fn main() -> Result<(), String> {
    let mut args = std::env::args().skip(1);
    let usage = "usage: colour_frames MODEL DATA_DIR [VIEWS [REPS]]";
    let model = PathBuf::from(args.next().ok_or(usage)?);
    let data = PathBuf::from(args.next().ok_or(usage)?);
    let number =
        |a: Option<String>, default: usize| a.map_or(Ok(default), |v| v.parse().map_err(|_| usage.to_string()));
    let (views, reps) = (number(args.next(), 3)?, number(args.next(), 5)?);
    let opts = LoadOptions::default();
    let test = Dataset::load(&data, "test", &opts).map_err(|e| e.to_string())?;
    let background = opts.background;
    let mut tail = DepthRenderer::load(&model)?.with_threads(2)?;
    let mut every = DepthRenderer::load(&model)?.with_threads(2)?.colour_tail(0.0)?;
    for cam in [&mut tail, &mut every] {
        cam.background = background;
    }
    let request = DepthRequest { method: DepthMethod::default(), kind: DepthKind::Z };
    println!(
        "{} test views of {}, {reps} frames each, colour tail {COLOUR_TAIL} against every step",
        views,
        data.display()
    );
    for (i, v) in test.views.iter().take(views).enumerate() {
        let n = (v.intrinsics.width * v.intrinsics.height) as usize;
        let mut frames =
            [(vec![0.0f32; n], vec![[0.0f32; 3]; n], Vec::new()), (vec![0.0; n], vec![[0.0; 3]; n], Vec::new())];
        for _ in 0..reps {
            for (cam, (z, rgb, ms)) in [&mut tail, &mut every].into_iter().zip(frames.iter_mut()) {
                let t = Instant::now();
                cam.render(&v.intrinsics, &v.pose, request, z, Extras { rgb: Some(rgb), beta: None })?;
                ms.push(t.elapsed().as_secs_f64() * 1e3);
            }
        }
        let psnr = |rgb: &[[f32; 3]]| eval::psnr(eval::mse(rgb, &v.rgb));
        let same_depth = frames[0].0.iter().zip(&frames[1].0).all(|(a, b)| a.to_bits() == b.to_bits());
        let median = |ms: &mut Vec<f64>| {
            ms.sort_by(f64::total_cmp);
            ms[ms.len() / 2]
        };
        let (tail_ms, every_ms) = (median(&mut frames[0].2), median(&mut frames[1].2));
        println!(
            "view {i} ({}x{}): colour tail {tail_ms:.1} ms, {:.3} dB; every step {every_ms:.1} ms, {:.3} dB; ratio {:.2}; threshold depth {}",
            v.intrinsics.width,
            v.intrinsics.height,
            psnr(&frames[0].1),
            psnr(&frames[1].1),
            tail_ms / every_ms,
            if same_depth { "the same bits" } else { "DIFFERENT" }
        );
    }
    Ok(())
}
