//! The narrow phase and response: pairs kept apart on their side, deferred while at rest.

use super::*;

/// Two triangles: a fixed one in y = 0 and a free one above it, whose first vertex dips to
/// `dip` below the first triangle's interior over the substep.
fn falling_vertex(dip: f32) -> (SelfContacts, Vec<Vec3>, Vec<Vec3>) {
    let start = vec![
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 0.0, 1.0),
        Vec3::new(0.25, 0.02, 0.25),
        Vec3::new(2.0, 0.5, 2.0),
        Vec3::new(3.0, 0.5, 2.0),
    ];
    let mut end = start.clone();
    end[3].y = -dip;
    let contacts = SelfContacts::new(&[0, 1, 2, 3, 4, 5], &start, 0.005, 0.0).unwrap();
    (contacts, start, end)
}

#[test]
fn a_resting_layer_is_resolved_every_few_substeps_and_sinks_at_most_the_slack() {
    // A free sheet lying the thickness above a fixed one, pulled down by gravity: between
    // resolutions it falls, and each resolution puts it back.
    // The top sheet's vertices lie over the centres of the bottom sheet's cells.
    let thickness = 0.005;
    let bottom = ClothModel::grid(&GridSpec::new(4, 4, 0.1)).unwrap();
    let top = ClothModel::grid(&GridSpec::new(3, 3, 0.1)).unwrap();
    let mut tris = bottom.triangles.clone();
    tris.extend(top.triangles.iter().map(|&i| i + 16));
    let rest: Vec<Vec3> = (bottom.rest_positions.iter())
        .chain(&top.rest_positions)
        .copied()
        .collect();
    let mut rest_apart = rest.clone();
    rest_apart[16..].iter_mut().for_each(|p| p.y = 1.0);
    let mut contacts = SelfContacts::new(&tris, &rest_apart, thickness, 0.0).unwrap();
    let mut x = rest.clone();
    x[16..].iter_mut().for_each(|p| p.y = thickness);
    let w: Vec<f32> = (0..x.len())
        .map(|i| if i < 16 { 0.0 } else { 1.0 })
        .collect();
    let mut v = vec![Vec3::ZERO; x.len()];
    // Three times gravity, as a crease's springs pull a layer down.
    let (h, g) = (1.0 / 1200.0, Vec3::new(0.0, -30.0, 0.0));
    let (frames, substeps) = (10, 20);
    for _ in 0..frames {
        contacts.begin_step(0.002);
        for sub in 0..substeps {
            let start = x.clone();
            for (x, v) in x.iter_mut().zip(&mut v).skip(16) {
                *v += g * h;
                *x += *v * h;
            }
            let last = sub + 1 == substeps;
            substep(&mut contacts, (h, last), &start, (&mut x, &mut v), &w);
            let lowest = x[16..].iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
            assert!(
                lowest >= thickness * (1.0 - DEFER_CLOSING) - 1e-6,
                "sank to {lowest} m, past the slack"
            );
            if last {
                assert!(
                    lowest >= thickness - 1e-6,
                    "a step ended with the layer {lowest} m apart"
                );
            }
        }
    }
    let (resolved, all) = (contacts.resolutions(), frames * substeps);
    assert!(
        resolved > frames as u64 && 4 * resolved <= all as u64,
        "{resolved} resolutions in {all} substeps"
    );
}

#[test]
fn a_vertex_that_passed_through_a_triangle_is_put_back_on_its_side() {
    for dip in [0.001, 0.004, 0.01] {
        let (mut c, start, mut x) = falling_vertex(dip);
        let mut v = vec![Vec3::ZERO; 6];
        v[3] = Vec3::new(0.1, -2.0, 0.0);
        let w = [0.0, 0.0, 0.0, 1.0, 1.0, 1.0];
        resolve(&mut c, &start, &mut x, &mut v, &w);
        assert!((x[3].y - 0.005).abs() < 1e-6, "dip {dip}: {}", x[3]);
        // The approach is removed, the sliding slowed by nothing (frictionless).
        assert!(
            v[3].y.abs() < 1e-6 && (v[3].x - 0.1).abs() < 1e-6,
            "{}",
            v[3]
        );
    }
}

#[test]
fn a_part_that_comes_from_far_away_is_found_and_kept_apart() {
    // A fixed triangle, and another 2.8 m away that slides over it as a whole, 7 mm at a
    // time, then dips through it: no two neighbouring cubes move relative to each other,
    // so only the far bound sees them come together.
    let mut x = vec![
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(0.1, 0.0, 0.0),
        Vec3::new(0.0, 0.0, 0.1),
        Vec3::new(2.02, 0.02, 2.02),
        Vec3::new(2.3, 0.02, 2.0),
        Vec3::new(2.0, 0.02, 2.3),
    ];
    let mut c = SelfContacts::new(&[0, 1, 2, 3, 4, 5], &x, 0.005, 0.0).unwrap();
    let w = [0.0, 0.0, 0.0, 1.0, 1.0, 1.0];
    let mut v = vec![Vec3::ZERO; 6];
    let mut slide = |c: &mut SelfContacts, x: &mut Vec<Vec3>, by: Vec3| {
        let start = x.clone();
        for p in &mut x[3..] {
            *p += by;
        }
        resolve_within(c, 0.01, &start, x, &mut v, &w);
    };
    for _ in 0..400 {
        slide(&mut c, &mut x, Vec3::new(-0.005, 0.0, -0.005));
    }
    assert!(c.searches() > 1, "{} searches", c.searches());
    // Put back on its side, at least the thickness away.
    slide(&mut c, &mut x, Vec3::new(0.0, -0.03, 0.0));
    assert!(x[3].y > 0.005 - 1e-5, "{}", x[3]);
}

