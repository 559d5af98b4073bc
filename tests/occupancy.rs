//! Occupancy grid and marching on analytic scenes.

mod common;

use common::cases;
use glam::Vec3;
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;
use residual_nerf::geometry::ChangeRegion;
use residual_nerf::render::{threshold_depth, Aabb, DensityThreshold, OccupancyConfig, OccupancyGrid, PackedSamples};
use residual_nerf::rng::Rng;

const CENTRE: Vec3 = Vec3::new(0.5, 0.5, 0.5);
const R: f32 = 0.2;

fn unit_box() -> Aabb {
    Aabb { min: Vec3::ZERO, max: Vec3::ONE }
}

fn sphere(points: &[Vec3], sigma: &mut [f32]) {
    for (p, s) in points.iter().zip(sigma) {
        *s = if (*p - CENTRE).length() < R { 100.0 } else { 0.0 };
    }
}

/// A 32³ grid after 8 warm-up updates of the sphere (every cell evaluated at a new jittered
/// point each time; max with decay keeps any hit).
fn sphere_grid() -> OccupancyGrid {
    let mut g = OccupancyGrid::new(
        unit_box(),
        OccupancyConfig { resolution: 32, steps_per_diagonal: 512, ..Default::default() },
    );
    let mut rng = Rng::new(1);
    for step in 0..8 {
        g.update(step, &mut rng, sphere);
    }
    g
}

#[test]
fn aabb_intersection_hand_computed() {
    let b = unit_box();
    assert_eq!(b.intersect(Vec3::new(-1.0, 0.5, 0.5), Vec3::X), Some((1.0, 2.0)));
    assert_eq!(b.intersect(Vec3::new(0.5, 0.5, 0.5), -Vec3::Z), Some((0.0, 0.5)));
    assert_eq!(b.intersect(Vec3::new(-1.0, 2.0, 0.5), Vec3::X), None);
    assert_eq!(b.intersect(Vec3::new(2.0, 0.5, 0.5), Vec3::X), None); // box behind the ray
    let d = Vec3::new(1.0, 1.0, 0.0).normalize();
    let (near, far) = b.intersect(Vec3::new(-0.5, -0.5, 0.5), d).unwrap();
    assert!((near - 0.5f32.hypot(0.5)).abs() < 1e-6 && (far - 1.5f32.hypot(1.5)).abs() < 1e-6);
}

/// After warm-up, occupied cells are those touching the sphere: its volume fraction is
/// 4/3·π·0.2³ ≈ 0.034; cells straddling the surface add a shell.
#[test]
fn update_marks_the_sphere() {
    let g = sphere_grid();
    assert!(g.is_occupied(CENTRE));
    assert!(!g.is_occupied(Vec3::new(0.05, 0.05, 0.05)));
    let f = g.occupancy();
    assert!((0.025..0.07).contains(&f), "occupancy {f}");
}

/// An empty field empties the grid; marching then yields no samples (every ray is empty).
#[test]
fn empty_field_empties_the_grid() {
    let mut g = OccupancyGrid::new(unit_box(), OccupancyConfig { resolution: 16, ..Default::default() });
    g.update(0, &mut Rng::new(2), |_, s| s.fill(0.0));
    assert_eq!(g.occupancy(), 0.0);
    let mut out = PackedSamples::default();
    g.march(Vec3::new(-1.0, 0.5, 0.5), Vec3::X, &mut out);
    assert_eq!(out.rays, [(0, 0)]);
}

/// With every cell occupied, a ray gets one sample per step from its entry, at step midpoints.
#[test]
fn full_grid_samples_every_step() {
    let g = OccupancyGrid::new(
        unit_box(),
        OccupancyConfig { resolution: 8, steps_per_diagonal: 100, ..Default::default() },
    );
    let mut out = PackedSamples::default();
    g.march(Vec3::new(-1.0, 0.5, 0.5), Vec3::X, &mut out);
    let dt = g.step_size();
    assert_eq!(out.rays[0].1 as usize, (1.0 / dt).ceil() as usize);
    for (k, &t) in out.t.iter().enumerate() {
        assert!((t - (1.0 + (k as f32 + 0.5) * dt)).abs() < 1e-5);
    }
}

