//! The fused training step's chunk path (chunk density → keep → chunk colour → chunk backward
//! → finish) against the batch path (forward → backward) on the same kept samples: the same
//! densities and colours, and the same gradients in every parameter group (up to the order of
//! floating-point sums), for the NeRF and for the residual model with each Mixnet encoding.
//! Each chunk grows in two calls (`chunk_density` from row 0, then from the split). The density-only
//! paths (batch `density`, per-chunk `chunk_density_only`: first network outputs only) give the
//! chunk path's σ bit for bit.

mod common;

use glam::Vec3;
use residual_nerf::encoding::HashGridConfig;
use residual_nerf::field::mix::{DensityMix, MixKind};
use residual_nerf::field::mixnet::MixnetEncoding;
use residual_nerf::field::model::Model;
use residual_nerf::field::residual::{ResidualConfig, ResidualField};
use residual_nerf::field::{Nerf, NerfConfig};
use residual_nerf::geometry::ChangeRegion;
use residual_nerf::render::Aabb;
use residual_nerf::rng::Rng;
use residual_nerf::simd::Isa;

fn grid() -> HashGridConfig {
    HashGridConfig { levels: 6, log2_table_size: 10, base_resolution: 4, finest_resolution: 64 }
}

fn aabb() -> Aabb {
    Aabb { min: Vec3::splat(-1.0), max: Vec3::splat(1.0) }
}

/// A random NeRF with a lively grid (densities and colours far from constant).
fn nerf(rng: &mut Rng) -> Nerf {
    common::lively_nerf(grid(), rng)
}

fn close(what: &str, got: &[f32], want: &[f32], rel: f32) {
    assert_eq!(got.len(), want.len(), "{what}: lengths differ");
    let scale = want.iter().fold(0f32, |m, v| m.max(v.abs())).max(1e-12);
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert!((g - w).abs() <= rel * scale, "{what}[{i}]: fused {g} vs batch {w} (scale {scale})");
    }
}

