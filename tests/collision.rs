//! Headless App tests of cloth–collider contact: resting on each shape with no particle inside at
//! any tick, a small fast sphere that cannot slip through, Coulomb friction on a slope, moving and
//! parented colliders, layers, and removal at runtime.

use bevy::prelude::*;
use bevy_cloth::prelude::*;
use bevy_cloth::scene::ConstantVelocity;
use bevy_cloth::sim::ClothSim;

mod common;
use common::*;

fn max_speed(app: &App, cloth: Entity) -> f32 {
    sim(app, cloth)
        .velocities()
        .iter()
        .map(|v| v.length())
        .fold(0.0, f32::max)
}

/// The smallest signed distance of any particle to the collider's surface (in the collider's
/// frame, as placed by `transform`).
fn min_distance(app: &App, cloth: Entity, collider: &ClothCollider, transform: &Transform) -> f32 {
    let to_local = transform.compute_affine().inverse();
    sim(app, cloth)
        .positions()
        .iter()
        .map(|p| {
            collider
                .shape
                .signed_distance(to_local.transform_point3(*p))
                .0
        })
        .fold(f32::INFINITY, f32::min)
}

/// Drops a horizontal `n`×`n` cloth (5 cm spacing) with velocity damping `damping` from `height`
/// above the origin onto a collider, runs `ticks` fixed steps checking that no particle is ever
/// inside (beyond 1 mm), and returns the app and cloth.
fn drop_onto(
    collider: ClothCollider,
    transform: Transform,
    (n, height, damping): (u32, f32, f32),
    ticks: u32,
) -> (App, Entity) {
    let mut app = app();
    app.world_mut().spawn((collider, transform));
    let cloth = spawn_valid(
        &mut app,
        (
            Cloth::grid(GridSpec::new(n, n, 0.05)),
            ClothConfig {
                solver: SolverSettings {
                    damping,
                    ..Default::default()
                },
                ..Default::default()
            },
            Transform::from_xyz(0.0, height, 0.0),
        ),
    );
    for tick in 0..ticks {
        app.update();
        let d = min_distance(&app, cloth, &collider, &transform);
        assert!(
            d >= collider.margin - 1e-3,
            "tick {tick}: a particle is {d} m from the surface (margin {})",
            collider.margin
        );
    }
    (app, cloth)
}

#[test]
fn cloth_dropped_on_a_sphere_comes_to_rest_with_no_particle_inside() {
    let sphere = ClothCollider::sphere(0.5);
    // 10 s at 60 Hz; 1.55 m cloth, 30 cm above the top of the ball.
    let (app, cloth) = drop_onto(sphere, Transform::IDENTITY, (32, 0.8, 0.5), 600);
    assert!(
        max_speed(&app, cloth) < 0.05,
        "still moving at {} m/s",
        max_speed(&app, cloth)
    );
    // Draped: the centre is on top of the ball, the corners hang below its equator.
    let p = sim(&app, cloth).positions();
    let centre = p[16 * 32 + 16];
    assert!((centre.y - 0.51).abs() < 0.01, "{centre}");
    assert!(p[0].y < 0.0, "{}", p[0]);
}

#[test]
fn cloth_dropped_on_a_capsule_rests_on_it() {
    // A horizontal bar along X.
    let capsule = ClothCollider::capsule(0.1, 0.6);
    let transform = Transform::from_rotation(Quat::from_rotation_z(std::f32::consts::FRAC_PI_2));
    // The two flaps hanging from the bar swing for a long time at the default damping (and pass
    // through each other: no self-collision), so this test damps harder.
    let (app, cloth) = drop_onto(capsule, transform, (24, 0.3, 2.0), 300);
    assert!(max_speed(&app, cloth) < 0.05);
    // Hanging over the bar like a towel: its middle row sits on top.
    let com = centre_of_mass(&app, cloth);
    assert!(com.y < 0.0 && com.y > -0.6, "{com}");
    let middle = sim(&app, cloth).positions()[12 * 24 + 12];
    assert!((middle.y - 0.11).abs() < 0.02, "{middle}");
}

#[test]
fn cloth_dropped_on_a_box_rests_on_it() {
    let cuboid = ClothCollider::cuboid(Vec3::new(0.3, 0.2, 0.3));
    let transform = Transform::from_rotation(Quat::from_rotation_y(0.4));
    let (app, cloth) = drop_onto(cuboid, transform, (24, 0.4, 2.0), 300);
    assert!(max_speed(&app, cloth) < 0.05);
    let middle = sim(&app, cloth).positions()[12 * 24 + 12];
    assert!((middle.y - 0.21).abs() < 0.01, "{middle}");
}

