//! The cubes and blocks of cubes bound how much closer particles came.

use std::collections::HashMap;

use super::*;

/// `ParticleCubes::closing` for particles found at `found` and now at `x` (started at `found`).
fn closing_of(
    cubes: &mut ParticleCubes,
    found: &[Vec3],
    x: &mut [Vec3],
    limit: f32,
) -> ClosingBounds {
    closing_from(cubes, found, found, x, limit)
}

/// `ParticleCubes::closing` for particles found at `found` that moved from `start` to `x`, with
/// every cube's limit and the far one at `limit`.
fn closing_from(
    cubes: &mut ParticleCubes,
    found: &[Vec3],
    start: &[Vec3],
    x: &mut [Vec3],
    limit: f32,
) -> ClosingBounds {
    cubes.limit.fill(limit);
    (cubes.least, cubes.most) = (limit, limit);
    closing_within(cubes, (found, start), x, limit)
}

/// `ParticleCubes::closing` for particles found at `found` that moved from `start` to `x`, with the
/// cubes' limits as they are and the far limit at `mid_limit`.
fn closing_within(
    cubes: &mut ParticleCubes,
    (found, start): (&[Vec3], &[Vec3]),
    x: &mut [Vec3],
    mid_limit: f32,
) -> ClosingBounds {
    let (mut v, w) = (vec![Vec3::ZERO; x.len()], vec![1.0; x.len()]);
    let state = Vectors {
        x,
        v: &mut v,
        start,
        inv_mass: &w,
        touches: None,
    };
    cubes.closing(&state, found, (mid_limit, mid_limit))
}

#[test]
fn cubes_and_blocks_bound_every_pair_that_was_within_their_reach() {
    // Particles strewn over a cube of 1.5 m, a few in each cube of 20 cm and across more than
    // two blocks; one in fifty displaced by up to 9 cm, more than its cube's mean.
    let h = |k: usize| unit_interval(mix64(k as u64));
    let n = 1500;
    let found: Vec<Vec3> = (0..n)
        .map(|i| 1.5 * Vec3::new(h(3 * i), h(3 * i + 1), h(3 * i + 2)))
        .collect();
    let slot: Vec<u32> = (0..n as u32).collect();
    let mut cubes = ParticleCubes {
        size: 0.2,
        ..ParticleCubes::default()
    };
    cubes.assign(&found, &slot);
    let mut x: Vec<Vec3> = (found.iter().enumerate())
        .map(|(i, p)| {
            let k = 10_000 + 3 * i;
            let d = 0.1 * (Vec3::new(h(k), h(k + 1), h(k + 2)) - 0.5);
            if i % 50 == 0 { *p + d } else { *p }
        })
        .collect();
    // No limit: every bound is worked out.
    let c = closing_of(&mut cubes, &found, &mut x, 0.0);
    assert!(
        c.near <= c.far && c.mid <= c.far,
        "{} {} {}",
        c.near,
        c.mid,
        c.far
    );
    let cell = |p: Vec3| cell_of(p, 1.0 / cubes.size);
    let neighbours = |a: [i32; 3], b: [i32; 3]| (0..3).all(|k| (a[k] - b[k]).abs() <= 1);
    let block = |c: [i32; 3]| c.map(|c| c.div_euclid(BLOCK_CUBES));
    let mut counted = [0; 3];
    for p in 0..n {
        for q in p + 1..n {
            let closer = (x[p] - found[p]).distance(x[q] - found[q]);
            let (a, b) = (cell(found[p]), cell(found[q]));
            let (bound, kind) = if neighbours(a, b) {
                (c.near, 0)
            } else if neighbours(block(a), block(b)) {
                // Plus a side for each cube between them beyond the first.
                let cells = (0..3).map(|k| (a[k] - b[k]).abs()).max().unwrap();
                (c.mid + (cells - 2) as f32 * cubes.size, 1)
            } else {
                (c.far, 2)
            };
            assert!(closer <= bound + 1e-6, "{p}, {q}: {closer} > {bound}");
            counted[kind] += 1;
        }
    }
    assert!(counted.iter().all(|&k| k > 0), "{counted:?}");
}

