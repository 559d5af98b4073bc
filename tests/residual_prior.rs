//! The background-aware residual model: at step 0 it is the background; outside its change
//! region it is the background bit for bit (and gets no gradient); change maps and the voted
//! region find the synthesiser's glass and nothing far from it, also when the scene was
//! captured from other poses than the background.

mod common;

use glam::Vec3;
use proptest::prelude::*;
use residual_nerf::data::workspace;
use residual_nerf::encoding::HashGridConfig;
use residual_nerf::field::mix::{DensityMix, MixKind};
use residual_nerf::field::mixnet::MixnetEncoding;
use residual_nerf::field::model::Model;
use residual_nerf::field::residual::{ResidualConfig, ResidualContext, ResidualField, ResidualNetGrads};
use residual_nerf::field::Nerf;
use residual_nerf::geometry::ChangeRegion;
use residual_nerf::render::{Aabb, DensityThreshold};
use residual_nerf::rng::Rng;
use residual_nerf::train::prior::{change_map, changed_pixels, close_and_fill, dilate, scene_prior, PriorConfig};
use residual_nerf::train::scene::SceneBackground;
use residual_nerf::train::trainer::train_nerf;
use residual_nerf::GradientMode;

fn grid() -> HashGridConfig {
    HashGridConfig { levels: 4, log2_table_size: 8, base_resolution: 4, finest_resolution: 16 }
}

fn aabb() -> Aabb {
    Aabb { min: Vec3::splat(-1.0), max: Vec3::splat(1.0) }
}

fn field(bg: &Nerf, kind: MixKind) -> ResidualField {
    let config = ResidualConfig { residual: bg.field.config().clone(), kind, mixnet: MixnetEncoding::default() };
    ResidualField::new(bg.clone(), config)
}

fn points(seed: u64, n: usize) -> (Vec<Vec3>, Vec<Vec3>) {
    let mut rng = Rng::new(seed);
    let p = (0..n).map(|_| Vec3::new(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0))).collect();
    let d = (0..n)
        .map(|_| {
            Vec3::new(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0)).normalize_or(Vec3::Z)
        })
        .collect();
    (p, d)
}

/// A random lively background, `n` random samples, and the background's own activated
/// density and colour there.
struct Case {
    rng: Rng,
    bg: Nerf,
    p: Vec<Vec3>,
    d: Vec<Vec3>,
    s_bg: Vec<f32>,
    c_bg: Vec<[f32; 3]>,
}

fn case(seed: u64, n: usize) -> Case {
    let mut rng = Rng::new(seed);
    let bg = common::lively_nerf(grid(), &mut rng);
    let (p, d) = points(seed ^ 7, n);
    let (mut s_bg, mut c_bg) = (vec![0.0; n], vec![[0.0; 3]; n]);
    let mut ctx = Default::default();
    Model::forward(&bg.field, common::best_fp32_isa(), &bg.params, &p, &d, &mut s_bg, &mut c_bg, &mut ctx);
    Case { rng, bg, p, d, s_bg, c_bg }
}

