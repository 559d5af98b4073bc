//! How many samples a ray of the robot's depth path should march per round
//! (`ViewRenderer::set_depth_round`). A ray stops at its first solid sample, and the samples a
//! round marched past it are evaluated for nothing; shorter rounds waste fewer but add rounds.
//! For the first three test views of DATA_DIR (200×200) and the first one at 640×480 (rescaled,
//! cropped to 480 rows, as `rnerf bench` does), on the grid the onboard renderer marches (solid
//! fraction `onboard::SOLID_FRACTION`), this prints
//! - where rays hit: the marched samples up to and including the hit, per ray, and the samples
//!   a round length evaluates (what it marches past the hit included);
//! - what the thinned grid keeps: its occupied cells, those in the upper half of the box (air
//!   above a table-top scene), and its blocks of `BLOCK`³ cells that hold one (the blocks
//!   marching crosses in one jump are the others);
//! - the time of a view per round length, the lengths interleaved frame by frame (REPS rounds
//!   of all of them) so a noisy host's drift falls on all alike; min and median per view, and
//!   whether every length gave the first one's depths bit for bit.
//!
//! ```text
//! cargo run --release --example depth_rounds -- MODEL DATA_DIR [LENGTHS [REPS]]
//! RNERF_CPU_LEVEL=avx2 cargo run --release --example depth_rounds -- bg.safetensors DEV/glass_up 4,2,1 15
//! ```

use glam::Vec3;
use residual_nerf::data::dataset::{Dataset, LoadOptions};
use residual_nerf::field::model::Model;
use residual_nerf::geometry::occupancy::{OccupancyGrid, BLOCK};
use residual_nerf::io::{load_model, LoadedModel};
use residual_nerf::render::view::Scene;
use residual_nerf::render::{pixel_ray, DepthMethod, Intrinsics, PackedSamples, Pose, ViewRenderer};
use residual_nerf::simd::Isa;
use std::path::Path;
use std::time::Instant;

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [model, data, rest @ ..] = &args[..] else {
        return Err("usage: depth_rounds MODEL DATA_DIR [LENGTHS [REPS]]".into());
    };
    let lengths: Vec<usize> = rest
        .first()
        .map_or("4,2,1", String::as_str)
        .split(',')
        .map(|s| s.parse().ok().filter(|&n| n > 0).ok_or(format!("'{s}' is not a round length")))
        .collect::<Result<_, _>>()?;
    let reps: usize = rest.get(1).map_or(Ok(15), |s| s.parse().map_err(|_| format!("'{s}' is not a count")))?;
    let opts = LoadOptions { ground_truth: false, ..Default::default() };
    let test = Dataset::load(Path::new(data), "test", &opts).map_err(|e| e.to_string())?;
    let mut views: Vec<(Intrinsics, Pose)> = test.views.iter().take(3).map(|v| (v.intrinsics, v.pose)).collect();
    let (k, pose) = *views.first().ok_or("the test split has no views")?;
    let k = residual_nerf::bench::resized(k, 640, Some(480));
    views.push((k, pose));
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().map_err(|e| e.to_string())?;
    let model = load_model(Path::new(model))?;
    pool.install(|| match &model {
        LoadedModel::Nerf(n) => run(&Scene::from(&**n), &views, &lengths, reps),
        LoadedModel::Residual(r) => run(&Scene::from(&**r), &views, &lengths, reps),
    });
    Ok(())
}