/// Runs `n` samples through three chunks in two slots, keeping every sample but each third,
/// and compares with one batch of the kept samples.
fn fused_matches_batch<M: Model>(name: &str, model: &M, params: &M::Params, rng: &mut Rng) {
    let isa = Isa::detect();
    let n = 150;
    let pos: Vec<Vec3> =
        (0..n).map(|_| Vec3::new(rng.uniform(-0.9, 0.9), rng.uniform(-0.9, 0.9), rng.uniform(-0.9, 0.9))).collect();
    let dirs: Vec<Vec3> =
        (0..n).map(|_| Vec3::new(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), 0.5).normalize()).collect();
    let kept: Vec<usize> = (0..n).filter(|i| i % 3 != 1).collect();
    let k = kept.len();
    let d_sigma: Vec<f32> = (0..k).map(|_| rng.uniform(-1.0, 1.0)).collect();
    let d_rgb: Vec<[f32; 3]> = (0..k).map(|_| std::array::from_fn(|_| rng.uniform(-1.0, 1.0))).collect();

    // The batch path on the kept samples.
    let (kp, kd): (Vec<Vec3>, Vec<Vec3>) = kept.iter().map(|&i| (pos[i], dirs[i])).unzip();
    let (mut sigma_ref, mut rgb_ref) = (vec![0.0; k], vec![[0.0; 3]; k]);
    let mut ctx = M::Context::default();
    model.forward(isa, params, &kp, &kd, &mut sigma_ref, &mut rgb_ref, &mut ctx);
    let mut g_ref = model.zero_grads();
    model.backward(isa, params, &mut ctx, &d_sigma, &d_rgb, &mut g_ref);

    // The chunk path: slot 0 takes two chunks, slot 1 one; one chunk state reused throughout.
    let mut slots: Vec<M::Slot> = (0..2).map(|_| M::Slot::default()).collect();
    slots.iter_mut().for_each(|s| model.begin_slot(s));
    let mut chunk = M::Chunk::default();
    let mut j = 0;
    for (s, range) in [(0, 0..40), (0, 40..75), (1, 75..n)] {
        let mut sigma = vec![0.0; range.len()];
        let mut only = vec![0.0; range.len()];
        model.chunk_density_only(isa, params, &pos[range.clone()], None, &mut only, &mut chunk);
        // The chunk grows in two calls (as a ray evaluated segment by segment does).
        let split = (range.len() * 2 / 5).max(1);
        let (first, rest) = sigma.split_at_mut(split);
        model.chunk_density(isa, params, 0, &pos[range.start..range.start + split], first, &mut chunk);
        model.chunk_density(isa, params, split, &pos[range.start + split..range.end], rest, &mut chunk);
        let mut batch = vec![0.0; range.len()];
        model.density(isa, params, &pos[range.clone()], &mut batch, &mut M::Context::default());
        let mut whole = vec![0.0; range.len()];
        model.chunk_density(isa, params, 0, &pos[range.clone()], &mut whole, &mut M::Chunk::default());
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&whole), bits(&sigma), "{name}: a chunk grown in two calls is not one call's σ");
        assert_eq!(bits(&only), bits(&sigma), "{name}: chunk_density_only is not chunk_density's σ");
        assert_eq!(bits(&batch), bits(&sigma), "{name}: density is not chunk_density's σ");
        let keep: Vec<u32> = range.clone().filter(|i| i % 3 != 1).map(|i| (i - range.start) as u32).collect();
        let kept_sigma: Vec<f32> = keep.iter().map(|&r| sigma[r as usize]).collect();
        let rows = j..j + keep.len();
        close(&format!("{name}: σ"), &kept_sigma, &sigma_ref[rows.clone()], 1e-5);
        let mut rgb = vec![[0.0; 3]; keep.len()];
        model.chunk_colour(isa, params, &keep, &kd[rows.clone()], &mut rgb, &mut chunk);
        close(&format!("{name}: colour"), rgb.as_flattened(), rgb_ref[rows.clone()].as_flattened(), 1e-5);
        model.chunk_backward(isa, params, &mut chunk, &d_sigma[rows.clone()], &d_rgb[rows.clone()], &mut slots[s]);
        j = rows.end;
    }
    assert_eq!(j, k);
    let mut g = model.zero_grads();
    model.finish_step(isa, &slots, &mut g);

    let (mut p1, mut p2) = (params.clone(), params.clone());
    let fused = model.groups(&mut p1, &g);
    let batch = model.groups(&mut p2, &g_ref);
    assert_eq!(fused.len(), batch.len());
    // The grid and both networks of the trained NeRF always receive gradient.
    assert!(batch.iter().take(3).all(|b| b.grad.iter().any(|&v| v != 0.0)), "{name}: nothing to compare");
    for (i, (f, b)) in fused.iter().zip(&batch).enumerate() {
        close(&format!("{name}: group {i} gradient"), f.grad, b.grad, 1e-4);
    }
}

#[test]
fn the_nerf_chunk_path_matches_the_batch_path() {
    let mut rng = Rng::new(5);
    let n = nerf(&mut rng);
    fused_matches_batch("nerf", &n.field, &n.params, &mut rng);
}

