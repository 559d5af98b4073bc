//! Command-line parsing for `rnerf` (DESIGN §4), kept in the library so it is tested and
//! fuzzed like any other parser of untrusted input. Parsing never panics: every problem is a
//! one-line [`CliError`] naming the flag.

use crate::render::DepthMethod;
use std::ffi::OsString;
use std::fmt;
use std::path::PathBuf;

/// Usage text printed by `rnerf help`.
pub const USAGE: &str = "usage: rnerf <command> [options]

commands:
  train  --data DIR --out MODEL [--steps N] [--rays N] [--log2t N] [--seed S] [--threads N]
         [--split NAME] [--csv FILE] [--lr LR] [--distortion L] [--near-grad D] [--fixed-background] [--background BG_MODEL [--mix mixnet|sum]
         [--density-mix raw|activated] [--mixnet-encoding own|shared] [--prior all|none|warm-start,region,focus,beta,reach]
         [--background-data BG_DIR] [--beta U,E] [--region-floor S|off] [--focus-share F]
         [--region-vote V,S] [--frozen-stride N] [--exposure-correction on|off]] [--checkpoint-every N]
         [--scene-views N]
         train a NeRF on DIR's transforms_<split>.json (default split: train); with --background,
         a Residual-NeRF (residual + Mixnet over the frozen background; --mix sum: Residual-NeRF-S),
         by default background-aware (--prior all: start at the background, a change region voted
         from change maps against BG_DIR's images at the same poses or the rendered background,
         half the rays from changed pixels and the rest from pixels whose ray crosses the region,
         the β regularisers at --beta's weights, default 0.02,0:
         penalty on unchanged rays, entropy; --prior none: the paper's Residual-NeRF).
         Checkpoints go to MODEL with '.ckpt' before the extension (every N steps, and on
         SIGINT/SIGTERM, which then exit 130/143); a finished run removes its checkpoint
  train  --resume CHECKPOINT --data DIR --out MODEL [--split NAME] [--csv FILE] [--threads N]
         [--checkpoint-every N]
         continue an interrupted run bit-exactly, with the checkpoint's settings, on the same data
  render --model MODEL --data DIR --out DIR [--split NAME] [--depth threshold|expected]
         [--m M | --m-raw S] [--threads N]
         depth (EXR metres, 16-bit PNG mm, .npy metres, colourised PNG), PLY point cloud (world
         frame) and RGB of the split's views
  eval   --model MODEL --data DIR [--split NAME] [--depth threshold|expected] [--m M | --m-raw S]
         [--crop frame|full|HALF] [--limit METRES] [--json] [--threads N]
         depth MAE / RMSE / hole rate inside the crops, and PSNR (default split: test)
  compare --background DIR --scene DIR [--scene DIR ...] --out DIR [--background-model MODEL]
         [--methods dex,finetune,residual-paper,residual,...] [--scene-views N] [--steps N] [--rays N]
         [--log2t N] [--seed S] [--eval-every N] [--m M | --m-raw S] [--m-sweep M,M,...] [--threads N]
         [--beta U,E] [--region-floor S|off] [--focus-share F] [--region-vote V,S] [--frozen-stride N]
         [--exposure-correction on|off]
         (--m-sweep: also score the final models at these σ thresholds, default 3,10,20,40;
         --beta: weights of the background-aware methods' β penalty and entropy;
         --region-floor: lift the warm-started residual's raw density in the change region to S;
         --focus-share: share of each step's rays drawn from changed pixels, default 0.5;
         --region-vote: a cell is in the change region when at least S of all views see it and
         at least V of those see a change there, default 0.5,0.25;
         --frozen-stride: outside the change region one training sample stands for N marching
         steps of the frozen background, default 1 (every step);
         --exposure-correction: fit each scene image's exposure and white balance to the
         background's before the change maps and training, default on;
         methods: dex, finetune, residual, residual-no-warm-start, residual-no-region,
         residual-no-focus, residual-no-reach, residual-no-beta, residual-activated, residual-activated-no-warm-start,
         residual-paper, residual-paper-activated, residual-paper-shared,
         residual-paper-activated-shared, residual-s)
         the paper's protocol and more: train the background on DIR (or load MODEL), then per scene
         Dex-NeRF (and NeRF's expected depth), the fine-tuned background, the paper's Residual-NeRF
         and the background-aware Residual-NeRF; scored on the object mask, the near crop (< 1.5 m)
         and the crop; writes table.md, table.json, curves.csv, <scene>/curves.png and
         <scene>/depth_<i>.png side by side
  import colmap --model SPARSE_DIR --images DIR --out DIR [--background-match TEXT]
         [--known-distance IMAGE_A,IMAGE_B,METRES]
         a COLMAP sparse model (cameras, images, points3D; .bin or .txt) as transforms_train.json
         (OpenGL poses, the lens, a scene box from the points); with --background-match, images
         whose name contains TEXT go to OUT/background and the rest to OUT/scene (one COLMAP run
         registers both, as in the paper); --known-distance fixes the scale from the distance
         between two images' camera centres (else COLMAP's unit is taken as a metre)
  demo   [--out DIR] [--steps N] [--size PX] [--seed S] [--threads N]
         synthesise a workspace and a glass object, then compare as above (default out: rnerf-demo)
  bench  [--json] [--reps N] [--log2t N] [--threads N] [--model MODEL [--model MODEL] --data DIR]
         throughput of the hot kernels on this machine (one JSON object with --json); with
         --model, render_depth_ms_200[_residual] time these trained models (a NeRF, a residual
         model) from the first test view of DIR instead of the bench's short-trained ones
  help   this text

threshold depth: --m M is a density sigma >= M per unit of the dataset's coordinates (per metre;
  default 10);
  --m-raw S compares the raw network output s >= S (sigma = exp(s)), as the authors' code does.
