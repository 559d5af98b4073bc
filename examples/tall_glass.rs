//! A glass standing in what was empty air: the synthesised workspace with a tall thin glass
//! cylinder (`workspace::Glass::Tall`), trained at the demo's settings with the methods of
//! `rnerf compare`, printing each method's threshold-depth figures on the glass's mask.
//!
//! ```text
//! cargo run --release --example tall_glass [SIZE [STEPS [METHODS]]]
//! cargo run --release --example tall_glass 40 400 dex,residual-paper,residual,residual-activated-no-warm-start
//! ```
//!
//! Defaults: 40-pixel images (the demo's), 400 steps, `dex,residual-paper,residual`; the
//! environment variable `GLASS` picks the object: `tall` (the default, clear glass), `amber`
//! (the same cylinder in amber glass) or `sphere` (the demo's glass sphere).

use residual_nerf::app::{demo_config, train_background};
use residual_nerf::compare::{run_scene, EvalSet, Method};
use residual_nerf::data::workspace::{self, Glass};
use residual_nerf::simd::Isa;

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let size: u32 = args.first().map_or(Ok(40), |s| s.parse().map_err(|_| format!("SIZE: '{s}' is not a number")))?;
    let steps: u32 = args.get(1).map_or(Ok(400), |s| s.parse().map_err(|_| format!("STEPS: '{s}' is not a number")))?;
    let methods = args
        .get(2)
        .map_or("dex,residual-paper,residual", String::as_str)
        .split(',')
        .map(|m| Method::parse(m).ok_or_else(|| format!("METHODS: unknown method '{m}' ({})", Method::names())))
        .collect::<Result<Vec<_>, _>>()?;
    let glass = match std::env::var("GLASS").as_deref() {
        Err(_) | Ok("tall") => Glass::Tall,
        Ok("amber") => Glass::TallAmber,
        Ok("sphere") => Glass::Sphere,
        Ok(other) => return Err(format!("GLASS: unknown object '{other}' (tall, amber, sphere)")),
    };
    let isa = Isa::detect();
    let bg = workspace::workspace_with(size, 32, 0.0, Glass::None);
    let scene = workspace::workspace_with(size, 32, 0.0, glass);
    let test = workspace::workspace_with(size, 4, 0.37, glass);
    let cfg = demo_config(steps, 0);
    eprintln!("{glass:?} glass, {size}x{size} images, 32 views, {steps} steps, cpu level {isa}");
    let background = train_background(isa, &bg.views, &cfg)?;
    let test = EvalSet::from_synth(&test);
    let r = run_scene(isa, "glass", &background, &bg.views, &scene.views, &test, &methods, &cfg, &mut |_, _| {})?;
    println!("| method | object MAE (m) | see-through | floaters | holes | crop w/o object MAE (m) | PSNR (dB) |");
    println!("|---|---|---|---|---|---|---|");
    for m in &r.methods {
        let (o, rest) = (&m.threshold.object, &m.threshold.rest);
        println!(
            "| {} | {:.4} | {:.1}% | {:.1}% | {:.1}% | {:.4} | {:.2} |",
            m.method.name(),
            o.mae(),
            100.0 * o.see_through_rate(),
            100.0 * o.floater_rate(),
            100.0 * o.hole_rate(),
            rest.mae(),
            m.psnr
        );
    }
    Ok(())
}
