//! Training checkpoints: a model file (loadable and renderable like any other) that also holds
//! what [`TrainState`] carries between steps, so `rnerf train --resume` continues bit-exactly.
//!
//! Beside the model's tensors ([`super::model`]):
//! - `train.adam.{g}.m`, `train.adam.{g}.v` f32 `[n]`: Adam's moments of parameter group `g`
//!   (in [`Model::groups`] order, padded MLP layouts included);
//! - with learned per-image gains ([`TrainConfig::image_gains`]): `train.gains` f32 `[3V]`, the
//!   log-gains of the V training images (r, g, b per image), and `train.gains.adam.m`,
//!   `train.gains.adam.v` f32 `[3V]`, their optimiser's moments;
//! - with a focus ([`TrainConfig::focus`]): `train.focus.pixels`, and when present
//!   `train.focus.reach` and `train.focus.spared`, f32 `[2n]` (view, pixel) pairs; metadata
//!   `train_focus_share`;
//! - with the photo tail's background colours ([`TrainConfig::behind`]): `train.behind.{v}` f32
//!   `[3n]`, training view `v`'s background colours (r, g, b per pixel);
//! - with the error map ([`TrainConfig::error_map`]): `train.error_map` f32 `[tiles]`, its tile
//!   values ([`crate::train::error_map`]);
//! - metadata `checkpoint`: `{"step", "skipped", "seconds", "adam_steps": [..], "fingerprint",
//!   "train": {the TrainConfig}}`, plus `"gain_adam_steps"` with learned gains. `fingerprint` hashes the training views (poses, intrinsics,
//!   pixels): a checkpoint resumes only on the data it was trained on. (A `prune` key, written
//!   before the training step was fused, is ignored.)

use super::model::{read_model_bytes, ModelFile, ModelReader};
use super::{model_from_bytes, LoadedModel};
use crate::data::View;
use crate::field::model::Model;
use crate::render::{OccupancyConfig, OccupancyGrid};
use crate::train::gains::ImageGains;
use crate::train::trainer::{NearGradient, TrainConfig, TrainState};
use crate::train::{Adam, AdamConfig, LrSchedule};
use serde_json::{json, Value};
use std::path::Path;

/// What a checkpoint holds beyond the model: everything to rebuild the [`TrainState`].
#[derive(Clone, Debug)]
pub struct Checkpoint {
    /// Steps completed.
    pub step: u32,
    /// Steps skipped for non-finite values so far.
    pub skipped: u32,
    /// Training seconds so far.
    pub seconds: f64,
    /// The run's settings.
    pub config: TrainConfig,
    /// [`views_fingerprint`] of the training views.
    pub fingerprint: u64,
    /// The checkpoint file's metadata (the run's informational entries among them).
    pub metadata: std::collections::HashMap<String, String>,
    /// Adam's first and second moments and step count per parameter group.
    pub moments: Vec<(Vec<f32>, Vec<f32>, u32)>,
    /// The learned per-image gains and their optimiser ([`TrainConfig::image_gains`]).
    pub gains: Option<ImageGains>,
    /// The error map's tile values ([`TrainConfig::error_map`]).
    pub error_map: Option<Vec<f32>>,
}

impl Checkpoint {
    /// The training state of `model` with `params` and `occupancy` (as loaded from the same
    /// file); refuses moments that do not fit the model's parameter groups.
    pub fn into_state<M: Model>(
        self,
        model: &M,
        mut params: M::Params,
        occupancy: OccupancyGrid,
    ) -> Result<TrainState<M::Params>, String> {
        let grads = model.zero_grads();
        let groups = model.groups(&mut params, &grads);
        if groups.len() != self.moments.len() {
            return Err(format!("{} optimiser states for {} parameter groups", self.moments.len(), groups.len()));
        }
        let mut adams = Vec::with_capacity(groups.len());
        for (g, (i, (m, v, t))) in groups.iter().zip(self.moments.into_iter().enumerate()) {
            if m.len() != g.master.len() || v.len() != g.master.len() {
                return Err(format!(
                    "tensor 'train.adam.{i}.m' has {} values, the model needs {}",
                    m.len(),
                    g.master.len()
                ));
            }
            let mut adam = Adam::new(g.master.len(), AdamConfig { l2: g.l2, ..Default::default() });
            adam.restore(m, v, t);
            adams.push(adam);
        }
        drop(groups);
        model.after_step(&mut params); // groups() lent the weights out mutably
        Ok(TrainState {
            step: self.step,
            params,
            occupancy,
            adams,
            skipped: self.skipped,
            seconds: self.seconds,
            gains: self.gains,
            error_map: self.error_map,
        })
    }
}

