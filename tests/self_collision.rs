//! Self-collision and cloth–cloth collision, judged by a crossing counter of this file's own (not
//! the solver's): the edges of a cloth that pass through one of its triangles they share no vertex
//! with, or through another cloth's. Piles, folds and coarse cloths must show none at any frame;
//! without the collision the same scenes show many.

use std::collections::HashMap;

use bevy::prelude::*;
use bevy_cloth::prelude::*;
use bevy_cloth::scene::ConstantVelocity;

mod common;
use common::*;

/// Number of (edge, triangle) pairs of the mesh `triangles` over `x` in which the edge passes
/// through the triangle's interior and shares no vertex with it.
fn crossings(x: &[Vec3], triangles: &[u32]) -> usize {
    let tris: Vec<[u32; 3]> = triangles
        .chunks_exact(3)
        .map(|t| [t[0], t[1], t[2]])
        .collect();
    let mut edges: Vec<(u32, u32)> = tris
        .iter()
        .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
        .map(|(a, b)| (a.min(b), a.max(b)))
        .collect();
    edges.sort_unstable();
    edges.dedup();
    // A uniform grid of cells as large as the largest triangle's box: every triangle is listed in
    // each cell its box meets, and an edge (never larger than its triangle) meets at most eight.
    let boxes: Vec<(Vec3, Vec3)> = tris
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| x[i as usize]);
            (a.min(b).min(c), a.max(b).max(c))
        })
        .collect();
    let cell = boxes
        .iter()
        .map(|(lo, hi)| (*hi - *lo).max_element())
        .fold(1e-4, f32::max);
    let key = |p: Vec3| (p / cell).floor().as_ivec3();
    let mut grid: HashMap<IVec3, Vec<usize>> = HashMap::new();
    for (t, (lo, hi)) in boxes.iter().enumerate() {
        let (a, b) = (key(*lo), key(*hi));
        for i in a.x..=b.x {
            for j in a.y..=b.y {
                for k in a.z..=b.z {
                    grid.entry(IVec3::new(i, j, k)).or_default().push(t);
                }
            }
        }
    }
    let mut count = 0;
    let mut seen: Vec<usize> = Vec::new();
    for &(a, b) in &edges {
        let (p, q) = (x[a as usize], x[b as usize]);
        let (lo, hi) = (key(p.min(q)), key(p.max(q)));
        seen.clear();
        for i in lo.x..=hi.x {
            for j in lo.y..=hi.y {
                for k in lo.z..=hi.z {
                    let Some(list) = grid.get(&IVec3::new(i, j, k)) else {
                        continue;
                    };
                    for &t in list {
                        if seen.contains(&t) || tris[t].contains(&a) || tris[t].contains(&b) {
                            continue;
                        }
                        seen.push(t);
                        let [u, v, w] = tris[t].map(|i| x[i as usize]);
                        count += usize::from(segment_crosses_triangle(p, q, u, v, w));
                    }
                }
            }
        }
    }
    count
}

/// Whether segment `pq` passes through the interior of triangle `abc`: its ends lie on opposite
/// sides of the triangle's plane, each by more than a micrometre (so that round-off in a flat,
/// coplanar stretch of cloth never counts), and the point where it meets the plane is inside.
fn segment_crosses_triangle(p: Vec3, q: Vec3, a: Vec3, b: Vec3, c: Vec3) -> bool {
    let Some(n) = (b - a).cross(c - a).try_normalize() else {
        return false;
    };
    let (dp, dq) = ((p - a).dot(n), (q - a).dot(n));
    if dp * dq >= 0.0 || dp.abs().min(dq.abs()) < 1e-6 {
        return false;
    }
    let hit = p + (dp / (dp - dq)) * (q - p);
    // Inside when the hit is on the inner side of all three edges.
    let inside = |e0: Vec3, e1: Vec3| (e1 - e0).cross(hit - e0).dot(n) > 0.0;
    inside(a, b) && inside(b, c) && inside(c, a)
}

