//! The cost of an update against the number of objects that changed: the synthesised
//! workspace's background trained once, then the default Residual-NeRF trained on scenes with
//! 1, 2, 3 and 4 small glass spheres (`workspace::Glass::Spheres`) at the crate's default
//! trainer and field (1024 rays a step, log2 T = 17, 128³ occupancy), printing per scene the
//! changed pixels, the change region's cells and volume, the share of training pixels whose ray crosses it, the training
//! seconds per step and the object-mask depth error.
//!
//! ```text
//! cargo run --release --example update_cost [SIZE [STEPS [VIEWS [BG_STEPS]]]]
//! DEX=1 cargo run --release --example update_cost 128 600 48 1000
//! ```
//!
//! Defaults: 128-pixel images, 600 scene steps, 48 views (background and scene, the same poses),
//! a 1000-step background. `DEX=1` trains Dex-NeRF on every scene too (its step costs the
//! room, whatever changed).

use residual_nerf::app::train_background;
use residual_nerf::compare::{run_scene, CompareConfig, EvalSet, Method};
use residual_nerf::data::workspace::{self, Glass, SKY};
use residual_nerf::encoding::hashgrid::HashGridConfig;
use residual_nerf::field::NerfConfig;
use residual_nerf::simd::Isa;
use residual_nerf::train::trainer::TrainConfig;

fn number<T: std::str::FromStr>(args: &[String], i: usize, name: &str, default: T) -> Result<T, String> {
    args.get(i).map_or(Ok(default), |s| s.parse().map_err(|_| format!("{name}: '{s}' is not a number")))
}

/// The crate's default trainer for synthesised data (every pixel a surface: random background
/// colours, as `rnerf train` does for data without alpha).
fn config(steps: u32) -> CompareConfig {
    let mut train = TrainConfig::with_steps(steps);
    train.background = SKY;
    train.random_background = true;
    let mut cfg = CompareConfig::new(train, NerfConfig { grid: HashGridConfig::default(), aabb: workspace::aabb() });
    cfg.eval_every = steps; // the final figures only
    cfg
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let size: u32 = number(&args, 0, "SIZE", 128)?;
    let steps: u32 = number(&args, 1, "STEPS", 600)?;
    let views: usize = number(&args, 2, "VIEWS", 48)?;
    let bg_steps: u32 = number(&args, 3, "BG_STEPS", 1000)?;
    let dex = std::env::var("DEX").is_ok_and(|v| v == "1");
    let methods: Vec<Method> = if dex { vec![Method::RESIDUAL, Method::Dex] } else { vec![Method::RESIDUAL] };
    let isa = Isa::detect();
    eprintln!(
        "update cost: {size}x{size} images, {views} views, background {bg_steps} steps, scenes {steps} steps, cpu level {isa}, {} threads",
        rayon::current_num_threads()
    );
    let bg = workspace::workspace_with(size, views, 0.0, Glass::None);
    let t0 = std::time::Instant::now();
    let background = train_background(isa, &bg.views, &config(bg_steps))?;
    eprintln!("background: {:.1} s", t0.elapsed().as_secs_f64());
    let cfg = config(steps);
    println!("| spheres | changed pixels | region (cells, m³) | pixels crossing it | method | training ms / step | object MAE (m) | holes |");
    println!("|---|---|---|---|---|---|---|---|");
    for n in 1..=4u8 {
        let scene = workspace::workspace_with(size, views, 0.0, Glass::Spheres(n));
        let test = EvalSet::from_synth(&workspace::workspace_with(size, 4, 0.37, Glass::Spheres(n)));
        let r = run_scene(isa, "spheres", &background, &bg.views, &scene.views, &test, &methods, &cfg, &mut |_, _| {})?;
        let prior = r.prior.ok_or("the default method ran without its prior")?;
        for m in &r.methods {
            let o = &m.threshold.object;
            println!(
                "| {n} | {:.1}% | {}, {:.4} | {:.1}% | {} | {:.1} | {:.4} | {:.1}% |",
                100.0 * prior.changed_pixels,
                prior.region_cells,
                prior.region_volume,
                100.0 * prior.reach_pixels,
                m.method.name(),
                1e3 * m.seconds / steps as f64,
                o.mae(),
                100.0 * o.hole_rate()
            );
        }
    }
    Ok(())
}
