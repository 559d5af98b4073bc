//! Command-line parsing for `rnerf` (DESIGN §4), kept in the library so it is tested and
//! fuzzed like any other parser of untrusted input. Parsing never panics: every problem is a
//! one-line [`CliError`] naming the flag.

mod args;
mod flags;
mod usage;

pub use args::{Command, CompareArgs, CropRule, PriorArgs, Rendering, TrainArgs};
use flags::{describe, Flags, COMMANDS, FLAGS};
use std::ffi::OsString;
use std::fmt;
pub use usage::USAGE;

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
    match command.as_str() {
        "help" => return Ok(Command::Help),
        "import" => match p.next().map_err(|e| err(e.to_string()))? {
            Some(Value(v)) if v == "colmap" => {}
            _ => return Err(err("import: expected 'colmap' (rnerf import colmap --model DIR --images DIR --out DIR)")),
        },
        c if COMMANDS.contains(&c) => {}
        other => return Err(err(format!("unknown command '{other}' (try 'rnerf help')"))),
    }
    let allowed = |name: &str| FLAGS.iter().any(|f| f.name == name && f.commands.contains(&command.as_str()));
    while let Some(arg) = p.next().map_err(|e| err(e.to_string()))? {
        match arg {
            Long(name) if allowed(name) => {
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
        if let Some(s) = f.given.iter().find(|g| FLAGS.iter().any(|f| f.setting && f.name == g.as_str())) {
            return Err(err(format!(
                "train: --resume continues with the checkpoint's own settings; --{s} cannot change them"
            )));
        }
    }
    if f.registration_passes.is_some() && (f.pose_registration != Some(true) || f.background.is_some()) {
        return Err(err(
            "train: --registration-passes counts the passes of a NeRF's --pose-registration on (without --background)",
        ));
    }
    // Without --rays the capture's count is a multiple of K (`trainer::rays_for_capture`).
    if let (Some(k), Some(rays)) = (f.pixel_rays, f.rays) {
        if !rays.is_multiple_of(k as usize) {
            return Err(err(format!("--pixel-rays: {rays} rays per step are not whole pixels of {k} rays (--rays)")));
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
            budget: f.budget,
            resume: f.resume.clone(),
            scene_views: f.scene_views,
            prior: f.prior_hints()?,
            background_data: f.background_data.clone(),
            prior_settings: f.prior_args(),
            frozen_stride: f.frozen_stride,
            frozen_tail: f.frozen_tail,
            frozen_coarse: f.frozen_coarse,
            photo_tail: f.photo_tail,
            ray_pool: f.ray_pool,
            image_gains: f.image_gains,
            error_map: f.error_map,
            pixel_jitter: f.pixel_jitter,
            pixel_rays: f.pixel_rays,
            registration_passes: f.registration_passes,
        }),
        "render" => Command::Render {
            model: f.need_path("model", &command)?,
            data: f.need_path("data", &command)?,
            out: f.need_path("out", &command)?,
            split: f.split.clone().unwrap_or_else(|| "test".into()),
            rendering: f.rendering(&command)?,
            threads,
        },
        "eval" => Command::Eval {
            model: f.need_path("model", &command)?,
            data: f.need_path("data", &command)?,
            split: f.split.clone().unwrap_or_else(|| "test".into()),
            rendering: f.rendering(&command)?,
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
            background_steps: f.background_steps,
            m: f.depth()?.threshold(),
            m_sweep: f.m_sweep.clone().unwrap_or_else(|| {
                DEFAULT_M_SWEEP.iter().map(|&v| crate::render::DensityThreshold::Sigma(v)).collect()
            }),
            threads,
            prior_settings: f.prior_args(),
            frozen_stride: f.frozen_stride,
            frozen_tail: f.frozen_tail,
            frozen_coarse: f.frozen_coarse,
            photo_tail: f.photo_tail,
            ray_pool: f.ray_pool,
            image_gains: f.image_gains,
            pixel_jitter: f.pixel_jitter,
            pixel_rays: f.pixel_rays,
            near_grad: f.near_grad,
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
            if f.scenes.len() > 1 {
                return Err(err("bench: one --scene (the scene phase is timed on one scene)"));
            }
            if f.scenes.is_empty() != f.background_data.is_none() {
                return Err(err(
                    "bench: --background-data and --scene go together (the scene phase trains over that background)",
                ));
            }
            Command::Bench {
                json: f.json,
                reps: f.reps,
                log2t: f.log2t,
                threads,
                models: f.models.clone(),
                data: f.data.clone(),
                background_data: f.background_data.clone(),
                scene: f.scenes.first().cloned(),
            }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

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
                data: None,
                background_data: None,
                scene: None,
            })
        );
        assert_eq!(
            parse(args("demo --steps=20 --threads 1")),
            Ok(Command::Demo { out: None, steps: Some(20), size: None, seed: None, threads: Some(1) })
        );
        assert!(matches!(
            parse(args("bench --background-data b --scene s")),
            Ok(Command::Bench { background_data: Some(b), scene: Some(s), .. }) if b.as_path() == std::path::Path::new("b") && s.as_path() == std::path::Path::new("s")
        ));
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
            ("bench --background-data b", "bench: --background-data and --scene go together"),
            ("bench --scene s", "bench: --background-data and --scene go together"),
            ("bench --background-data b --scene s --scene t", "bench: one --scene"),
            ("demo --threads", "--threads"),
            ("demo --frobnicate", "unexpected argument '--frobnicate'"),
            ("train --data d", "--out is required"),
            ("train --data d --out m --m 3", "unexpected argument '--m'"),
            ("eval --model m --data d --m 3 --m-raw 3", "exclude each other"),
            ("eval --model m --data d --m -1", "--m: -1 is outside"),
            ("eval --model m --data d --m nan", "--m: NaN is outside"),
            ("eval --model m --data d --crop huge", "--crop: 'huge'"),
            ("render --model m --data d --out o --depth median", "--depth: 'median'"),
            ("eval --model m --data d --depth expected --depth-only", "--depth expected needs the colour pass"),
            ("compare --background b --scene s --out o --depth-only", "unexpected argument '--depth-only'"),
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
            ("eval --model m --data d --solid-fraction 0.5", "add --depth-only"),
            ("eval --model m --data d --coarse-start 2", "add --depth-only"),
            ("render --model m --data d --out o --solid-fraction 0.5", "render: --solid-fraction"),
            ("render --model m --data d --out o --coarse-start 1", "render: --coarse-start"),
            ("bench --coarse-start 1", "unexpected argument '--coarse-start'"),
            ("eval --model m --data d --depth-only --coarse-start near", "--coarse-start: 'near' is not off"),
            ("eval --model m --data d --depth-only --solid-fraction -1", "--solid-fraction: -1 is outside"),
            ("train --data d --out m --pixel-rays 0", "--pixel-rays: expected"),
            ("train --data d --out m --rays 1024 --pixel-rays 3", "--pixel-rays: 1024 rays per step"),
            ("compare --background b --scene s --out o --rays 500 --pixel-rays 8", "--pixel-rays: 500 rays"),
            ("eval --model m --data d --depth-only --colour-tail 0.4", "eval: --colour-tail marches the colour pass"),
            ("render --model m --data d --out o --colour-tail 0", "--colour-tail: '0' is not off"),
            ("eval --model m --data d --colour-tail far", "--colour-tail: 'far' is not off"),
            ("compare --background b --scene s --out o --colour-tail 1", "unexpected argument '--colour-tail'"),
            ("--json", "expected a command"),
        ] {
            let e = parse(args(bad)).unwrap_err();
            assert!(e.0.contains(needle), "{bad}: {e}");
            assert!(!e.0.contains('\n'), "{bad}: error must be one line: {e}");
        }
        // The colour tail: on by default (threshold depth), off on request.
        for (line, want) in [
            ("eval --model m --data d", crate::render::view::COLOUR_TAIL),
            ("eval --model m --data d --colour-tail off", 0.0),
            ("eval --model m --data d --colour-tail 1.5", 1.5),
            // Expected depth comes from the colour pass: exact unless the tail is asked for.
            ("eval --model m --data d --depth expected", 0.0),
            ("eval --model m --data d --depth expected --colour-tail 0.4", 0.4),
            ("eval --model m --data d --depth-only", 0.0),
        ] {
            match parse(args(line)) {
                Ok(Command::Eval { rendering, .. }) => assert_eq!(rendering.colour_tail, want, "{line}"),
                other => panic!("{line} parsed as {other:?}"),
            }
        }
        // Without --rays the capture's count is whole pixels of K (`trainer::rays_for_capture`).
        assert!(parse(args("train --data d --out m --pixel-rays 3")).is_ok());
    }
}