#[test]
fn a_push_within_a_pass_counts_toward_the_later_pairs() {
    // A free vertex in a wedge between two fixed triangles, 1 mm above the floor one and
    // 7 mm from the tilted one (thickness 5 mm). Nothing moves, so nothing has drifted;
    // pushing the vertex up out of the floor brings it within the thickness of the tilted
    // one, which must then be tested in the same pass. The vertex is in no triangle.
    let (p0, n2) = (Vec3::new(0.25, 0.001, 0.25), Vec3::new(-0.6, -0.8, 0.0));
    let q = p0 - 0.007 * n2;
    let (t1, t2) = (Vec3::new(0.8, -0.6, 0.0), Vec3::Z);
    let start = vec![
        Vec3::new(-1.0, 0.0, -1.0),
        Vec3::new(-1.0, 0.0, 2.0),
        Vec3::new(2.0, 0.0, -1.0),
        q + 0.004 * t1 - t2,
        q + 0.004 * t1 + t2,
        q - t1,
        p0,
    ];
    // At rest the vertex is far away (so that neither pair is exempt).
    let mut rest = start.clone();
    rest[6].y = 1.0;
    let mut c = SelfContacts::new(&[0, 1, 2, 3, 4, 5], &rest, 0.005, 0.0).unwrap();
    let (mut x, mut v) = (start.clone(), vec![Vec3::ZERO; start.len()]);
    let w = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];
    // A reach wide enough for the tilted triangle to be a candidate.
    resolve_within(&mut c, 0.01, &start, &mut x, &mut v, &w);
    let p = x[6];
    let floor = p.y;
    let tilted = (p - q).dot(n2);
    assert!(floor > 0.0044 && tilted > 0.0044, "{floor} {tilted}");
}

#[test]
fn a_pair_of_free_particles_keeps_its_momentum() {
    let (c, start, mut x) = falling_vertex(0.003);
    let mut v: Vec<Vec3> = (0..6)
        .map(|i| Vec3::new(0.3 * i as f32, -1.0, 0.1))
        .collect();
    let w = [2.0, 1.0, 0.5, 1.0, 1.0, 1.0];
    let momentum = |v: &[Vec3]| -> Vec3 { v.iter().zip(&w).map(|(v, w)| *v / *w).sum() };
    let (p0, v0) = (momentum(&v), v.clone());
    let centre = |x: &[Vec3]| -> Vec3 { x.iter().zip(&w).map(|(x, w)| *x / *w).sum() };
    let c0 = centre(&x);
    let mut c = SelfContacts { friction: 0.5, ..c };
    resolve(&mut c, &start, &mut x, &mut v, &w);
    assert!(v != v0, "the contact acted");
    assert!(
        (momentum(&v) - p0).length() < 1e-5,
        "{} vs {p0}",
        momentum(&v)
    );
    assert!((centre(&x) - c0).length() < 1e-5);
}

#[test]
fn edges_that_passed_through_each_other_are_put_back_apart() {
    // Edge 0–1 along x at y = 0 (fixed), edge 3–4 along z, which moves from above it to
    // below it over the substep; their triangles' other vertices are far away.
    let start = vec![
        Vec3::new(-1.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 0.0, -3.0),
        Vec3::new(0.0, 0.01, -1.0),
        Vec3::new(0.0, 0.01, 1.0),
        Vec3::new(-3.0, 0.01, 3.0),
    ];
    let mut x = start.clone();
    x[3].y = -0.01;
    x[4].y = -0.01;
    let mut c = SelfContacts::new(&[0, 1, 2, 3, 4, 5], &start, 0.005, 0.0).unwrap();
    let mut v = vec![Vec3::ZERO; 6];
    let w = [0.0, 0.0, 0.0, 1.0, 1.0, 0.0];
    resolve(&mut c, &start, &mut x, &mut v, &w);
    // The closest points, at the edges' middles, are the edges' kept distance apart on the
    // starting side.
    let middle = 0.5 * (x[3] + x[4]);
    let kept = EDGES_APART_SHARE * 0.005;
    assert!((middle.y - kept).abs() < 1e-4, "{} {}", x[3], x[4]);
}

#[test]
fn edges_off_every_triangle_are_kept_their_distance_apart_on_their_side() {
    // Edge 3–4 crosses edge 0–1 obliquely at their middles and moves down from above it:
    // slowly to within their distance, or through it to twice the thickness below. Neither
    // of its ends is over triangle 0–1–2, and its own triangle stands upright, far from 0
    // and 1: only the edge pair sees them.
    for end in [0.004, -0.01] {
        let start = vec![
            Vec3::new(-1.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, -3.0),
            Vec3::new(-0.9, 0.006, -0.5),
            Vec3::new(0.9, 0.006, 0.5),
            Vec3::new(0.0, 3.0, 0.0),
        ];
        let mut x = start.clone();
        x[3].y = end;
        x[4].y = end;
        let mut c = SelfContacts::new(&[0, 1, 2, 3, 4, 5], &start, 0.005, 0.0).unwrap();
        let mut v = vec![Vec3::ZERO; 6];
        let w = [0.0, 0.0, 0.0, 1.0, 1.0, 0.0];
        resolve(&mut c, &start, &mut x, &mut v, &w);
        let middle = 0.5 * (x[3] + x[4]);
        assert!(
            (middle.y - EDGES_APART_SHARE * 0.005).abs() < 1e-4,
            "end {end}: {} {}",
            x[3],
            x[4]
        );
    }
}