environment: RNERF_CPU_LEVEL=scalar|avx2|avx512|amx|neon lowers the SIMD level (never raises it;
  x86: scalar < avx2 < avx512 < amx, aarch64: scalar < neon)";

/// Scoring crop of `rnerf eval`.
pub use crate::eval::CropRule;

/// A parsed command line.
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    /// `rnerf train`.
    Train(TrainArgs),
    /// `rnerf import colmap`.
    ImportColmap(crate::data::colmap::ImportOptions),
    /// `rnerf render`.
    Render {
        /// Model file (`--model`).
        model: PathBuf,
        /// Dataset folder (`--data`).
        data: PathBuf,
        /// Output folder (`--out`).
        out: PathBuf,
        /// Split (`--split`, default `test`).
        split: String,
        /// Depth method (`--depth`, `--m`, `--m-raw`).
        depth: DepthMethod,
        /// Worker threads (`--threads`).
        threads: Option<usize>,
    },
    /// `rnerf eval`.
    Eval {
        /// Model file (`--model`).
        model: PathBuf,
        /// Dataset folder (`--data`).
        data: PathBuf,
        /// Split (`--split`, default `test`).
        split: String,
        /// Depth method (`--depth`, `--m`, `--m-raw`).
        depth: DepthMethod,
        /// Scoring crop (`--crop`, default the frames' own).
        crop: CropRule,
        /// Score only ground truth nearer than this (`--limit`, metres).
        limit: Option<f32>,
        /// One JSON object on stdout (`--json`).
        json: bool,
        /// Worker threads (`--threads`).
        threads: Option<usize>,
    },
    /// `rnerf compare`.
    Compare(CompareArgs),
    /// `rnerf demo`.
    Demo {
        /// Output folder (`--out`, default `rnerf-demo`).
        out: Option<PathBuf>,
        /// Training steps (`--steps`).
        steps: Option<u32>,
        /// Image size in pixels (`--size`, square images).
        size: Option<u32>,
        /// Seed (`--seed`).
        seed: Option<u64>,
        /// Worker threads (`--threads`); all cores when absent.
        threads: Option<usize>,
    },
    /// `rnerf bench`.
    Bench {
        /// One JSON object instead of a table (`--json`).
        json: bool,
        /// Repetitions per figure (`--reps`).
        reps: Option<usize>,
        /// Hash-grid table size (`--log2t`).
        log2t: Option<u32>,
        /// Worker threads (`--threads`).
        threads: Option<usize>,
        /// Trained models whose depth rendering is timed instead of the bench's own (`--model`,
        /// repeatable: one NeRF, one residual model).
        models: Vec<PathBuf>,
        /// Their camera: the first test view of this dataset (`--data`, needed with `--model`).
        data: Option<PathBuf>,
    },
    /// `rnerf help`, `-h`, `--help` or no arguments.
    Help,
}