proptest! {
    #![proptest_config(common::cases(8))]

    /// Warm-started, the mixed field is the background at step 0, whatever β, for both density
    /// mixes (to rounding: the raw mix computes (1−β)s + βs).
    #[test]
    fn warm_start_equals_the_background(seed in 0u64..1000) {
        let isa = common::best_fp32_isa();
        let Case { mut rng, bg, p, d, s_bg, c_bg } = case(seed, 64);
        for kind in [MixKind::Mixnet(DensityMix::Raw), MixKind::Mixnet(DensityMix::Activated)] {
            let f = field(&bg, kind);
            let mut params = f.warm_params(&mut rng).expect("same architecture");
            // A Mixnet that is not ½ everywhere: random output weights.
            let w = params.mixnet.mlp.weights_mut();
            for x in w.iter_mut() { *x = rng.uniform(-1.0, 1.0); }
            params.mixnet.mlp.sync();
            let n = p.len();
            let (mut s, mut c) = (vec![0.0; n], vec![[0.0; 3]; n]);
            f.forward(isa, &params, &p, &d, &mut s, &mut c, &mut ResidualContext::default());
            for i in 0..n {
                prop_assert!((s[i] - s_bg[i]).abs() <= 1e-4 * s_bg[i].abs().max(1.0), "{kind:?}: σ {} vs {}", s[i], s_bg[i]);
                for k in 0..3 {
                    prop_assert!((c[i][k] - c_bg[i][k]).abs() <= 1e-5, "{kind:?}: colour {} vs {}", c[i][k], c_bg[i][k]);
                }
            }
        }
    }

    /// Outside the change region the field is the background bit for bit (fresh, untrained
    /// residual and Mixnet), and no gradient reaches the residual or the Mixnet from there.
    #[test]
    fn outside_the_region_the_field_is_the_background(seed in 0u64..1000) {
        let isa = common::best_fp32_isa();
        let Case { mut rng, bg, p, d, s_bg, c_bg } = case(seed, 96);
        // A region of a few random cells of an 8³ grid; most points fall outside.
        let cells: Vec<u32> = (0..6).map(|_| rng.below(512) as u32).collect();
        let region = ChangeRegion::from_cells(aabb(), 8, &cells).unwrap();
        for kind in [MixKind::Mixnet(DensityMix::Raw), MixKind::Mixnet(DensityMix::Activated)] {
            let f = field(&bg, kind).with_region(region.clone());
            let params = Model::init_params(&f, &mut rng);
            let n = p.len();
            let (mut s, mut c) = (vec![0.0; n], vec![[0.0; 3]; n]);
            let mut ctx = ResidualContext::default();
            f.forward(isa, &params, &p, &d, &mut s, &mut c, &mut ctx);
            let mut outside = 0;
            for i in (0..n).filter(|&i| !region.contains(p[i])) {
                outside += 1;
                prop_assert_eq!(s[i].to_bits(), s_bg[i].to_bits(), "{:?}: σ at {}", kind, p[i]);
                for k in 0..3 {
                    prop_assert_eq!(c[i][k].to_bits(), c_bg[i][k].to_bits());
                }
            }
            prop_assert!(outside > 0);
            // Chunk path (training, depth-only rendering; the residual and the Mixnet skipped
            // outside the region, often on every row here): the same σ and colours, and no
            // gradient from outside.
            let mut chunk = Default::default();
            let mut s2 = vec![0.0; n];
            f.chunk_density(isa, &params, 0, &p, &mut s2, &mut chunk);
            for i in (0..n).filter(|&i| !region.contains(p[i])) {
                prop_assert_eq!(s2[i].to_bits(), s_bg[i].to_bits());
            }
            let keep: Vec<u32> = (0..n as u32).collect();
            let mut c2 = vec![[0.0; 3]; n];
            f.chunk_colour(isa, &params, &keep, &d, &mut c2, &mut chunk);
            for i in (0..n).filter(|&i| !region.contains(p[i])) {
                for k in 0..3 {
                    prop_assert_eq!(c2[i][k].to_bits(), c_bg[i][k].to_bits());
                }
            }
            let d_out: Vec<f32> = (0..n).map(|i| if region.contains(p[i]) { 0.0 } else { 1.0 }).collect();
            let d_rgb_out: Vec<[f32; 3]> = d_out.iter().map(|&g| [g; 3]).collect();
            let mut nets = ResidualNetGrads::default();
            nets.residual.clear(f.residual());
            nets.mixnet.resize(f.mixnet().mlp().n_params(), 0.0);
            f.chunk_backward(isa, &params, &mut chunk, &d_out, &d_rgb_out, &mut nets);
            let ResidualNetGrads { residual, mixnet } = &nets;
            let chunk_grads = [&residual.density, &residual.colour, mixnet];
            for g in chunk_grads {
                prop_assert!(g.iter().all(|&x| x == 0.0), "{:?}: a chunk gradient from outside the region", kind);
            }
            prop_assert!(chunk.residual().feature_grad().iter().all(|&x| x == 0.0));
            // Gradients of outside samples only: zero everywhere.
            let d_sigma: Vec<f32> = (0..n).map(|i| if region.contains(p[i]) { 0.0 } else { 1.0 }).collect();
            let d_rgb: Vec<[f32; 3]> = d_sigma.iter().map(|&g| [g; 3]).collect();
            let mut grads = f.zero_grads();
            f.backward(isa, &params, &mut ctx, &d_sigma, &d_rgb, &mut grads, GradientMode::Overwrite);
            let all = [&grads.residual.grid, &grads.residual.density, &grads.residual.colour, &grads.mixnet.grid, &grads.mixnet.mlp];
            for g in all {
                prop_assert!(g.iter().all(|&x| x == 0.0), "{:?}: a gradient from outside the region", kind);
            }
        }
    }
}

