//! Contacts between cloths: the search, the pushes apart, and the deferral while at rest.

use super::*;
use crate::sim::contact::pairs::EDGES_APART_SHARE;
use crate::sim::contact::{Vectors, bounds};
use crate::sim::{ClothModel, GridSpec};

#[test]
fn triangle_lists_compare_as_slices_do() {
    let (one, two) = ([[0, 1, 2]], [[0, 1, 2], [2, 1, 3]]);
    let lists: [&[[u32; 3]]; 4] = [&[], &one, &two, &[[0, 1, 3]]];
    for a in lists {
        for b in lists {
            assert_eq!(same_triangles(a, b), a == b, "{a:?} against {b:?}");
        }
    }
}

/// An 8×8 grid of 3 cm cells at rest (its model), and contacts for it begun with the same
/// grid shifted by `shift` (held still, 5 mm thick, with `friction`), the step's particles
/// moving `reach` at most.
fn under_a_copy(shift: Vec3, friction: f32, reach: f32) -> (ClothModel, ClothContacts) {
    let model = ClothModel::grid(&GridSpec::new(8, 8, 0.03)).unwrap();
    let lower = &model.rest_positions;
    let upper: Vec<Vec3> = lower.iter().map(|p| *p + shift).collect();
    let mut contacts = ClothContacts::default();
    let other = OtherCloth {
        triangles: &model.triangles,
        start: &upper,
        end: &upper,
        thickness: 0.005,
        friction,
    };
    contacts.begin_step(
        &[other],
        (0.005, friction),
        (bounds(lower), reach),
        (0.03, f32::INFINITY),
        1.0 / 60.0,
    );
    (model, contacts)
}

/// [`ClothContacts::resolve`] over substep `t` for particles of unit mass that moved from
/// `start` to `x` (velocities `v`).
fn resolve(
    contacts: &mut ClothContacts,
    t: (f32, f32, f32),
    tris: &[u32],
    start: &[Vec3],
    x: &mut [Vec3],
    v: &mut [Vec3],
) -> bool {
    let inv_mass = vec![1.0; x.len()];
    let mut state = Vectors {
        x,
        v,
        start,
        inv_mass: &inv_mass,
        touches: None,
    };
    let moved = contacts.resolve(t, tris, &mut state);
    contacts.end_substep(&state);
    moved
}

/// Ten steps of 20 substeps of the free 8×8 grid `x` (velocities `v`) pulled down at 30 m/s²
/// above a fixed copy of it at `other`, 5 mm thick; the copy moves by `jump` before step 5
/// (or, with `glide`, along a straight line during it). Calls `check(step, substep, lowest
/// height over the copy)` after each substep.
fn rest_on_a_copy(
    other: Vec<Vec3>,
    (jump, glide): (Vec3, bool),
    x: &mut [Vec3],
    mut check: impl FnMut(u32, u32, f32),
) -> ClothContacts {
    let model = ClothModel::grid(&GridSpec::new(8, 8, 0.03)).unwrap();
    let tris = &model.triangles;
    let mut v = vec![Vec3::ZERO; x.len()];
    let (h, g) = (1.0 / 1200.0, Vec3::new(0.0, -30.0, 0.0));
    let mut contacts = ClothContacts::default();
    let moved: Vec<Vec3> = other.iter().map(|p| *p + jump).collect();
    for step in 0..10 {
        let (start, end) = match step {
            0..5 => (&other, &other),
            5 if glide => (&other, &moved),
            _ => (&moved, &moved),
        };
        let copy = OtherCloth {
            triangles: tris,
            start,
            end,
            thickness: 0.005,
            friction: 0.0,
        };
        contacts.begin_step(
            &[copy],
            (0.005, 0.0),
            (bounds(x), 0.002),
            (0.03, f32::INFINITY),
            1.0 / 60.0,
        );
        for sub in 0..20 {
            let start = x.to_vec();
            for (x, v) in x.iter_mut().zip(&mut v) {
                *v += g * h;
                *x += *v * h;
            }
            let t = (sub as f32 / 20.0, (sub + 1) as f32 / 20.0, h);
            resolve(&mut contacts, t, tris, &start, x, &mut v);
            let lowest = x.iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
            check(step, sub, lowest - copy.start[0].lerp(copy.end[0], t.1).y);
        }
    }
    contacts
}