/// FNV-1a over the views' intrinsics, poses and pixels: equal for the same training data.
pub fn views_fingerprint(views: &[View]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
        }
    };
    for v in views {
        let k = &v.intrinsics;
        eat(&k.width.to_le_bytes());
        eat(&k.height.to_le_bytes());
        for x in [k.fx, k.fy, k.cx, k.cy] {
            eat(&x.to_le_bytes());
        }
        if !k.distortion.is_none() {
            eat(k.distortion.model_name().as_bytes());
            for (_, c) in k.distortion.coefficients() {
                eat(&c.to_le_bytes());
            }
        }
        for x in v.pose.rotation.to_cols_array().iter().chain(&v.pose.translation.to_array()) {
            eat(&x.to_le_bytes());
        }
        eat(bytemuck::cast_slice(&v.rgb));
    }
    h
}

/// Writes `field`'s model file plus the training state, atomically; `extra` is informational
/// metadata. Non-finite values are refused (nothing is written).
pub fn save_checkpoint<M: ModelFile>(
    path: &Path,
    field: &M,
    state: &TrainState<M::Params>,
    config: &TrainConfig,
    fingerprint: u64,
    extra: &[(&str, String)],
) -> Result<(), String> {
    let at = |e: String| format!("{}: {e}", path.display());
    let mut w = field.writer(&state.params, &state.occupancy).map_err(at)?;
    for (k, v) in extra {
        w.meta(k, v);
    }
    for (g, adam) in state.adams.iter().enumerate() {
        let (m, v) = adam.moments();
        w.tensor(&format!("train.adam.{g}.m"), vec![m.len()], m).map_err(at)?;
        w.tensor(&format!("train.adam.{g}.v"), vec![v.len()], v).map_err(at)?;
    }
    if let Some(g) = &state.gains {
        let (m, v) = g.adam.moments();
        let a: &[f32] = bytemuck::cast_slice(&g.log_gains);
        w.tensor("train.gains", vec![a.len()], a).map_err(at)?;
        w.tensor("train.gains.adam.m", vec![m.len()], m).map_err(at)?;
        w.tensor("train.gains.adam.v", vec![v.len()], v).map_err(at)?;
    }
    if let Some(f) = &config.focus {
        // (view, pixel) pairs as f32: exact below 2^24, which the loader checks.
        let flat = |list: &[(u32, u32)]| -> Vec<f32> { list.iter().flat_map(|&(v, p)| [v as f32, p as f32]).collect() };
        let pixels = flat(&f.pixels);
        w.tensor("train.focus.pixels", vec![pixels.len()], &pixels).map_err(at)?;
        if let Some(reach) = &f.reach {
            let reach = flat(reach);
            w.tensor("train.focus.reach", vec![reach.len()], &reach).map_err(at)?;
        }
        if let Some(spared) = &f.spared {
            let spared = flat(spared);
            w.tensor("train.focus.spared", vec![spared.len()], &spared).map_err(at)?;
        }
        w.meta("train_focus_share", &f.share.to_string());
    }
    if let Some(behind) = &config.behind {
        for v in 0..behind.len() {
            let flat: Vec<f32> = (0..behind.pixels(v)).flat_map(|p| behind.get(v, p)).collect();
            w.tensor(&format!("train.behind.{v}"), vec![flat.len()], &flat).map_err(at)?;
        }
    }
    if let Some(values) = &state.error_map {
        w.tensor("train.error_map", vec![values.len()], values).map_err(at)?;
    }
    let mut meta = json!({
        "step": state.step,
        "skipped": state.skipped,
        "seconds": state.seconds,
        "adam_steps": state.adams.iter().map(Adam::steps).collect::<Vec<_>>(),
        "fingerprint": format!("{fingerprint:016x}"),
        "train": train_config_json(config),
    });
    if let Some(g) = &state.gains {
        meta["gain_adam_steps"] = json!(g.adam.steps());
    }
    w.meta("checkpoint", &meta.to_string());
    w.write(path)
}