/// Arguments of `rnerf train`.
#[derive(Clone, Debug, PartialEq)]
pub struct TrainArgs {
    /// Dataset folder (`--data`).
    pub data: PathBuf,
    /// Model file to write (`--out`).
    pub out: PathBuf,
    /// Split to train on (`--split`, default `train`).
    pub split: String,
    /// Steps (`--steps`).
    pub steps: Option<u32>,
    /// Rays per step (`--rays`).
    pub rays: Option<usize>,
    /// log2 of the hash-table size (`--log2t`).
    pub log2t: Option<u32>,
    /// Seed (`--seed`).
    pub seed: Option<u64>,
    /// Worker threads (`--threads`).
    pub threads: Option<usize>,
    /// Metrics log (`--csv`).
    pub csv: Option<PathBuf>,
    /// Frozen background model: train a residual model (`--background`).
    pub background: Option<PathBuf>,
    /// How background and residual mix (`--mix`, `--density-mix`); default Mixnet, raw.
    pub mix: Option<crate::field::mix::MixKind>,
    /// The Mixnet's encoding (`--mixnet-encoding`); default its own grid.
    pub mixnet: Option<crate::field::mixnet::MixnetEncoding>,
    /// Weight of the distortion loss (`--distortion`, 0 turns it off).
    pub distortion: Option<f32>,
    /// Base learning rate (`--lr`).
    pub lr: Option<f32>,
    /// Near-camera gradient scaling distance (`--near-grad`, 0 turns it off).
    pub near_grad: Option<f32>,
    /// `Some(false)`: train over the fixed background colour even for images without
    /// alpha (`--fixed-background`).
    pub random_bg: Option<bool>,
    /// Steps between checkpoints (`--checkpoint-every`); none when absent (an interrupted run
    /// still writes one).
    pub checkpoint_every: Option<u32>,
    /// A checkpoint to continue from with its own settings (`--resume`).
    pub resume: Option<PathBuf>,
    /// Train on this many evenly spaced views of the split (`--scene-views`); all when absent.
    pub scene_views: Option<usize>,
    /// The background hints a residual model uses (`--prior`; default all).
    pub prior: Option<crate::train::prior::Prior>,
    /// The background's dataset, whose images at the scene's poses give the change maps
    /// (`--background-data`; without it the background model is rendered at those poses).
    pub background_data: Option<PathBuf>,
    /// Weights of the β penalty on unchanged rays and of the β entropy (`--beta U,E`).
    pub beta: Option<(f32, f32)>,
    /// The residual's density floor in the change region (`--region-floor S|off`).
    pub region_floor: Option<Option<f32>>,
    /// Share of each step's rays drawn from changed pixels (`--focus-share F`).
    pub focus_share: Option<f32>,
    /// The region's vote: share of the seeing views that must see a change, share of all
    /// views that must see the cell (`--region-vote V,S`).
    pub region_vote: Option<(f32, f32)>,
    /// Whether the scene images are corrected to the background's exposure and white balance
    /// (`--exposure-correction on|off`; default on).
    pub exposure_correction: Option<bool>,
    /// Lattice steps per training sample outside a residual model's change region
    /// (`--frozen-stride N`).
    pub frozen_stride: Option<u32>,
}