#[test]
fn a_cloth_resting_on_another_is_resolved_every_few_substeps_and_sinks_at_most_the_slack() {
    let model = ClothModel::grid(&GridSpec::new(8, 8, 0.03)).unwrap();
    let other = model.rest_positions.clone();
    let mut x: Vec<Vec3> = other.iter().map(|p| *p + Vec3::Y * 0.005).collect();
    let mut deepest = f32::INFINITY;
    let contacts = rest_on_a_copy(other, (Vec3::ZERO, false), &mut x, |_, sub, above| {
        assert!(
            above >= 0.005 * (1.0 - DEFER_CLOSING) - 1e-6,
            "sank to {above} m, past the slack"
        );
        if sub == 19 {
            assert!(above >= 0.005 - 1e-6, "a step ended {above} m apart");
        }
        deepest = deepest.min(above);
    });
    // It sank between resolutions: some were deferred.
    assert!(deepest < 0.0045, "never deferred (deepest {deepest} m)");
    assert_eq!(
        contacts.searches(),
        1,
        "the candidates kept from step to step"
    );
}

#[test]
fn a_cloth_that_moved_between_steps_is_resolved_at_once() {
    // The other cloth jumps 4 mm up into the resting one between two steps.
    let model = ClothModel::grid(&GridSpec::new(8, 8, 0.03)).unwrap();
    let other = model.rest_positions.clone();
    let mut x: Vec<Vec3> = other.iter().map(|p| *p + Vec3::Y * 0.005).collect();
    rest_on_a_copy(
        other,
        (Vec3::Y * 0.004, false),
        &mut x,
        |step, sub, above| {
            if step == 5 && sub == 0 {
                assert!(above >= 0.005 - 1e-6, "{above} m apart after the jump");
            }
        },
    );
}

#[test]
fn a_cloth_that_rises_into_a_resting_one_is_met_within_the_slack() {
    // The other cloth rises 4 mm into the resting one over one step.
    let model = ClothModel::grid(&GridSpec::new(8, 8, 0.03)).unwrap();
    let other = model.rest_positions.clone();
    let mut x: Vec<Vec3> = other.iter().map(|p| *p + Vec3::Y * 0.005).collect();
    rest_on_a_copy(other, (Vec3::Y * 0.004, true), &mut x, |_, _, above| {
        assert!(
            above >= 0.005 * (1.0 - DEFER_CLOSING) - 1e-6,
            "{above} m apart, past the slack"
        );
    });
}

#[test]
fn a_particle_that_comes_within_reach_of_another_cloth_is_kept_apart() {
    // A fixed 8×8 grid 7 mm above a free one: every pair is a candidate but none touches.
    // In the next substep one particle rises 3 mm (within the reach, so no search), to 4 mm
    // below the other cloth: its pairs are found far from touching and must still be tested.
    let (model, mut contacts) = under_a_copy(Vec3::Y * 0.007, 0.0, 0.004);
    let (tris, lower) = (&model.triangles, &model.rest_positions);
    let (mut x, mut v) = (lower.clone(), vec![Vec3::ZERO; lower.len()]);
    let first = (0.0, 0.5, 1.0 / 120.0);
    assert!(!resolve(&mut contacts, first, tris, lower, &mut x, &mut v));
    let start = x.clone();
    x[27].y += 0.003;
    resolve(
        &mut contacts,
        (0.5, 1.0, 1.0 / 120.0),
        tris,
        &start,
        &mut x,
        &mut v,
    );
    assert_eq!(contacts.searches(), 1);
    assert!((x[27].y - 0.002).abs() < 1e-5, "{}", x[27]);
}

#[test]
fn edges_of_two_cloths_are_kept_their_distance_apart() {
    // This cloth's edge 0–1 crosses the other cloth's edge 0–1 obliquely at their middles
    // and moves down from 6 mm above it to 4 mm, within the edges' kept distance but not
    // half of it. Neither edge's ends are over the other cloth's triangle (both triangles'
    // third corners are far away): only the edge pair sees them.
    let other = [
        Vec3::new(-1.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 0.0, -3.0),
    ];
    let start = vec![
        Vec3::new(-0.9, 0.006, -0.5),
        Vec3::new(0.9, 0.006, 0.5),
        Vec3::new(0.0, 3.0, 0.0),
    ];
    let tris = [0, 1, 2];
    let mut contacts = ClothContacts::default();
    contacts.begin_step(
        &[OtherCloth {
            triangles: &tris,
            start: &other,
            end: &other,
            thickness: 0.005,
            friction: 0.0,
        }],
        (0.005, 0.0),
        (bounds(&start), 0.01),
        (3.0, f32::INFINITY),
        1.0 / 60.0,
    );
    let mut x = start.clone();
    x[0].y = 0.004;
    x[1].y = 0.004;
    let mut v = vec![Vec3::ZERO; 3];
    assert!(resolve(
        &mut contacts,
        (0.0, 1.0, 1.0 / 60.0),
        &tris,
        &start,
        &mut x,
        &mut v
    ));
    let middle = 0.5 * (x[0] + x[1]);
    let kept = EDGES_APART_SHARE * 0.005;
    assert!((middle.y - kept).abs() < 1e-4, "{} {}", x[0], x[1]);
}

