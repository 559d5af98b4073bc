//! Crash-safe training: a run checkpointed, reloaded from the file and resumed (on another
//! thread count) ends with the same bits as one never stopped — plain NeRF and residual model;
//! non-finite losses skip steps and too many in a row stop with the last good parameters;
//! a scene box the rays never cross stops with an error naming the box.

use glam::Vec3;
use residual_nerf::data::workspace;
use residual_nerf::data::View;
use residual_nerf::encoding::HashGridConfig;
use residual_nerf::field::mix::{DensityMix, MixKind};
use residual_nerf::field::mixnet::MixnetEncoding;
use residual_nerf::field::model::Model;
use residual_nerf::field::residual::{ResidualConfig, ResidualField};
use residual_nerf::field::{Nerf, NerfConfig, NerfField};
use residual_nerf::io::{load_checkpoint, save_checkpoint, save_nerf, views_fingerprint, LoadedModel, ModelFile};
use residual_nerf::render::{Aabb, OccupancyConfig, OccupancyGrid};
use residual_nerf::rng::Rng;
use residual_nerf::simd::Isa;
use residual_nerf::train::trainer::{
    Focus, TrainConfig, TrainError, TrainState, Trainer, GAIN_PRIOR, MAX_BAD_STEPS_IN_A_ROW,
};
use std::path::{Path, PathBuf};

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("train_robust").join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn field_config(aabb: Aabb) -> NerfConfig {
    NerfConfig { grid: HashGridConfig { log2_table_size: 12, ..Default::default() }, aabb }
}

fn train_config(steps: u32) -> TrainConfig {
    let mut cfg = TrainConfig::with_steps(steps);
    cfg.rays_per_step = 128;
    cfg.occupancy_interval = 8;
    cfg.occupancy = OccupancyConfig { resolution: 16, warmup_steps: 16, steps_per_diagonal: 128, ..Default::default() };
    cfg.random_background = true;
    cfg.seed = 7;
    cfg
}

fn run_to_end<M: Model>(trainer: &mut Trainer<'_, M>) {
    while !trainer.is_done() {
        trainer.step().expect("a clean scene trains");
    }
}

fn same_state<P: PartialEq>(a: &TrainState<P>, b: &TrainState<P>) {
    assert_eq!(a.step, b.step);
    assert!(a.params == b.params, "parameters differ after resuming");
    assert_eq!(a.occupancy.values(), b.occupancy.values(), "occupancy differs after resuming");
    for (x, y) in a.adams.iter().zip(&b.adams) {
        assert_eq!(x.steps(), y.steps());
        assert_eq!(x.moments(), y.moments(), "Adam moments differ after resuming");
    }
    match (&a.gains, &b.gains) {
        (Some(x), Some(y)) => {
            assert_eq!(x.log_gains, y.log_gains, "image gains differ after resuming");
            assert_eq!(x.adam.moments(), y.adam.moments(), "the gains' Adam moments differ after resuming");
            assert_eq!(x.adam.steps(), y.adam.steps());
        }
        (None, None) => {}
        _ => panic!("one state has learned gains, the other not"),
    }
    assert_eq!(a.error_map, b.error_map, "the error maps differ after resuming");
}

/// Trains `steps` steps straight, and again stopping at `stop`, writing a checkpoint file,
/// loading it back and finishing on one thread; both states must be equal.
fn resume_matches<M: ModelFile>(
    model: &M,
    aabb: Aabb,
    views: &[View],
    dir: &Path,
    cfg: &TrainConfig,
    start: Option<(M::Params, OccupancyGrid)>,
    unpack: impl Fn(LoadedModel) -> (M::Params, OccupancyGrid),
) where
    M::Params: PartialEq,
{
    let isa = Isa::detect();
    let cfg = cfg.clone();
    let new = || match start.clone() {
        Some((params, occupancy)) => Trainer::starting_at(isa, model, views, &cfg, params, occupancy),
        None => Trainer::new(isa, model, aabb, views, &cfg),
    };
    let mut straight = new();
    run_to_end(&mut straight);

    let mut first = new();
    for _ in 0..17 {
        first.step().unwrap();
    }
    let path = dir.join("run.ckpt.safetensors");
    save_checkpoint(&path, model, first.state(), &cfg, views_fingerprint(views), &[]).unwrap();
    drop(first);
    let (loaded, checkpoint) = load_checkpoint(&path).unwrap();
    assert_eq!(checkpoint.step, 17);
    assert_eq!(checkpoint.fingerprint, views_fingerprint(views));
    let cfg_back = checkpoint.config.clone();
    assert_eq!(format!("{cfg_back:?}"), format!("{cfg:?}"), "settings must survive the file exactly");
    let (params, occupancy) = unpack(loaded);
    let state = checkpoint.into_state(model, params, occupancy).unwrap();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let resumed = pool.install(|| {
        let mut t = Trainer::from_state(isa, model, views, &cfg_back, state).unwrap();
        run_to_end(&mut t);
        t.into_state()
    });
    same_state(straight.state(), &resumed);
}

