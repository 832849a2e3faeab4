//! Patches: their cones cull the search, and their limits hold the cubes.

use super::*;

#[test]
fn the_elements_of_patches_searched_together_lie_in_tight_cubes() {
    // A 16×16 grid (3 cm) with its last 9 cm folded back over a 1 cm radius: the layers are
    // searched together, the flat part beyond them is not.
    let model = ClothModel::grid(&GridSpec::new(16, 16, 0.03)).unwrap();
    let rest = &model.rest_positions;
    let mut c = SelfContacts::new(&model.triangles, rest, 0.005, 0.0).unwrap();
    let mut x = folded(rest, 0.12, 0.01);
    let (start, w) = (x.clone(), vec![1.0; x.len()]);
    let mut v = vec![Vec3::ZERO; x.len()];
    resolve_within(&mut c, 0.01, &start, &mut x, &mut v, &w);
    assert!(!c.patches.pairs().is_empty());
    let tight =
        |p: u32| c.cubes.limit[c.cubes.of[c.slot[p as usize] as usize] as usize] <= 2.0 * c.reach;
    for &patch in c.patches.pairs().iter().flat_map(|(a, b)| [a, b]) {
        for &t in c.patch_triangles.of(patch) {
            assert!(c.tris[t as usize].iter().all(|&p| tight(p)), "{t}");
        }
    }
    assert!(
        (0..x.len() as u32).any(|p| !tight(p)),
        "the flat part is not tight"
    );
    // Every other cube is held to what the patches with a corner in it allow.
    for (t, tri) in c.tris.iter().enumerate() {
        let clear = c.patches.clear_of(c.patches.of_triangle(t as u32));
        for &p in tri {
            let limit = c.cubes.limit[c.cubes.of[c.slot[p as usize] as usize] as usize];
            assert!(
                limit <= (clear - c.thickness).max(2.0 * c.reach),
                "{t}: {limit}"
            );
        }
    }
}

#[test]
fn a_vertex_takes_the_least_value_of_the_patches_of_its_triangles() {
    // A 20×20 grid: its patches meet along their borders, where a vertex is a corner of
    // triangles of two to four patches.
    let model = ClothModel::grid(&GridSpec::new(20, 20, 0.03)).unwrap();
    let c = SelfContacts::new(&model.triangles, &model.rest_positions, 0.005, 0.0).unwrap();
    let h = |k: usize| unit_interval(mix64(k as u64));
    let value: Vec<f32> = (0..c.patches.len()).map(h).collect();
    let mut shared = 0;
    for p in 0..model.rest_positions.len() as u32 {
        let of: Vec<u32> = (c.tris.iter().enumerate())
            .filter(|(_, tri)| tri.contains(&p))
            .map(|(t, _)| c.patches.of_triangle(t as u32))
            .collect();
        let least = of.iter().map(|&a| value[a as usize]).reduce(f32::min);
        assert_eq!(c.patches.least_around(p, &value), least, "vertex {p}");
        shared += usize::from(of.iter().any(|&a| a != of[0]));
    }
    assert!(shared > 20, "{shared} vertices on patch borders");
}

#[test]
fn elements_left_uncovered_are_at_least_the_clear_distance_apart() {
    // A 14×14 grid (3 cm) rippled along x: its patches' cones are within a wide cull, but
    // patches farther along the mesh are neither culled nor searched together.
    let model = ClothModel::grid(&GridSpec::new(14, 14, 0.03)).unwrap();
    let mut c = SelfContacts::new(&model.triangles, &model.rest_positions, 0.005, 0.0).unwrap();
    let x: Vec<Vec3> = (model.rest_positions.iter())
        .map(|p| *p + Vec3::new(0.0, 0.0, 0.03 * (p.x / 0.06).sin()))
        .collect();
    let margin = 0.012;
    c.find_candidates(&x, margin, usize::MAX, Some((move |_| 1.2, 0.2)));
    let patches = &c.patches;
    let clear = (0..patches.len() as u32)
        .map(|p| patches.clear_of(p))
        .fold(f32::INFINITY, f32::min);
    assert!(clear > margin, "{clear}");
    let covered =
        |a: u32, b: u32| patches.culled(a, b) || patches.pairs().contains(&(a.min(b), a.max(b)));
    // Each at least either patch's own clear distance apart, which is more than the least
    // for some.
    let clear_of = |a: u32, b: u32| patches.clear_of(a).max(patches.clear_of(b));
    let widest = (0..patches.len() as u32)
        .map(|p| patches.clear_of(p))
        .fold(0.0, f32::max);
    assert!(widest > clear + 0.01, "{widest} {clear}");
    let mut uncovered = 0;
    for (p, &at) in x.iter().enumerate() {
        for (t, tri) in c.tris.iter().enumerate() {
            let (a, b) = (patches.of_vertex(p as u32), patches.of_triangle(t as u32));
            if tri.contains(&(p as u32)) || covered(a, b) {
                continue;
            }
            let [ta, tb, tc] = tri.map(|i| x[i as usize]);
            let gap = point_triangle_distance(at, ta, tb, tc);
            let clear = clear_of(a, b);
            assert!(gap >= clear - 1e-6, "{p} and {t}: {gap} < {clear}");
            uncovered += 1;
        }
    }
    for (e, &[a, b]) in c.edges.iter().enumerate() {
        for (f, &[p, q]) in c.edges.iter().enumerate() {
            let (ea, fb) = (c.edge_patch[e], c.edge_patch[f]);
            if [a, b].iter().any(|i| [p, q].contains(i)) || covered(ea, fb) {
                continue;
            }
            let [a, b, p, q] = [a, b, p, q].map(|i| x[i as usize]);
            let (s, t) = closest_on_segments(a, b, p, q);
            let gap = a.lerp(b, s).distance(p.lerp(q, t));
            let clear = clear_of(ea, fb);
            assert!(gap >= clear - 1e-6, "edges {e} and {f}: {gap} < {clear}");
        }
    }
    assert!(uncovered > 0);
}