proptest! {
    #![proptest_config(cases(48))]

    /// Marching through the sphere grid (built once per case) returns exactly the brute-force sample set: every step
    /// of the lattice `near + (k + ½)·δ` whose midpoint is in an occupied cell, none other (so
    /// the empty-cell jumps lose nothing). Threshold depth through those samples is within one
    /// cell diagonal of the analytic entry distance (a surface cell whose jittered sample missed
    /// the sphere stays empty until a later update hits it); a ray that misses is a hole.
    #[test]
    fn marching_equals_brute_force_and_finds_the_surface(oy in -0.3f32..0.3, oz in -0.3f32..0.3, dy in -0.2f32..0.2, dz in -0.2f32..0.2) {
        let g = sphere_grid();
        let origin = Vec3::new(-0.5, 0.5 + oy, 0.5 + oz);
        let dir = Vec3::new(1.0, dy, dz).normalize();
        let mut out = PackedSamples::default();
        g.march(origin, dir, &mut out);
        prop_assert_eq!(out.rays.clone(), vec![(0, out.t.len() as u32)]);
        let (near, far) = unit_box().intersect(origin, dir).unwrap();
        let dt = g.step_size();
        let brute: Vec<f32> = (0..)
            .map(|k| near + (k as f32 + 0.5) * dt)
            .take_while(|&m| m - 0.5 * dt < far)
            .filter(|&m| g.is_occupied(origin + m * dir))
            .collect();
        prop_assert_eq!(out.t.len(), brute.len(), "marched {:?}\nbrute {:?}", out.t, brute);
        for (a, b) in out.t.iter().zip(&brute) {
            prop_assert!((a - b).abs() < 1e-4, "{} vs {}", a, b);
        }
        prop_assert!(out.delta.iter().all(|&d| d == dt));
        let b = dir.dot(CENTRE - origin);
        let disc = b * b - ((origin - CENTRE).length_squared() - R * R);
        let raw: Vec<f32> = out.t.iter().map(|&t| if (origin + t * dir - CENTRE).length() < R { 100f32.ln() } else { f32::NEG_INFINITY }).collect();
        let hit = threshold_depth(&out.t, &raw, DensityThreshold::Sigma(3.0));
        if disc > 1e-4 {
            let want = b - disc.sqrt();
            let cell_diagonal = 3f32.sqrt() / 32.0;
            if let Some(got) = hit {
                prop_assert!(got >= want - dt && got <= want + cell_diagonal, "{} vs {}", got, want);
            } else {
                // Only a grazing ray may see no sample inside: its chord is shorter than a cell.
                prop_assert!(2.0 * disc.sqrt() < cell_diagonal, "missed a chord of {}", 2.0 * disc.sqrt());
            }
        } else if disc < 0.0 {
            prop_assert_eq!(hit, None);
        }
    }
}

/// A 30³ grid (blocks of 4³ cells, the last ones cut by the grid's edge) with 40 occupied
/// cells scattered at random: most blocks are empty, some hold one cell. Also the centres of
/// the occupied cells.
fn scattered_grid(seed: u64) -> (OccupancyGrid, Vec<Vec3>) {
    let r = 30u32;
    let aabb = Aabb { min: Vec3::new(-1.0, -0.5, 0.0), max: Vec3::new(1.0, 1.0, 0.75) };
    let mut rng = Rng::new(seed);
    let mut values = vec![0.0f32; (r * r * r) as usize];
    let mut centres = Vec::new();
    for _ in 0..40 {
        let c = [rng.below(r as u64) as u32, rng.below(r as u64) as u32, rng.below(r as u64) as u32];
        values[(c[0] + r * (c[1] + r * c[2])) as usize] = 1.0;
        centres.push(aabb.min + (Vec3::from(c.map(|v| v as f32)) + 0.5) * aabb.size() / r as f32);
    }
    let config = OccupancyConfig { resolution: r, steps_per_diagonal: 400, ..Default::default() };
    (OccupancyGrid::from_values(aabb, config, values), centres)
}

