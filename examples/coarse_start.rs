//! What the robot's depth path gains and moves by starting most rays at their neighbours'
//! depth (`ViewRenderer::set_coarse_start`): every `s`-th row and column is rendered first
//! (`s` from the view's pixel angle, `ViewRenderer::set_coarse_spacing`: 2 on a 200×200 dev
//! view, 4 at 640×480), then every pass halves `s` and starts its rays `margin` lattice steps
//! before the nearest hit among the last passes' pixels around them.
//!
//! For the first three test views of DATA_DIR (200×200) and the first one at 640×480 (rescaled,
//! cropped to 480 rows, as `rnerf bench` does), on the grid the onboard renderer marches (solid
//! fraction `onboard::SOLID_FRACTION`), it renders each view from the box and at each setting,
//! interleaved frame by frame (REPS rounds) so a noisy host's drift falls on all alike, and
//! prints per setting and view the median and min time and the pixels whose depth differs from
//! marching from the box (nearer, farther, turned into a hole or out of one), at 200×200 and at
//! 640×480 apart. Every test view of DATA_DIR, and each of them at 640×480, is compared for the
//! moved pixels, not only the timed ones. A setting is a margin, or `MARGIN@MRAD` for a first
//! pass's spacing other than `COARSE_SPACING` (`1@0`: margin 1 in two passes at any size).
//!
//! ```text
//! cargo run --release --example coarse_start -- MODEL DATA_DIR [SETTINGS [REPS]]
//! RNERF_CPU_LEVEL=avx2 cargo run --release --example coarse_start -- bg.safetensors DEV/glass_up 1@0,1 9
//! ```

use residual_nerf::data::dataset::{Dataset, LoadOptions};
use residual_nerf::field::model::Model;
use residual_nerf::io::{load_model, LoadedModel};
use residual_nerf::render::view::Scene;
use residual_nerf::render::{DepthMethod, Intrinsics, Pose, ViewRenderer};
use residual_nerf::simd::Isa;
use std::path::Path;
use std::time::Instant;

#[path = "shared/coarse_setting.rs"]
mod coarse_setting;

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [model, data, rest @ ..] = &args[..] else {
        return Err("usage: coarse_start MODEL DATA_DIR [SETTINGS [REPS]]".into());
    };
    // Marching from the box is always measured (the reference of the moved pixels).
    let settings: Vec<(u32, f32)> = rest
        .first()
        .map_or("1,2,4", String::as_str)
        .split(',')
        .map(|s| coarse_setting::parse(s)?.ok_or_else(|| "'off' is always measured: leave it out".to_string()))
        .collect::<Result<_, String>>()?;
    let reps: usize = rest.get(1).map_or(Ok(9), |s| s.parse().map_err(|_| format!("'{s}' is not a count")))?;
    let opts = LoadOptions { ground_truth: false, ..Default::default() };
    let test = Dataset::load(Path::new(data), "test", &opts).map_err(|e| e.to_string())?;
    let mut views: Vec<(Intrinsics, Pose)> = test.views.iter().map(|v| (v.intrinsics, v.pose)).collect();
    if views.is_empty() {
        return Err("the test split has no views".into());
    }
    // Timed: the first three views and the first at 640×480; then the others at 640×480.
    let large: Vec<(Intrinsics, Pose)> =
        views.iter().map(|&(k, pose)| (residual_nerf::bench::resized(k, 640, Some(480)), pose)).collect();
    views.insert(3.min(views.len()), large[0]);
    let timed = 4.min(views.len());
    views.extend_from_slice(&large[1..]);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().map_err(|e| e.to_string())?;
    let model = load_model(Path::new(model))?;
    pool.install(|| match &model {
        LoadedModel::Nerf(n) => run(&Scene::from(&**n), &views, timed, &settings, reps),
        LoadedModel::Residual(r) => run(&Scene::from(&**r), &views, timed, &settings, reps),
    });
    Ok(())
}

fn run<M: Model>(
    scene: &Scene<'_, M>,
    views: &[(Intrinsics, Pose)],
    timed: usize,
    margins: &[(u32, f32)],
    reps: usize,
) {
    let isa = Isa::detect();
    let m = DepthMethod::default().threshold();
    let grid = scene.occupancy.keep_solid(residual_nerf::onboard::SOLID_FRACTION, m.min_sigma());
    let thinned = scene.with_grid(Some(&grid));
    // Setting 0 marches from the box; setting i + 1 starts at margins[i].
    let settings: Vec<Option<(u32, f32)>> = std::iter::once(None).chain(margins.iter().map(|&m| Some(m))).collect();
    let mut renderers: Vec<ViewRenderer<M>> = settings
        .iter()
        .map(|&c| {
            let mut r = ViewRenderer::new();
            r.set_coarse_start(c.map(|(margin, _)| margin));
            if let Some((_, spacing)) = c {
                r.set_coarse_spacing(spacing);
            }
            r
        })
        .collect();
    let mut depth: Vec<Vec<Vec<f32>>> = settings
        .iter()
        .map(|_| views.iter().map(|(k, _)| vec![0.0; (k.width * k.height) as usize]).collect())
        .collect();
    let mut ms = vec![vec![Vec::new(); timed]; settings.len()];
    for rep in 0..reps {
        for (i, r) in renderers.iter_mut().enumerate() {
            for (v, (k, pose)) in views.iter().enumerate().take(if rep == 0 { views.len() } else { timed }) {
                let t = Instant::now();
                r.depth(isa, &thinned, k, pose, m, &mut depth[i][v]);
                if v < timed {
                    ms[i][v].push(t.elapsed().as_secs_f64() * 1e3);
                }
            }
        }
    }
    for (i, c) in settings.iter().enumerate() {
        let name = coarse_setting::name(*c);
        let mut line = format!("{name}:");
        for t in &mut ms[i] {
            t.sort_by(f64::total_cmp);
        }
        for (v, t) in ms[i].iter().enumerate() {
            let (k, _) = views[v];
            line += &format!(" view {v} ({}x{}) median {:.1} min {:.1} ms;", k.width, k.height, t[t.len() / 2], t[0]);
        }
        if i > 0 {
            for large in [false, true] {
                let (mut pixels, mut nearer, mut farther, mut to_hole, mut from_hole, mut largest) =
                    (0, 0, 0, 0, 0, 0f32);
                let (mut count, mut size) = (0, String::new());
                for (v, (k, _)) in views.iter().enumerate().filter(|(_, (k, _))| (k.width == 640) == large) {
                    (count, size) = (count + 1, format!("{}x{}", k.width, k.height));
                    for (a, b) in depth[i][v].iter().zip(&depth[0][v]) {
                        pixels += 1;
                        match (a.is_nan(), b.is_nan()) {
                            (true, false) => to_hole += 1,
                            (false, true) => from_hole += 1,
                            (false, false) if a.to_bits() != b.to_bits() => {
                                nearer += (a < b) as usize;
                                farther += (a > b) as usize;
                                largest = largest.max((a - b).abs());
                            }
                            _ => {}
                        }
                    }
                }
                line += &format!(
                    " moved against the box, {count} views at {size} ({pixels} pixels): {farther} farther, {nearer} nearer, {to_hole} into holes, {from_hole} out of holes; largest move {largest:.3} m;",
                );
            }
        }
        println!("{line}");
    }
}
