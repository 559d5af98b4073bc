//! What the robot's depth path gains and moves by starting most rays at their neighbours'
//! depth (`ViewRenderer::set_coarse_start`): the pixels of even rows and columns are rendered
//! first, every other ray starts `margin` lattice steps before the nearest hit among the
//! first-pass pixels around it.
//!
//! For the first three test views of DATA_DIR (200×200) and the first one at 640×480 (rescaled,
//! cropped to 480 rows, as `rnerf bench` does), on the grid the onboard renderer marches (solid
//! fraction `onboard::SOLID_FRACTION`), it renders each view from the box and at each margin,
//! interleaved frame by frame (REPS rounds) so a noisy host's drift falls on all alike, and
//! prints per margin and view the median and min time and the pixels whose depth differs from
//! marching from the box (nearer, farther, turned into a hole or out of one). Every test view
//! of DATA_DIR is compared for the moved pixels, not only the timed ones.
//!
//! ```text
//! cargo run --release --example coarse_start -- MODEL DATA_DIR [MARGINS [REPS]]
//! RNERF_CPU_LEVEL=avx2 cargo run --release --example coarse_start -- bg.safetensors DEV/glass_up 1,2,4 9
//! ```

use residual_nerf::data::dataset::{Dataset, LoadOptions};
use residual_nerf::field::model::Model;
use residual_nerf::io::{load_model, LoadedModel};
use residual_nerf::render::view::Scene;
use residual_nerf::render::{DepthMethod, Intrinsics, Pose, ViewRenderer};
use residual_nerf::simd::Isa;
use std::path::Path;
use std::time::Instant;

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [model, data, rest @ ..] = &args[..] else {
        return Err("usage: coarse_start MODEL DATA_DIR [MARGINS [REPS]]".into());
    };
    let margins: Vec<u32> = rest
        .first()
        .map_or("1,2,4", String::as_str)
        .split(',')
        .map(|s| s.parse().map_err(|_| format!("'{s}' is not a margin")))
        .collect::<Result<_, _>>()?;
    let reps: usize = rest.get(1).map_or(Ok(9), |s| s.parse().map_err(|_| format!("'{s}' is not a count")))?;
    let opts = LoadOptions { ground_truth: false, ..Default::default() };
    let test = Dataset::load(Path::new(data), "test", &opts).map_err(|e| e.to_string())?;
    let mut views: Vec<(Intrinsics, Pose)> = test.views.iter().map(|v| (v.intrinsics, v.pose)).collect();
    let (k, pose) = *views.first().ok_or("the test split has no views")?;
    views.insert(3.min(views.len()), (residual_nerf::bench::resized(k, 640, Some(480)), pose));
    let timed = 4.min(views.len());
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().map_err(|e| e.to_string())?;
    let model = load_model(Path::new(model))?;
    pool.install(|| match &model {
        LoadedModel::Nerf(n) => run(&Scene::from(&**n), &views, timed, &margins, reps),
        LoadedModel::Residual(r) => run(&Scene::from(&**r), &views, timed, &margins, reps),
    });
    Ok(())
}

fn run<M: Model>(scene: &Scene<'_, M>, views: &[(Intrinsics, Pose)], timed: usize, margins: &[u32], reps: usize) {
    let isa = Isa::detect();
    let m = DepthMethod::default().threshold();
    let grid = scene.occupancy.keep_solid(residual_nerf::onboard::SOLID_FRACTION, m.min_sigma());
    let thinned = Scene { model: scene.model, params: scene.params, occupancy: &grid };
    // Setting 0 marches from the box; setting i + 1 starts at margins[i].
    let settings: Vec<Option<u32>> = std::iter::once(None).chain(margins.iter().map(|&m| Some(m))).collect();
    let mut renderers: Vec<ViewRenderer<M>> = settings
        .iter()
        .map(|&c| {
            let mut r = ViewRenderer::new();
            r.set_coarse_start(c);
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
        let name = c.map_or("from the box".to_string(), |m| format!("margin {m}"));
        let mut line = format!("{name}:");
        for t in &mut ms[i] {
            t.sort_by(f64::total_cmp);
        }
        for (v, t) in ms[i].iter().enumerate() {
            let (k, _) = views[v];
            line += &format!(" view {v} ({}x{}) median {:.1} min {:.1} ms;", k.width, k.height, t[t.len() / 2], t[0]);
        }
        if i > 0 {
            let (mut pixels, mut nearer, mut farther, mut to_hole, mut from_hole, mut largest) = (0, 0, 0, 0, 0, 0f32);
            for (a, b) in depth[i].iter().flatten().zip(depth[0].iter().flatten()) {
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
            line += &format!(
                " moved against the box, all {} views ({pixels} pixels): {farther} farther, {nearer} nearer, {to_hole} into holes, {from_hole} out of holes; largest move {largest:.3} m",
                views.len()
            );
        }
        println!("{line}");
    }
}