/// Arguments of `rnerf compare`.
#[derive(Clone, Debug, PartialEq)]
pub struct CompareArgs {
    /// Background dataset folder (`--background`).
    pub background: PathBuf,
    /// A trained background model to use instead of training one (`--background-model`).
    pub background_model: Option<PathBuf>,
    /// Scene dataset folders (`--scene`, repeatable).
    pub scenes: Vec<PathBuf>,
    /// Output folder (`--out`), created if missing.
    pub out: PathBuf,
    /// Methods (`--methods`, default [`crate::compare::Method::defaults`]: dex, finetune,
    /// residual-paper, residual).
    pub methods: Vec<crate::compare::Method>,
    /// Train every method on this many evenly spaced scene views (`--scene-views`); the
    /// background keeps all of its own.
    pub scene_views: Option<usize>,
    /// Steps per method (`--steps`).
    pub steps: Option<u32>,
    /// Rays per step (`--rays`).
    pub rays: Option<usize>,
    /// log2 of the hash-table size (`--log2t`).
    pub log2t: Option<u32>,
    /// Seed (`--seed`).
    pub seed: Option<u64>,
    /// Steps between points of the speed curves (`--eval-every`).
    pub eval_every: Option<u32>,
    /// Threshold of threshold depth (`--m`, `--m-raw`).
    pub m: crate::render::DensityThreshold,
    /// Further σ thresholds the final models are scored at (`--m-sweep`).
    pub m_sweep: Vec<crate::render::DensityThreshold>,
    /// Worker threads (`--threads`).
    pub threads: Option<usize>,
    /// Weights of the β penalty on unchanged rays and of the β entropy (`--beta U,E`).
    pub beta: Option<(f32, f32)>,
    /// The residual's density floor in the change region (`--region-floor S|off`).
    pub region_floor: Option<Option<f32>>,
    /// Share of each step's rays drawn from changed pixels (`--focus-share F`).
    pub focus_share: Option<f32>,
    /// The region's vote: share of the seeing views that must see a change, share of all
    /// views that must see the cell (`--region-vote V,S`).
    pub region_vote: Option<(f32, f32)>,
    /// Whether the scene images are corrected to the background's exposure and white balance
    /// (`--exposure-correction on|off`; default on).
    pub exposure_correction: Option<bool>,
    /// Lattice steps per training sample outside a residual model's change region
    /// (`--frozen-stride N`).
    pub frozen_stride: Option<u32>,
}

/// A command-line error: one line saying what is wrong and where.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CliError(pub String);

impl fmt::Display for CliError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for CliError {}

fn err(msg: impl Into<String>) -> CliError {
    CliError(msg.into())
}

/// Thresholds `rnerf compare` also scores the final models at (σ per dataset unit).
pub const DEFAULT_M_SWEEP: [f32; 4] = [3.0, 10.0, 20.0, 40.0];