fn run<M: Model>(scene: &Scene<'_, M>, views: &[(Intrinsics, Pose)], lengths: &[usize], reps: usize) {
    let isa = Isa::detect();
    let m = DepthMethod::default().threshold();
    let grid = scene.occupancy.keep_solid(residual_nerf::onboard::SOLID_FRACTION, m.min_sigma());
    let thinned = Scene { model: scene.model, params: scene.params, occupancy: &grid };
    print_grid(&grid);
    let mut renderers: Vec<ViewRenderer<M>> = lengths
        .iter()
        .map(|&l| {
            let mut r = ViewRenderer::new();
            r.set_depth_round(l);
            r
        })
        .collect();
    let mut depth: Vec<Vec<Vec<f32>>> =
        lengths.iter().map(|_| views.iter().map(|(k, _)| vec![0.0; (k.width * k.height) as usize]).collect()).collect();
    let mut ms = vec![vec![Vec::new(); views.len()]; lengths.len()];
    for _ in 0..reps {
        for (i, r) in renderers.iter_mut().enumerate() {
            for (v, (k, pose)) in views.iter().enumerate() {
                let t = Instant::now();
                r.depth(isa, &thinned, k, pose, m, &mut depth[i][v]);
                ms[i][v].push(t.elapsed().as_secs_f64() * 1e3);
            }
        }
    }
    // Where the rays hit: marched samples up to the hit (the first length's depths).
    let mut samples = PackedSamples::default();
    for (v, (k, pose)) in views.iter().enumerate() {
        let mut to_hit = Vec::new();
        for (p, &z) in depth[0][v].iter().enumerate() {
            if z.is_finite() {
                let ray = pixel_ray(k, pose, p as u32 % k.width, p as u32 / k.width);
                samples.clear();
                grid.march(ray.origin, ray.dir, &mut samples);
                let t = ray.z_to_range(z);
                to_hit.push(samples.t.iter().take_while(|&&s| s <= t).count().max(1));
            }
        }
        let hits = to_hit.len().max(1) as f64;
        let mean = to_hit.iter().sum::<usize>() as f64 / hits;
        let evaluated: Vec<String> = lengths
            .iter()
            .map(|&l| format!("{l}: {:.2}", to_hit.iter().map(|&h| h.div_ceil(l) * l).sum::<usize>() as f64 / hits))
            .collect();
        println!(
            "view {v} ({}x{}): {} of {} rays hit, {mean:.2} samples marched to the hit; evaluated per hit ray by round length {}",
            k.width,
            k.height,
            to_hit.len(),
            k.width * k.height,
            evaluated.join(", ")
        );
    }
    for (i, &l) in lengths.iter().enumerate() {
        let same =
            depth[i].iter().zip(&depth[0]).all(|(a, b)| a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()));
        let mut line = format!("round of {l}: depths equal the first length's bit for bit: {same};");
        for t in &mut ms[i] {
            t.sort_by(f64::total_cmp);
        }
        for (v, t) in ms[i].iter().enumerate() {
            line += &format!(" view {v} min {:.1} median {:.1} ms;", t[0], t[t.len() / 2]);
        }
        println!("{line}");
    }
}

/// The thinned grid's occupied share of cells, of the cells in the box's upper half, and of its
/// blocks of [`BLOCK`]³ cells.
fn print_grid(grid: &OccupancyGrid) {
    let r = grid.config().resolution as usize;
    let (aabb, cell) = (grid.aabb(), grid.aabb().size() / r as f32);
    let bl = BLOCK as usize;
    let b = r.div_ceil(bl);
    let mut blocks = vec![false; b * b * b];
    let (mut upper, mut upper_set) = (0usize, 0usize);
    for z in 0..r {
        for y in 0..r {
            for x in 0..r {
                let centre = aabb.min + (Vec3::new(x as f32, y as f32, z as f32) + 0.5) * cell;
                let set = grid.is_occupied(centre);
                if 2 * z >= r {
                    upper += 1;
                    upper_set += set as usize;
                }
                blocks[x / bl + b * (y / bl + b * (z / bl))] |= set;
            }
        }
    }
    let held = blocks.iter().filter(|&&h| h).count();
    println!(
        "thinned grid: {:.1}% of the cells occupied, {:.1}% of the cells in the box's upper half, {:.1}% of the {}^3-cell blocks hold one",
        100.0 * grid.occupancy(),
        100.0 * upper_set as f64 / upper as f64,
        100.0 * held as f64 / blocks.len() as f64,
        BLOCK
    );
}
