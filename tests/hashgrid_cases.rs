//! Hand-computed hash-grid cases (values worked out independently, see the comments).

use residual_nerf::encoding::hashgrid::unpack_entry;
use residual_nerf::encoding::{HashGrid, HashGridConfig, HashGridParams};
use residual_nerf::rng::Rng;
use residual_nerf::simd::Isa;

/// b = exp((ln 2048 − ln 16)/15) ≈ 1.3819; N_l = ⌊16 · b^l⌋; a level is dense while
/// (N_l + 1)³ ≤ T: for T = 2^19 = 524288, 59³ = 205379 is, 81³ = 531441 is not (5 dense
/// levels); for the default T = 2^17 = 131072, 43³ = 79507 is, 59³ is not (4 dense levels).
#[test]
fn default_levels_match_hand_computed() {
    assert_eq!(HashGridConfig::default().log2_table_size, 17);
    for (log2t, dense_levels) in [(19, 5), (17, 4)] {
        let grid = HashGrid::new(HashGridConfig { log2_table_size: log2t, ..Default::default() });
        let res: Vec<u32> = grid.levels().iter().map(|l| l.resolution).collect();
        assert_eq!(res, [16, 22, 30, 42, 58, 80, 111, 153, 212, 294, 406, 561, 776, 1072, 1482, 2048]);
        let mut offset = 0;
        for (l, level) in grid.levels().iter().enumerate() {
            assert_eq!(level.dense, l < dense_levels, "log2T {log2t} level {l}");
            let want = if level.dense { (level.resolution as usize + 1).pow(3) } else { 1 << log2t };
            assert_eq!(level.size, want, "log2T {log2t} level {l}");
            assert_eq!(level.offset, offset, "log2T {log2t} level {l}");
            offset += level.size;
        }
        assert_eq!(grid.entries(), offset);
    }
    let grid = HashGrid::new(HashGridConfig::default());
    assert_eq!((grid.features(), grid.output_width()), (32, 32));
    let twelve = HashGrid::new(HashGridConfig { levels: 12, ..Default::default() });
    assert_eq!((twelve.features(), twelve.output_width()), (24, 32)); // padded to the MLP tile
}

/// Dense: i = x + y(N+1) + z(N+1)²; N = 16: (1,2,3) → 1 + 34 + 867 = 902.
/// Hashed, T = 4096: (x ⊕ y·2654435761 ⊕ z·805459861) mod 4096 (32-bit products):
/// (1,2,3) → 1500, (100,200,300) → 176, (7,0,0) → 7, (0,1,0) → 2481, (0,0,1) → 1941.
#[test]
fn dense_and_hashed_indices_match_hand_computed() {
    let grid =
        HashGrid::new(HashGridConfig { levels: 2, log2_table_size: 12, base_resolution: 15, finest_resolution: 100 });
    let (dense, hashed) = (grid.levels()[0], grid.levels()[1]);
    assert!(dense.dense && dense.resolution == 15 && dense.size == 4096); // 16³ = 4096 ≤ T
    assert!(!hashed.dense && hashed.size == 4096);
    let d16 =
        HashGrid::new(HashGridConfig { levels: 1, log2_table_size: 14, base_resolution: 16, finest_resolution: 16 })
            .levels()[0];
    assert!(d16.dense);
    assert_eq!(d16.index(1, 2, 3), 902);
    assert_eq!(hashed.index(1, 2, 3), 1500);
    assert_eq!(hashed.index(100, 200, 300), 176);
    assert_eq!(hashed.index(7, 0, 0), 7);
    assert_eq!(hashed.index(0, 1, 0), 2481);
    assert_eq!(hashed.index(0, 0, 1), 1941);
}

/// A point on a grid vertex returns that vertex's features, on dense and hashed levels, at
/// every CPU level — including vertices on the far faces (x = 1).
#[test]
fn vertex_returns_its_features() {
    // Resolutions 4, 16, 64: powers of two, so i/N is exact. T = 8192: 5³ and 17³ = 4913
    // fit (dense), 65³ does not (hashed).
    let grid =
        HashGrid::new(HashGridConfig { levels: 3, log2_table_size: 13, base_resolution: 4, finest_resolution: 64 });
    assert_eq!(
        grid.levels().iter().map(|l| (l.resolution, l.dense)).collect::<Vec<_>>(),
        [(4, true), (16, true), (64, false)]
    );
    let mut rng = Rng::new(3);
    let params = HashGridParams::from_master((0..grid.n_params()).map(|_| rng.uniform(-1.0, 1.0)).collect());
    for isa in Isa::all() {
        for (l, level) in grid.levels().iter().enumerate() {
            let r = level.resolution;
            for v in [[0, 0, 0], [1, 2, 3], [r, r, r], [r, 0, r - 1], [r / 2, r, 1]] {
                let p = v.map(|c| c as f32 / r as f32);
                let mut out = vec![0.0; grid.output_width()];
                grid.forward(isa, &params.table, &[p], &mut out);
                let want = unpack_entry(params.table[level.offset + level.index(v[0], v[1], v[2]) as usize]);
                assert_eq!([out[2 * l], out[2 * l + 1]], want, "{isa} level {l} vertex {v:?}");
            }
        }
    }
}

/// Half-way between two vertices along x gives their mean; outside the cube, or NaN, zeros.
#[test]
fn midpoints_and_outside_points() {
    let grid =
        HashGrid::new(HashGridConfig { levels: 1, log2_table_size: 10, base_resolution: 4, finest_resolution: 4 });
    let level = grid.levels()[0];
    let mut rng = Rng::new(5);
    let params = HashGridParams::from_master((0..grid.n_params()).map(|_| rng.uniform(-1.0, 1.0)).collect());
    for isa in Isa::all() {
        let mut out = vec![0.0; grid.output_width()];
        grid.forward(isa, &params.table, &[[0.375, 0.25, 0.5]], &mut out); // x between vertices 1 and 2
        let a = unpack_entry(params.table[level.index(1, 1, 2) as usize]);
        let b = unpack_entry(params.table[level.index(2, 1, 2) as usize]);
        for f in 0..2 {
            assert!((out[f] - 0.5 * (a[f] + b[f])).abs() < 1e-6, "{isa} feature {f}");
        }
        for p in [[-0.01, 0.5, 0.5], [0.5, 1.01, 0.5], [0.5, 0.5, f32::NAN], [f32::INFINITY, 0.0, 0.0]] {
            let mut out = vec![9.0; grid.output_width()];
            grid.forward(isa, &params.table, &[p], &mut out);
            assert!(out.iter().all(|&v| v == 0.0), "{isa} {p:?}: {out:?}");
        }
    }
}