/// Crossings of cloth `e` now.
fn cloth_crossings(app: &App, e: Entity) -> usize {
    let sim = sim(app, e);
    crossings(sim.positions(), &sim.model().triangles)
}

/// Settings with self-collision on (`on`) or off, `thickness` thick.
fn config(on: bool, thickness: f32) -> ClothConfig {
    ClothConfig {
        solver: SolverSettings {
            self_collision: SelfCollision {
                enabled: on,
                thickness,
                ..Default::default()
            },
            ..Default::default()
        },
        ..Default::default()
    }
}

/// Runs `ticks` fixed steps and returns the most crossings cloth `e` had after any of them.
fn worst_crossings(app: &mut App, e: Entity, ticks: u32) -> usize {
    let mut worst = 0;
    for _ in 0..ticks {
        app.update();
        worst = worst.max(cloth_crossings(app, e));
        assert!(
            sim(app, e).positions().iter().all(|p| p.is_finite()),
            "positions finite"
        );
    }
    worst
}

/// An app with a floor at y = 0.
fn app_with_floor() -> App {
    let mut app = app();
    app.world_mut()
        .spawn((ClothCollider::half_space(Vec3::Y), Transform::IDENTITY));
    app
}

/// An `n`×`n` cloth of `spacing`, `thickness` thick, tilted nearly upright and dropped onto the
/// floor: it lands on an edge and crumples onto itself.
fn upright_drop(n: u32, spacing: f32, thickness: f32, on: bool) -> (App, Entity) {
    let mut app = app_with_floor();
    let cloth = spawn_valid(
        &mut app,
        (
            Cloth::grid(GridSpec::new(n, n, spacing)),
            config(on, thickness),
            Transform::from_xyz(0.0, 0.8, 0.0)
                .with_rotation(Quat::from_rotation_z(1.45) * Quat::from_rotation_x(0.3)),
        ),
    );
    (app, cloth)
}

/// Runs `scene` for `ticks` steps without and with self-collision: the former must cross itself
/// (so the scene can fail), the latter never. Returns the second app and cloth.
fn crosses_only_without(scene: impl Fn(bool) -> (App, Entity), ticks: u32) -> (App, Entity) {
    let (mut app, cloth) = scene(false);
    let without = worst_crossings(&mut app, cloth, ticks);
    assert!(without > 0, "{without} crossings without self-collision");
    let (mut app, cloth) = scene(true);
    let with = worst_crossings(&mut app, cloth, ticks);
    assert_eq!(with, 0, "crossings with self-collision ({without} without)");
    (app, cloth)
}

#[test]
fn the_crossing_counter_sees_an_edge_through_a_triangle() {
    // A triangle in z = 0 and a vertical edge through its interior, then beside it; an edge that
    // shares a vertex with the triangle never counts, nor does one in the triangle's plane.
    let x = [
        Vec3::ZERO,
        Vec3::X,
        Vec3::Y,
        Vec3::new(0.2, 0.2, -0.5),
        Vec3::new(0.2, 0.2, 0.5),
        Vec3::new(0.3, 0.2, 0.5),
    ];
    assert_eq!(crossings(&x, &[0, 1, 2, 3, 4, 5]), 2);
    let beside = [
        x[0],
        x[1],
        x[2],
        x[3] + Vec3::X,
        x[4] + Vec3::X,
        x[5] + Vec3::X,
    ];
    assert_eq!(crossings(&beside, &[0, 1, 2, 3, 4, 5]), 0);
    let flat = [
        x[0],
        x[1],
        x[2],
        Vec3::new(0.2, 0.2, 0.0),
        Vec3::new(0.9, 0.9, 0.0),
        Vec3::X * 5.0,
    ];
    assert_eq!(crossings(&flat, &[0, 1, 2, 3, 4, 5]), 0);
}

