//! Running the protocol: each method trained on a scene with the curves scored while it trains
//! ([`run_scene`]), the crops' errors of a model ([`crop_errors`]).

use super::{CompareConfig, CurvePoint, EvalSet, Method, MethodResult, PriorSummary, SceneResult};
use crate::data::View;
use crate::eval::{mse, psnr, DepthReport, NEAR_LIMIT};
use crate::field::mixnet::MixnetEncoding;
use crate::field::model::Model;
use crate::field::residual::ResidualConfig;
use crate::field::{Nerf, NerfField};
use crate::io::{save_model, ModelFile};
use crate::render::view::Scene;
use crate::render::{DensityThreshold, Intrinsics, OccupancyGrid, ViewRenderer};
use crate::simd::Isa;
use crate::train::prior::{residual_start, scene_prior, Prior, ScenePrior};
use crate::train::trainer::{train_model_from, StepStats, TrainError};

/// The intrinsics of the sub-window `crop` of `k` (the same rays as those pixels of `k`).
pub fn crop_intrinsics(k: &Intrinsics, crop: [u32; 4]) -> Intrinsics {
    Intrinsics {
        width: crop[2] - crop[0],
        height: crop[3] - crop[1],
        cx: k.cx - crop[0] as f32,
        cy: k.cy - crop[1] as f32,
        ..*k
    }
}

/// Threshold-depth errors of `scene` inside the crops of `test`, every region (renders the
/// crops only).
pub fn crop_errors<M: Model>(
    isa: Isa,
    scene: &Scene<'_, M>,
    test: &EvalSet,
    m: DensityThreshold,
    renderer: &mut ViewRenderer<M>,
    z: &mut Vec<f32>,
    truth: &mut Vec<f32>,
) -> DepthReport {
    let mut e = DepthReport::default();
    let mut mask = Vec::new();
    for (((v, gt), &crop), full_mask) in test.views.iter().zip(&test.depth).zip(&test.crops).zip(&test.masks) {
        let k = crop_intrinsics(&v.intrinsics, crop);
        z.resize((k.width * k.height) as usize, 0.0);
        renderer.depth(isa, scene, &k, &v.pose, m, z);
        truth.clear();
        mask.clear();
        for y in crop[1]..crop[3] {
            let row = (y * v.intrinsics.width) as usize;
            let r = row + crop[0] as usize..row + crop[2] as usize;
            truth.extend_from_slice(&gt[r.clone()]);
            if let Some(fm) = full_mask {
                mask.extend_from_slice(&fm[r]);
            }
        }
        let mask = full_mask.as_ref().map(|_| &mask[..]);
        e.add_frame(z, truth, mask, k.width, [0, 0, k.width, k.height], NEAR_LIMIT);
    }
    e
}

fn gcd(a: u32, b: u32) -> u32 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// The file [`CompareConfig::models`] gets for `method` trained on `scene`.
pub fn model_path(dir: &std::path::Path, scene: &str, method: Method) -> std::path::PathBuf {
    dir.join(format!("{scene}_{}.safetensors", method.name()))
}

/// Trains `model` on `train` (from `start` when given) with the curve observer, then renders
/// and scores every test view (and saves the model where [`CompareConfig::models`] says).
#[allow(clippy::too_many_arguments)]
fn run_method<M: Model + ModelFile>(
    isa: Isa,
    scene_name: &str,
    method: Method,
    model: &M,
    start: Option<(M::Params, OccupancyGrid)>,
    train: &[View],
    test: &EvalSet,
    cfg: &CompareConfig,
    log: &mut dyn FnMut(Method, &StepStats),
) -> Result<MethodResult, String> {
    let mut curve = Vec::new();
    let mut renderer = ViewRenderer::<M>::new();
    let (mut z, mut truth) = (Vec::new(), Vec::new());
    let steps = cfg.train.steps;
    let every = if cfg.eval_every == 0 { steps } else { cfg.eval_every };
    let log_every = gcd(10, every);
    let tcfg = cfg.train_for(train);
    let (params, occupancy) =
        train_model_from(isa, model, cfg.field.aabb, train, &tcfg, start, log_every, |s, params, occupancy| {
            log(method, &s);
            let done = s.step + 1;
            if done % every == 0 || done == steps {
                let scene = Scene { model, params, occupancy };
                let errors = crop_errors(isa, &scene, test, cfg.m, &mut renderer, &mut z, &mut truth);
                curve.push(CurvePoint { step: done, seconds: s.seconds, errors });
            }
        })
        .map_err(|e: TrainError| e.to_string())?;
    if let Some(dir) = &cfg.models {
        save_model(
            &model_path(dir, scene_name, method),
            model,
            &params,
            &occupancy,
            &[("compare_method", method.name().to_string())],
        )?;
    }
    let seconds = curve.last().map_or(0.0, |p| p.seconds);
    let scene = Scene { model, params: &params, occupancy: &occupancy };
    let (mut threshold, mut expected) = (DepthReport::default(), DepthReport::default());
    let mut psnr_sum = 0.0;
    let mut renders = Vec::new();
    for (((v, gt), &crop), mask) in test.views.iter().zip(&test.depth).zip(&test.crops).zip(&test.masks) {
        let k = &v.intrinsics;
        let r = renderer.render(isa, &scene, k, &v.pose, cfg.train.background, cfg.m);
        threshold.add_frame(&r.threshold_z, gt, mask.as_deref(), k.width, crop, NEAR_LIMIT);
        expected.add_frame(&r.expected_z, gt, mask.as_deref(), k.width, crop, NEAR_LIMIT);
        psnr_sum += psnr(mse(&r.rgb, &v.rgb));
        renders.push(r);
    }
    let psnr = psnr_sum / test.views.len().max(1) as f64;
    let sweep = cfg
        .m_sweep
        .iter()
        .map(|&m| (m, crop_errors(isa, &scene, test, m, &mut renderer, &mut z, &mut truth)))
        .collect();
    Ok(MethodResult {
        method,
        seconds,
        rays_per_step: tcfg.rays_per_step,
        curve,
        threshold,
        expected,
        psnr,
        renders,
        sweep,
    })
}