/// Marching a ray of `scattered_grid(seed)` from `o` at occupied cell `pick` returns exactly
/// the lattice steps whose midpoint's cell is occupied, found step by step. The midpoint's
/// cell is computed the way marching computes it, in grid coordinates `q0 + t·dq`: a point
/// taken through world space can round to the other side of a cell face.
fn march_matches_every_step(seed: u64, o: [f32; 3], pick: usize) -> Result<(), TestCaseError> {
    let (g, centres) = scattered_grid(seed);
    let origin = Vec3::from(o);
    let dir = centres[pick] - origin;
    prop_assume!(dir.length() > 0.1);
    let dir = dir.normalize();
    let mut out = PackedSamples::default();
    g.march(origin, dir, &mut out);
    let (aabb, r) = (g.aabb(), g.config().resolution as f32);
    let to_grid = aabb.size().recip() * r;
    let (q0, dq) = ((origin - aabb.min) * to_grid, dir * to_grid);
    let occupied = |t: f32| {
        let cell = (q0 + t * dq).floor().clamp(Vec3::ZERO, Vec3::splat(r - 1.0));
        g.is_occupied(aabb.min + (cell + 0.5) / to_grid)
    };
    let brute: Vec<f32> = match aabb.intersect(origin, dir) {
        Some((near, far)) => {
            let near = near.max(g.config().near);
            let dt = g.step_size();
            (0..)
                .map(|k| near + (k as f32 + 0.5) * dt)
                .take_while(|&m| m - 0.5 * dt < far)
                .filter(|&m| occupied(m))
                .take(g.config().max_samples as usize)
                .collect()
        }
        None => Vec::new(),
    };
    prop_assert!(!brute.is_empty(), "the ray aims at an occupied cell");
    prop_assert_eq!(out.t, brute);
    Ok(())
}

/// A ray whose first sample lies 1e-5 cells inside an occupied cell's face, where the DDA's
/// summed crossing time came out later than the sample (a proptest case that once failed).
#[test]
fn a_sample_just_inside_a_cell_face_is_kept() {
    march_matches_every_step(1, [0.26364094, 0.99614084, -1.1657212], 8).unwrap();
}

proptest! {
    #![proptest_config(cases(48))]

    /// Crossing whole empty blocks loses no sample: on a grid of scattered single cells,
    /// marching returns exactly the step-by-step sample set, for rays from inside and outside
    /// the box aimed at an occupied cell.
    #[test]
    fn empty_blocks_are_crossed_without_losing_samples(seed in 0u64..8, o in prop::array::uniform3(-1.2f32..1.2), pick in 0usize..40) {
        march_matches_every_step(seed, o, pick)?;
    }
}

/// Marches a whole ray with `march_segment` at `stride`, in segments of 7 samples (segments
/// must concatenate to one march).
fn march_strided(g: &OccupancyGrid, origin: Vec3, dir: Vec3, stride: u32) -> (Vec<f32>, Vec<f32>) {
    let (mut t, mut delta) = (Vec::new(), Vec::new());
    if let Some(span) = g.span(origin, dir) {
        let mut next = 0;
        while next < span.steps {
            next = g.march_segment(origin, dir, span, next..span.steps, 7, stride, &mut t, &mut delta);
        }
    }
    (t, delta)
}

