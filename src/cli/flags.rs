//! The flags: one table of every flag ([`FLAGS`]: name, commands, whether a checkpoint fixes
//! it), their values as the command line is read ([`Flags`]), and the checks that need more
//! than one flag.

use super::{err, CliError, CropRule};
use crate::render::DepthMethod;
use std::path::PathBuf;

/// A flag: its name (`--name`), the commands that take it, and whether it is a training setting
/// a checkpoint fixes (`train --resume` refuses it rather than ignore it: the background prior's
/// flags too, since a resumed run does not recompute the prior).
pub(super) struct Flag {
    pub(super) name: &'static str,
    pub(super) commands: &'static [&'static str],
    pub(super) setting: bool,
}

/// The commands (besides `help`).
pub(super) const COMMANDS: [&str; 7] = ["train", "render", "eval", "compare", "demo", "import", "bench"];

/// Every flag: the one list the parser's allow-lists and the resume check read
/// ([`Flags::take`] parses each; `tests` check that USAGE names each one).
pub(super) const FLAGS: &[Flag] = &[
    Flag { name: "data", commands: &["train", "render", "eval", "bench"], setting: false },
    Flag { name: "out", commands: &["train", "render", "compare", "demo", "import"], setting: false },
    Flag { name: "split", commands: &["train", "render", "eval"], setting: false },
    Flag { name: "steps", commands: &["train", "compare", "demo"], setting: true },
    Flag { name: "rays", commands: &["train", "compare"], setting: true },
    Flag { name: "log2t", commands: &["train", "compare", "bench"], setting: true },
    Flag { name: "seed", commands: &["train", "compare", "demo"], setting: true },
    Flag { name: "threads", commands: &["train", "render", "eval", "compare", "demo", "bench"], setting: false },
    Flag { name: "csv", commands: &["train"], setting: false },
    Flag { name: "background", commands: &["train", "compare"], setting: true },
    Flag { name: "mix", commands: &["train"], setting: true },
    Flag { name: "density-mix", commands: &["train"], setting: true },
    Flag { name: "mixnet-encoding", commands: &["train"], setting: true },
    Flag { name: "distortion", commands: &["train"], setting: true },
    Flag { name: "lr", commands: &["train"], setting: true },
    Flag { name: "near-grad", commands: &["train", "compare"], setting: true },
    Flag { name: "fixed-background", commands: &["train"], setting: true },
    Flag { name: "checkpoint-every", commands: &["train"], setting: false },
    Flag { name: "budget", commands: &["train"], setting: false },
    Flag { name: "resume", commands: &["train"], setting: false },
    Flag { name: "scene-views", commands: &["train", "compare"], setting: false },
    Flag { name: "prior", commands: &["train"], setting: true },
    Flag { name: "background-data", commands: &["train", "bench"], setting: true },
    Flag { name: "beta", commands: &["train", "compare"], setting: true },
    Flag { name: "beta-margin", commands: &["train", "compare"], setting: true },
    Flag { name: "beta-fill", commands: &["train", "compare"], setting: true },
    Flag { name: "region-floor", commands: &["train", "compare"], setting: true },
    Flag { name: "focus-share", commands: &["train", "compare"], setting: true },
    Flag { name: "region-vote", commands: &["train", "compare"], setting: true },
    Flag { name: "region-dilate", commands: &["train", "compare"], setting: true },
    Flag { name: "region-subdivide", commands: &["train", "compare"], setting: true },
    Flag { name: "change-tolerance", commands: &["train", "compare"], setting: true },
    Flag { name: "frozen-stride", commands: &["train", "compare"], setting: true },
    Flag { name: "frozen-tail", commands: &["train", "compare"], setting: true },
    Flag { name: "frozen-coarse", commands: &["train", "compare"], setting: true },
    Flag { name: "photo-tail", commands: &["train", "compare"], setting: true },
    Flag { name: "ray-pool", commands: &["train", "compare"], setting: true },
    Flag { name: "image-gains", commands: &["train", "compare"], setting: true },
    Flag { name: "error-map", commands: &["train"], setting: true },
    Flag { name: "pixel-jitter", commands: &["train", "compare"], setting: true },
    Flag { name: "pixel-rays", commands: &["train", "compare"], setting: true },
    Flag { name: "exposure-correction", commands: &["train", "compare"], setting: true },
    Flag { name: "pose-registration", commands: &["train", "compare"], setting: true },
    Flag { name: "registration-passes", commands: &["train"], setting: true },
    Flag { name: "model", commands: &["render", "eval", "import", "bench"], setting: false },
    Flag { name: "depth", commands: &["render", "eval"], setting: false },
    Flag { name: "depth-only", commands: &["render", "eval"], setting: false },
    Flag { name: "solid-fraction", commands: &["render", "eval"], setting: false },
    Flag { name: "coarse-start", commands: &["render", "eval"], setting: false },
    Flag { name: "colour-tail", commands: &["render", "eval"], setting: false },
    Flag { name: "m", commands: &["render", "eval", "compare"], setting: false },
    Flag { name: "m-raw", commands: &["render", "eval", "compare"], setting: false },
    Flag { name: "crop", commands: &["eval"], setting: false },
    Flag { name: "limit", commands: &["eval"], setting: false },
    Flag { name: "json", commands: &["eval", "bench"], setting: false },
    Flag { name: "background-model", commands: &["compare"], setting: false },
    Flag { name: "scene", commands: &["compare", "bench"], setting: false },
    Flag { name: "methods", commands: &["compare"], setting: false },
    Flag { name: "eval-every", commands: &["compare"], setting: false },
    Flag { name: "background-steps", commands: &["compare"], setting: false },
    Flag { name: "m-sweep", commands: &["compare"], setting: false },
    Flag { name: "size", commands: &["demo"], setting: false },
    Flag { name: "images", commands: &["import"], setting: false },
    Flag { name: "background-match", commands: &["import"], setting: false },
    Flag { name: "known-distance", commands: &["import"], setting: false },
    Flag { name: "reps", commands: &["bench"], setting: false },
];

