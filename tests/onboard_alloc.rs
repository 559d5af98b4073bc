//! The onboard renderer allocates nothing per frame once warm: a counting global allocator
//! around three frames of several views (its own test binary, so no other test allocates
//! meanwhile).

use residual_nerf::data::synth;
use residual_nerf::encoding::HashGridConfig;
use residual_nerf::field::{Nerf, NerfConfig};
use residual_nerf::io::LoadedModel;
use residual_nerf::onboard::{DepthRenderer, DepthRequest, Extras};
use residual_nerf::render::OccupancyConfig;
use residual_nerf::simd::Isa;
use residual_nerf::train::trainer::{train_nerf, TrainConfig};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

/// Counts allocations of the whole process (one test in this binary).
struct Counting;
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);
// SAFETY: forwards every call to the system allocator unchanged.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: the caller's contract is passed on.
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        // SAFETY: the caller's contract is passed on.
        unsafe { System.dealloc(p, l) }
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, n: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: the caller's contract is passed on.
        unsafe { System.realloc(p, l, n) }
    }
}
#[global_allocator]
static GLOBAL: Counting = Counting;

fn trained() -> Nerf {
    let scene = synth::tabletop(16, 12, 0.0);
    let field = NerfConfig {
        grid: HashGridConfig { levels: 8, log2_table_size: 12, base_resolution: 4, finest_resolution: 64 },
        aabb: scene.aabb,
    };
    let mut cfg = TrainConfig::with_steps(40);
    cfg.rays_per_step = 512;
    cfg.background = synth::SKY;
    cfg.occupancy = OccupancyConfig { resolution: 16, steps_per_diagonal: 128, warmup_steps: 16, ..Default::default() };
    train_nerf(Isa::detect(), &scene.views, field, &cfg, 0, |_| {}).expect("trains")
}

#[test]
fn no_allocation_per_frame_once_warm() {
    let mut cam = DepthRenderer::new(LoadedModel::Nerf(Box::new(trained()))).with_threads(2).unwrap();
    let views: Vec<_> = synth::tabletop(24, 3, 0.3).views.into_iter().map(|v| (v.intrinsics, v.pose)).collect();
    let (k, _) = views[0];
    let n = (k.width * k.height) as usize;
    let mut z = vec![0.0; n];
    let mut rgb = vec![[0.0; 3]; n];
    let req = DepthRequest::default();
    let frame = |cam: &mut DepthRenderer, z: &mut [f32], rgb: &mut [[f32; 3]]| {
        for (k, pose) in &views {
            cam.depth(k, pose, req, z).unwrap();
            cam.render(k, pose, req, z, Extras { rgb: Some(rgb), beta: None }).unwrap();
        }
    };
    // Warm-up: buffers grow to the largest segment of these views.
    frame(&mut cam, &mut z, &mut rgb);
    frame(&mut cam, &mut z, &mut rgb);
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    frame(&mut cam, &mut z, &mut rgb);
    let allocated = ALLOCATIONS.load(Ordering::SeqCst) - before;
    assert_eq!(allocated, 0, "{allocated} allocations in {} warm frames", 2 * views.len());
}