#[test]
fn cubes_that_are_not_neighbours_bound_their_particles_in_one_block_or_in_two() {
    // Cubes of 0.2 m along x: cells 0, 1 and 2 make block 0, cell 3 begins block 1. The
    // particle in cell 2 moves 5 cm toward the one in cell 0 (same block), then the one in
    // cell 3 toward it (neighbouring blocks); nothing else moves.
    let found: Vec<Vec3> = [0.1, 0.3, 0.5, 0.7]
        .map(|x| Vec3::new(x, 0.1, 0.1))
        .to_vec();
    let slot: Vec<u32> = (0..4).collect();
    for (moved, by) in [(2, -0.05), (3, -0.05), (0, 0.05)] {
        let mut cubes = ParticleCubes {
            size: 0.2,
            ..ParticleCubes::default()
        };
        cubes.assign(&found, &slot);
        let mut x = found.clone();
        x[moved].x += by;
        let c = closing_of(&mut cubes, &found, &mut x, 0.0);
        assert!(c.mid >= 0.05 - 1e-6, "particle {moved}: mid {}", c.mid);
        assert!(
            c.mid <= c.far + 1e-6,
            "particle {moved}: {} {}",
            c.mid,
            c.far
        );
    }
}

#[test]
fn cubes_farther_apart_may_come_closer_by_a_side_for_each_cube_between() {
    // Cubes of 0.2 m along x: particles in cells 0 and 3 (neighbouring blocks), 0.6 m apart,
    // the second moved 0.25 m toward the first: against the limit of cubes two apart, that
    // counts as 0.05 m.
    let found: Vec<Vec3> = [0.1, 0.7].map(|x| Vec3::new(x, 0.1, 0.1)).to_vec();
    let mut cubes = ParticleCubes {
        size: 0.2,
        ..ParticleCubes::default()
    };
    cubes.assign(&found, &[0, 1]);
    let mut x = found.clone();
    x[1].x -= 0.25;
    let c = closing_of(&mut cubes, &found, &mut x, 0.0);
    assert!((c.mid - 0.05).abs() < 1e-6, "mid {}", c.mid);
    assert!(c.far >= 0.25 - 1e-6, "far {}", c.far);
}

#[test]
fn a_cube_takes_the_least_limit_of_its_particles() {
    // Cubes of 0.2 m along x: particles 0, 2 and 4 in cell 0, 1 and 3 in cell 1, stored in
    // reverse; each particle's limit is its index plus one.
    let found: Vec<Vec3> = [0.05, 0.25, 0.1, 0.3, 0.15]
        .map(|x| Vec3::new(x, 0.1, 0.1))
        .to_vec();
    let slot: Vec<u32> = (0..5).rev().collect();
    let mut cubes = ParticleCubes {
        size: 0.2,
        ..ParticleCubes::default()
    };
    cubes.assign(&found, &slot);
    cubes.limit(&slot, |p| p as f32 + 1.0);
    let cube = |p: usize| cubes.of[slot[p] as usize] as usize;
    assert_eq!(cubes.limit[cube(0)], 1.0);
    assert_eq!(cubes.limit[cube(1)], 2.0);
    assert_eq!((cubes.least, cubes.most), (1.0, 2.0));
}

#[test]
fn neighbouring_cubes_may_come_closer_by_the_larger_of_their_limits() {
    // Cubes of 0.2 m along x, one particle in each of cells 0, 1 and 2 (one block); the
    // middle one moves 3 cm toward the last.
    let found: Vec<Vec3> = [0.1, 0.3, 0.5].map(|x| Vec3::new(x, 0.1, 0.1)).to_vec();
    for (limits, slack) in [([0.01, 0.05, 0.01], 0.01), ([0.01, 0.01, 0.05], -0.02)] {
        let mut cubes = ParticleCubes {
            size: 0.2,
            ..ParticleCubes::default()
        };
        cubes.assign(&found, &[0, 1, 2]);
        cubes.limit = limits.to_vec();
        (cubes.least, cubes.most) = (0.01, 0.05);
        let mut x = found.clone();
        x[1].x += 0.03;
        let c = closing_within(&mut cubes, (&found, &found), &mut x, 1.0);
        assert!((c.near - 0.03).abs() < 1e-6, "{limits:?}: near {}", c.near);
        assert!(
            (c.slack - slack).abs() < 1e-6,
            "{limits:?}: slack {}",
            c.slack
        );
    }
}