fn frac(mask: &[bool], map: &[bool]) -> f64 {
    let n = mask.iter().filter(|&&m| m).count();
    mask.iter().zip(map).filter(|(&m, &c)| m && c).count() as f64 / n.max(1) as f64
}

/// Pixels farther than `r` pixels from every mask pixel.
fn far_from(mask: &[bool], w: usize, r: i64) -> Vec<bool> {
    let h = mask.len() / w;
    (0..mask.len())
        .map(|p| {
            let (x, y) = ((p % w) as i64, (p / w) as i64);
            !(-r..=r).any(|dy| {
                (-r..=r).any(|dx| {
                    let (a, b) = (x + dx, y + dy);
                    a >= 0 && b >= 0 && (a as usize) < w && (b as usize) < h && mask[b as usize * w + a as usize]
                })
            })
        })
        .collect()
}

/// A map from rows of `#` (set) and `.` (unset).
fn map_of(rows: &[&str]) -> (Vec<bool>, u32, u32) {
    let map = rows.iter().flat_map(|r| r.chars().map(|c| c == '#')).collect();
    (map, rows[0].len() as u32, rows.len() as u32)
}

#[test]
fn closing_and_filling_spares_what_a_changed_outline_encloses_and_nothing_outside_it() {
    // An outline open by two pixels on its right, a lone pixel and a bay open to the border.
    let (map, w, h) = map_of(&[
        "............",
        ".#####......",
        ".#..........",
        ".#..........",
        ".#####......",
        "............",
        "............",
        "........#...",
        "............",
        "#####.......",
        "#...#.......",
    ]);
    let by_1 = close_and_fill(&map, w, h, 1);
    // The outline's inside and its opening (rows 2 and 3, columns 2 to 5) set, nothing else.
    let mut expected = map.clone();
    for y in 2..4 {
        expected[y * w as usize + 2..y * w as usize + 6].fill(true);
    }
    assert_eq!(by_1, expected, "radius 1 closes the outline and fills it, and leaves the lone pixel and the bay");
    // Radius 0 fills the holes only: the outline's gap keeps its inside joined to the border.
    assert_eq!(close_and_fill(&map, w, h, 0), map, "an open outline encloses nothing");
    let (ring, rw, rh) = map_of(&["......", ".####.", ".#..#.", ".####.", "......"]);
    let (filled, ..) = map_of(&["......", ".####.", ".####.", ".####.", "......"]);
    assert_eq!(close_and_fill(&ring, rw, rh, 0), filled, "a closed outline's inside is filled");
    // Every set pixel stays set, whatever the radius.
    for r in 0..4 {
        let out = close_and_fill(&map, w, h, r);
        assert!(map.iter().zip(&out).all(|(&a, &b)| !a || b), "radius {r} lost a set pixel");
    }
}