/// Trains and scores every method of `methods` on one scene over the frozen `background`.
/// `bg_views` are the background's own training images (matched by pose for the change maps;
/// may be empty). `log` sees every method's training progress. A method whose training fails
/// ends the scene with an error naming the scene and method.
#[allow(clippy::too_many_arguments)]
pub fn run_scene(
    isa: Isa,
    name: &str,
    background: &Nerf,
    bg_views: &[View],
    train: &[View],
    test: &EvalSet,
    methods: &[Method],
    cfg: &CompareConfig,
    log: &mut dyn FnMut(Method, &StepStats),
) -> Result<SceneResult, String> {
    let mut prior: Option<(ScenePrior, PriorSummary)> = None;
    if methods.iter().any(|m| m.prior() != Prior::NONE) {
        let t0 = std::time::Instant::now();
        let p = scene_prior(isa, background, bg_views, train, cfg.train.background, cfg.m, &cfg.prior);
        let summary = PriorSummary {
            changed_pixels: p.changed_share(),
            reach_pixels: p.reach_share(),
            matched_views: p.matched_views,
            registered_views: p.registered_count(),
            views: train.len(),
            region_cells: p.region.count(),
            region_volume: p.region.volume(),
            seconds: t0.elapsed().as_secs_f64(),
        };
        prior = Some((p, summary));
    }
    let results = methods
        .iter()
        .map(|&method| {
            match method {
                Method::Dex => {
                    run_method(isa, name, method, &NerfField::new(cfg.field.clone()), None, train, test, cfg, log)
                }
                Method::DexErrorMap => {
                    let mut mcfg = cfg.clone();
                    mcfg.train.error_map = Some(crate::train::error_map::ERROR_MAP_SHARE);
                    run_method(isa, name, method, &NerfField::new(cfg.field.clone()), None, train, test, &mcfg, log)
                }
                Method::FineTune => {
                    let field = NerfField::new(background.field.config().clone());
                    let start = Some((background.params.clone(), background.occupancy.clone()));
                    run_method(isa, name, method, &field, start, train, test, cfg, log)
                }
                Method::Residual { kind, shared, prior: hints } => {
                    let mixnet = if shared { MixnetEncoding::Shared } else { MixnetEncoding::Own(cfg.mixnet_grid) };
                    let config = ResidualConfig { residual: cfg.field.clone(), kind, mixnet };
                    let p = prior.as_ref().map(|p| &p.0);
                    let mut start = residual_start(isa, background, config, hints, p, &cfg.train, &cfg.prior);
                    let mcfg = CompareConfig { train: start.train_config(&cfg.train), ..cfg.clone() };
                    if let Some(l) = start.lift {
                        eprintln!("{name}: {l}");
                    }
                    let init = Some((start.params, start.occupancy));
                    // In the background's frame and appearance when the prior registered a pose
                    // or corrected the exposure.
                    let corrected = p.filter(|p| p.corrects_views()).map(|p| p.corrected_views(train));
                    let views = corrected.as_deref().unwrap_or(train);
                    run_method(isa, name, method, &start.field, init, views, test, &mcfg, log)
                }
            }
            .map_err(|e| format!("{name}: {}: {e}", method.name()))
        })
        .collect::<Result<_, _>>()?;
    Ok(SceneResult { name: name.to_string(), methods: results, prior: prior.map(|p| p.1) })
}

/// The first curve point whose object-mask MAE is ≤ `target` (None: never).
pub fn first_reaching(curve: &[CurvePoint], target: f64) -> Option<&CurvePoint> {
    curve.iter().find(|p| p.errors.object.mae() <= target)
}
