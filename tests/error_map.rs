//! The error map (`train::error_map`): tiles cover every pixel once, a drawn pixel lies in its
//! tile, tiles are drawn in proportion to their values, and in training the map finds the
//! pixels no field can fit.

use residual_nerf::data::workspace;
use residual_nerf::encoding::HashGridConfig;
use residual_nerf::field::{NerfConfig, NerfField};
use residual_nerf::render::OccupancyConfig;
use residual_nerf::rng::Rng;
use residual_nerf::simd::Isa;
use residual_nerf::train::error_map::{record, ErrorSampler, TileLayout, EMA, INITIAL, TILE};
use residual_nerf::train::trainer::{TrainConfig, Trainer};

#[test]
fn tiles_cover_every_pixel_once_and_draws_stay_in_their_tile() {
    // Two views whose sizes are not multiples of the tile: the last tiles are cut.
    let mut scene = workspace::workspace(16, 2, 0.0, false);
    for (v, (w, h)) in scene.views.iter_mut().zip([(20u32, 12u32), (9, 17)]) {
        v.intrinsics.width = w;
        v.intrinsics.height = h;
        v.rgb = vec![[0.5; 3]; (w * h) as usize];
    }
    let tiles = TileLayout::new(&scene.views);
    let expected: usize =
        [(20u32, 12u32), (9, 17)].iter().map(|(w, h)| (w.div_ceil(TILE) * h.div_ceil(TILE)) as usize).sum();
    assert_eq!(tiles.len(), expected);
    let mut hits = vec![0u32; tiles.len()];
    for (vi, v) in scene.views.iter().enumerate() {
        for p in 0..v.intrinsics.width * v.intrinsics.height {
            hits[tiles.tile_of(vi as u32, p)] += 1;
        }
    }
    // Every tile holds at least one pixel, and the pixels add up.
    assert!(hits.iter().all(|&h| h > 0 && h <= TILE * TILE), "{hits:?}");
    assert_eq!(hits.iter().sum::<u32>(), 20 * 12 + 9 * 17);
    let mut rng = Rng::new(5);
    for t in 0..tiles.len() {
        for _ in 0..50 {
            let (v, p) = tiles.draw_pixel(t, &mut rng);
            let k = &scene.views[v as usize].intrinsics;
            assert!(p < k.width * k.height, "pixel {p} outside view {v}");
            assert_eq!(tiles.tile_of(v, p), t, "a pixel drawn in tile {t} lies in another");
        }
    }
}

#[test]
fn tiles_are_drawn_in_proportion_to_their_values() {
    let values = [0.0f32, 1.0, 3.0, 0.0];
    let mut sampler = ErrorSampler::default();
    sampler.rebuild(&values);
    let mut rng = Rng::new(11);
    let mut counts = [0u32; 4];
    let n = 40_000;
    for _ in 0..n {
        counts[sampler.draw(&mut rng)] += 1;
    }
    assert_eq!((counts[0], counts[3]), (0, 0), "tiles of value 0 are never drawn: {counts:?}");
    let share = counts[2] as f64 / n as f64;
    assert!((share - 0.75).abs() < 0.01, "tile 2 holds 3/4 of the weight, drawn {share}");
    // All zero: uniform.
    sampler.rebuild(&[0.0; 4]);
    let mut counts = [0u32; 4];
    for _ in 0..n {
        counts[sampler.draw(&mut rng)] += 1;
    }
    assert!(counts.iter().all(|&c| (c as f64 / n as f64 - 0.25).abs() < 0.01), "{counts:?}");
    // The running estimate moves by EMA towards each error.
    let mut v = vec![INITIAL; 2];
    record(&mut v, 1, 0.2);
    assert_eq!(v, vec![INITIAL, INITIAL + EMA * (0.2 - INITIAL)]);
}

/// One tile of one view holds noise no consistent field can fit: after training with the error
/// map, that tile carries the largest error of all, so the map's rays go there.
#[test]
fn the_error_map_finds_the_pixels_no_field_fits() {
    let mut scene = workspace::workspace(16, 8, 0.0, false);
    let mut rng = Rng::new(3);
    let w = scene.views[3].intrinsics.width;
    for y in 8..16 {
        for x in 8..16 {
            scene.views[3].rgb[(y * w + x) as usize] = std::array::from_fn(|_| rng.f32());
        }
    }
    let field = NerfField::new(NerfConfig {
        grid: HashGridConfig { log2_table_size: 12, ..Default::default() },
        aabb: scene.aabb,
    });
    let mut cfg = TrainConfig::with_steps(60);
    cfg.rays_per_step = 256;
    cfg.occupancy_interval = 8;
    cfg.occupancy = OccupancyConfig { resolution: 16, warmup_steps: 16, steps_per_diagonal: 128, ..Default::default() };
    cfg.random_background = false;
    cfg.error_map = Some(0.5);
    let mut t = Trainer::new(Isa::detect(), &field, scene.aabb, &scene.views, &cfg);
    while !t.is_done() {
        t.step().unwrap();
    }
    let tiles = TileLayout::new(&scene.views);
    let values = t.state().error_map.as_ref().expect("the run keeps an error map");
    let noisy = tiles.tile_of(3, 8 * w + 8);
    // Every tile was visited (none left at its starting value) ...
    assert!(values.iter().all(|&v| v < INITIAL), "a tile was never drawn");
    // ... and the noisy one is the worst by far.
    let (worst, &top) = values.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)).unwrap();
    let mut sorted = values.clone();
    sorted.sort_by(f32::total_cmp);
    let median = sorted[sorted.len() / 2];
    assert_eq!(worst, noisy, "the worst tile is {worst} ({top}), the noisy one {noisy} ({})", values[noisy]);
    assert!(top > 5.0 * median, "noisy tile {top} against the median {median}");
}