/// Every flag's value, filled as the command line is read.
#[derive(Default)]
pub(super) struct Flags {
    pub(super) data: Option<PathBuf>,
    pub(super) out: Option<PathBuf>,
    /// Every `--model` given: bench takes several, render and eval the last.
    pub(super) models: Vec<PathBuf>,
    pub(super) csv: Option<PathBuf>,
    pub(super) split: Option<String>,
    pub(super) steps: Option<u32>,
    pub(super) size: Option<u32>,
    pub(super) rays: Option<usize>,
    pub(super) log2t: Option<u32>,
    pub(super) seed: Option<u64>,
    pub(super) threads: Option<usize>,
    pub(super) reps: Option<usize>,
    pub(super) depth: Option<String>,
    pub(super) m: Option<f32>,
    pub(super) m_raw: Option<f32>,
    pub(super) crop: Option<CropRule>,
    pub(super) limit: Option<f32>,
    pub(super) json: bool,
    pub(super) depth_only: bool,
    /// `--solid-fraction F`.
    pub(super) solid_fraction: Option<f32>,
    /// `--coarse-start N|off` (`Some(None)`: off).
    pub(super) coarse_start: Option<Option<u32>>,
    /// `--colour-tail R|off` (`Some(0.0)`: off).
    pub(super) colour_tail: Option<f32>,
    pub(super) background: Option<PathBuf>,
    pub(super) mix: Option<String>,
    pub(super) density_mix: Option<String>,
    pub(super) mixnet_encoding: Option<String>,
    pub(super) distortion: Option<f32>,
    pub(super) lr: Option<f32>,
    pub(super) near_grad: Option<f32>,
    pub(super) m_sweep: Option<Vec<crate::render::DensityThreshold>>,
    pub(super) fixed_background: bool,
    pub(super) background_model: Option<PathBuf>,
    pub(super) scenes: Vec<PathBuf>,
    pub(super) methods: Option<Vec<crate::compare::Method>>,
    pub(super) eval_every: Option<u32>,
    pub(super) background_steps: Option<u32>,
    pub(super) checkpoint_every: Option<u32>,
    pub(super) budget: Option<f64>,
    pub(super) resume: Option<PathBuf>,
    pub(super) scene_views: Option<usize>,
    pub(super) prior: Option<crate::train::prior::Prior>,
    pub(super) background_data: Option<PathBuf>,
    pub(super) beta: Option<(f32, f32)>,
    /// `--beta-margin N`: pixels around the changed ones the β penalty spares.
    pub(super) beta_margin: Option<u32>,
    /// `--beta-fill R`: the changed pixels the β penalty spares closed by R pixels, holes filled.
    pub(super) beta_fill: Option<u32>,
    pub(super) region_floor: Option<Option<f32>>,
    pub(super) focus_share: Option<f32>,
    pub(super) region_vote: Option<(f32, f32)>,
    /// `--region-dilate N`: cells the voted change region grows by.
    pub(super) region_dilate: Option<u32>,
    /// `--region-subdivide K`: the region voted on a grid K times finer than the occupancy grid.
    pub(super) region_subdivide: Option<u32>,
    /// `--change-tolerance T[,R]`: colour difference above which a scene pixel changed
    /// (against the rendered background: R).
    pub(super) change_tolerance: Option<(f32, Option<f32>)>,
    pub(super) exposure_correction: Option<bool>,
    pub(super) pose_registration: Option<bool>,
    pub(super) registration_passes: Option<u32>,
    pub(super) frozen_stride: Option<u32>,
    pub(super) frozen_tail: Option<f32>,
    pub(super) frozen_coarse: Option<(f32, u32)>,
    /// `--photo-tail on|off`.
    pub(super) photo_tail: Option<bool>,
    pub(super) ray_pool: Option<u32>,
    /// `--image-gains on`: the identity prior's weight; off or not given: `None`.
    pub(super) image_gains: Option<f32>,
    /// `--error-map S`: the share of rays drawn by the error map; off or not given: `None`.
    pub(super) error_map: Option<f32>,
    /// `--pixel-jitter on|off`.
    pub(super) pixel_jitter: Option<bool>,
    /// `--pixel-rays K`.
    pub(super) pixel_rays: Option<u32>,
    /// Flags given, in order.
    pub(super) given: Vec<String>,
    pub(super) images: Option<PathBuf>,
    pub(super) background_match: Option<String>,
    pub(super) known_distance: Option<(String, String, f64)>,
}