#[test]
fn change_maps_find_the_glass_and_nothing_far_from_it() {
    let size = 48;
    let bg = workspace::workspace(size, 6, 0.0, false);
    let scene = workspace::workspace(size, 6, 0.0, true);
    let cfg = PriorConfig::default();
    for i in 0..6 {
        let map = change_map(&scene.views[i].rgb, &bg.views[i].rgb, size, size, &cfg);
        let mask = &scene.masks[i];
        let raw = changed_pixels(&scene.views[i].rgb, &bg.views[i].rgb, size, size, &cfg);
        assert_eq!(dilate(&raw, size, size, cfg.dilate_px), map, "view {i}: the map is the changed pixels dilated");
        let found = frac(mask, &map);
        let far = far_from(mask, size as usize, 6);
        let false_alarm =
            far.iter().zip(&map).filter(|(&f, &c)| f && c).count() as f64 / far.iter().filter(|&&f| f).count() as f64;
        assert!(found >= 0.9, "view {i}: {:.1}% of the glass pixels marked changed", 100.0 * found);
        assert!(
            false_alarm <= 0.02,
            "view {i}: {:.1}% of the pixels far from the glass marked changed",
            100.0 * false_alarm
        );
    }
}

/// An exposure and white-balance change between the captures (the scene ×1.2, ×1.1, ×0.9 per
/// channel, saturating) is fitted back despite the glass (the inverse gains within 1%), and after
/// the correction the change maps find the glass and nothing far from it again; without it
/// most of the image reads as changed.
#[test]
fn an_exposure_change_is_corrected_before_the_change_maps() {
    use residual_nerf::data::workspace::{Capture, Glass};
    use residual_nerf::train::prior::fit_correction;
    let size = 48;
    let gain = [1.2, 1.1, 0.9];
    let bg = workspace::workspace(size, 4, 0.0, false);
    let scene = workspace::workspace_capture(size, 4, 0.0, Glass::Sphere, &Capture { gain, ..Default::default() });
    // The correction is what is tested, at the tolerance 0.05: at the default 0.03 the pixels
    // the gain saturated keep differences above it after the correction (2.4% of the pixels far
    // from the glass on view 0; docs/DECISIONS.md, "The change maps' tolerance").
    let cfg = PriorConfig { tolerance: 0.05, ..Default::default() };
    for i in 0..4 {
        let c = fit_correction(&scene.views[i].rgb, &bg.views[i].rgb);
        for k in 0..3 {
            assert!((c.gain[k] * gain[k] - 1.0).abs() < 0.01, "view {i}: {c:?}");
        }
        let mask = &scene.masks[i];
        let far = far_from(mask, size as usize, 6);
        let false_alarm = |map: &[bool]| {
            far.iter().zip(map).filter(|(&f, &c)| f && c).count() as f64 / far.iter().filter(|&&f| f).count() as f64
        };
        let raw = change_map(&scene.views[i].rgb, &bg.views[i].rgb, size, size, &cfg);
        assert!(false_alarm(&raw) > 0.5, "view {i}: the change should read as everywhere without the correction");
        let corrected: Vec<[f32; 3]> = scene.views[i].rgb.iter().map(|&x| c.apply(x)).collect();
        let map = change_map(&corrected, &bg.views[i].rgb, size, size, &cfg);
        assert!(frac(mask, &map) >= 0.9, "view {i}: {:.1}% of the glass found", 100.0 * frac(mask, &map));
        assert!(false_alarm(&map) <= 0.02, "view {i}: {:.1}% far from the glass changed", 100.0 * false_alarm(&map));
    }
    // Identical captures fit the identity, which the prior does not apply.
    let same = fit_correction(&bg.views[0].rgb, &bg.views[0].rgb);
    assert!(same.is_negligible(), "{same:?}");
}