#[test]
fn a_tilted_cloth_dropped_on_a_floor_folds_without_crossing_itself() {
    // 32×32, 3 cm spacing, 5 mm thick.
    let (app, cloth) = crosses_only_without(|on| upright_drop(32, 0.03, 0.005, on), 300);
    // It still lies on the floor, folded: the pile is thicker than one layer.
    let top = sim(&app, cloth)
        .positions()
        .iter()
        .map(|p| p.y)
        .fold(f32::MIN, f32::max);
    assert!(top > 0.012 && top < 0.3, "top of the pile at {top} m");
}

#[test]
fn a_coarse_cloth_four_times_its_thickness_piles_without_crossing() {
    // 24×24, spacing 4 cm, thickness 1 cm: particle–particle distances alone would let its
    // layers slip between each other's particles.
    let _ = crosses_only_without(|on| upright_drop(24, 0.04, 0.01, on), 240);
}

#[test]
fn a_cloth_in_tolerance_mode_piles_without_crossing_itself() {
    // The coarse pile again with the integrator and substeps chosen by tolerance mode: the copy
    // its estimates run on keeps its own self-contacts, and the cloth never crosses itself.
    let (mut app, cloth) = upright_drop(24, 0.04, 0.01, true);
    app.world_mut()
        .get_mut::<ClothConfig>(cloth)
        .unwrap()
        .solver
        .accuracy = bevy_cloth::sim::Accuracy::relative(1e-2, 128);
    assert_eq!(worst_crossings(&mut app, cloth, 240), 0);
    let report = sim(&app, cloth).accuracy_report().unwrap();
    assert!(report.estimates > 0 && report.substeps <= 128, "{report:?}");
}

/// A 64×64 cloth (2 cm spacing, 5 mm thick) lying on the floor, pushed 0.72 m by a capsule lying
/// across it.
fn capsule_sweep(on: bool) -> (App, Entity) {
    let mut app = app_with_floor();
    app.world_mut().spawn((
        ClothCollider::capsule(0.04, 0.8),
        Transform::from_xyz(-0.75, 0.045, 0.0)
            .with_rotation(Quat::from_rotation_x(std::f32::consts::FRAC_PI_2)),
        ConstantVelocity(Vec3::new(0.6, 0.0, 0.0)),
    ));
    let cloth = spawn_valid(
        &mut app,
        (
            Cloth::grid(GridSpec::new(64, 64, 0.02)),
            config(on, 0.005),
            Transform::from_xyz(0.0, 0.01, 0.0),
        ),
    );
    (app, cloth)
}

#[test]
fn a_cloth_swept_into_folds_by_a_moving_capsule_never_crosses_itself() {
    let (app, cloth) = crosses_only_without(capsule_sweep, 120);
    // The capsule has pushed the cloth's near edge up into folds.
    let top = sim(&app, cloth)
        .positions()
        .iter()
        .map(|p| p.y)
        .fold(f32::MIN, f32::max);
    assert!(top > 0.05, "the cloth rose to {top} m");
}

#[test]
fn a_hanging_cloth_has_no_self_contact_candidates() {
    // A flat cloth hanging from two corners cannot touch itself: its broad phase finds nothing, so
    // no pair is tested in any substep.
    let mut app = app();
    let cloth = spawn_valid(
        &mut app,
        (
            Cloth::grid(GridSpec::new(32, 32, 0.03).with_plane(GridPlane::Vertical)),
            config(true, 0.005),
            ClothPins::new([0, 31]),
        ),
    );
    for _ in 0..60 {
        app.update();
        let stats = sim(&app, cloth).self_contact_stats();
        assert_eq!((stats.vertex_triangle, stats.edge_edge), (0, 0));
    }
}