/// Checks that `g`'s march at `stride` tiles exactly the lattice steps of its march at stride 1:
/// each sample a run of up to `stride` consecutive fine steps at the run's middle, `δ` the run's
/// length, no run longer than one step covering a pinned step (`pinned`) and a pinned step's
/// sample its fine one; so `Σ δ` agrees, and a constant density gives the same transmittance.
/// Returns the fine march's sample distances and the strided march's sample count.
fn check_runs(
    g: &OccupancyGrid,
    origin: Vec3,
    dir: Vec3,
    stride: u32,
    pinned: impl Fn(Vec3) -> bool,
) -> Result<(Vec<f32>, usize), TestCaseError> {
    let (fine_t, fine_d) = march_strided(g, origin, dir, 1);
    let (t, d) = march_strided(g, origin, dir, stride);
    let dt = g.step_size();
    let mut f = 0;
    for (&ts, &ds) in t.iter().zip(&d) {
        let run = (ds / dt).round() as usize;
        prop_assert!(run >= 1 && run <= stride as usize && (ds - run as f32 * dt).abs() < 1e-6 * run as f32);
        prop_assert!(f + run <= fine_t.len(), "more steps than the fine march");
        let (first, last) = (fine_t[f], fine_t[f + run - 1]);
        prop_assert!((last - first - (run - 1) as f32 * dt).abs() < 1e-4, "a run skips a step");
        prop_assert!((ts - 0.5 * (first + last)).abs() < 1e-4, "{} is not the run's middle", ts);
        if run > 1 {
            prop_assert!(fine_t[f..f + run].iter().all(|&m| !pinned(origin + m * dir)), "a run covers a pinned step");
        } else if pinned(origin + first * dir) {
            prop_assert_eq!(ts, first);
        }
        f += run;
    }
    prop_assert_eq!(f, fine_t.len());
    let (sum, fine_sum) = (d.iter().sum::<f32>(), fine_d.iter().sum::<f32>());
    prop_assert!((sum - fine_sum).abs() < 1e-4, "Σδ {} vs {}", sum, fine_sum);
    let transmittance = |ds: &[f32]| ds.iter().map(|&x| (-7.0 * x).exp()).product::<f32>();
    prop_assert!((transmittance(&d) - transmittance(&fine_d)).abs() < 1e-4);
    Ok((fine_t, t.len()))
}

proptest! {
    #![proptest_config(cases(48))]

    /// `stride > 1` merges runs of up to `stride` occupied steps outside the pinned cells
    /// (everywhere on a grid without pins) and keeps the samples inside them: the strided
    /// samples tile exactly the lattice steps the fine march samples ([`check_runs`]). Without
    /// pins a stride does merge consecutive occupied steps.
    #[test]
    fn a_stride_outside_the_pinned_region_covers_the_same_steps(
        oy in -0.3f32..0.3, oz in -0.3f32..0.3, dy in -0.2f32..0.2, dz in -0.2f32..0.2,
        x0 in 0u32..32, w in 1u32..12, stride in 2u32..7,
    ) {
        let mut g = sphere_grid();
        let origin = Vec3::new(-0.5, 0.5 + oy, 0.5 + oz);
        let dir = Vec3::new(1.0, dy, dz).normalize();
        let (fine, coarse) = check_runs(&g, origin, dir, stride, |_| false)?;
        // Two consecutive occupied steps merge into one sample.
        let dt = g.step_size();
        let consecutive = fine.windows(2).any(|w| (w[1] - w[0] - dt).abs() < 1e-4);
        prop_assert!(!consecutive || coarse < fine.len(), "no run merged: {} samples", coarse);
        // Pin a slab of cells across the sphere (x in x0..x0 + w).
        let r = 32u32;
        let cells: Vec<u32> = (0..r * r * r).filter(|i| (x0..x0 + w).contains(&(i % r))).collect();
        g.pin(&ChangeRegion::from_cells(unit_box(), r, &cells).unwrap());
        let pinned = |p: Vec3| (x0..x0 + w).contains(&((p.x * r as f32).floor().clamp(0.0, 31.0) as u32));
        check_runs(&g, origin, dir, stride, pinned)?;
    }
}