/// The voted region holds the glass sphere's centre and little else; with the scene captured
/// from other poses than the background (or at the same poses known only to 2 mm and 0.2°) the
/// change maps come from the rendered background.
#[test]
fn the_voted_region_holds_the_glass_from_the_same_and_from_other_poses() {
    let isa = residual_nerf::simd::Isa::detect();
    let size = 32;
    let demo = residual_nerf::app::demo_config(300, 0);
    let bg_views = workspace::workspace(size, 24, 0.0, false);
    let background = train_nerf(isa, &bg_views.views, demo.field.clone(), &demo.train, 0, |_| {}).expect("trains");
    let m = DensityThreshold::Sigma(10.0);
    let (centre, radius) = workspace::GLASS;
    // The third case: the scene's poses off by 2 mm and 0.2° (a robot's kinematics), so none
    // matches a background image and the maps come from the rendered background.
    let noisy = workspace::Capture { pose_noise: Some((0.002, 0.2, 7)), ..Default::default() };
    for (phase, matched, capture) in [(0.0, true, None), (0.5, false, None), (0.0, false, Some(noisy))] {
        let scene = match capture {
            None => workspace::workspace(size, 24, phase, true),
            Some(c) => workspace::workspace_capture(size, 24, phase, workspace::Glass::Sphere, &c),
        };
        let bgv = if matched || capture.is_some() { &bg_views.views[..] } else { &[] };
        // The tighter vote for a tiny, weak background with holes (PriorConfig docs).
        let cfg = PriorConfig { min_seen: 0.25, holes_see: false, ..Default::default() };
        let p = scene_prior(isa, &background, bgv, &scene.views, workspace::SKY, m, &cfg);
        assert_eq!(p.matched_views, if matched { 24 } else { 0 });
        // The β penalty spares the changed pixels, closed and filled by its radius, dilated by
        // its margin: by default (no closing, the maps' dilation) the focus pixels, with margin
        // 0 the changed pixels alone, a subset; closed and filled, a superset of those.
        assert_eq!(p.spared, p.focus);
        if matched {
            let tight = PriorConfig { beta_close_px: 0, beta_dilate_px: 0, ..cfg };
            let q = scene_prior(isa, &background, bgv, &scene.views, workspace::SKY, m, &tight);
            assert_eq!(q.focus, p.focus, "the margin changes the focus pixels");
            let focus: std::collections::HashSet<_> = q.focus.iter().collect();
            assert!(q.spared.iter().all(|x| focus.contains(x)), "a spared pixel outside the focus");
            assert!(
                q.spared.len() < q.focus.len(),
                "margin 0 spares {} of {} focus pixels",
                q.spared.len(),
                q.focus.len()
            );
            let (v, w) = (0, size as usize);
            let raw = changed_pixels(&scene.views[v].rgb, &bg_views.views[v].rgb, size, size, &cfg);
            let spared: Vec<usize> = q.spared.iter().filter(|x| x.0 == v as u32).map(|x| x.1 as usize).collect();
            let expected: Vec<usize> = (0..w * w).filter(|&p| raw[p]).collect();
            assert_eq!(spared, expected, "view {v}: margin 0 spares exactly the changed pixels");
            let shut = PriorConfig { beta_close_px: 4, beta_dilate_px: 0, ..cfg };
            let f = scene_prior(isa, &background, bgv, &scene.views, workspace::SKY, m, &shut);
            let closed = close_and_fill(&raw, size, size, 4);
            let spared: Vec<usize> = f.spared.iter().filter(|x| x.0 == v as u32).map(|x| x.1 as usize).collect();
            let expected: Vec<usize> = (0..w * w).filter(|&p| closed[p]).collect();
            assert_eq!(spared, expected, "view {v}: radius 4 spares the changed pixels closed and filled");
            let filled: std::collections::HashSet<_> = f.spared.iter().collect();
            assert!(q.spared.iter().all(|x| filled.contains(x)), "closing lost a changed pixel");
            // Kept between scene phases, the background's depth at its images' poses is
            // rendered once and read back after: the same priors as rendering it each time.
            let mut kept = SceneBackground::new(&background, bgv).expect("usable views");
            assert_eq!(kept.depths_held(), 0);
            for (cfg, fresh) in [(&cfg, &p), (&tight, &q), (&shut, &f), (&cfg, &p)] {
                let held = kept.prior(isa, &scene.views, workspace::SKY, m, cfg);
                assert_eq!(kept.depths_held(), 24, "one depth per background image");
                let same = held.maps == fresh.maps && held.focus == fresh.focus && held.spared == fresh.spared;
                assert!(same && held.reach == fresh.reach, "the held depths give another prior");
                assert!(held.region.cells() == fresh.region.cells(), "the held depths give another region");
            }
            // Voted twice as fine (the default): inside the grid's vote's cells and their
            // neighbours, then dilated by a fine cell, so within the grid-cell region (voted
            // on the grid's cells, dilated by one) grown by a cell.
            let grid_cells = PriorConfig { region_subdivide: 1, ..cfg };
            let g = scene_prior(isa, &background, bgv, &scene.views, workspace::SKY, m, &grid_cells);
            let res = g.region.resolution();
            assert_eq!((p.region.resolution(), res), (2 * res, background.occupancy.config().resolution));
            let outer = g.region.dilated(1);
            let coarse = p.region.coarsened(res).unwrap();
            assert!(coarse.cells().iter().all(|&c| outer.has_cell(c as usize)), "a fine cell beyond the grid's vote");
            assert!(g.region.contains(centre), "the grid-cell region misses the glass centre");
            eprintln!("region {:.4} m³ against {:.4} m³ on the grid's cells", p.region.volume(), g.region.volume());
            // Another threshold's depths are other depths: rendered again, the same as fresh.
            let m20 = DensityThreshold::Sigma(20.0);
            let held = kept.prior(isa, &scene.views, workspace::SKY, m20, &cfg);
            let fresh = scene_prior(isa, &background, bgv, &scene.views, workspace::SKY, m20, &cfg);
            let same = held.region.cells() == fresh.region.cells() && held.reach == fresh.reach;
            assert!(same, "σ ≥ 20's prior from the held depths is another prior");
            assert!(fresh.reach != p.reach, "σ ≥ 20 should move the background's surface and so the reach pixels");
        }
        assert!(p.region.contains(centre), "phase {phase}: the glass centre is outside the region");
        let volume = p.region.volume() as f32;
        let sphere = 4.0 / 3.0 * std::f32::consts::PI * radius.powi(3);
        eprintln!("phase {phase}: region {} cells, {volume:.4} m³ (glass {sphere:.4} m³)", p.region.count());
        let cs: Vec<Vec3> = p.region.cells().iter().map(|&c| p.region.cell_centre(c as usize)).collect();
        let near = cs.iter().filter(|c| (**c - centre).length() < 0.4).count();
        eprintln!("phase {phase}: {near} of the region's cells within 0.4 m of the glass");
        // At this tiny scale (32 px, 24 views, a 300-step background, 10 cm cells) the hull is
        // loose: bounded against the room and concentrated around the glass.
        let room = p.region.aabb().size();
        // Against the rendered background (other poses) the maps carry the tiny background's
        // rendering noise and the region is looser still: only containment is asserted there.
        if matched {
            assert!(volume < 0.1 * room.x * room.y * room.z, "phase {phase}: region {volume} m³");
            assert!(near * 5 >= cs.len(), "phase {phase}: {near} of {} cells near the glass", cs.len());
        }
        // A point of the room far from the glass is outside.
        assert!(!p.region.contains(Vec3::new(-1.2, 1.2, 0.5)));
    }
}