impl Flags {
    pub(super) fn take(&mut self, name: &str, p: &mut lexopt::Parser) -> Result<(), CliError> {
        self.given.push(name.to_string());
        match name {
            "checkpoint-every" => self.checkpoint_every = Some(positive(p, name)?),
            "budget" => {
                let v: f64 = number(p, name)?;
                if !(v.is_finite() && (0.0..=1e7).contains(&v)) {
                    return Err(err(format!("--budget: {v} is not a number of seconds in [0, 1e7]")));
                }
                self.budget = Some(v);
            }
            "scene-views" => self.scene_views = Some(positive(p, name)?),
            "background-data" => self.background_data = Some(path(p, name)?),
            "prior" => {
                let s = text(p, name)?;
                let mut h = crate::train::prior::Prior::NONE;
                if s != "none" {
                    for part in s.split(',') {
                        match part {
                            "warm-start" => h.warm_start = true,
                            "region" => h.region = true,
                            "focus" => h.focus = true,
                            "beta" => h.beta = true,
                            "reach" => h.reach = true,
                            "solid" => h.solid = true,
                            "all" => h = crate::train::prior::Prior::ALL,
                            _ => {
                                return Err(err(format!(
                                "--prior: '{part}' is not all, none, warm-start, region, focus, beta, reach or solid"
                            )))
                            }
                        }
                    }
                }
                self.prior = Some(h);
            }
            "beta" => {
                let s = text(p, name)?;
                match numbers(&s, |v| (0.0..=1e6).contains(&v))[..] {
                    [Some(u), Some(e)] => self.beta = Some((u, e)),
                    _ => return Err(err(format!("--beta: '{s}' is not two weights U,E in [0, 1e6]"))),
                }
            }
            "beta-margin" => self.beta_margin = Some(whole(p, name, 16, "pixels")?),
            "beta-fill" => self.beta_fill = Some(whole(p, name, 64, "pixels")?),
            "region-floor" => {
                let s = text(p, name)?;
                self.region_floor = Some(match s.as_str() {
                    "off" => None,
                    _ => Some(s.parse::<f32>().ok().filter(|v| v.is_finite() && v.abs() <= 15.0).ok_or_else(|| {
                        err(format!("--region-floor: '{s}' is not off or a log-density in [-15, 15]"))
                    })?),
                });
            }
            "focus-share" => self.focus_share = Some(finite(p, name, 0.0, 1.0)?),
            "frozen-stride" => {
                let n: u32 = positive(p, name)?;
                if n > 64 {
                    return Err(err(format!("--frozen-stride: {n} is outside 1..=64")));
                }
                self.frozen_stride = Some(n);
            }
            "frozen-tail" => {
                let v: f32 = number(p, name)?;
                if !(0.0..=0.5).contains(&v) {
                    return Err(err(format!("--frozen-tail: {v} is outside [0, 0.5]")));
                }
                self.frozen_tail = Some(v);
            }
            "frozen-coarse" => {
                let s = text(p, name)?;
                self.frozen_coarse = Some(match s.split_once(',') {
                    None if s == "off" => (0.0, 1),
                    Some((t, n)) => match (t.parse::<f32>(), n.parse::<u32>()) {
                        (Ok(t), Ok(n)) if (0.0..=1.0).contains(&t) && (1..=64).contains(&n) => (t, n),
                        _ => {
                            return Err(err(format!("--frozen-coarse: '{s}' is not T,N with T in [0, 1], N in 1..=64")))
                        }
                    },
                    None => return Err(err(format!("--frozen-coarse: '{s}' is not T,N or off"))),
                });
            }
            "ray-pool" => {
                let max = crate::train::trainer::MAX_RAY_POOL;
                let n: u32 =
                    text(p, name)?.parse().ok().filter(|n| *n <= max).ok_or_else(|| {
                        err(format!("--ray-pool: expected a whole number of draws per ray in 0..={max}"))
                    })?;
                self.ray_pool = Some(n);
            }
            "region-vote" => {
                let s = text(p, name)?;
                match numbers(&s, |v| (0.0..=1.0).contains(&v))[..] {
                    [Some(vote), Some(seen)] => self.region_vote = Some((vote, seen)),
                    _ => return Err(err(format!("--region-vote: '{s}' is not two shares V,S in [0, 1]"))),
                }
            }
            "region-dilate" => self.region_dilate = Some(whole(p, name, 4, "cells")?),
            "region-subdivide" => match whole(p, name, 4, "subdivisions")? {
                0 => return Err(err("--region-subdivide: 0 is not a subdivision (1: the occupancy grid's cells)")),
                k => self.region_subdivide = Some(k),
            },
            "change-tolerance" => {
                let s = text(p, name)?;
                self.change_tolerance = match numbers(&s, |t| t > 0.0 && t <= 0.5)[..] {
                    [Some(t)] => Some((t, None)),
                    [Some(t), Some(r)] => Some((t, Some(r))),
                    _ => {
                        return Err(err(format!(
                            "--change-tolerance: '{s}' is not T or T,R, colour differences in (0, 0.5]"
                        )))
                    }
                };
            }
            "resume" => self.resume = Some(path(p, name)?),
            "exposure-correction" => self.exposure_correction = Some(choice(p, name, &["on", "off"])? == "on"),
            "pose-registration" => self.pose_registration = Some(choice(p, name, &["on", "off"])? == "on"),
            "image-gains" => {
                self.image_gains =
                    (choice(p, name, &["on", "off"])? == "on").then_some(crate::train::trainer::GAIN_PRIOR)
            }
            "pixel-jitter" => self.pixel_jitter = Some(choice(p, name, &["on", "off"])? == "on"),
            "photo-tail" => self.photo_tail = Some(choice(p, name, &["on", "off"])? == "on"),
            "pixel-rays" => {
                let max = crate::train::trainer::MAX_PIXEL_RAYS;
                let n: u32 = text(p, name)?.parse().ok().filter(|n| (1..=max).contains(n)).ok_or_else(|| {
                    err(format!("--pixel-rays: expected a whole number of rays per pixel in 1..={max}"))
                })?;
                self.pixel_rays = Some(n);
            }
            "error-map" => {
                let s = text(p, name)?;
                self.error_map = match s.as_str() {
                    "off" => None,
                    _ => match s.parse::<f32>() {
                        Ok(v) if v > 0.0 && v <= 1.0 => Some(v),
                        _ => return Err(err(format!("--error-map: '{s}' is not a share in (0, 1] or 'off'"))),
                    },
                }
            }
            "registration-passes" => {
                let n: u32 = positive(p, name)?;
                if n > 4 {
                    return Err(err(format!("--registration-passes: {n} is outside 1..=4")));
                }
                self.registration_passes = Some(n);
            }
            "images" => self.images = Some(path(p, name)?),
            "background-match" => {
                let s = text(p, name)?;
                if s.is_empty() {
                    return Err(err("--background-match: empty text would match every image"));
                }
                self.background_match = Some(s);
            }
            "known-distance" => {
                let s = text(p, name)?;
                let parts: Vec<&str> = s.rsplitn(2, ',').collect();
                let parsed = match parts[..] {
                    [metres, names] => names.split_once(',').zip(metres.parse::<f64>().ok()),
                    _ => None,
                };
                match parsed {
                    Some(((a, b), m)) if m.is_finite() && m > 0.0 && !a.is_empty() && !b.is_empty() => {
                        self.known_distance = Some((a.to_string(), b.to_string(), m))
                    }
                    _ => {
                        return Err(err(format!(
                            "--known-distance: '{s}' is not IMAGE_A,IMAGE_B,METRES (two image names and a positive distance)"
                        )))
                    }
                }
            }
            "json" => self.json = true,
            "depth-only" => self.depth_only = true,
            "solid-fraction" => {
                let v: f32 = number(p, name)?;
                if !(0.0..=16.0).contains(&v) {
                    return Err(err(format!("--solid-fraction: {v} is outside [0, 16]")));
                }
                self.solid_fraction = Some(v);
            }
            "coarse-start" => {
                let s = text(p, name)?;
                self.coarse_start = Some(match s.as_str() {
                    "off" => None,
                    _ => Some(s.parse::<u32>().ok().filter(|&n| n <= 64).ok_or_else(|| {
                        err(format!("--coarse-start: '{s}' is not off or a whole number of lattice steps in 0..=64"))
                    })?),
                });
            }
            "colour-tail" => {
                let s = text(p, name)?;
                self.colour_tail = Some(match s.as_str() {
                    "off" => 0.0,
                    _ => s
                        .parse::<f32>()
                        .ok()
                        .filter(|v| *v > 0.0 && *v <= 4.0)
                        .ok_or_else(|| err(format!("--colour-tail: '{s}' is not off or a reach in (0, 4]")))?,
                });
            }
            "fixed-background" => self.fixed_background = true,
            "data" => self.data = Some(path(p, name)?),
            "out" => self.out = Some(path(p, name)?),
            "model" => self.models.push(path(p, name)?),
            "csv" => self.csv = Some(path(p, name)?),
            "background" => self.background = Some(path(p, name)?),
            "background-model" => self.background_model = Some(path(p, name)?),
            "scene" => self.scenes.push(path(p, name)?),
            "eval-every" => self.eval_every = Some(positive(p, name)?),
            "background-steps" => self.background_steps = Some(positive(p, name)?),
            "methods" => {
                let s = text(p, name)?;
                let mut methods = Vec::new();
                for m in s.split(',') {
                    let method = crate::compare::Method::parse(m).ok_or_else(|| {
                        err(format!("--methods: '{m}' is not one of {}", crate::compare::Method::names()))
                    })?;
                    if methods.contains(&method) {
                        return Err(err(format!("--methods: '{m}' given twice")));
                    }
                    methods.push(method);
                }
                self.methods = Some(methods);
            }
            "mix" => self.mix = Some(choice(p, name, &["mixnet", "sum"])?),
            "density-mix" => self.density_mix = Some(choice(p, name, &["raw", "activated"])?),
            "mixnet-encoding" => self.mixnet_encoding = Some(choice(p, name, &["own", "shared"])?),
            "split" => {
                let s = text(p, name)?;
                if s.is_empty() || !s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-') {
                    return Err(err(format!("--split: '{s}' is not a split name (letters, digits, _ and -)")));
                }
                self.split = Some(s);
            }
            "steps" => self.steps = Some(positive(p, name)?),
            "size" => {
                let v: u32 = positive(p, name)?;
                if !(16..=512).contains(&v) {
                    return Err(err(format!("--size: {v} is outside 16..=512")));
                }
                self.size = Some(v);
            }
            "rays" => {
                let v: usize = positive(p, name)?;
                if v > 1 << 20 {
                    return Err(err(format!("--rays: {v} is beyond 1048576")));
                }
                self.rays = Some(v);
            }
            "log2t" => {
                let v: u32 = number(p, name)?;
                if !(4..=26).contains(&v) {
                    return Err(err(format!("--log2t: {v} is outside 4..=26")));
                }
                self.log2t = Some(v);
            }
            "seed" => self.seed = Some(number(p, name)?),
            "threads" => self.threads = Some(positive(p, name)?),
            "reps" => self.reps = Some(positive(p, name)?),
            "depth" => self.depth = Some(choice(p, name, &["threshold", "expected"])?),
            "m" => self.m = Some(finite(p, name, 0.0, 1e9)?),
            "m-raw" => self.m_raw = Some(finite(p, name, -1e3, 1e3)?),
            "limit" => self.limit = Some(finite(p, name, 0.0, 1e6)?),
            "lr" => self.lr = Some(finite(p, name, 0.0, 1.0)?),
            "m-sweep" => {
                let s = text(p, name)?;
                let mut v = Vec::new();
                for x in s.split(',').filter(|x| !x.is_empty()) {
                    match x.parse::<f32>() {
                        Ok(m) if m.is_finite() && m > 0.0 && m <= 1e9 => {
                            v.push(crate::render::DensityThreshold::Sigma(m))
                        }
                        _ => return Err(err(format!("--m-sweep: '{x}' is not a density in (0, 1e9]"))),
                    }
                }
                self.m_sweep = Some(v);
            }
            "near-grad" => {
                let v: f32 = number(p, name)?;
                if !(v.is_finite() && (0.0..=1e6).contains(&v)) {
                    return Err(err(format!("--near-grad: {v} is outside [0, 1e6]")));
                }
                self.near_grad = Some(v);
            }
            "distortion" => {
                let v: f32 = number(p, name)?;
                if !(v.is_finite() && (0.0..=1.0).contains(&v)) {
                    return Err(err(format!("--distortion: {v} is outside [0, 1]")));
                }
                self.distortion = Some(v);
            }
            "crop" => {
                let s = text(p, name)?;
                self.crop = Some(match s.as_str() {
                    "frame" => CropRule::Frame,
                    "full" => CropRule::Full,
                    n => match n.parse::<u32>() {
                        Ok(h) if (1..=1 << 16).contains(&h) => CropRule::Centre(h),
                        _ => return Err(err(format!("--crop: '{s}' is not 'frame', 'full' or a half-size in pixels"))),
                    },
                });
            }
            _ => unreachable!("flag list and take() disagree on --{name}"),
        }
        Ok(())
    }

    pub(super) fn prior_args(&self) -> super::PriorArgs {
        super::PriorArgs {
            beta: self.beta,
            beta_margin: self.beta_margin,
            beta_fill: self.beta_fill,
            region_floor: self.region_floor,
            focus_share: self.focus_share,
            region_vote: self.region_vote,
            region_dilate: self.region_dilate,
            region_subdivide: self.region_subdivide,
            change_tolerance: self.change_tolerance,
            exposure_correction: self.exposure_correction,
            pose_registration: self.pose_registration,
        }
    }

    pub(super) fn need_path(&self, name: &str, command: &str) -> Result<PathBuf, CliError> {
        let v = match name {
            "data" => self.data.as_ref(),
            "out" => self.out.as_ref(),
            _ => self.models.last(),
        };
        v.cloned().ok_or_else(|| err(format!("{command}: --{name} is required (try 'rnerf help')")))
    }

    pub(super) fn prior_hints(&self) -> Result<Option<crate::train::prior::Prior>, CliError> {
        if self.background.is_none() && (self.prior.is_some() || self.background_data.is_some()) {
            return Err(err("--prior / --background-data need --background (they configure a residual model)"));
        }
        if self.mix.as_deref() == Some("sum") && self.prior.is_some_and(|p| p.region) {
            return Err(err("--prior region needs --mix mixnet (the region sets the Mixnet's β)"));
        }
        Ok(self.prior)
    }

    pub(super) fn mix_kind(&self) -> Result<Option<crate::field::mix::MixKind>, CliError> {
        use crate::field::mix::{DensityMix, MixKind};
        if self.background.is_none() && (self.mix.is_some() || self.density_mix.is_some()) {
            return Err(err("--mix / --density-mix need --background (they configure a residual model)"));
        }
        let density = match self.density_mix.as_deref() {
            Some("activated") => DensityMix::Activated,
            _ => DensityMix::Raw,
        };
        Ok(match self.mix.as_deref() {
            Some("sum") if self.density_mix.is_some() => {
                return Err(err("--density-mix applies to --mix mixnet, not sum"));
            }
            Some("sum") => Some(MixKind::Sum),
            _ if self.background.is_some() => Some(MixKind::Mixnet(density)),
            _ => None,
        })
    }

    pub(super) fn mixnet_encoding(&self) -> Result<Option<crate::field::mixnet::MixnetEncoding>, CliError> {
        use crate::field::mixnet::MixnetEncoding;
        match self.mixnet_encoding.as_deref() {
            None => Ok(None),
            Some(_) if self.background.is_none() || self.mix.as_deref() == Some("sum") => {
                Err(err("--mixnet-encoding needs --background and a Mixnet (not --mix sum)"))
            }
            Some("shared") => Ok(Some(MixnetEncoding::Shared)),
            Some(_) => Ok(Some(MixnetEncoding::default())),
        }
    }

    /// `--solid-fraction F` of `command`'s depth-only path (0 when absent: every occupied cell).
    pub(super) fn solid_fraction(&self, command: &str) -> Result<f32, CliError> {
        match (self.solid_fraction, self.depth_only) {
            (Some(_), false) => {
                Err(err(format!("{command}: --solid-fraction thins the depth-only path's grid; add --depth-only")))
            }
            (s, _) => Ok(s.unwrap_or(0.0)),
        }
    }

    /// `--coarse-start N|off` of `command`'s depth-only path (`None` when absent or off: every
    /// ray marched from the box).
    pub(super) fn coarse_start(&self, command: &str) -> Result<Option<u32>, CliError> {
        match (self.coarse_start, self.depth_only) {
            (Some(_), false) => {
                Err(err(format!("{command}: --coarse-start starts the depth-only path's rays; add --depth-only")))
            }
            (c, _) => Ok(c.flatten()),
        }
    }

    /// What `command` (`render` or `eval`) renders and how.
    pub(super) fn rendering(&self, command: &str) -> Result<super::Rendering, CliError> {
        let depth = self.depth()?;
        Ok(super::Rendering {
            depth,
            depth_only: self.depth_only,
            solid_fraction: self.solid_fraction(command)?,
            coarse_start: self.coarse_start(command)?,
            colour_tail: self.colour_tail(command, depth)?,
        })
    }

    /// `--colour-tail R|off` of `command`'s colour pass ([`crate::render::view::COLOUR_TAIL`]
    /// when absent; 0 when off: every lattice step; 0 with `--depth-only`, which has no colour
    /// pass). With `--depth expected` the depth comes from the colour pass, so the tail is off
    /// unless asked for: the command's depth stays the exact pass's either way.
    pub(super) fn colour_tail(&self, command: &str, depth: DepthMethod) -> Result<f32, CliError> {
        match (self.colour_tail, self.depth_only) {
            (Some(_), true) => {
                Err(err(format!("{command}: --colour-tail marches the colour pass; --depth-only has none")))
            }
            (Some(t), false) => Ok(t),
            (None, true) => Ok(0.0),
            (None, false) => Ok(crate::render::view::default_colour_tail(depth)),
        }
    }

    pub(super) fn depth(&self) -> Result<DepthMethod, CliError> {
        use crate::render::DensityThreshold;
        if self.m.is_some() && self.m_raw.is_some() {
            return Err(err("--m and --m-raw exclude each other (σ units or raw network output)"));
        }
        match self.depth.as_deref() {
            Some("expected") if self.m.is_some() || self.m_raw.is_some() => {
                Err(err("--m / --m-raw apply to --depth threshold, not expected"))
            }
            Some("expected") if self.depth_only => {
                Err(err("--depth-only renders threshold depth alone; --depth expected needs the colour pass"))
            }
            Some("expected") => Ok(DepthMethod::Expected),
            _ => Ok(DepthMethod::Threshold(match self.m_raw {
                Some(s) => DensityThreshold::Raw(s),
                None => self.m.map_or(DensityThreshold::DEFAULT, DensityThreshold::Sigma),
            })),
        }
    }
}