/// Loads a checkpoint: the model and its training state. A finished model (no training
/// state) is refused; errors name the file.
pub fn load_checkpoint(path: &Path) -> Result<(LoadedModel, Checkpoint), String> {
    let bytes = read_model_bytes(path)?;
    checkpoint_from_bytes(&bytes).map_err(|e| format!("{}: {e}", path.display()))
}

/// A checkpoint from model-file bytes.
pub fn checkpoint_from_bytes(bytes: &[u8]) -> Result<(LoadedModel, Checkpoint), String> {
    let model = model_from_bytes(bytes)?;
    let r = ModelReader::parse(bytes)?;
    let occupancy = match &model {
        LoadedModel::Nerf(n) => n.occupancy.config().clone(),
        LoadedModel::Residual(m) => m.occupancy.config().clone(),
    };
    Ok((model, read_checkpoint(&r, occupancy)?))
}

/// A tensor of `(view, pixel)` pairs stored as f32 (exact below 2^24).
fn pixel_pairs(r: &ModelReader, name: &str) -> Result<Vec<(u32, u32)>, String> {
    let flat = flat_tensor(r, name)?;
    if flat.len() % 2 != 0 {
        return Err(format!("tensor '{name}' does not hold (view, pixel) pairs"));
    }
    let mut pixels = Vec::with_capacity(flat.len() / 2);
    for (i, pair) in flat.chunks(2).enumerate() {
        let ok = |x: f32| x.is_finite() && x >= 0.0 && x.fract() == 0.0 && x < (1u32 << 24) as f32;
        if !(ok(pair[0]) && ok(pair[1])) {
            return Err(format!("tensor '{name}' holds a bad (view, pixel) pair at {i}"));
        }
        pixels.push((pair[0] as u32, pair[1] as u32));
    }
    Ok(pixels)
}