/// A grid frozen outside its pinned cells (a warm-started residual model's: outside the change
/// region the field is the background, whose grid it holds) refreshes the pinned cells only:
/// an update evaluates exactly those cells, no bit changes, the other cells keep their values
/// and the pinned cells' values follow the field. Unfrozen, the same update re-marks the grid.
#[test]
fn a_grid_frozen_outside_its_pins_refreshes_the_pinned_cells_only() {
    let r = 32u32;
    // A slab of cells x < 3 (x is the fastest index), away from the sphere.
    let slab: Vec<u32> = (0..r * r * r).filter(|i| i % r < 3).collect();
    let in_slab = |p: &Vec3| p.x * (r as f32) < 3.0;
    let mut g = sphere_grid();
    g.pin(&ChangeRegion::from_cells(unit_box(), r, &slab).unwrap());
    let mut unfrozen = g.clone();
    g.freeze_outside_pins();
    assert!(g.is_frozen_outside_pins() && !unfrozen.is_frozen_outside_pins());
    let centres: Vec<Vec3> = (0..r * r * r)
        .map(|i| (Vec3::new((i % r) as f32, (i / r % r) as f32, (i / (r * r)) as f32) + 0.5) / r as f32)
        .collect();
    let bits_before: Vec<bool> = centres.iter().map(|&p| g.is_occupied(p)).collect();
    let values_before = g.values().to_vec();
    // A field dense everywhere, in warm-up (step 0), when an unfrozen grid evaluates and then
    // marks every cell.
    let (mut evaluated, mut outside) = (0, 0);
    g.update(0, &mut Rng::new(3), |p, s| {
        evaluated += p.len();
        outside += p.iter().filter(|p| !in_slab(p)).count();
        s.fill(1e3);
    });
    assert_eq!((evaluated, outside), (slab.len(), 0), "the update evaluated other cells than the pinned ones");
    let bits_after: Vec<bool> = centres.iter().map(|&p| g.is_occupied(p)).collect();
    assert!(bits_after == bits_before, "a frozen grid's bits changed");
    for (i, (&a, &b)) in g.values().iter().zip(&values_before).enumerate() {
        match slab.binary_search(&(i as u32)) {
            Ok(_) => assert_eq!(a, 1e3 * g.step_size(), "pinned cell {i} not refreshed"),
            Err(_) => assert_eq!(a.to_bits(), b.to_bits(), "frozen cell {i} changed"),
        }
    }
    unfrozen.update(0, &mut Rng::new(3), |_, s| s.fill(1e3));
    assert_eq!(unfrozen.occupancy(), 1.0);
}

/// Settling a pinned region: each pinned cell's value rises to the densest σ·δ on a lattice
/// in it, so a sheet thinner than a cell that a refresh's single point missed is found (the
/// lattice's spacing is a quarter cell, so a sheet a quarter cell thick always holds a point);
/// values never drop, and no bit and no cell outside the pins changes.
#[test]
fn settling_the_pinned_cells_finds_a_sheet_the_refreshes_missed() {
    let r = 32u32;
    let cell = 1.0 / r as f32;
    // Pinned: the cells x = 8..10 (a slab of 2 × 32 × 32 cells); in it a sheet of density
    // 50 a quarter cell thick at x in [8.6, 8.85) cells; elsewhere the sphere of sphere_grid.
    let pinned: Vec<u32> = (0..r * r * r).filter(|i| (8..10).contains(&(i % r))).collect();
    let sheet = |p: &Vec3| (8.6 * cell..8.85 * cell).contains(&p.x);
    let field = |points: &[Vec3], sigma: &mut [f32]| {
        sphere(points, sigma);
        for (p, s) in points.iter().zip(sigma) {
            if sheet(p) {
                *s = 50.0;
            }
        }
    };
    let mut g = sphere_grid();
    g.pin(&ChangeRegion::from_cells(unit_box(), r, &pinned).unwrap());
    g.freeze_outside_pins();
    // The refreshes' points: one per pinned cell; most of the sheet's cells stay under-reported.
    g.update(100, &mut Rng::new(5), field);
    let sheet_cells: Vec<u32> = pinned.iter().copied().filter(|i| i % r == 8).collect();
    let want = 50.0 * g.step_size();
    let missed = sheet_cells.iter().filter(|&&i| g.values()[i as usize] < want).count();
    assert!(missed > sheet_cells.len() / 2, "the single points should miss the sheet ({missed} missed)");
    let (values, occupancy) = (g.values().to_vec(), g.occupancy());
    g.settle_pinned(4, field);
    for (i, (&a, &b)) in g.values().iter().zip(&values).enumerate() {
        assert!(a >= b, "cell {i}: settling lowered its value ({b} -> {a})");
        if pinned.binary_search(&(i as u32)).is_err() {
            assert_eq!(a.to_bits(), b.to_bits(), "cell {i} outside the pins changed");
        }
    }
    for &i in &sheet_cells {
        assert_eq!(g.values()[i as usize], want, "sheet cell {i} not found");
    }
    assert_eq!(g.occupancy(), occupancy, "settling changed the bits");
    // Without pins it does nothing.
    let mut plain = sphere_grid();
    let before = plain.values().to_vec();
    plain.settle_pinned(4, |_, s| s.fill(1e3));
    assert_eq!(plain.values(), &before[..]);
}