#[test]
fn a_resumed_nerf_run_equals_an_uninterrupted_one() {
    let scene = workspace::workspace(16, 8, 0.0, false);
    let field = NerfField::new(field_config(scene.aabb));
    // Plain, learning a gain per image (the gains and their moments ride in the file), and
    // with rays drawn by the error map (its tile values ride in the file).
    let mut gains = train_config(40);
    gains.image_gains = Some(GAIN_PRIOR);
    let mut errors = train_config(40);
    errors.error_map = Some(0.5);
    for cfg in [train_config(40), gains, errors] {
        resume_matches(&field, scene.aabb, &scene.views, &scratch("nerf"), &cfg, None, |m| match m {
            LoadedModel::Nerf(n) => (n.params, n.occupancy),
            LoadedModel::Residual(_) => panic!("saved a NeRF"),
        });
    }
}

#[test]
fn a_resumed_residual_run_equals_an_uninterrupted_one() {
    let scene = workspace::workspace(16, 8, 0.5, true);
    let bg_field = NerfField::new(field_config(scene.aabb));
    let params = bg_field.init_params(&mut Rng::new(3));
    let occupancy = OccupancyGrid::new(scene.aabb, train_config(1).occupancy);
    let background = Nerf { field: bg_field, params, occupancy };
    for mixnet in
        [MixnetEncoding::Shared, MixnetEncoding::Own(HashGridConfig { log2_table_size: 10, ..Default::default() })]
    {
        let config =
            ResidualConfig { residual: field_config(scene.aabb), kind: MixKind::Mixnet(DensityMix::Raw), mixnet };
        let field = ResidualField::new(background.clone(), config);
        // Plain, and with focus and reach pixels and the β penalty (the background-aware
        // method's sampling, whose pixel lists the checkpoint carries).
        let mut aware = train_config(40);
        let pixels = |step: u32| (0..8u32).flat_map(|v| (0..256).step_by(step as usize).map(move |p| (v, p))).collect();
        aware.focus = Some(Focus {
            share: 0.5,
            pixels: std::sync::Arc::new(pixels(7)),
            reach: Some(std::sync::Arc::new(pixels(3))),
            spared: Some(std::sync::Arc::new(pixels(11))),
        });
        aware.beta.unchanged = 0.02;
        for cfg in [train_config(40), aware] {
            resume_matches(&field, scene.aabb, &scene.views, &scratch("residual"), &cfg, None, |m| match m {
                LoadedModel::Residual(r) => (r.params, r.occupancy),
                LoadedModel::Nerf(_) => panic!("saved a residual model"),
            });
        }
    }
}

/// The background-aware method's start over `scene`: warm-started, a change region pinned in a
/// grid frozen outside it, focus and reach pixels and the β penalty.
fn aware_start(
    scene: &residual_nerf::data::synth::SynthScene,
) -> (ResidualField, <ResidualField as Model>::Params, OccupancyGrid, TrainConfig) {
    use residual_nerf::geometry::ChangeRegion;
    let bg_field = NerfField::new(field_config(scene.aabb));
    let mut rng = Rng::new(3);
    let mut params = bg_field.init_params(&mut rng);
    params.grid.master.iter_mut().for_each(|v| *v = rng.uniform(-1.0, 1.0));
    params.grid.sync_mirror();
    let occupancy = OccupancyGrid::new(scene.aabb, train_config(1).occupancy);
    let background = Nerf { field: bg_field, params, occupancy };
    let cells: Vec<u32> =
        (5..11).flat_map(|z| (5..11).flat_map(move |y| (5..11).map(move |x| x + 16 * (y + 16 * z)))).collect();
    let region = ChangeRegion::from_cells(scene.aabb, 16, &cells).unwrap();
    let config = ResidualConfig {
        residual: field_config(scene.aabb),
        kind: MixKind::Mixnet(DensityMix::Raw),
        mixnet: MixnetEncoding::Shared,
    };
    let field = ResidualField::new(background.clone(), config).with_region(region.clone());
    let params = field.warm_params(&mut Rng::new(5)).expect("same architecture");
    let mut occupancy = background.occupancy.clone();
    occupancy.pin(&region);
    occupancy.freeze_outside_pins();
    let mut cfg = train_config(40);
    let pixels = |step: u32| (0..8u32).flat_map(|v| (0..256).step_by(step as usize).map(move |p| (v, p))).collect();
    cfg.focus = Some(Focus {
        share: 0.5,
        pixels: std::sync::Arc::new(pixels(7)),
        reach: Some(std::sync::Arc::new(pixels(3))),
        spared: None,
    });
    cfg.beta.unchanged = 0.02;
    (field, params, occupancy, cfg)
}