/// Whether a sphere centre is on the +Y side of the cloth surface along the vertical through it,
/// and its smallest distance to any cloth triangle.
fn sphere_side_and_clearance(sim: &ClothSim, centre: Vec3) -> (bool, f32) {
    let p = sim.positions();
    let mut above = true;
    let mut clearance = f32::INFINITY;
    for t in sim.model().triangles.chunks_exact(3) {
        let [a, b, c] = [p[t[0] as usize], p[t[1] as usize], p[t[2] as usize]];
        clearance = clearance.min(distance_to_triangle(centre, a, b, c));
        // Vertical line through the centre against the triangle (barycentric in XZ).
        let (v0, v1, v2) = (b - a, c - a, centre - a);
        let det = v0.x * v1.z - v1.x * v0.z;
        if det.abs() < 1e-12 {
            continue;
        }
        let s = (v2.x * v1.z - v1.x * v2.z) / det;
        let u = (v0.x * v2.z - v2.x * v0.z) / det;
        if s >= 0.0 && u >= 0.0 && s + u <= 1.0 {
            let y = a.y + s * v0.y + u * v1.y;
            above &= centre.y > y;
        }
    }
    (above, clearance)
}

/// Distance from `p` to triangle `abc`, by projection and edge checks.
fn distance_to_triangle(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> f32 {
    let n = (b - a).cross(c - a).normalize();
    let q = p - n * (p - a).dot(n);
    let inside = [(a, b), (b, c), (c, a)]
        .iter()
        .all(|(u, v)| (*v - *u).cross(q - *u).dot(n) >= 0.0);
    if inside {
        return (p - q).length();
    }
    [(a, b), (b, c), (c, a)]
        .iter()
        .map(|(u, v)| {
            let e = *v - *u;
            let t = ((p - *u).dot(e) / e.length_squared()).clamp(0.0, 1.0);
            p.distance(*u + e * t)
        })
        .fold(f32::INFINITY, f32::min)
}

#[test]
fn a_sphere_smaller_than_the_spacing_pushed_through_a_pinned_cloth_never_passes() {
    let mut app = app();
    let n = 16;
    let spacing = 0.05;
    // Every border particle pinned.
    let border = (0..n * n).filter(|&k| {
        let (i, j) = (k % n, k / n);
        i == 0 || j == 0 || i == n - 1 || j == n - 1
    });
    let cloth = spawn_valid(
        &mut app,
        (
            Cloth::grid(GridSpec::new(n, n, spacing)),
            ClothPins::new(border),
            ClothConfig {
                solver: SolverSettings {
                    gravity: Vec3::ZERO,
                    ..Default::default()
                },
                ..Default::default()
            },
        ),
    );
    // Radius 0.3 × spacing, starting 5 cm above the centre of the middle cell (between four
    // particles), moving down at 5 m/s.
    let sphere = ClothCollider::sphere(0.3 * spacing);
    let reach = 0.3 * spacing + sphere.margin;
    let ball = app
        .world_mut()
        .spawn((
            sphere,
            Transform::from_xyz(0.0, 0.05, 0.0),
            ConstantVelocity(Vec3::new(0.0, -5.0, 0.0)),
        ))
        .id();
    // 8 steps: the ball ends 0.6 m below the cloth's rest plane, the 0.75 m wide cloth stretched
    // into a deep sleeve around it.
    for tick in 0..8 {
        // The pose this step collides with: the ball moves after the cloths step.
        let centre = app.world().get::<Transform>(ball).unwrap().translation;
        app.update();
        let (above, clearance) = sphere_side_and_clearance(sim(&app, cloth), centre);
        assert!(
            above,
            "tick {tick}: the sphere at {centre} is below the cloth"
        );
        // No triangle ever cuts into the ball; while the tent is moderate (first 0.3 m) the margin
        // is kept too. Deeper, neighbouring triangles fold around the ball and the fixed number of
        // projection passes leaves them partly inside the margin.
        let needed = if tick < 4 {
            reach - 1e-3
        } else {
            0.3 * spacing
        };
        assert!(
            clearance >= needed,
            "tick {tick}: clearance {clearance} < {needed}"
        );
    }
    let centre = app.world().get::<Transform>(ball).unwrap().translation;
    assert!(centre.y < -0.5, "{centre}");
}

/// A cloth lying on a 30° slope with friction `mu`; returns how far its centre of mass moved
/// downhill in 1 s, and the frictionless-free-slide distance for comparison.
fn slide_on_slope(mu: f32) -> f32 {
    let mut app = app();
    let tilt = Quat::from_rotation_z(30f32.to_radians());
    let plane = ClothCollider::half_space(Vec3::Y).with_friction(Friction::new(mu));
    app.world_mut()
        .spawn((plane, Transform::from_rotation(tilt)));
    let normal = tilt * Vec3::Y;
    let cloth = spawn_valid(
        &mut app,
        (
            Cloth::grid(GridSpec::new(12, 12, 0.05)),
            ClothConfig {
                solver: SolverSettings {
                    damping: 0.0,
                    ..Default::default()
                },
                ..Default::default()
            },
            Transform::from_translation(normal * (plane.margin + 0.001)).with_rotation(tilt),
        ),
    );
    let start = centre_of_mass(&app, cloth);
    for _ in 0..60 {
        app.update();
    }
    let downhill = tilt * Vec3::NEG_X;
    (centre_of_mass(&app, cloth) - start).dot(downhill)
}

#[test]
fn cloth_on_a_30_degree_slope_sticks_with_high_friction_and_slides_with_low() {
    let (sin, cos) = 30f32.to_radians().sin_cos();
    // μ = 0.8 > tan 30° = 0.577: static friction holds it.
    let stuck = slide_on_slope(0.8);
    assert!(stuck.abs() < 2e-3, "slid {stuck} m with μ = 0.8");
    // μ = 0.1: slides with acceleration g (sin 30° − μ cos 30°), 2.03 m in 1 s.
    let slid = slide_on_slope(0.1);
    let expected = 0.5 * 9.81 * (sin - 0.1 * cos);
    assert!(
        (slid - expected).abs() < 0.05 * expected,
        "slid {slid} m with μ = 0.1, expected {expected}"
    );
}

#[test]
fn a_moving_box_carries_the_cloth_on_it_even_as_a_child_of_a_moving_parent() {
    let mut app = app();
    let platform =
        ClothCollider::cuboid(Vec3::new(0.5, 0.1, 0.5)).with_friction(Friction::new(1.0));
    // The collider is a child of a moving entity: 0.5 m/s along X.
    app.world_mut()
        .spawn((
            Transform::from_xyz(0.0, -0.1, 0.0),
            ConstantVelocity(Vec3::new(0.5, 0.0, 0.0)),
        ))
        .with_child((platform, Transform::IDENTITY));
    let cloth = spawn_valid(
        &mut app,
        (
            Cloth::grid(GridSpec::new(10, 10, 0.05)),
            Transform::from_xyz(0.0, 0.011, 0.0),
        ),
    );
    let start = centre_of_mass(&app, cloth);
    for _ in 0..60 {
        app.update();
    }
    let moved = centre_of_mass(&app, cloth) - start;
    // The platform moved 0.5 m; static friction accelerates the cloth to its speed within a few
    // steps, after which it rides along.
    assert!((moved.x - 0.5).abs() < 0.03, "{moved}");
    assert!(moved.y.abs() < 0.01, "{moved}");
}

#[test]
fn collision_layers_let_a_cloth_ignore_a_collider() {
    let mut app = app();
    app.world_mut().spawn((
        ClothCollider::half_space(Vec3::Y).with_layers(0b10),
        Transform::IDENTITY,
    ));
    let touching = spawn_valid(
        &mut app,
        (
            Cloth::grid(GridSpec::new(6, 6, 0.05)),
            Transform::from_xyz(0.0, 0.1, 0.0),
        ),
    );
    let ignoring = spawn_valid(
        &mut app,
        (
            Cloth::grid(GridSpec::new(6, 6, 0.05)),
            ClothConfig {
                collision_mask: 0b01,
                ..Default::default()
            },
            Transform::from_xyz(2.0, 0.1, 0.0),
        ),
    );
    for _ in 0..60 {
        app.update();
    }
    assert!((centre_of_mass(&app, touching).y - 0.01).abs() < 1e-3);
    assert!(centre_of_mass(&app, ignoring).y < -2.0);
}

#[test]
fn removing_a_collider_releases_the_cloth() {
    let mut app = app();
    let floor = app
        .world_mut()
        .spawn((
            ClothCollider::cuboid(Vec3::new(1.0, 0.1, 1.0)),
            Transform::IDENTITY,
        ))
        .id();
    let cloth = spawn_valid(
        &mut app,
        (
            Cloth::grid(GridSpec::new(10, 10, 0.05)),
            Transform::from_xyz(0.0, 0.2, 0.0),
        ),
    );
    for _ in 0..120 {
        app.update();
    }
    let resting = centre_of_mass(&app, cloth).y;
    assert!((resting - 0.11).abs() < 2e-3, "{resting}");
    assert_eq!(sim(&app, cloth).active_colliders(), 1);
    app.world_mut().entity_mut(floor).remove::<ClothCollider>();
    for _ in 0..30 {
        app.update();
    }
    // Free fall for 0.5 s: about g t² / 2 = 1.23 m, less a little to damping.
    let fallen = resting - centre_of_mass(&app, cloth).y;
    assert!(fallen > 1.1, "fell only {fallen} m");
    assert_eq!(sim(&app, cloth).active_colliders(), 0);
}

#[test]
fn far_away_colliders_are_skipped_by_the_broad_phase() {
    let mut app = app();
    for k in 0..100 {
        app.world_mut().spawn((
            ClothCollider::sphere(0.5),
            Transform::from_xyz(100.0 + k as f32, 0.0, 0.0),
        ));
    }
    let cloth = spawn_valid(&mut app, Cloth::grid(GridSpec::new(8, 8, 0.05)));
    app.update();
    assert_eq!(sim(&app, cloth).active_colliders(), 0);
}