fn read_checkpoint(r: &ModelReader, occupancy: OccupancyConfig) -> Result<Checkpoint, String> {
    let text =
        r.meta("checkpoint").map_err(|_| "not a checkpoint (a finished model: no training state)".to_string())?;
    let v: Value = serde_json::from_str(text).map_err(|e| format!("metadata 'checkpoint' is not JSON: {e}"))?;
    let field = |k: &str| format!("metadata 'checkpoint': '{k}' missing or out of range");
    let u32_of = |k: &str| v.get(k).and_then(Value::as_u64).and_then(|x| u32::try_from(x).ok()).ok_or_else(|| field(k));
    let step = u32_of("step")?;
    let skipped = u32_of("skipped")?;
    let seconds = v.get("seconds").and_then(Value::as_f64).filter(|s| s.is_finite()).ok_or_else(|| field("seconds"))?;
    let fingerprint = v
        .get("fingerprint")
        .and_then(Value::as_str)
        .and_then(|s| u64::from_str_radix(s, 16).ok())
        .ok_or_else(|| field("fingerprint"))?;
    let mut config = parse_train_config(v.get("train").ok_or_else(|| field("train"))?, occupancy)
        .map_err(|e| format!("metadata 'checkpoint': 'train': {e}"))?;
    if let Ok(share) = r.meta("train_focus_share") {
        let share: f32 = share
            .parse()
            .ok()
            .filter(|s: &f32| (0.0..=1.0).contains(s))
            .ok_or_else(|| format!("metadata 'train_focus_share' = '{share}' is not in [0, 1]"))?;
        let pixels = pixel_pairs(r, "train.focus.pixels")?;
        let reach = match r.shape("train.focus.reach").is_ok() {
            true => Some(std::sync::Arc::new(pixel_pairs(r, "train.focus.reach")?)),
            false => None,
        };
        let spared = match r.shape("train.focus.spared").is_ok() {
            true => Some(std::sync::Arc::new(pixel_pairs(r, "train.focus.spared")?)),
            false => None,
        };
        config.focus = Some(crate::train::trainer::Focus { share, pixels: std::sync::Arc::new(pixels), reach, spared });
    }
    let mut behind = Vec::new();
    while r.shape(&format!("train.behind.{}", behind.len())).is_ok() {
        let name = format!("train.behind.{}", behind.len());
        let flat = flat_tensor(r, &name)?;
        if flat.len() % 3 != 0 || flat.iter().any(|x| !(0.0..=1.0).contains(x)) {
            return Err(format!("tensor '{name}' does not hold (r, g, b) colours in [0, 1]"));
        }
        behind.push(flat.chunks(3).map(|c| [c[0], c[1], c[2]]).collect::<Vec<[f32; 3]>>());
    }
    if !behind.is_empty() {
        config.behind = Some(std::sync::Arc::new(crate::train::prior::BackgroundColours::new(&behind)));
    }
    if step > config.steps {
        return Err(format!("metadata 'checkpoint': step {step} is past the run's {} steps", config.steps));
    }
    let adam_steps = v.get("adam_steps").and_then(Value::as_array).ok_or_else(|| field("adam_steps"))?;
    let mut moments = Vec::with_capacity(adam_steps.len());
    for (g, t) in adam_steps.iter().enumerate() {
        let t = t.as_u64().and_then(|t| u32::try_from(t).ok()).ok_or_else(|| field("adam_steps"))?;
        let m = flat_tensor(r, &format!("train.adam.{g}.m"))?;
        let v = flat_tensor(r, &format!("train.adam.{g}.v"))?;
        if let Some(i) = v.iter().position(|&x| x < 0.0) {
            return Err(format!("tensor 'train.adam.{g}.v' holds a negative value at {i}"));
        }
        moments.push((m, v, t));
    }
    let gains = match config.image_gains {
        None => None,
        Some(prior) => {
            let t = u32_of("gain_adam_steps")?;
            let a = flat_tensor(r, "train.gains")?;
            let (m, v) = (flat_tensor(r, "train.gains.adam.m")?, flat_tensor(r, "train.gains.adam.v")?);
            if a.len() % 3 != 0 || m.len() != a.len() || v.len() != a.len() {
                return Err(format!(
                    "tensors 'train.gains' ({}), 'train.gains.adam.m' ({}) and 'train.gains.adam.v' ({}) must hold \
                     3 values per image each",
                    a.len(),
                    m.len(),
                    v.len()
                ));
            }
            for (name, x, lo) in
                [("train.gains", &a, f32::MIN), ("train.gains.adam.m", &m, f32::MIN), ("train.gains.adam.v", &v, 0.0)]
            {
                if let Some(i) = x.iter().position(|x| !(x.is_finite() && *x >= lo)) {
                    return Err(format!("tensor '{name}' holds a non-finite or negative value at {i}"));
                }
            }
            let mut g = ImageGains::new(a.len() / 3, prior);
            g.log_gains = a.chunks(3).map(|c| [c[0], c[1], c[2]]).collect();
            g.adam.restore(m, v, t);
            Some(g)
        }
    };
    let error_map = match config.error_map {
        None => None,
        Some(_) => {
            let values = flat_tensor(r, "train.error_map")?;
            if let Some(i) = values.iter().position(|x| !(x.is_finite() && *x >= 0.0)) {
                return Err(format!("tensor 'train.error_map' holds a non-finite or negative value at {i}"));
            }
            Some(values)
        }
    };
    Ok(Checkpoint {
        step,
        skipped,
        seconds,
        config,
        fingerprint,
        moments,
        gains,
        error_map,
        metadata: r.metadata().clone(),
    })
}

/// A one-dimensional f32 tensor of any length.
fn flat_tensor(r: &ModelReader, name: &str) -> Result<Vec<f32>, String> {
    let n = r.shape(name)?;
    match n.as_slice() {
        [n] => r.tensor(name, &[*n]),
        other => Err(format!("tensor '{name}' has shape {other:?}, expected one dimension")),
    }
}

