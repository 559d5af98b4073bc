//! The onboard renderer allocates nothing per frame once warm: a counting global allocator
//! around three frames of several views (its own test binary, so no other test allocates
//! meanwhile).

mod common;

use residual_nerf::data::synth;
use residual_nerf::field::Nerf;
use residual_nerf::io::LoadedModel;
use residual_nerf::onboard::{DepthRenderer, DepthRequest, Extras};
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
    common::trained_tabletop()
}

#[test]
fn no_allocation_per_frame_once_warm() {
    let nerf = trained();
    let mut cam = DepthRenderer::new(LoadedModel::Nerf(Box::new(nerf.clone()))).with_threads(2).unwrap();
    // A first pass of every 8th or 16th row and column on these 24-px views: the coarse start's
    // middle passes reuse the same buffers.
    let mut sparse = DepthRenderer::new(LoadedModel::Nerf(Box::new(nerf))).coarse_spacing(1.0).with_threads(2).unwrap();
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
    let sparse_frame = |cam: &mut DepthRenderer, z: &mut [f32]| {
        for (k, pose) in &views {
            cam.depth(k, pose, req, z).unwrap();
        }
    };
    // Warm-up: buffers grow to the largest segment of these views.
    frame(&mut cam, &mut z, &mut rgb);
    frame(&mut cam, &mut z, &mut rgb);
    sparse_frame(&mut sparse, &mut z);
    sparse_frame(&mut sparse, &mut z);
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    frame(&mut cam, &mut z, &mut rgb);
    sparse_frame(&mut sparse, &mut z);
    let allocated = ALLOCATIONS.load(Ordering::SeqCst) - before;
    assert_eq!(allocated, 0, "{allocated} allocations in {} warm frames", 3 * views.len());
}