/// Parses the arguments after the program name.
pub fn parse(args: impl IntoIterator<Item = OsString>) -> Result<Command, CliError> {
    use lexopt::Arg::{Long, Short, Value};
    let mut p = lexopt::Parser::from_args(args);
    let command = match p.next().map_err(|e| err(e.to_string()))? {
        None | Some(Long("help")) | Some(Short('h')) => return Ok(Command::Help),
        Some(Value(v)) => {
            v.into_string().map_err(|v| err(format!("command '{}' is not valid UTF-8", v.to_string_lossy())))?
        }
        Some(other) => return Err(err(format!("expected a command before {} (try 'rnerf help')", describe(&other)))),
    };
    let mut f = Flags::default();
    let allowed: &[&str] = match command.as_str() {
        "help" => return Ok(Command::Help),
        "train" => &[
            "data",
            "out",
            "split",
            "steps",
            "rays",
            "log2t",
            "seed",
            "threads",
            "csv",
            "background",
            "mix",
            "density-mix",
            "mixnet-encoding",
            "distortion",
            "lr",
            "near-grad",
            "fixed-background",
            "checkpoint-every",
            "resume",
            "scene-views",
            "prior",
            "background-data",
            "beta",
            "region-floor",
            "focus-share",
            "region-vote",
            "frozen-stride",
            "exposure-correction",
        ],
        "render" => &["model", "data", "out", "split", "depth", "m", "m-raw", "threads"],
        "eval" => &["model", "data", "split", "depth", "m", "m-raw", "crop", "limit", "json", "threads"],
        "compare" => &[
            "background",
            "background-model",
            "scene",
            "out",
            "methods",
            "steps",
            "rays",
            "log2t",
            "seed",
            "eval-every",
            "m",
            "m-raw",
            "m-sweep",
            "threads",
            "scene-views",
            "beta",
            "region-floor",
            "focus-share",
            "region-vote",
            "frozen-stride",
            "exposure-correction",
        ],
        "demo" => &["out", "steps", "size", "seed", "threads"],
        "import" => {
            match p.next().map_err(|e| err(e.to_string()))? {
                Some(Value(v)) if v == "colmap" => {}
                _ => {
                    return Err(err(
                        "import: expected 'colmap' (rnerf import colmap --model DIR --images DIR --out DIR)",
                    ))
                }
            }
            &["model", "images", "out", "background-match", "known-distance"]
        }
        "bench" => &["json", "reps", "log2t", "threads", "model", "data"],
        other => return Err(err(format!("unknown command '{other}' (try 'rnerf help')"))),
    };
    while let Some(arg) = p.next().map_err(|e| err(e.to_string()))? {
        match arg {
            Long(name) if allowed.contains(&name) => {
                let name = name.to_string();
                f.take(&name, &mut p)?;
            }
            other => {
                return Err(err(format!("{command}: unexpected argument {} (try 'rnerf help')", describe(&other))))
            }
        }
    }
    let threads = f.threads;
    if f.resume.is_some() {
        const SETTINGS: [&str; 13] = [
            "steps",
            "rays",
            "log2t",
            "seed",
            "background",
            "mix",
            "density-mix",
            "mixnet-encoding",
            "distortion",
            "lr",
            "near-grad",
            "fixed-background",
            "frozen-stride",
        ];
        if let Some(s) = f.given.iter().find(|g| SETTINGS.contains(&g.as_str())) {
            return Err(err(format!(
                "train: --resume continues with the checkpoint's own settings; --{s} cannot change them"
            )));
        }
    }
    Ok(match command.as_str() {
        "train" => Command::Train(TrainArgs {
            data: f.need_path("data", &command)?,
            out: f.need_path("out", &command)?,
            split: f.split.clone().unwrap_or_else(|| "train".into()),
            steps: f.steps,
            rays: f.rays,
            log2t: f.log2t,
            seed: f.seed,
            threads,
            csv: f.csv.clone(),
            background: f.background.clone(),
            mix: f.mix_kind()?,
            mixnet: f.mixnet_encoding()?,
            distortion: f.distortion,
            lr: f.lr,
            near_grad: f.near_grad,
            random_bg: f.fixed_background.then_some(false),
            checkpoint_every: f.checkpoint_every,
            resume: f.resume.clone(),
            scene_views: f.scene_views,
            prior: f.prior_hints()?,
            background_data: f.background_data.clone(),
            beta: f.beta,
            region_floor: f.region_floor,
            focus_share: f.focus_share,
            region_vote: f.region_vote,
            exposure_correction: f.exposure_correction,
            frozen_stride: f.frozen_stride,
        }),
        "render" => Command::Render {
            model: f.need_path("model", &command)?,
            data: f.need_path("data", &command)?,
            out: f.need_path("out", &command)?,
            split: f.split.clone().unwrap_or_else(|| "test".into()),
            depth: f.depth()?,
            threads,
        },
        "eval" => Command::Eval {
            model: f.need_path("model", &command)?,
            data: f.need_path("data", &command)?,
            split: f.split.clone().unwrap_or_else(|| "test".into()),
            depth: f.depth()?,
            crop: f.crop.unwrap_or(CropRule::Frame),
            limit: f.limit,
            json: f.json,
            threads,
        },
        "compare" => Command::Compare(CompareArgs {
            background: f
                .background
                .clone()
                .ok_or_else(|| err("compare: --background is required (try 'rnerf help')"))?,
            background_model: f.background_model.clone(),
            scenes: if f.scenes.is_empty() {
                return Err(err("compare: --scene is required (try 'rnerf help')"));
            } else {
                f.scenes.clone()
            },
            out: f.need_path("out", &command)?,
            methods: f.methods.clone().unwrap_or_else(crate::compare::Method::defaults),
            scene_views: f.scene_views,
            steps: f.steps,
            rays: f.rays,
            log2t: f.log2t,
            seed: f.seed,
            eval_every: f.eval_every,
            m: f.depth()?.threshold(),
            m_sweep: f.m_sweep.clone().unwrap_or_else(|| {
                DEFAULT_M_SWEEP.iter().map(|&v| crate::render::DensityThreshold::Sigma(v)).collect()
            }),
            threads,
            beta: f.beta,
            region_floor: f.region_floor,
            focus_share: f.focus_share,
            region_vote: f.region_vote,
            exposure_correction: f.exposure_correction,
            frozen_stride: f.frozen_stride,
        }),
        "demo" => Command::Demo { out: f.out.clone(), steps: f.steps, size: f.size, seed: f.seed, threads },
        "import" => Command::ImportColmap(crate::data::colmap::ImportOptions {
            model: f.need_path("model", "import colmap")?,
            images: f.images.clone().ok_or_else(|| err("import colmap: --images is required (try 'rnerf help')"))?,
            out: f.need_path("out", "import colmap")?,
            background_match: f.background_match.clone(),
            known_distance: f.known_distance.clone(),
        }),
        _ => {
            if f.models.is_empty() != f.data.is_none() {
                return Err(err(
                    "bench: --model and --data go together (the model's camera is the data's first test view)",
                ));
            }
            Command::Bench {
                json: f.json,
                reps: f.reps,
                log2t: f.log2t,
                threads,
                models: f.models.clone(),
                data: f.data.clone(),
            }
        }
    })
}