/// The settings of a run as JSON (exact: every f32 survives the round trip).
pub fn train_config_json(c: &TrainConfig) -> Value {
    let s = &c.schedule;
    json!({
        "steps": c.steps, "rays_per_step": c.rays_per_step,
        "schedule": {
            "base": s.base, "warmup_steps": s.warmup_steps, "decay_start": s.decay_start,
            "decay_interval": s.decay_interval, "decay_factor": s.decay_factor,
        },
        "occupancy_interval": c.occupancy_interval,
        "background": c.background, "random_background": c.random_background,
        "seed": c.seed, "distortion": c.distortion,
        "near_gradient_distance": match c.near_gradient { NearGradient::Distance(d) => d, _ => 0.0 },
        "near_gradient_share": match c.near_gradient { NearGradient::OfCapture(s) => Some(s), _ => None },
        "beta_unchanged": c.beta.unchanged, "beta_entropy": c.beta.entropy, "beta_entropy_from": c.beta.entropy_from,
        "frozen_stride": c.frozen_stride, "image_gains": c.image_gains, "error_map": c.error_map,
        "pixel_jitter": c.pixel_jitter, "pixel_rays": c.pixel_rays, "ray_pool": c.ray_pool,
        "photo_tail": c.photo_tail,
        "frozen_tail": c.frozen_tail, "frozen_coarse": c.frozen_coarse, "frozen_coarse_stride": c.frozen_coarse_stride,
    })
}