/// The value of `--name`, one of `options` (the error lists them: `'a' or 'b'`).
fn choice(p: &mut lexopt::Parser, name: &str, options: &[&str]) -> Result<String, CliError> {
    let s = text(p, name)?;
    if options.contains(&s.as_str()) {
        return Ok(s);
    }
    let list: Vec<String> = options.iter().map(|o| format!("'{o}'")).collect();
    Err(err(format!("--{name}: '{s}' is not {}", list.join(" or "))))
}

fn text(p: &mut lexopt::Parser, name: &str) -> Result<String, CliError> {
    let raw = p.value().map_err(|e| err(format!("--{name}: {e}")))?;
    raw.into_string().map_err(|v| err(format!("--{name}: '{}' is not valid UTF-8", v.to_string_lossy())))
}

fn path(p: &mut lexopt::Parser, name: &str) -> Result<PathBuf, CliError> {
    let raw = p.value().map_err(|e| err(format!("--{name}: {e}")))?;
    if raw.is_empty() {
        return Err(err(format!("--{name}: empty path")));
    }
    Ok(PathBuf::from(raw))
}

/// A comma-separated list of numbers, each `None` where it does not parse or fails `ok`.
fn numbers(s: &str, ok: impl Fn(f32) -> bool) -> Vec<Option<f32>> {
    s.split(',').map(|x| x.parse::<f32>().ok().filter(|&v| v.is_finite() && ok(v))).collect()
}