#[test]
fn neighbours_closer_than_the_thickness_at_rest_are_exempt() {
    let coarse = ClothModel::grid(&GridSpec::new(8, 8, 0.03)).unwrap();
    let c = SelfContacts::new(&coarse.triangles, &coarse.rest_positions, 0.005, 0.0).unwrap();
    assert_eq!(c.exempt_count(), 0);
    // At 4.5 mm spacing a 5 mm thickness (just within the mean edge length, the most a cloth
    // takes) reaches the next ring of triangles and edges.
    let fine = ClothModel::grid(&GridSpec::new(8, 8, 0.0045)).unwrap();
    assert!(0.005 <= crate::sim::MAX_THICKNESS_PER_EDGE * fine.mean_edge_length());
    let mut c = SelfContacts::new(&fine.triangles, &fine.rest_positions, 0.005, 0.0).unwrap();
    assert!(c.exempt_count() > 100, "{}", c.exempt_count());
    // So the flat cloth at rest has no candidate pairs and nothing moves.
    let start = fine.rest_positions.clone();
    let (mut x, mut v) = (start.clone(), vec![Vec3::ZERO; start.len()]);
    resolve(&mut c, &start, &mut x, &mut v, &vec![1.0; start.len()]);
    assert_eq!(c.candidate_count(), (0, 0));
    assert_eq!(x, start);
}

/// The most the normal of the triangle with a right angle at the origin and legs `(u, 0, 0)`
/// and `(0, 0, w)` turns as its right-angle vertex moves by `d` any way.
fn most_turn(u: f32, w: f32, d: f32) -> f32 {
    let [a, b] = [Vec3::new(u, 0.0, 0.0), Vec3::new(0.0, 0.0, w)];
    let normal = |p: Vec3| (b - a).cross(p - a).normalize();
    let mut most = 0.0f32;
    for i in 0..=200 {
        let polar = std::f32::consts::PI * i as f32 / 200.0;
        for j in 0..40 {
            let azimuth = std::f32::consts::TAU * j as f32 / 40.0;
            let dir = Vec3::new(
                polar.sin() * azimuth.cos(),
                polar.cos(),
                polar.sin() * azimuth.sin(),
            );
            most = most.max(normal(Vec3::ZERO).angle_between(normal(d * dir)));
        }
    }
    most
}

#[test]
fn a_culled_patch_cannot_fold_while_its_vertices_stay_within_the_reach() {
    // A thin cloth, so that the reach is most of a triangle's altitude.
    let e = 1.0 / 63.0;
    let grid = ClothModel::grid(&GridSpec::new(8, 8, e)).unwrap();
    let mut c = SelfContacts::new(&grid.triangles, &grid.rest_positions, 0.001, 0.0).unwrap();
    c.reach = c.reach_cap;
    let flat = cull_angle(c.reach, c.altitude);
    assert!(flat > 0.0, "the thin cloth culls at {flat} rad");
    // A degenerate triangle (no altitude, with or without a reach) culls nothing.
    for reach in [0.0, c.reach] {
        assert!(cull_angle(reach, 0.0) < 0.0, "degenerate, reach {reach}");
    }
    // A triangle of the grid whose right-angle vertex moves by twice the reach relative to
    // the other two, every way: its normal may not turn past the right angle that the
    // culled patches' cones leave.
    let most = most_turn(e, e, 2.0 * c.reach);
    assert!(
        flat + most < std::f32::consts::FRAC_PI_2,
        "cones of {flat} rad culled, a triangle turned {most} rad"
    );
    // The same cloth compressed to 0.8 of its width at the search: thinner triangles turn
    // further, and the search culls less.
    let x: Vec<Vec3> = grid
        .rest_positions
        .iter()
        .map(|p| p * Vec3::new(0.8, 1.0, 1.0))
        .collect();
    let margin = c.thickness + 2.0 * c.reach;
    c.find_candidates(&x, margin, usize::MAX, Some((c.cull(), 0.0)));
    let flat = c.patches.flat();
    let most = most_turn(0.8 * e, e, 2.0 * c.reach);
    assert!(
        flat + most < std::f32::consts::FRAC_PI_2,
        "compressed: cones of {flat} rad culled, a triangle turned {most} rad"
    );
}