/// Parses [`train_config_json`]; the occupancy settings come from the model.
pub fn parse_train_config(v: &Value, occupancy: OccupancyConfig) -> Result<TrainConfig, String> {
    let uint = |v: &Value, k: &str, lo: u64, hi: u64| -> Result<u64, String> {
        v.get(k)
            .and_then(Value::as_u64)
            .filter(|x| (lo..=hi).contains(x))
            .ok_or(format!("'{k}' missing or not in {lo}..={hi}"))
    };
    let real = |v: &Value, k: &str, lo: f64, hi: f64| -> Result<f32, String> {
        v.get(k)
            .and_then(Value::as_f64)
            .filter(|x| (lo..=hi).contains(x))
            .map(|x| x as f32)
            .ok_or(format!("'{k}' missing or not in [{lo}, {hi}]"))
    };
    // Fields added after the first checkpoints: absent means 0 (off).
    let optional = |v: &Value, k: &str, hi: f64| if v.get(k).is_none() { Ok(0.0) } else { real(v, k, 0.0, hi) };
    let s = v.get("schedule").ok_or("'schedule' missing")?;
    let schedule = LrSchedule {
        base: real(s, "base", 0.0, 1.0)?,
        warmup_steps: uint(s, "warmup_steps", 0, u32::MAX as u64)? as u32,
        decay_start: uint(s, "decay_start", 0, u32::MAX as u64)? as u32,
        decay_interval: uint(s, "decay_interval", 1, u32::MAX as u64)? as u32,
        decay_factor: real(s, "decay_factor", 0.0, 1.0)?,
    };
    let bg =
        v.get("background").and_then(Value::as_array).filter(|a| a.len() == 3).ok_or("'background' not 3 numbers")?;
    let background: Vec<f32> = bg
        .iter()
        .map(|x| x.as_f64().filter(|x| (0.0..=1.0).contains(x)).map(|x| x as f32))
        .collect::<Option<_>>()
        .ok_or("'background' not in [0, 1]")?;
    Ok(TrainConfig {
        steps: uint(v, "steps", 1, 100_000_000)? as u32,
        rays_per_step: uint(v, "rays_per_step", 1, 1 << 24)? as usize,
        schedule,
        occupancy_interval: uint(v, "occupancy_interval", 1, u32::MAX as u64)? as u32,
        occupancy,
        background: [background[0], background[1], background[2]],
        random_background: v
            .get("random_background")
            .and_then(Value::as_bool)
            .ok_or("'random_background' not a bool")?,
        seed: uint(v, "seed", 0, u64::MAX)?,
        distortion: real(v, "distortion", 0.0, 1e6)?,
        // The share was added later: absent or null means the distance (0: off).
        near_gradient: match v.get("near_gradient_share") {
            None | Some(Value::Null) => match real(v, "near_gradient_distance", 0.0, 1e6)? {
                0.0 => NearGradient::Off,
                d => NearGradient::Distance(d),
            },
            Some(_) => NearGradient::OfCapture(real(v, "near_gradient_share", 0.0, 1e3)?),
        },
        // The focus pixels are tensors beside this JSON ([`read_checkpoint`] reads them).
        focus: None,
        beta: crate::train::beta::BetaRegulariser {
            unchanged: optional(v, "beta_unchanged", 1e6)?,
            entropy: optional(v, "beta_entropy", 1e6)?,
            entropy_from: optional(v, "beta_entropy_from", 1.0)?,
        },
        // Added later: absent means off (how they were trained).
        frozen_tail: optional(v, "frozen_tail", 0.5)?,
        photo_tail: v.get("photo_tail").and_then(Value::as_bool).unwrap_or(false),
        behind: None,
        frozen_coarse: optional(v, "frozen_coarse", 1.0)?,
        frozen_coarse_stride: match v.get("frozen_coarse_stride") {
            None => 1,
            Some(_) => uint(v, "frozen_coarse_stride", 1, 64)? as u32,
        },
        // Added after the first checkpoints: absent means every step (how they were trained).
        frozen_stride: match v.get("frozen_stride") {
            None => 1,
            Some(_) => uint(v, "frozen_stride", 1, 64)? as u32,
        },
        // Added later: absent or null means off.
        image_gains: match v.get("image_gains") {
            None | Some(Value::Null) => None,
            Some(_) => Some(real(v, "image_gains", 0.0, 1e6)?),
        },
        // Added later: absent or null means off.
        error_map: match v.get("error_map") {
            None | Some(Value::Null) => None,
            Some(_) => Some(real(v, "error_map", 0.0, 1.0)?),
        },
        // Added later: absent means rays through the pixels' centres.
        pixel_jitter: match v.get("pixel_jitter") {
            None => false,
            Some(b) => b.as_bool().ok_or("'pixel_jitter' is not true or false")?,
        },
        // Added later: absent means one ray per pixel.
        pixel_rays: match v.get("pixel_rays") {
            None => 1,
            Some(_) => uint(v, "pixel_rays", 1, crate::train::trainer::MAX_PIXEL_RAYS as u64)? as u32,
        },
        // Added later: absent means every ray fresh (how those runs were trained).
        ray_pool: match v.get("ray_pool") {
            None => 0,
            Some(_) => uint(v, "ray_pool", 0, crate::train::trainer::MAX_RAY_POOL as u64)? as u32,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_train_config_survives_its_json_with_the_beta_weights_and_gains() {
        let mut c = TrainConfig::with_steps(300);
        c.beta = crate::train::beta::BetaRegulariser { unchanged: 0.25, entropy: 0.5, entropy_from: 0.75 };
        c.seed = 7;
        c.image_gains = Some(crate::train::trainer::GAIN_PRIOR);
        c.error_map = Some(0.375);
        c.pixel_jitter = !c.pixel_jitter;
        c.pixel_rays = 4;
        let back = parse_train_config(&train_config_json(&c), c.occupancy.clone()).unwrap();
        assert_eq!(back.beta, c.beta);
        assert_eq!(back.image_gains, c.image_gains);
        assert_eq!(back.error_map, c.error_map);
        assert_eq!(back.pixel_jitter, c.pixel_jitter);
        assert_eq!(back.pixel_rays, c.pixel_rays);
        assert_eq!((back.steps, back.seed, back.schedule), (c.steps, c.seed, c.schedule.clone()));
        // A checkpoint written before the β weights and the gains existed reads them as off.
        let mut old = train_config_json(&c);
        for k in ["beta_unchanged", "beta_entropy", "beta_entropy_from", "image_gains", "error_map"] {
            old.as_object_mut().unwrap().remove(k);
        }
        let back = parse_train_config(&old, c.occupancy.clone()).unwrap();
        assert_eq!(back.beta, Default::default());
        assert_eq!(back.image_gains, None);
        // A negative prior weight is refused.
        let mut bad = train_config_json(&c);
        bad["image_gains"] = json!(-1.0);
        assert!(parse_train_config(&bad, c.occupancy.clone()).unwrap_err().contains("image_gains"));
    }
}