/// Every flag's value, filled as the command line is read.
#[derive(Default)]
struct Flags {
    data: Option<PathBuf>,
    out: Option<PathBuf>,
    /// Every `--model` given: bench takes several, render and eval the last.
    models: Vec<PathBuf>,
    csv: Option<PathBuf>,
    split: Option<String>,
    steps: Option<u32>,
    size: Option<u32>,
    rays: Option<usize>,
    log2t: Option<u32>,
    seed: Option<u64>,
    threads: Option<usize>,
    reps: Option<usize>,
    depth: Option<String>,
    m: Option<f32>,
    m_raw: Option<f32>,
    crop: Option<CropRule>,
    limit: Option<f32>,
    json: bool,
    background: Option<PathBuf>,
    mix: Option<String>,
    density_mix: Option<String>,
    mixnet_encoding: Option<String>,
    distortion: Option<f32>,
    lr: Option<f32>,
    near_grad: Option<f32>,
    m_sweep: Option<Vec<crate::render::DensityThreshold>>,
    fixed_background: bool,
    background_model: Option<PathBuf>,
    scenes: Vec<PathBuf>,
    methods: Option<Vec<crate::compare::Method>>,
    eval_every: Option<u32>,
    checkpoint_every: Option<u32>,
    resume: Option<PathBuf>,
    scene_views: Option<usize>,
    prior: Option<crate::train::prior::Prior>,
    background_data: Option<PathBuf>,
    beta: Option<(f32, f32)>,
    region_floor: Option<Option<f32>>,
    focus_share: Option<f32>,
    region_vote: Option<(f32, f32)>,
    exposure_correction: Option<bool>,
    frozen_stride: Option<u32>,
    /// Flags given, in order.
    given: Vec<String>,
    images: Option<PathBuf>,
    background_match: Option<String>,
    known_distance: Option<(String, String, f64)>,
}