/// A whole number of `unit` in `0..=max`.
fn whole(p: &mut lexopt::Parser, name: &str, max: u32, unit: &str) -> Result<u32, CliError> {
    let s = text(p, name)?;
    match s.parse::<u32>() {
        Ok(n) if n <= max => Ok(n),
        _ => Err(err(format!("--{name}: '{s}' is not a whole number of {unit} in 0..={max}"))),
    }
}

/// A finite number in `(lo, hi]`.
fn finite(p: &mut lexopt::Parser, name: &str, lo: f32, hi: f32) -> Result<f32, CliError> {
    let v: f32 = number(p, name)?;
    if !(v.is_finite() && v > lo && v <= hi) {
        return Err(err(format!("--{name}: {v} is outside ({lo}, {hi}]")));
    }
    Ok(v)
}

pub(super) fn describe(arg: &lexopt::Arg) -> String {
    match arg {
        lexopt::Arg::Short(c) => format!("'-{c}'"),
        lexopt::Arg::Long(l) => format!("'--{l}'"),
        lexopt::Arg::Value(v) => format!("'{}'", v.to_string_lossy()),
    }
}

/// The value of `--name` parsed as a `T`, naming the flag in the error.
fn number<T: std::str::FromStr>(p: &mut lexopt::Parser, name: &str) -> Result<T, CliError> {
    let raw = p.value().map_err(|e| err(format!("--{name}: {e}")))?;
    let s = raw.to_string_lossy();
    s.parse().map_err(|_| err(format!("--{name}: '{s}' is not a valid value")))
}

