//! Model files (safetensors): a saved NeRF loads back bit for bit and renders the same; the
//! writer is atomic and refuses non-finite weights; the reader refuses truncated, foreign,
//! other-version and non-finite files with one-line errors.

use residual_nerf::data::synth;
use residual_nerf::encoding::HashGridConfig;
use residual_nerf::error::ErrorKind;
use residual_nerf::field::{Nerf, NerfConfig};
use residual_nerf::geometry::ChangeRegion;
use residual_nerf::io::model::{ModelReader, ModelWriter};
use residual_nerf::io::{load_nerf, nerf_from_bytes, save_nerf};
use residual_nerf::render::{DensityThreshold, OccupancyConfig, OccupancyGrid};
use residual_nerf::rng::Rng;
use residual_nerf::simd::Isa;
use residual_nerf::train::trainer::{train_nerf, TrainConfig};
use std::path::{Path, PathBuf};

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("model_file").join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn small_nerf() -> Nerf {
    let scene = synth::tabletop(8, 4, 0.0);
    let field = NerfConfig {
        grid: HashGridConfig { levels: 4, log2_table_size: 10, base_resolution: 4, finest_resolution: 32 },
        aabb: scene.aabb,
    };
    let mut cfg = TrainConfig::with_steps(20);
    cfg.rays_per_step = 128;
    cfg.occupancy = OccupancyConfig {
        resolution: 8,
        steps_per_diagonal: 64,
        max_samples: 64,
        warmup_steps: 4,
        decay: 0.95,
        ..Default::default()
    };
    train_nerf(Isa::detect(), &scene.views, field, &cfg, 0, |_| {}).expect("trains")
}

fn bytes_of(nerf: &Nerf) -> Vec<u8> {
    let mut w = ModelWriter::new("nerf");
    w.nerf("", nerf).unwrap();
    w.to_bytes().unwrap()
}

#[test]
fn saved_model_loads_back_exactly_and_renders_the_same() {
    let nerf = small_nerf();
    let dir = scratch("roundtrip");
    let path = dir.join("m.safetensors");
    save_nerf(&path, &nerf, &[("note", "test".into())]).unwrap();
    let back = load_nerf(&path).unwrap();
    assert!(back.params == nerf.params, "parameters differ after a round trip");
    assert_eq!(back.occupancy.values(), nerf.occupancy.values());
    assert_eq!(back.occupancy.occupancy(), nerf.occupancy.occupancy());
    assert_eq!(back.field.config(), nerf.field.config());
    let s = synth::tabletop(8, 1, 0.3);
    let v = &s.views[0];
    let (a, b) = (
        nerf.render(Isa::detect(), &v.intrinsics, &v.pose, [0.0; 3], DensityThreshold::Sigma(3.0)),
        back.render(Isa::detect(), &v.intrinsics, &v.pose, [0.0; 3], DensityThreshold::Sigma(3.0)),
    );
    assert_eq!(a.rgb, b.rgb);
    // No temporary file is left beside the model.
    let names: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(names, ["m.safetensors"]);
    // The metadata says what the file is.
    let bytes = std::fs::read(&path).unwrap();
    let r = ModelReader::parse(&bytes).unwrap();
    assert_eq!(r.meta("kind").unwrap(), "nerf");
    assert_eq!(r.meta("note").unwrap(), "test");
}