/// The density floor: after the lift a warm-started residual's raw density inside the region
/// is close to max(s_bg, floor) (it starts at s_bg, far from it), and the background's
/// surfaces above the floor are kept.
#[test]
fn the_lift_raises_the_residual_to_the_floor_inside_the_region() {
    use residual_nerf::train::lift::{lift_region, LiftConfig};
    let isa = common::best_fp32_isa();
    let Case { mut rng, bg, .. } = case(11, 4);
    let f = field(&bg, MixKind::Mixnet(DensityMix::Activated));
    let mut params = f.warm_params(&mut rng).expect("same architecture");
    let region = ChangeRegion::from_cells(aabb(), 4, &[21, 22, 25, 26]).unwrap();
    // A floor above most of the random background's raw densities.
    let cfg = LiftConfig { floor: 3.0, steps: 200, batch: 1024, lr: 1e-2 };
    let report = lift_region(isa, &bg.field, &mut params.residual, &bg, &region, &cfg, 5);
    assert!(report.error_before > 0.5, "{report:?}: the floor is not above the background");
    assert!(report.error_after < 0.2 * report.error_before, "{report:?}");
}

/// The reach pixels of a region: every pixel whose ray crosses a region cell in front of the
/// background's surface (found by marching the ray finely) is in the set, the set hugs those
/// pixels (each within two pixels of one), and a surface in front of the region hides it.
#[test]
fn reach_pixels_are_the_rays_that_cross_the_region() {
    use residual_nerf::data::View;
    use residual_nerf::geometry::camera::{pixel_ray, Intrinsics, Pose};
    use residual_nerf::train::prior::reach_pixels;
    let res = 16;
    let cells: Vec<u32> =
        [(7, 8, 8), (8, 8, 8), (8, 9, 8), (3, 4, 10)].iter().map(|&(x, y, z)| x + res * (y + res * z)).collect();
    let region = ChangeRegion::from_cells(aabb(), res, &cells).unwrap();
    let (w, h) = (48u32, 40u32);
    let k = Intrinsics::from_fov_x(w, h, 0.9);
    let views: Vec<View> = [Vec3::new(2.5, -1.0, 0.8), Vec3::new(-0.3, 2.6, -0.4)]
        .iter()
        .map(|&eye| View { intrinsics: k, pose: Pose::look_at(eye, Vec3::ZERO), rgb: vec![[0.0; 3]; (w * h) as usize] })
        .collect();
    let margin = (aabb().size() / res as f32).length();
    for hidden in [false, true] {
        // The background's surface: far behind the box, or 0.4 m in front of the camera.
        let depth: Vec<Vec<f32>> =
            views.iter().map(|_| vec![if hidden { 0.4 } else { 50.0 }; (w * h) as usize]).collect();
        let reach = reach_pixels(&region, &views, &depth);
        for (vi, v) in views.iter().enumerate() {
            let set: std::collections::HashSet<u32> = reach.iter().filter(|r| r.0 == vi as u32).map(|r| r.1).collect();
            let crossing: Vec<u32> = (0..w * h)
                .filter(|&p| {
                    let ray = pixel_ray(&v.intrinsics, &v.pose, p % w, p / w);
                    (0..4000).any(|i| {
                        let t = i as f32 * 0.002;
                        ray.range_to_z(t) <= depth[vi][p as usize] + margin && region.contains(ray.at(t))
                    })
                })
                .collect();
            if hidden {
                assert!(
                    crossing.is_empty() && set.is_empty(),
                    "view {vi}: a hidden region is reached by {} pixels",
                    set.len()
                );
                continue;
            }
            assert!(crossing.len() > 10, "view {vi}: the region covers {} pixels", crossing.len());
            for p in &crossing {
                assert!(set.contains(p), "view {vi}: pixel {p} crosses the region but is not in reach");
            }
            let near = |p: u32| {
                crossing.iter().any(|&q| {
                    ((p % w) as i64 - (q % w) as i64).abs() <= 2 && ((p / w) as i64 - (q / w) as i64).abs() <= 2
                })
            };
            assert!(set.iter().all(|&p| near(p)), "view {vi}: a reach pixel lies far from every crossing ray");
        }
    }
}