/// The parameters a run of `cfg` from `params` and `occupancy` ends with.
fn trained_params(
    field: &ResidualField,
    views: &[View],
    cfg: &TrainConfig,
    params: &<ResidualField as Model>::Params,
    occupancy: &OccupancyGrid,
) -> <ResidualField as Model>::Params {
    let mut t = Trainer::starting_at(Isa::detect(), field, views, cfg, params.clone(), occupancy.clone());
    run_to_end(&mut t);
    t.into_state().params
}

/// The background-aware start with the ray pool on: the resumed run refills the pool at its
/// step and ends with the same bits.
#[test]
fn a_resumed_run_with_the_ray_pool_equals_an_uninterrupted_one() {
    let scene = workspace::workspace(16, 8, 0.5, true);
    let (field, params, occupancy, mut cfg) = aware_start(&scene);
    cfg.ray_pool = 4;
    // The pool is on: it draws other rays than fresh sampling does.
    let ends = |cfg: &TrainConfig| trained_params(&field, &scene.views, cfg, &params, &occupancy);
    let mut fresh = cfg.clone();
    fresh.ray_pool = 0;
    assert!(ends(&cfg) != ends(&fresh), "the pooled run trained as the fresh one");
    let start = Some((params, occupancy));
    resume_matches(&field, scene.aabb, &scene.views, &scratch("pool"), &cfg, start, |m| match m {
        LoadedModel::Residual(r) => (r.params, r.occupancy),
        LoadedModel::Nerf(_) => panic!("saved a residual model"),
    });
}

/// The background-aware start with the photo tail (its background colours ride in the
/// checkpoint): the resumed run ends with the same bits, and the colours change the run.
#[test]
fn a_resumed_run_with_the_photo_tail_equals_an_uninterrupted_one() {
    use residual_nerf::train::prior::BackgroundColours;
    let scene = workspace::workspace(16, 8, 0.5, true);
    let (field, params, occupancy, mut cfg) = aware_start(&scene);
    let dimmed: Vec<Vec<[f32; 3]>> =
        scene.views.iter().map(|v| v.rgb.iter().map(|c| c.map(|x| 0.8 * x + 0.1)).collect()).collect();
    cfg.behind = Some(std::sync::Arc::new(BackgroundColours::new(&dimmed)));
    assert!(cfg.photo_tail, "the photo tail is on by default");
    let ends = |cfg: &TrainConfig| trained_params(&field, &scene.views, cfg, &params, &occupancy);
    let mut without = cfg.clone();
    without.behind = None;
    assert!(ends(&cfg) != ends(&without), "the photo tail changed nothing");
    let start = Some((params, occupancy));
    resume_matches(&field, scene.aabb, &scene.views, &scratch("photo"), &cfg, start, |m| match m {
        LoadedModel::Residual(r) => (r.params, r.occupancy),
        LoadedModel::Nerf(_) => panic!("saved a residual model"),
    });
}