/// Like [`number`], and at least 1.
fn positive<T: std::str::FromStr + PartialOrd + From<u8>>(p: &mut lexopt::Parser, name: &str) -> Result<T, CliError> {
    let v: T = number(p, name)?;
    if v < T::from(1) {
        return Err(err(format!("--{name}: must be at least 1")));
    }
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The table, the parser and the usage text agree: every flag is parsed by [`Flags::take`]
    /// (a value it refuses is an error, never the `unreachable!`), named in USAGE, and taken by
    /// a command USAGE lists.
    #[test]
    fn every_flag_is_parsed_and_documented() {
        for f in FLAGS {
            assert!(super::super::USAGE.contains(&format!("--{}", f.name)), "--{} is not in USAGE", f.name);
            assert!(f.commands.iter().all(|c| COMMANDS.contains(c)), "--{}: unknown command", f.name);
            for value in ["1", "x"] {
                let mut p = lexopt::Parser::from_args([value]);
                let taken = std::panic::catch_unwind(move || {
                    let mut flags = Flags::default();
                    let _ = flags.take(f.name, &mut p);
                });
                assert!(taken.is_ok(), "--{} is in the table but not parsed", f.name);
            }
        }
        for c in COMMANDS {
            assert!(super::super::USAGE.contains(&format!("\n  {c} ")), "command {c} is not in USAGE");
        }
        let names: std::collections::BTreeSet<&str> = FLAGS.iter().map(|f| f.name).collect();
        assert_eq!(names.len(), FLAGS.len(), "a flag is listed twice");
    }
}