#[test]
fn the_residual_chunk_path_matches_the_batch_path() {
    let own = MixnetEncoding::Own(HashGridConfig {
        levels: 4,
        log2_table_size: 8,
        base_resolution: 4,
        finest_resolution: 32,
    });
    for (kind, mixnet) in [
        (MixKind::Mixnet(DensityMix::Raw), own),
        (MixKind::Mixnet(DensityMix::Activated), MixnetEncoding::Shared),
        (MixKind::Sum, own),
    ] {
        let mut rng = Rng::new(9);
        let bg = nerf(&mut rng);
        let cfg = ResidualConfig { residual: NerfConfig { grid: grid(), aabb: aabb() }, kind, mixnet };
        let f = ResidualField::new(bg, cfg);
        let mut p = f.init_params(&mut rng);
        p.residual.grid.master.iter_mut().for_each(|v| *v = rng.uniform(-1.0, 1.0));
        p.residual.grid.sync_mirror();
        p.mixnet.grid.master.iter_mut().for_each(|v| *v = rng.uniform(-1.0, 1.0));
        p.mixnet.grid.sync_mirror();
        // The Mixnet's output layer starts at zero (β = ½); give it real weights.
        let last = *f.mixnet().mlp().layers().last().unwrap();
        let w = p.mixnet.mlp.weights_mut();
        for k in 0..last.k_real {
            w[last.offset + k * last.o] = rng.uniform(-0.3, 0.3);
        }
        p.mixnet.mlp.sync();
        fused_matches_batch(&format!("residual {kind:?} {mixnet:?}"), &f, &p, &mut rng);
        // With a change region the chunk path evaluates the residual and the Mixnet inside it
        // only; the batch path evaluates them everywhere and masks β. A thin slab along one
        // edge (few rows inside) and half the box.
        if let MixKind::Mixnet(_) = kind {
            // Colour-only mixing where the background is solid, at the median background σ of
            // points across the box (so part of the rows mix colour only).
            let pts: Vec<Vec3> = (0..256)
                .map(|_| Vec3::new(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0)))
                .collect();
            let mut s_bg = vec![0.0; pts.len()];
            f.background.field.density(Isa::detect(), &f.background.params, &pts, &mut s_bg, &mut Default::default());
            s_bg.sort_by(f32::total_cmp);
            assert!(s_bg[0] < s_bg[255], "the background's density varies across the box");
            let solid = f.clone().with_solid_background(s_bg[128].exp());
            fused_matches_batch(&format!("residual {kind:?} {mixnet:?} colour-only on solid"), &solid, &p, &mut rng);
            for cells in [(0..4).collect::<Vec<u32>>(), (0..32).collect()] {
                let region = ChangeRegion::from_cells(aabb(), 4, &cells).unwrap();
                let fr = f.clone().with_region(region);
                fused_matches_batch(
                    &format!("residual {kind:?} {mixnet:?} in {} cells", cells.len()),
                    &fr,
                    &p,
                    &mut rng,
                );
            }
        }
    }
}