#[test]
fn a_cloth_at_rest_keeps_its_candidates() {
    // A cloth lying still on the floor (never asleep, so it steps) finds its self-contact
    // candidates once, then keeps them while nothing moves.
    let mut app = app_with_floor();
    let mut c = config(true, 0.005);
    c.solver.sleep_speed = 0.0;
    let cloth = spawn_valid(
        &mut app,
        (
            Cloth::grid(GridSpec::new(16, 16, 0.03)),
            c,
            Transform::from_xyz(0.0, 0.006, 0.0),
        ),
    );
    run(&mut app, 60);
    let before = sim(&app, cloth).self_contact_stats().searches;
    run(&mut app, 60);
    let after = sim(&app, cloth).self_contact_stats().searches;
    assert!(before >= 1, "searched {before} times");
    assert_eq!(after, before, "searched again at rest");
}

#[test]
fn a_scene_file_sets_self_collision() {
    let scene = bevy_cloth::scene::ClothScene::from_ron(
        "(cloth: Grid((nx: 4, ny: 4, spacing: 0.1)), \
          solver: (self_collision: (enabled: true, thickness: 0.004)))",
    )
    .unwrap();
    let c = scene.solver.self_collision;
    assert!(c.enabled);
    assert_eq!(
        (c.thickness, c.friction),
        (0.004, SelfCollision::default().friction)
    );
    let bad = bevy_cloth::scene::ClothScene::from_ron(
        "(cloth: Grid((nx: 4, ny: 4, spacing: 0.1)), \
          solver: (self_collision: (enabled: true, thickness: -1.0)))",
    );
    assert!(bad.is_err(), "a negative thickness in a scene is an error");
}

#[test]
fn a_bad_thickness_is_a_typed_error() {
    for thickness in [0.0, -0.01, f32::NAN, f32::INFINITY] {
        let error = config(true, thickness).validate().unwrap_err();
        assert!(
            matches!(
                error.innermost(),
                ClothError::InvalidValue {
                    field: "self_collision.thickness",
                    ..
                }
            ),
            "{thickness}: {error}"
        );
    }
    let mut bad_friction = config(true, 0.005);
    bad_friction.solver.self_collision.friction = f32::NAN;
    assert!(bad_friction.validate().is_err());
}

/// Crossings among the cloths `cloths` now, within each and between any two: the counter run on
/// their meshes taken as one.
fn crossings_among(app: &App, cloths: &[Entity]) -> usize {
    let (mut x, mut triangles) = (Vec::new(), Vec::new());
    for &e in cloths {
        let sim = sim(app, e);
        let offset = x.len() as u32;
        x.extend_from_slice(sim.positions());
        triangles.extend(sim.model().triangles.iter().map(|i| i + offset));
    }
    crossings(&x, &triangles)
}

/// Three 24×24 cloths (3 cm spacing, self-collision on) dropped one above the other, each turned
/// differently, onto a sphere on a floor; with `meet`, they keep apart from each other
/// ([`ClothConfig::cloth_layers`]).
fn laundry(meet: bool) -> (App, Vec<Entity>) {
    let mut app = app_with_floor();
    app.world_mut().spawn((
        ClothCollider::sphere(0.25),
        Transform::from_xyz(0.0, 0.25, 0.0),
    ));
    let cloths = (0..3)
        .map(|k| {
            let k = k as f32;
            spawn_valid(
                &mut app,
                (
                    Cloth::grid(GridSpec::new(24, 24, 0.03)),
                    ClothConfig {
                        cloth_layers: if meet { 1 } else { 0 },
                        ..config(true, 0.005)
                    },
                    Transform::from_xyz(0.02 * k, 0.7 + 0.12 * k, -0.015 * k).with_rotation(
                        Quat::from_rotation_y(0.7 * k) * Quat::from_rotation_x(0.15 * (k - 1.0)),
                    ),
                ),
            )
        })
        .collect();
    (app, cloths)
}

/// Runs `ticks` fixed steps and returns the most crossings among `cloths` after any of them.
fn worst_crossings_among(app: &mut App, cloths: &[Entity], ticks: u32) -> usize {
    let mut worst = 0;
    for _ in 0..ticks {
        app.update();
        worst = worst.max(crossings_among(app, cloths));
    }
    worst
}

