//! The text of `rnerf help`.

/// Usage text printed by `rnerf help`.
pub const USAGE: &str = "usage: rnerf <command> [options]

commands:
  train  --data DIR --out MODEL [--steps N] [--rays N] [--log2t N] [--seed S] [--threads N]
         [--split NAME] [--csv FILE] [--lr LR] [--distortion L] [--near-grad D] [--fixed-background] [--background BG_MODEL [--mix mixnet|sum]
         [--density-mix raw|activated] [--mixnet-encoding own|shared] [--prior all|none|warm-start,region,focus,beta,reach,solid]
         [--background-data BG_DIR] [--beta U,E] [--beta-fill R] [--beta-margin N] [--region-floor S|off]
         [--focus-share F] [--region-vote V,S] [--region-dilate N] [--region-subdivide K] [--change-tolerance T[,R]] [--frozen-stride N] [--frozen-tail T] [--frozen-coarse T,N|off] [--photo-tail on|off] [--ray-pool N]
         [--exposure-correction on|off] [--pose-registration on|off]] [--pose-registration on [--registration-passes N]]
         [--image-gains on|off] [--error-map S|off] [--pixel-jitter on|off] [--pixel-rays K] [--checkpoint-every N]
         [--scene-views N] [--budget SECONDS]
         train a NeRF on DIR's transforms_<split>.json (default split: train; --steps default
         1000; a background, the empty workspace trained once, takes --steps 3000); with --background,
         a Residual-NeRF (residual + Mixnet over the frozen background; --mix sum: Residual-NeRF-S),
         by default background-aware (--prior all: start at the background, a change region voted
         from change maps against BG_DIR's images at the same poses or the rendered background,
         half the rays from changed pixels and the rest from pixels whose ray crosses the region,
         the β regularisers at --beta's weights, default 0.02,0.005:
         penalty on unchanged rays, entropy; --prior none: the paper's Residual-NeRF).
         --rays N: rays per step (default by the capture's size: 1024 from 2 M training pixels,
         e.g. 50 views of 200x200, in proportion below down to 512 at 1 M pixels and fewer).
         --near-grad D: scale each sample's gradients by min(1, (t/D)^2), t its distance from
         the camera, so density right in front of one camera learns slower than the scene
         (default: off).
         A NeRF with --pose-registration on (for a background whose poses came from a robot
         arm): a first NeRF, every image's pose registered against it, N times (default 1),
         then the run at the registered poses. --image-gains on: learn a gain per image and
         colour channel with the field, for captures whose auto-exposure or white balance moved
         from shot to shot (renders show the capture's mean appearance; default off).
         --error-map S: draw share S of each step's rays by the training error (a running
         error per 8x8-pixel tile, Instant-NGP's error map; default off). --pixel-jitter on:
         each training ray through a random point of its pixel instead of its centre (default
         off). --pixel-rays K: score each training pixel by the mean colour of K rays through
         its footprint (a 1.5 px Blackman-Harris filter, as the dev renders'; the step's rays
         cover rays/K pixels; default 1). --beta-fill R --beta-margin N: the β penalty spares
         the changed pixels closed by a square of radius R pixels with the holes they enclose
         filled (0: neither), then grown by N pixels (defaults 0 and 2, the maps' own dilation).
         --budget S: once S seconds of wall time have passed since the command started
         (loading and the background prior included), stop after the current step and write
         the model of the steps so far (a residual model's change region settled as at a run's
         end; the learning rate keeps the whole run's schedule).
         Checkpoints go to MODEL with '.ckpt' before the extension (every N steps, and on
         SIGINT/SIGTERM, which then exit 130/143); a finished run removes its checkpoint
  train  --resume CHECKPOINT --data DIR --out MODEL [--split NAME] [--csv FILE] [--threads N]
         [--checkpoint-every N] [--budget SECONDS]
         continue an interrupted run bit-exactly, with the checkpoint's settings, on the same data
  render --model MODEL --data DIR --out DIR [--split NAME] [--depth threshold|expected]
         [--m M | --m-raw S] [--colour-tail R|off] [--depth-only [--solid-fraction F] [--coarse-start N|off]]
         [--threads N]
         depth (EXR metres, 16-bit PNG mm, .npy metres, colourised PNG), PLY point cloud (world
         frame) and RGB of the split's views (--depth-only: threshold depth and an uncoloured
         point cloud, without the colour pass; --solid-fraction 0.5 --coarse-start 1 render it
         as the onboard renderer does by default; --colour-tail: see eval)
  eval   --model MODEL --data DIR [--split NAME] [--depth threshold|expected] [--m M | --m-raw S]
         [--crop frame|full|HALF] [--limit METRES] [--json] [--colour-tail R|off]
         [--depth-only [--solid-fraction F] [--coarse-start N|off]] [--threads N]
         depth MAE / RMSE / hole rate inside the crops, and PSNR (default split: test;
         --colour-tail R: behind each ray's threshold hit the colour pass takes one sample for
         up to R/T lattice steps, T the ray's transmittance, at most 16; the same threshold
         depth, PSNR within its quadrature error; default 0.4 (off with --depth expected, whose
         depth comes from that pass), off: every step, as compare's curves;
         --depth-only: the same threshold-depth figures without the colour pass, no PSNR;
         --solid-fraction F: as the onboard renderer, skip the cells whose occupancy stayed
         below F·m, default 0: every occupied cell; --coarse-start N: as the onboard renderer,
         render every other row and column first (every 4th or 8th on finer views) and start
         the other rays N lattice steps before their neighbours' depth, default off: every ray
         from the box)
  compare --background DIR --scene DIR [--scene DIR ...] --out DIR [--background-model MODEL]
         [--methods dex,finetune,residual-paper,residual,...] [--scene-views N] [--steps N] [--rays N]
         [--log2t N] [--seed S] [--eval-every N] [--background-steps N] [--m M | --m-raw S] [--m-sweep M,M,...] [--threads N]
         [--beta U,E] [--beta-fill R] [--beta-margin N] [--region-floor S|off] [--focus-share F] [--region-vote V,S] [--region-dilate N] [--region-subdivide K] [--change-tolerance T[,R]]
         [--frozen-stride N] [--frozen-tail T] [--frozen-coarse T,N|off] [--photo-tail on|off] [--ray-pool N] [--exposure-correction on|off] [--pose-registration on|off]
         [--image-gains on|off] [--pixel-jitter on|off] [--pixel-rays K] [--near-grad D]
         (--rays: every run's rays per step, default each run's own capture's as for train;
         --background-steps: the background's training steps when no --background-model is
         given, default 3 x --steps (it is trained once, offline; 3000 at the defaults);
         --m-sweep: also score the final models at these σ thresholds, default 3,10,20,40;
         --beta: weights of the background-aware methods' β penalty and entropy;
         --beta-fill, --beta-margin: the β penalty spares the changed pixels closed by R pixels,
         their holes filled (0: neither), grown by N pixels, defaults 0 and 2;
         --region-floor: lift the warm-started residual's raw density in the change region to at
         least S before training (σ = e^S per metre), default off;
         --focus-share: share of each step's rays drawn from changed pixels, default 0.5;
         --near-grad: every training's near-camera gradient scaling, as for train;
         --region-vote: a cell is in the change region when at least S of all views see it and
         at least V of those see a change there, default 0.75,0.25;
         --region-dilate: cells the voted region grows by, default 1;
         --region-subdivide: the region voted on cells K (1 to 4) times finer than the occupancy grid's, default 2;
         --change-tolerance: colour difference (0-1, of 3x3-filtered colours) above which a
         scene pixel changed against a background image at its pose (T, default 0.03; 0.05 for
         noisy captures) and against the rendered background (R, default 0.05);
         --frozen-stride: outside the change region one training sample stands for N marching
         steps of the frozen background, default 1 (every step);
         --frozen-tail: a training ray past the change region stops once its transmittance is
         below T, its last sample's colour standing for the rest, default 0.05 (0: off);
         --frozen-coarse: past the change region, once a training ray's transmittance is below
         T its frozen samples each stand for N marching steps (0.5,4 trains 9-20% faster and
         loses 1-5% of the near crop), default off;
         --photo-tail: a training ray stops where it leaves the change region, the light behind
         read off the background's image of its pixel (the image at the same pose, else the
         background rendered there), default on;
         --ray-pool: the background-aware residual draws each training ray not taken from the
         changed pixels N times on average, its background evaluated once, default 0 (every
         ray fresh);
         --exposure-correction: fit each scene image's exposure and white balance to the
         background's before the change maps and training, default on;
         --pose-registration: correct each scene image's pose so it agrees with the background
         where nothing changed (a robot arm's poses are millimetres off), default on;
         --image-gains: every run (background included) learns a gain per image, default off;
         --pixel-jitter: every run's training rays through random points of their pixels,
         default off;
         --pixel-rays: every run scores each training pixel by the mean of K rays through its
         footprint, default 1;
         methods: dex, dex-error-map, finetune, residual, residual-no-warm-start, residual-no-region,
         residual-no-focus, residual-no-reach, residual-no-beta, residual-solid, residual-activated,
         residual-activated-no-warm-start,
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
         [--background-data BG_DIR --scene DIR]
         throughput of the hot kernels on this machine (one JSON object with --json); with
         --model, render_depth_ms_200[_residual] and render_depth_ms_640x480[_residual] time
         these trained models (a NeRF, a residual model) from the first test view of DIR (rescaled
         to 200 wide, and to 640 wide cropped to 480 rows) instead of the bench's short-trained ones;
         with --background-data and --scene, time to quality at the defaults: the background
         trained on BG_DIR until its test PSNR reaches 28 dB (background_seconds_to_28db), then
         the default Residual-NeRF on DIR until its object-mask MAE is within 5% of its final
         one (scene_seconds_to_quality; curves every 100 steps, evaluation not counted)
  help   this text

threshold depth: --m M is a density sigma >= M per unit of the dataset's coordinates (per metre;
  default 10);
  --m-raw S compares the raw network output s >= S (sigma = exp(s)), as the authors' code does.
environment: RNERF_CPU_LEVEL=scalar|avx2|avx512|amx|neon lowers the SIMD level (never raises it;
  x86: scalar < avx2 < avx512 < amx, aarch64: scalar < neon)";