impl Flags {
    fn take(&mut self, name: &str, p: &mut lexopt::Parser) -> Result<(), CliError> {
        self.given.push(name.to_string());
        match name {
            "checkpoint-every" => self.checkpoint_every = Some(positive(p, name)?),
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
                            "all" => h = crate::train::prior::Prior::ALL,
                            _ => {
                                return Err(err(format!(
                                    "--prior: '{part}' is not all, none, warm-start, region, focus, beta or reach"
                                )))
                            }
                        }
                    }
                }
                self.prior = Some(h);
            }
            "beta" => {
                let s = text(p, name)?;
                let v: Vec<Option<f32>> = s
                    .split(',')
                    .map(|x| x.parse::<f32>().ok().filter(|v| v.is_finite() && (0.0..=1e6).contains(v)))
                    .collect();
                match v[..] {
                    [Some(u), Some(e)] => self.beta = Some((u, e)),
                    _ => return Err(err(format!("--beta: '{s}' is not two weights U,E in [0, 1e6]"))),
                }
            }
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
            "region-vote" => {
                let s = text(p, name)?;
                let v: Vec<Option<f32>> =
                    s.split(',').map(|x| x.parse::<f32>().ok().filter(|v| (0.0..=1.0).contains(v))).collect();
                match v[..] {
                    [Some(vote), Some(seen)] => self.region_vote = Some((vote, seen)),
                    _ => return Err(err(format!("--region-vote: '{s}' is not two shares V,S in [0, 1]"))),
                }
            }
            "resume" => self.resume = Some(path(p, name)?),
            "exposure-correction" => {
                self.exposure_correction = Some(match text(p, name)?.as_str() {
                    "on" => true,
                    "off" => false,
                    other => return Err(err(format!("--exposure-correction: '{other}' is not on or off"))),
                })
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
            "fixed-background" => self.fixed_background = true,
            "data" => self.data = Some(path(p, name)?),
            "out" => self.out = Some(path(p, name)?),
            "model" => self.models.push(path(p, name)?),
            "csv" => self.csv = Some(path(p, name)?),
            "background" => self.background = Some(path(p, name)?),
            "background-model" => self.background_model = Some(path(p, name)?),
            "scene" => self.scenes.push(path(p, name)?),
            "eval-every" => self.eval_every = Some(positive(p, name)?),
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
            "mix" => {
                let s = text(p, name)?;
                if s != "mixnet" && s != "sum" {
                    return Err(err(format!("--mix: '{s}' is not 'mixnet' or 'sum'")));
                }
                self.mix = Some(s);
            }
            "density-mix" => {
                let s = text(p, name)?;
                if s != "raw" && s != "activated" {
                    return Err(err(format!("--density-mix: '{s}' is not 'raw' or 'activated'")));
                }
                self.density_mix = Some(s);
            }
            "mixnet-encoding" => {
                let s = text(p, name)?;
                if s != "own" && s != "shared" {
                    return Err(err(format!("--mixnet-encoding: '{s}' is not 'own' or 'shared'")));
                }
                self.mixnet_encoding = Some(s);
            }
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
            "depth" => {
                let s = text(p, name)?;
                if s != "threshold" && s != "expected" {
                    return Err(err(format!("--depth: '{s}' is not 'threshold' or 'expected'")));
                }
                self.depth = Some(s);
            }
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

    fn need_path(&self, name: &str, command: &str) -> Result<PathBuf, CliError> {
        let v = match name {
            "data" => self.data.as_ref(),
            "out" => self.out.as_ref(),
            _ => self.models.last(),
        };
        v.cloned().ok_or_else(|| err(format!("{command}: --{name} is required (try 'rnerf help')")))
    }

    fn prior_hints(&self) -> Result<Option<crate::train::prior::Prior>, CliError> {
        if self.background.is_none() && (self.prior.is_some() || self.background_data.is_some()) {
            return Err(err("--prior / --background-data need --background (they configure a residual model)"));
        }
        if self.mix.as_deref() == Some("sum") && self.prior.is_some_and(|p| p.region) {
            return Err(err("--prior region needs --mix mixnet (the region sets the Mixnet's β)"));
        }
        Ok(self.prior)
    }

    fn mix_kind(&self) -> Result<Option<crate::field::mix::MixKind>, CliError> {
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

    fn mixnet_encoding(&self) -> Result<Option<crate::field::mixnet::MixnetEncoding>, CliError> {
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

    fn depth(&self) -> Result<DepthMethod, CliError> {
        use crate::render::DensityThreshold;
        if self.m.is_some() && self.m_raw.is_some() {
            return Err(err("--m and --m-raw exclude each other (σ units or raw network output)"));
        }
        match self.depth.as_deref() {
            Some("expected") if self.m.is_some() || self.m_raw.is_some() => {
                Err(err("--m / --m-raw apply to --depth threshold, not expected"))
            }
            Some("expected") => Ok(DepthMethod::Expected),
            _ => Ok(DepthMethod::Threshold(match self.m_raw {
                Some(s) => DensityThreshold::Raw(s),
                None => self.m.map_or(DensityThreshold::DEFAULT, DensityThreshold::Sigma),
            })),
        }
    }
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

/// A finite number in `(lo, hi]`.
fn finite(p: &mut lexopt::Parser, name: &str, lo: f32, hi: f32) -> Result<f32, CliError> {
    let v: f32 = number(p, name)?;
    if !(v.is_finite() && v > lo && v <= hi) {
        return Err(err(format!("--{name}: {v} is outside ({lo}, {hi}]")));
    }
    Ok(v)
}

fn describe(arg: &lexopt::Arg) -> String {
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

    fn args(s: &str) -> Vec<OsString> {
        s.split_whitespace().map(OsString::from).collect()
    }

    #[test]
    fn usage_names_every_cpu_level() {
        use crate::simd::CpuLevel;
        let line = USAGE.lines().find(|l| l.contains("RNERF_CPU_LEVEL=")).expect("the environment line");
        for level in [CpuLevel::Scalar, CpuLevel::Avx2, CpuLevel::Avx512, CpuLevel::Amx, CpuLevel::Neon] {
            assert!(line.contains(level.name()), "`rnerf help` does not name {}", level.name());
        }
    }

    #[test]
    fn parses_commands_and_rejects_bad_values() {
        assert_eq!(parse(args("")), Ok(Command::Help));
        assert_eq!(parse(args("--help")), Ok(Command::Help));
        assert_eq!(
            parse(args("bench --json --reps 3 --log2t 15")),
            Ok(Command::Bench {
                json: true,
                reps: Some(3),
                log2t: Some(15),
                threads: None,
                models: vec![],
                data: None
            })
        );
        assert_eq!(
            parse(args("demo --steps=20 --threads 1")),
            Ok(Command::Demo { out: None, steps: Some(20), size: None, seed: None, threads: Some(1) })
        );
        match parse(args("compare --background b --scene s1 --scene s2 --out o --methods dex,residual-s --m 5")) {
            Ok(Command::Compare(CompareArgs { scenes, methods, m, .. })) => {
                assert_eq!(scenes, [PathBuf::from("s1"), PathBuf::from("s2")]);
                assert_eq!(methods.len(), 2);
                assert_eq!(m, crate::render::DensityThreshold::Sigma(5.0));
            }
            other => panic!("compare parsed as {other:?}"),
        }
        for (bad, needle) in [
            ("bench --log2t 40", "--log2t: 40 is outside"),
            ("bench --reps 0", "--reps: must be at least 1"),
            ("bench --model m.safetensors", "bench: --model and --data go together"),
            ("bench --data d", "bench: --model and --data go together"),
            ("bench --reps many", "--reps: 'many' is not a valid value"),
            ("demo --threads", "--threads"),
            ("demo --frobnicate", "unexpected argument '--frobnicate'"),
            ("train --data d", "--out is required"),
            ("train --data d --out m --m 3", "unexpected argument '--m'"),
            ("eval --model m --data d --m 3 --m-raw 3", "exclude each other"),
            ("eval --model m --data d --m -1", "--m: -1 is outside"),
            ("eval --model m --data d --m nan", "--m: NaN is outside"),
            ("eval --model m --data d --crop huge", "--crop: 'huge'"),
            ("render --model m --data d --out o --depth median", "--depth: 'median'"),
            ("train --data d --out m --split ../x", "--split"),
            ("train --data d --out m --mix sum", "need --background"),
            ("train --data d --out m --background b --mix sum --density-mix raw", "applies to --mix mixnet"),
            ("train --data d --out m --background b --mix blend", "--mix: 'blend'"),
            ("trian", "unknown command 'trian'"),
            ("compare --background b --out o", "--scene is required"),
            ("train --data d --out m --mixnet-encoding shared", "needs --background"),
            ("train --data d --out m --background b --mix sum --mixnet-encoding shared", "not --mix sum"),
            ("train --data d --out m --background b --mixnet-encoding both", "--mixnet-encoding: 'both'"),
            ("compare --background b --scene s --out o --methods dex,nerf", "--methods: 'nerf'"),
            ("compare --background b --scene s --out o --methods dex,dex", "given twice"),
            ("compare --background b --scene s --out o --m-sweep 3,x", "--m-sweep: 'x'"),
            ("compare --background b --scene s --out o --depth expected", "unexpected argument '--depth'"),
            ("--json", "expected a command"),
        ] {
            let e = parse(args(bad)).unwrap_err();
            assert!(e.0.contains(needle), "{bad}: {e}");
            assert!(!e.0.contains('\n'), "{bad}: error must be one line: {e}");
        }
    }
}