#[test]
fn three_cloths_dropped_on_a_sphere_never_cross_each_other() {
    let ticks = 150;
    let (mut app, cloths) = laundry(false);
    let without = worst_crossings_among(&mut app, &cloths, ticks);
    assert!(
        without > 0,
        "{without} crossings between cloths that do not meet"
    );
    let (mut app, cloths) = laundry(true);
    let with = worst_crossings_among(&mut app, &cloths, ticks);
    assert_eq!(
        with, 0,
        "crossings among cloths that meet ({without} without)"
    );
    // They lie on each other over the sphere: the top cloth's highest particle is above the
    // bottom one's.
    let top = |e: Entity| {
        sim(&app, e)
            .positions()
            .iter()
            .map(|p| p.y)
            .fold(f32::MIN, f32::max)
    };
    let tops: Vec<f32> = cloths.iter().map(|&e| top(e)).collect();
    assert!(tops[2] > tops[0] + 0.004, "stacked: {tops:?}");
}

#[test]
fn cloths_out_of_each_others_reach_never_search() {
    // Two cloths on one layer, 3 m apart, falling side by side onto the floor: each step's broad
    // phase drops the other, so neither ever looks for contact candidates.
    let mut app = app_with_floor();
    let cloths: Vec<Entity> = [-1.5, 1.5]
        .into_iter()
        .map(|x| {
            spawn_valid(
                &mut app,
                (
                    Cloth::grid(GridSpec::new(16, 16, 0.03)),
                    ClothConfig {
                        cloth_layers: 1,
                        ..default()
                    },
                    Transform::from_xyz(x, 0.5, 0.0),
                ),
            )
        })
        .collect();
    let start = centre_of_mass(&app, cloths[0]);
    run(&mut app, 60);
    assert!(centre_of_mass(&app, cloths[0]).y < start.y - 0.3, "it fell");
    for e in cloths {
        assert_eq!(sim(&app, e).cloth_contact_searches(), 0);
    }
}

#[test]
fn a_cloth_cut_in_two_on_its_way_down_piles_without_crossing() {
    // The tilted drop, cut in two across its middle five steps before it lands: the two halves
    // land and fold onto each other, their torn edges taking part in self-collision like any.
    let cut_drop = |on: bool| {
        let (mut app, cloth) = upright_drop(32, 0.03, 0.005, on);
        for _ in 0..5 {
            app.update();
        }
        let x = sim(&app, cloth).positions();
        let (centre, side) = (x[16 * 32 + 16], x[16 * 32 + 31]);
        let cut = bevy_cloth::sim::Cut::Plane {
            point: centre,
            normal: side - centre,
        };
        app.world_mut().write_message(ClothCut { cloth, cut });
        app.update();
        assert_eq!(sim(&app, cloth).model().pieces().0, 2);
        (app, cloth)
    };
    let _ = crosses_only_without(cut_drop, 300);
}

#[test]
fn a_cloth_with_a_hole_punched_on_its_way_down_piles_without_crossing() {
    // The tilted drop with a 7 cm hole punched through its middle five steps before it lands:
    // the disc knocked out and the rim around it lay within the thickness of each other at
    // jagged corners of the cut, and must still never pass through each other as they pile.
    let punched_drop = |on: bool| {
        let (mut app, cloth) = upright_drop(32, 0.03, 0.005, on);
        for _ in 0..5 {
            app.update();
        }
        let x = sim(&app, cloth).positions();
        let centre = 16 * 32 + 16;
        let normal = (x[centre + 1] - x[centre]).cross(x[centre + 32] - x[centre]);
        let cut = bevy_cloth::sim::Cut::Ray {
            origin: x[centre] - 0.5 * normal.normalize(),
            direction: normal,
            radius: 0.07,
        };
        app.world_mut().write_message(ClothCut { cloth, cut });
        app.update();
        assert_eq!(sim(&app, cloth).model().pieces().0, 2);
        (app, cloth)
    };
    let _ = crosses_only_without(punched_drop, 300);
}
