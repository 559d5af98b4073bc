//! The training step's work per sample, stage by stage, as a program an instruction-counting
//! emulator can run: for the CPU levels a host cannot time (NEON on an x86 machine, under
//! qemu). `scripts/insn_mix.sh` runs it once per cumulative stage under qemu with one
//! instruction per translation block and every executed block logged, and takes the
//! differences: each stage's executed instructions per sample.
//!
//! ```text
//! insn_mix STAGE [N]
//! ```
//!
//! Stages, each including the ones before it: `setup` (a NeRF at the default architecture with a
//! 2^14-entry table, so the setup stays small: the per-sample work does not depend on the
//! table's size; `N` random samples, directions and output gradients), `density` (the chunk
//! path's grid encoding and density network, [`Model::chunk_density`]), `colour` (the colour
//! network on every row), `backward` (both networks' backward and the feature gradients),
//! `finish` (the slot's reduction and the grid's gradient scatter), `adam` (one Adam step
//! over every parameter). `N` samples (default 1024) in chunks of [`CHUNK_SAMPLES`] rows, as
//! the training step runs them; run it on one thread (`RAYON_NUM_THREADS=1`) and at the level
//! to count (`RNERF_CPU_LEVEL`).

use glam::Vec3;
use residual_nerf::encoding::HashGridConfig;
use residual_nerf::field::model::Model;
use residual_nerf::field::{NerfConfig, NerfField};
use residual_nerf::render::Aabb;
use residual_nerf::rng::Rng;
use residual_nerf::simd::Isa;
use residual_nerf::train::trainer::CHUNK_SAMPLES;
use residual_nerf::train::{Adam, AdamConfig};

const STAGES: [&str; 6] = ["setup", "density", "colour", "backward", "finish", "adam"];

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = || format!("usage: insn_mix {} [N]", STAGES.join("|"));
    let stage = args.first().and_then(|s| STAGES.iter().position(|x| x == s)).ok_or_else(usage)?;
    let n: usize = match args.get(1) {
        Some(s) => s.parse().ok().filter(|&n| n > 0).ok_or_else(usage)?,
        None => 1024,
    };
    let isa = Isa::detect();
    eprintln!("insn_mix: {} samples, stage {}, level {}", n, STAGES[stage], isa.level());
    let aabb = Aabb { min: Vec3::splat(-1.0), max: Vec3::splat(1.0) };
    let field = NerfField::new(NerfConfig { grid: HashGridConfig { log2_table_size: 14, ..Default::default() }, aabb });
    let mut rng = Rng::new(1);
    let mut params = Model::init_params(&field, &mut rng);
    let pos: Vec<Vec3> =
        (0..n).map(|_| Vec3::new(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0))).collect();
    let dirs: Vec<Vec3> =
        (0..n).map(|_| Vec3::new(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), 0.5).normalize()).collect();
    let d_sigma: Vec<f32> = (0..n).map(|_| rng.uniform(-1.0, 1.0)).collect();
    let d_rgb: Vec<[f32; 3]> = (0..n).map(|_| std::array::from_fn(|_| rng.uniform(-1.0, 1.0))).collect();
    let mut grads = Model::zero_grads(&field);
    let mut slot = Default::default();
    let mut chunk = Default::default();
    let (mut sigma, mut rgb) = (vec![0.0; CHUNK_SAMPLES], vec![[0.0; 3]; CHUNK_SAMPLES]);
    let keep: Vec<u32> = (0..CHUNK_SAMPLES as u32).collect();
    let mut adams: Vec<Adam> = field
        .groups(&mut params, &grads)
        .iter()
        .map(|g| Adam::new(g.master.len(), AdamConfig { l2: g.l2, ..Default::default() }))
        .collect();
    field.after_step(&mut params);
    let n_params: usize = adams.iter().map(|a| a.moments().0.len()).sum();
    eprintln!("insn_mix: params {n_params}");
    let mut check = 0f32;
    if stage >= 1 {
        field.begin_slot(&mut slot);
        for c in (0..n).step_by(CHUNK_SAMPLES) {
            let rows = c..(c + CHUNK_SAMPLES).min(n);
            let k = rows.len();
            Model::chunk_density(&field, isa, &params, 0, &pos[rows.clone()], &mut sigma[..k], &mut chunk);
            check += sigma[..k].iter().sum::<f32>();
            if stage >= 2 {
                Model::chunk_colour(&field, isa, &params, &keep[..k], &dirs[rows.clone()], &mut rgb[..k], &mut chunk);
                check += rgb[..k].iter().flatten().sum::<f32>();
            }
            if stage >= 3 {
                Model::chunk_backward(
                    &field,
                    isa,
                    &params,
                    &mut chunk,
                    &d_sigma[rows.clone()],
                    &d_rgb[rows],
                    &mut slot,
                );
            }
        }
    }
    if stage >= 4 {
        field.finish_step(isa, std::slice::from_ref(&slot), &mut grads);
    }
    if stage >= 5 {
        for (adam, g) in adams.iter_mut().zip(field.groups(&mut params, &grads)) {
            adam.step(isa, 1e-2, g.master, g.grad, g.mirror);
        }
        field.after_step(&mut params);
    }
    println!("{check}");
    Ok(())
}