#[test]
fn neighbouring_cells_are_paired_once_whether_looked_up_densely_or_hashed() {
    // A compact cluster (looked up in a dense array) and the same cells with one far away
    // (the hash map), against every pair of cells tried.
    let h = |k: usize| unit_interval(mix64(k as u64));
    let cluster: Vec<[i32; 3]> = (0..300)
        .map(|i| [0, 1, 2].map(|k| (8.0 * h(3 * i + k)) as i32 - 3))
        .collect();
    // One scratch for all: a dense lookup after another, larger one finds no stale cells.
    let mut scratch = Vec::new();
    let far = Some([1 << 20, -(1 << 20), 7]);
    for (shift, far) in [(0, None), (2, None), (0, far), (-1, None)] {
        let mut index = HashMap::default();
        let shifted = (cluster.iter()).map(|c| [(c[0] + shift).min(3), c[1] + shift, c[2]]);
        for c in shifted.chain(far) {
            let next = index.len() as u32;
            index.entry(c).or_insert(next);
        }
        let mut pairs = Vec::new();
        neighbouring_cells(&index, &mut pairs, &mut scratch);
        let mut expected = Vec::new();
        for (a, &i) in &index {
            for (b, &j) in &index {
                if i <= j && (0..3).all(|k| (a[k] - b[k]).abs() <= 1) {
                    expected.push((i, j));
                }
            }
        }
        let mut found = pairs.clone();
        found.sort_unstable();
        expected.sort_unstable();
        assert_eq!(found, expected, "far: {far:?}");
    }
    let mut pairs = vec![(0, 0)];
    neighbouring_cells(&HashMap::default(), &mut pairs, &mut Vec::new());
    assert!(pairs.is_empty());
}

#[test]
fn edges_close_by_their_ends_relative_displacement_and_infinitely_when_not_finite() {
    let mut cubes = ParticleCubes {
        moved: vec![
            Vec3A::ZERO,
            Vec3A::X,
            Vec3A::new(0.0, 0.5, 0.0),
            Vec3A::ZERO,
        ],
        ..ParticleCubes::default()
    };
    let edges = [[0, 1], [1, 2], [2, 3]];
    let closing = cubes.edges_closing(&edges);
    assert!((closing - 1.25f32.sqrt()).abs() < 1e-6, "{closing}");
    // The edge that turned most, wherever it is in a list of any length.
    let one_among = |n: usize, k: usize, edge: [u32; 2], rest: [u32; 2]| {
        let mut edges = vec![rest; n];
        edges[k] = edge;
        edges
    };
    for n in 1..10 {
        for k in 0..n {
            let closing = cubes.edges_closing(&one_among(n, k, [1, 2], [0, 3]));
            assert!(
                (closing - 1.25f32.sqrt()).abs() < 1e-6,
                "{n}, {k}: {closing}"
            );
        }
    }
    for bad in [f32::NAN, f32::INFINITY, 1e30] {
        cubes.moved[3] = Vec3A::splat(bad);
        assert_eq!(cubes.edges_closing(&edges), f32::INFINITY, "{bad}");
        for n in 1..10 {
            for k in 0..n {
                let edges = one_among(n, k, [2, 3], [0, 1]);
                assert_eq!(cubes.edges_closing(&edges), f32::INFINITY, "{bad} {n} {k}");
            }
        }
    }
}