#[test]
fn a_search_finds_every_pair_within_the_margin_once() {
    // Two 8×8 grids 4 mm apart, the upper one shifted across the lower one's cells: every
    // edge of one is near several of the other's.
    let shift = Vec3::new(0.011, 0.004, 0.017);
    let (model, mut contacts) = under_a_copy(shift, 0.3, 0.0);
    let (tris, lower) = (&model.triangles, &model.rest_positions);
    let upper: Vec<Vec3> = lower.iter().map(|p| *p + shift).collect();
    let (mut x, mut v) = (lower.clone(), vec![Vec3::ZERO; lower.len()]);
    resolve(
        &mut contacts,
        (0.0, 1.0, 1.0 / 60.0),
        tris,
        lower,
        &mut x,
        &mut v,
    );
    assert_eq!(contacts.searches(), 1);
    let margin = 0.005 + 2.0 * contacts.reach;
    // The grid's edges, found here independently of the contacts.
    let mut edges: Vec<[u32; 2]> = tris
        .chunks_exact(3)
        .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
        .map(|(a, b)| [a.min(b), a.max(b)])
        .collect();
    edges.sort_unstable();
    edges.dedup();
    assert_eq!(edges, contacts.edges);
    let mut expected: Vec<(u32, [u32; 2])> = Vec::new();
    for (e, &[a, b]) in edges.iter().enumerate() {
        for &[c, d] in &edges {
            let (s, t) = closest_on_segments(
                lower[a as usize],
                lower[b as usize],
                upper[c as usize],
                upper[d as usize],
            );
            let gap = lower[a as usize]
                .lerp(lower[b as usize], s)
                .distance(upper[c as usize].lerp(upper[d as usize], t));
            if gap < margin {
                expected.push((e as u32, [c, d]));
            }
        }
    }
    let mut found: Vec<(u32, [u32; 2])> = contacts
        .pairs
        .iter()
        .filter_map(|(pair, _)| match pair {
            ClothPair::Edges(e, f) => Some((*e, *f)),
            _ => None,
        })
        .collect();
    let count = found.len();
    found.sort_unstable();
    found.dedup();
    assert_eq!(found.len(), count, "an edge pair found twice");
    expected.sort_unstable();
    assert!(expected.len() > 4 * edges.len(), "{} pairs", expected.len());
    assert_eq!(found, expected);
}

#[test]
fn a_bad_other_cloth_is_a_typed_error() {
    let x = [Vec3::ZERO, Vec3::X, Vec3::Y];
    let good = OtherCloth {
        triangles: &[0, 1, 2],
        start: &x,
        end: &x,
        thickness: 0.005,
        friction: 0.3,
    };
    assert!(good.validate().is_ok());
    let out_of_range = OtherCloth {
        triangles: &[0, 1, 3],
        ..good
    };
    assert!(matches!(
        out_of_range.validate(),
        Err(ClothError::MeshIndexOutOfRange { index: 3, .. })
    ));
    let short = OtherCloth {
        end: &x[..2],
        ..good
    };
    assert!(matches!(
        short.validate(),
        Err(ClothError::InvalidMesh { .. })
    ));
    let nan = [Vec3::ZERO, Vec3::NAN, Vec3::Y];
    let not_finite = OtherCloth { end: &nan, ..good };
    assert!(matches!(
        not_finite.validate(),
        Err(ClothError::InvalidMesh { .. })
    ));
    for thickness in [-0.01, f32::NAN] {
        let bad = OtherCloth { thickness, ..good };
        assert!(matches!(
            bad.validate(),
            Err(ClothError::InvalidValue { .. })
        ));
    }
    // The step leaves it out: nothing is copied, nothing is searched.
    let mut contacts = ClothContacts::default();
    contacts.begin_step(
        &[out_of_range, short, not_finite],
        (0.005, 0.3),
        ((Vec3::splat(-1.0), Vec3::splat(1.0)), 1.0),
        (0.1, f32::INFINITY),
        1.0 / 60.0,
    );
    assert!(!contacts.is_active());
    contacts.begin_step(
        &[good],
        (0.005, 0.3),
        ((Vec3::splat(-1.0), Vec3::splat(1.0)), 1.0),
        (0.1, f32::INFINITY),
        1.0 / 60.0,
    );
    assert!(contacts.is_active());
}