#[test]
fn non_finite_weights_are_never_saved_and_never_loaded() {
    let mut nerf = small_nerf();
    let dir = scratch("nonfinite");
    let path = dir.join("m.safetensors");
    nerf.params.grid.master[7] = f32::NAN;
    let e = save_nerf(&path, &nerf, &[]).unwrap_err();
    assert_eq!(e.kind(), ErrorKind::BadInput);
    let e = e.to_string();
    assert!(e.contains("grid.params") && e.contains("non-finite"), "{e}");
    assert!(!path.exists() && std::fs::read_dir(&dir).unwrap().next().is_none(), "nothing may be written");
    // A file holding a NaN (written by someone else) is refused on load.
    let good = bytes_of(&small_nerf());
    let mut bad = good.clone();
    let header_len = u64::from_le_bytes(good[..8].try_into().unwrap()) as usize;
    bad[8 + header_len..8 + header_len + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    let e = nerf_from_bytes(&bad).unwrap_err();
    assert_eq!(e.kind(), ErrorKind::CorruptModel);
    assert!(e.message().contains("non-finite"), "{e}");
}

#[test]
fn broken_model_files_are_refused_with_one_line_errors() {
    let good = bytes_of(&small_nerf());
    // Same-length replacement inside the JSON header (byte offsets stay valid).
    let retag = |from: &str, to: &str| {
        assert_eq!(from.len(), to.len());
        let mut b = good.clone();
        let at = b.windows(from.len()).position(|w| w == from.as_bytes()).expect("tag present");
        b[at..at + to.len()].copy_from_slice(to.as_bytes());
        b
    };
    let mut random = vec![0u8; 4096];
    let mut x = 12345u32;
    for b in &mut random {
        x = x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        *b = (x >> 24) as u8;
    }
    let mut huge_header = good.clone();
    huge_header[..8].copy_from_slice(&u64::MAX.to_le_bytes());
    use ErrorKind::{CorruptModel, Unsupported};
    let cases: Vec<(&str, Vec<u8>, &str, ErrorKind)> = vec![
        ("empty", Vec::new(), "truncated or empty", CorruptModel),
        ("truncated", good[..good.len() / 2].to_vec(), "truncated", CorruptModel),
        ("header only", good[..100].to_vec(), "not a model file", CorruptModel),
        ("random", random, "not a model file", CorruptModel),
        ("malicious header length", huge_header, "not a model file", CorruptModel),
        ("other format", retag("residual-nerf-model", "residual-nerf-xxxxx"), "not a residual-nerf model", Unsupported),
        (
            "other version",
            retag("\"format_version\":\"1\"", "\"format_version\":\"9\""),
            "format version 9",
            Unsupported,
        ),
        ("other kind", retag("\"kind\":\"nerf\"", "\"kind\":\"xxxx\""), "model kind 'xxxx'", Unsupported),
    ];
    for (name, bytes, needle, kind) in cases {
        let e = match std::panic::catch_unwind(|| nerf_from_bytes(&bytes)) {
            Ok(r) => r.expect_err(name),
            Err(_) => panic!("{name}: the loader panicked"),
        };
        assert_eq!(e.kind(), kind, "{name}: {e}");
        let e = e.to_string();
        assert!(e.contains(needle), "{name}: '{e}' should contain '{needle}'");
        assert!(!e.contains('\n'), "{name}: not one line: {e}");
    }
    let e = load_nerf(Path::new("/nonexistent/m.safetensors")).unwrap_err();
    assert_eq!(e.kind(), ErrorKind::Io);
    assert!(e.message().contains("/nonexistent/m.safetensors"), "{e}");
}

#[test]
fn residual_model_round_trips_with_its_background_embedded() {
    use residual_nerf::field::mix::{DensityMix, MixKind};
    use residual_nerf::field::mixnet::MixnetEncoding;
    use residual_nerf::field::residual::ResidualConfig;
    use residual_nerf::io::{load_model, save_residual, LoadedModel};
    use residual_nerf::train::trainer::train_residual;
    let bg = small_nerf();
    let scene = synth::tabletop(8, 4, 0.2);
    let mut cfg = TrainConfig::with_steps(10);
    cfg.rays_per_step = 128;
    cfg.occupancy = bg.occupancy.config().clone();
    let own =
        MixnetEncoding::Own(HashGridConfig { levels: 2, log2_table_size: 8, base_resolution: 4, finest_resolution: 8 });
    for (kind, mixnet) in [
        (MixKind::Mixnet(DensityMix::Raw), own),
        (MixKind::Mixnet(DensityMix::Activated), own),
        (MixKind::Mixnet(DensityMix::Raw), MixnetEncoding::Shared),
        (MixKind::Sum, own),
    ] {
        let config = ResidualConfig { residual: bg.field.config().clone(), kind, mixnet };
        let model = train_residual(Isa::detect(), bg.clone(), &scene.views, config, &cfg, 0, |_| {}).expect("trains");
        assert!(model.field.background.params == bg.params, "training must not touch the background");
        let dir = scratch("residual");
        let path = dir.join("r.safetensors");
        save_residual(&path, &model, &[]).unwrap();
        let LoadedModel::Residual(back) = load_model(&path).unwrap() else {
            panic!("{kind:?}: loaded as a plain NeRF")
        };
        assert_eq!(back.field.kind(), kind);
        assert_eq!(back.field.mixnet_encoding(), mixnet);
        assert!(back.params == model.params && back.field.background.params == bg.params);
        assert_eq!(back.occupancy.values(), model.occupancy.values());
        assert_eq!(back.field.solid_background(), None);
        // A residual file is not a plain NeRF.
        let e = load_nerf(&path).unwrap_err();
        assert_eq!(e.kind(), ErrorKind::Unsupported);
        assert!(e.message().contains("residual"), "{e}");
        // With a change region: pinned, and frozen outside it when the run froze it (a
        // warm-started run), so a resumed run refreshes the same cells.
        if kind == MixKind::Sum {
            continue;
        }
        // Colour-only mixing where the background is solid keeps its level.
        let mut m = model.clone();
        m.field = m.field.with_solid_background(10.0);
        save_residual(&path, &m, &[]).unwrap();
        let LoadedModel::Residual(back) = load_model(&path).unwrap() else { panic!("loaded as a plain NeRF") };
        assert_eq!(back.field.solid_background(), Some(10.0), "{kind:?}: the solid level did not round-trip");
        let region = ChangeRegion::from_cells(scene.aabb, bg.occupancy.config().resolution, &[0, 9, 100]).unwrap();
        for freeze in [false, true] {
            let mut m = model.clone();
            // An empty grid, so that only the pin makes the region's cells occupied.
            m.occupancy = OccupancyGrid::new(scene.aabb, bg.occupancy.config().clone());
            m.occupancy.update(0, &mut Rng::new(1), |_, s| s.fill(0.0));
            assert_eq!(m.occupancy.occupancy(), 0.0);
            m.field = m.field.with_region(region.clone());
            m.occupancy.pin(&region);
            if freeze {
                m.occupancy.freeze_outside_pins();
            }
            save_residual(&path, &m, &[]).unwrap();
            let LoadedModel::Residual(back) = load_model(&path).unwrap() else { panic!("loaded as a plain NeRF") };
            assert_eq!(back.occupancy.is_frozen_outside_pins(), freeze, "{kind:?}: the freeze did not round-trip");
            assert!(
                region.cells().iter().all(|&c| back.occupancy.is_occupied(region.cell_centre(c as usize))),
                "{kind:?}: the region is not pinned after loading"
            );
        }
        // A region voted twice as fine as the grid (`PriorConfig::region_subdivide`): kept at
        // its resolution, and pinned on loading as the grid cells that hold it, no others.
        let res = bg.occupancy.config().resolution;
        let fine = ChangeRegion::from_cells(scene.aabb, 2 * res, &[0, 1, 2 * res * (2 * res + 1) + 5]).unwrap();
        let mut m = model.clone();
        m.occupancy = OccupancyGrid::new(scene.aabb, bg.occupancy.config().clone());
        m.occupancy.update(0, &mut Rng::new(1), |_, s| s.fill(0.0));
        m.field = m.field.with_region(fine.clone());
        m.occupancy.pin(&fine);
        m.occupancy.freeze_outside_pins();
        save_residual(&path, &m, &[]).unwrap();
        let LoadedModel::Residual(back) = load_model(&path).unwrap() else { panic!("loaded as a plain NeRF") };
        let region = back.field.region().expect("the fine region round-trips");
        assert_eq!((region.resolution(), region.cells()), (fine.resolution(), fine.cells()), "{kind:?}");
        let coarse = fine.coarsened(res).unwrap();
        assert_eq!(coarse.count(), 2, "{kind:?}: cells 0 and 1 share a grid cell");
        assert_eq!(back.occupancy.occupancy(), 2.0 / (res * res * res) as f64, "{kind:?}: pinned other cells");
        assert!(coarse.cells().iter().all(|&c| back.occupancy.is_occupied(coarse.cell_centre(c as usize))));
        // Finer than 256³ cells the file holds coordinates: an index above 2^24 (not exact
        // in f32) round-trips, the last cell included; finer than 512³ is refused.
        let r = 509u32;
        let last = r * r * r - 1;
        let finest = ChangeRegion::from_cells(scene.aabb, r, &[0, (1 << 24) + 1, last - r, last]).unwrap();
        let mut m = model.clone();
        m.field = m.field.with_region(finest.clone());
        save_residual(&path, &m, &[]).unwrap();
        let LoadedModel::Residual(back) = load_model(&path).unwrap() else { panic!("loaded as a plain NeRF") };
        let region = back.field.region().expect("the finest region round-trips");
        assert_eq!((region.resolution(), region.cells()), (r, finest.cells()), "{kind:?}");
        m.field = m.field.with_region(ChangeRegion::from_cells(scene.aabb, 513, &[0]).unwrap());
        let e = save_residual(&path, &m, &[]).unwrap_err();
        assert!(e.to_string().contains("at most 512^3"), "{kind:?}: {e}");
    }
}
