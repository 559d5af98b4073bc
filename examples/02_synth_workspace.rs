//! Writes the synthetic workspace as two datasets — `background/` (no glass) and `scene/`
//! (with the glass sphere) — each with train and test splits, poses, z-depth EXRs, masks and
//! crops, in the NeRF-synthetic layout `rnerf train` / `rnerf eval` read.
//!
//! `cargo run --release --example 02_synth_workspace -- OUT_DIR [SIZE] [TRAIN_VIEWS]`

use residual_nerf::data::workspace::workspace;

fn main() -> Result<(), String> {
    let mut args = std::env::args().skip(1);
    let out = std::path::PathBuf::from(args.next().ok_or("usage: 02_synth_workspace OUT_DIR [SIZE] [TRAIN_VIEWS]")?);
    let size = args.next().map(|s| s.parse().map_err(|_| format!("SIZE: '{s}'"))).transpose()?.unwrap_or(100);
    let views = args.next().map(|s| s.parse().map_err(|_| format!("TRAIN_VIEWS: '{s}'"))).transpose()?.unwrap_or(60);
    let t0 = std::time::Instant::now();
    for (name, glass) in [("background", false), ("scene", true)] {
        let dir = out.join(name);
        workspace(size, views, 0.0, glass).write_split(&dir, "train")?;
        workspace(size, 8, 0.41, glass).write_split(&dir, "test")?;
        println!("wrote {}", dir.display());
    }
    println!("{size}x{size}, {views} train + 8 test views per set, {:.2} s", t0.elapsed().as_secs_f64());
    Ok(())
}