/// The ray pool's entry points ([`FrozenOutside`]): a chunk inside the change region run with
/// the background's raw densities and colours handed in holds the same bits as one that
/// evaluates them (σ, colours, and the gradients its backward accumulates), and a sample
/// outside the region gets the chunk path's σ and colour from the background's raw outputs.
#[test]
fn the_frozen_outside_entry_points_give_the_chunk_path_bits() {
    let isa = Isa::detect();
    let mut rng = Rng::new(21);
    let bg = nerf(&mut rng);
    let own = MixnetEncoding::Own(HashGridConfig {
        levels: 4,
        log2_table_size: 8,
        base_resolution: 4,
        finest_resolution: 32,
    });
    for mixnet in [own, MixnetEncoding::Shared] {
        let cfg = ResidualConfig {
            residual: NerfConfig { grid: grid(), aabb: aabb() },
            kind: MixKind::Mixnet(DensityMix::Raw),
            mixnet,
        };
        // Half the box (x < 0) is the region.
        let cells: Vec<u32> = (0..64).filter(|c| c % 4 < 2).collect();
        let f = ResidualField::new(bg.clone(), cfg).with_region(ChangeRegion::from_cells(aabb(), 4, &cells).unwrap());
        let mut p = f.init_params(&mut rng);
        p.residual.grid.master.iter_mut().for_each(|v| *v = rng.uniform(-1.0, 1.0));
        p.residual.grid.sync_mirror();
        let last = *f.mixnet().mlp().layers().last().unwrap();
        let w = p.mixnet.mlp.weights_mut();
        for k in 0..last.k_real {
            w[last.offset + k * last.o] = rng.uniform(-0.3, 0.3);
        }
        p.mixnet.mlp.sync();
        let split = f.frozen_outside().expect("a field with a region is frozen outside it");
        let n = 90;
        let inside: Vec<Vec3> = (0..n)
            .map(|_| Vec3::new(rng.uniform(-0.95, -0.05), rng.uniform(-0.95, 0.95), rng.uniform(-0.95, 0.95)))
            .collect();
        assert!(inside.iter().all(|&q| split.is_inside(q)));
        let dirs: Vec<Vec3> =
            (0..n).map(|_| Vec3::new(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), 0.5).normalize()).collect();
        let keep: Vec<u32> = (0..n as u32).filter(|i| i % 4 != 2).collect();
        let kd: Vec<Vec3> = keep.iter().map(|&i| dirs[i as usize]).collect();
        let k = keep.len();
        let d_sigma: Vec<f32> = (0..k).map(|_| rng.uniform(-1.0, 1.0)).collect();
        let d_rgb: Vec<[f32; 3]> = (0..k).map(|_| std::array::from_fn(|_| rng.uniform(-1.0, 1.0))).collect();
        // The background's raw outputs at the kept rows, as the pool keeps them.
        let bgf = &f.background;
        let mut fc = Default::default();
        let mut s_bg = vec![0.0; n];
        bgf.field.chunk_density(isa, &bgf.params, 0, &inside, &mut s_bg, &mut fc);
        bgf.field.chunk_keep(&mut fc, &keep);
        let mut c_bg = vec![[0.0; 3]; k];
        bgf.field.chunk_colour(isa, &bgf.params, &kd, &mut c_bg, &mut fc);
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let mut outs = Vec::new();
        for given in [false, true] {
            let mut chunk = Default::default();
            let (mut sigma, mut rgb) = (vec![0.0; n], vec![[0.0; 3]; k]);
            match given {
                false => Model::chunk_density(&f, isa, &p, 0, &inside, &mut sigma, &mut chunk),
                true => split.chunk_density_over(isa, &p, &inside, &s_bg, &mut sigma, &mut chunk),
            }
            match given {
                false => Model::chunk_colour(&f, isa, &p, &keep, &kd, &mut rgb, &mut chunk),
                true => split.chunk_colour_over(isa, &p, &keep, &kd, &c_bg, &mut rgb, &mut chunk),
            }
            let mut slot = Default::default();
            Model::begin_slot(&f, &mut slot);
            Model::chunk_backward(&f, isa, &p, &mut chunk, &d_sigma, &d_rgb, &mut slot);
            let mut g = Model::zero_grads(&f);
            Model::finish_step(&f, isa, &[slot], &mut g);
            let mut pc = p.clone();
            let grads: Vec<Vec<u32>> = Model::groups(&f, &mut pc, &g).iter().map(|g| bits(g.grad)).collect();
            outs.push((bits(&sigma), bits(rgb.as_flattened()), grads));
        }
        assert!(outs[0] == outs[1], "{mixnet:?}: the background's values handed in change the chunk's bits");
        // Outside the region: σ and colour from the background's raw outputs alone.
        let outside: Vec<Vec3> = inside.iter().map(|q| Vec3::new(-q.x, q.y, q.z)).collect();
        let mut chunk = Default::default();
        let (mut sigma, mut rgb) = (vec![0.0; n], vec![[0.0; 3]; k]);
        Model::chunk_density(&f, isa, &p, 0, &outside, &mut sigma, &mut chunk);
        Model::chunk_colour(&f, isa, &p, &keep, &kd, &mut rgb, &mut chunk);
        let mut s_out = vec![0.0; n];
        bgf.field.chunk_density(isa, &bgf.params, 0, &outside, &mut s_out, &mut fc);
        bgf.field.chunk_keep(&mut fc, &keep);
        bgf.field.chunk_colour(isa, &bgf.params, &kd, &mut c_bg, &mut fc);
        for (j, &r) in keep.iter().enumerate() {
            let (s, c) = split.outside(s_out[r as usize], c_bg[j]);
            assert_eq!(s.to_bits(), sigma[r as usize].to_bits(), "{mixnet:?}: σ outside at row {r}");
            assert_eq!(bits(&c), bits(&rgb[j]), "{mixnet:?}: colour outside at row {r}");
        }
    }
}