#[test]
fn non_finite_steps_are_skipped_and_counted() {
    let mut scene = workspace::workspace(16, 8, 0.0, false);
    // A NaN in 1 pixel of 16 of one view: the steps that draw one are skipped.
    for (i, px) in scene.views[0].rgb.iter_mut().enumerate() {
        if i % 16 == 0 {
            *px = [f32::NAN; 3];
        }
    }
    let isa = Isa::detect();
    let field = NerfField::new(field_config(scene.aabb));
    let cfg = train_config(40);
    let mut t = Trainer::new(isa, &field, scene.aabb, &scene.views, &cfg);
    run_to_end(&mut t);
    let state = t.into_state();
    assert!(state.skipped > 0 && state.skipped < 40, "skipped {} of 40", state.skipped);
    for adam in &state.adams {
        assert_eq!(adam.steps(), 40 - state.skipped, "a skipped step must not reach Adam");
    }
    let nerf = Nerf { field, params: state.params, occupancy: state.occupancy };
    let path = scratch("nan").join("m.safetensors");
    save_nerf(&path, &nerf, &[]).expect("the parameters stay finite");
}

#[test]
fn too_many_non_finite_steps_stop_with_the_last_good_parameters() {
    let mut scene = workspace::workspace(16, 4, 0.0, false);
    for v in &mut scene.views {
        v.rgb.fill([f32::NAN; 3]);
    }
    let isa = Isa::detect();
    let field = NerfField::new(field_config(scene.aabb));
    let cfg = train_config(100);
    let mut t = Trainer::new(isa, &field, scene.aabb, &scene.views, &cfg);
    let initial = t.state().params.clone();
    let err = loop {
        if let Err(e) = t.step() {
            break e;
        }
    };
    assert_eq!(err, TrainError::NonFinite { step: MAX_BAD_STEPS_IN_A_ROW - 1, skipped: MAX_BAD_STEPS_IN_A_ROW });
    assert!(err.to_string().contains("non-finite"), "{err}");
    assert!(t.state().params == initial, "no update may reach the parameters");
}

#[test]
fn a_box_the_rays_never_cross_stops_with_an_error_naming_it() {
    let scene = workspace::workspace(16, 4, 0.0, false);
    let far = Aabb { min: Vec3::splat(100.0), max: Vec3::splat(101.0) };
    let field = NerfField::new(field_config(far));
    let cfg = train_config(200);
    let mut t = Trainer::new(Isa::detect(), &field, far, &scene.views, &cfg);
    let err = loop {
        if let Err(e) = t.step() {
            break e;
        }
        assert!(!t.is_done(), "training must not finish without a single sample");
    };
    let msg = err.to_string();
    assert!(matches!(err, TrainError::NoLiveSamples { .. }), "{msg}");
    assert!(msg.contains("scene box") && msg.contains("[100.0, 100.0, 100.0]") && !msg.contains('\n'), "{msg}");
}

/// A checkpoint whose learned gains do not fit is refused with a one-line error: gains for
/// other images than the run's, and settings that learn gains without the gains' tensors.
#[test]
fn a_checkpoint_whose_gains_do_not_fit_is_refused() {
    let scene = workspace::workspace(16, 8, 0.0, false);
    let field = NerfField::new(field_config(scene.aabb));
    let dir = scratch("gains");
    let mut cfg = train_config(20);
    cfg.image_gains = Some(GAIN_PRIOR);
    let mut t = Trainer::new(Isa::detect(), &field, scene.aabb, &scene.views, &cfg);
    t.step().unwrap();
    let unpack = |m: LoadedModel| match m {
        LoadedModel::Nerf(n) => (n.params, n.occupancy),
        LoadedModel::Residual(_) => panic!("saved a NeRF"),
    };
    // Gains of 8 images, resumed on 5 of them.
    let path = dir.join("eight.ckpt.safetensors");
    save_checkpoint(&path, &field, t.state(), &cfg, views_fingerprint(&scene.views), &[]).unwrap();
    let (loaded, checkpoint) = load_checkpoint(&path).unwrap();
    let (params, occupancy) = unpack(loaded);
    let cfg_back = checkpoint.config.clone();
    let state = checkpoint.into_state(&field, params, occupancy).unwrap();
    let err = Trainer::from_state(Isa::detect(), &field, &scene.views[..5], &cfg_back, state).err().unwrap();
    assert!(err.contains("gains for 8 images") && err.contains("has 5") && !err.contains('\n'), "{err}");
    // Settings that learn gains, saved from a state without them: the tensors are missing.
    let mut state = t.state().clone();
    state.gains = None;
    let path = dir.join("none.ckpt.safetensors");
    save_checkpoint(&path, &field, &state, &cfg, views_fingerprint(&scene.views), &[]).unwrap();
    let err = load_checkpoint(&path).err().unwrap();
    assert!(err.contains("none.ckpt.safetensors") && err.contains("gain_adam_steps") && !err.contains('\n'), "{err}");
}