#[test]
fn a_triangle_turning_beyond_the_cull_is_searched_again_though_the_cubes_allow_it() {
    // A flat 12×12 grid (3 cm): its patches are culled, and elements it leaves uncovered are
    // far apart, so the cubes allow more than twice the reach; a vertex lifted by more than
    // that turns its triangles further than the cull allowed for.
    let model = ClothModel::grid(&GridSpec::new(12, 12, 0.03)).unwrap();
    let rest = &model.rest_positions;
    let mut c = SelfContacts::new(&model.triangles, rest, 0.005, 0.0).unwrap();
    let w = vec![1.0; rest.len()];
    let mut x = rest.clone();
    let mut v = vec![Vec3::ZERO; x.len()];
    resolve_within(&mut c, 1.0, rest, &mut x, &mut v, &w);
    assert_eq!(c.searches(), 1);
    let lift = 1.4 * c.reach;
    assert!(
        c.cubes.least > 2.0 * lift,
        "least limit {}, reach {}",
        c.cubes.least,
        c.reach
    );
    let [a, b, d] = [0, 1, 12].map(|i| rest[i]);
    let normal = (b - a).cross(d - a).normalize();
    let start = x.clone();
    x[5 * 12 + 5] += normal * 2.0 * lift;
    resolve_within(&mut c, 1.0, &start, &mut x, &mut v, &w);
    assert_eq!(c.searches(), 2, "the turned triangles are searched again");
}

#[test]
fn the_cubes_bound_how_much_closer_particles_came() {
    // A row of particles 0.1 m apart along x, in cubes of 0.25 m.
    let found: Vec<Vec3> = (0..20)
        .map(|i| Vec3::new(0.1 * i as f32, 0.0, 0.0))
        .collect();
    let slot: Vec<u32> = (0..20).collect();
    let fresh = || {
        let mut r = ParticleCubes {
            size: 0.25,
            ..ParticleCubes::default()
        };
        r.assign(&found, &slot);
        r
    };
    // A rigid translation, however large, brings nothing closer.
    let mut x: Vec<Vec3> = found.iter().map(|p| *p + Vec3::splat(3.0)).collect();
    let c = closing_of(&mut fresh(), &found, &mut x, 0.01);
    assert!(c.near < 1e-5 && c.far < 1e-5, "{} {}", c.near, c.far);
    assert!((c.mean.1 - Vec3::splat(3.0)).length() < 1e-5);
    // One particle moved 5 cm toward its neighbour: neighbouring cubes see it, whether or not
    // the pairs are looked at, and wherever it is stored among its cube's particles (5, 6 and
    // 7 share one).
    for (limit, p) in [0.0, 1.0].into_iter().flat_map(|l| [(l, 5), (l, 7)]) {
        let mut x = found.clone();
        x[p].x -= 0.05;
        let c = closing_of(&mut fresh(), &found, &mut x, limit);
        assert!(
            c.near >= 0.05 - 1e-6 && c.far >= c.near,
            "{p}: {} {}",
            c.near,
            c.far
        );
    }
    // Particles moving on as they moved over the first substep checked: every cube's
    // reference follows them, so the next check sees nothing come closer.
    let mut cubes = fresh();
    let step = Vec3::new(0.03, -0.01, 0.02);
    let start: Vec<Vec3> = found.iter().map(|p| *p + step).collect();
    let mut x = start.clone();
    closing_of(&mut cubes, &found, &mut x, 0.01);
    let mut x: Vec<Vec3> = start.iter().map(|p| *p + step).collect();
    let c = closing_from(&mut cubes, &found, &start, &mut x, 1.0);
    assert!(c.near < 1e-5, "{}", c.near);
    // The same after three substeps without a check: the references are extrapolated over
    // all four, and the next one from the motion over those four.
    let mut cubes = fresh();
    let at = |k: f32| -> Vec<Vec3> { found.iter().map(|p| *p + step * k).collect() };
    closing_from(&mut cubes, &found, &found, &mut at(1.0), 0.01);
    for _ in 0..3 {
        cubes.skip();
    }
    for k in [5.0, 6.0] {
        let c = closing_from(&mut cubes, &found, &at(k - 1.0), &mut at(k), 1.0);
        assert!(c.near < 1e-5, "substep {k}: {}", c.near);
    }
    // A position that is not a number makes both bounds infinite.
    let mut x = found.clone();
    x[3] = Vec3::NAN;
    let c = closing_of(&mut fresh(), &found, &mut x, 0.01);
    assert!(c.near == f32::INFINITY && c.far == f32::INFINITY);
}
