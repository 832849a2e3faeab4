//! Headless App tests of sleeping: a cloth at rest stops stepping (its positions and mesh stay
//! exactly as they were), and a moving pin, a moving or arriving collider, wind, or an edit wakes it.

use bevy::prelude::*;
use bevy_cloth::prelude::*;

mod common;
use common::*;

/// A 12×12 cloth hanging from two corners, damped so that it settles within a few seconds.
fn hanging(app: &mut App, solver: SolverSettings) -> Entity {
    let e = app
        .world_mut()
        .spawn((
            Cloth::grid(GridSpec::new(12, 12, 0.05).with_plane(GridPlane::Vertical)),
            ClothPins::new([0, 11]),
            ClothConfig {
                solver: SolverSettings {
                    damping: 4.0,
                    ..solver
                },
                ..default()
            },
            Transform::from_xyz(0.0, 2.0, 0.0),
        ))
        .id();
    app.update();
    e
}

/// Runs until the cloth sleeps (at most `limit` steps); returns the steps taken.
fn until_asleep(app: &mut App, e: Entity, limit: u32) -> u32 {
    for n in 0..limit {
        if sim(app, e).is_sleeping() {
            return n;
        }
        app.update();
    }
    panic!("the cloth did not fall asleep in {limit} steps");
}

#[test]
fn a_cloth_at_rest_sleeps_and_stays_exactly_where_it_was() {
    let mut app = app();
    let cloth = hanging(&mut app, SolverSettings::default());
    let steps = until_asleep(&mut app, cloth, 900);
    println!("asleep after {steps} steps");
    let positions = sim(&app, cloth).positions().to_vec();
    let mesh_handle = app.world().get::<ClothState>(cloth).unwrap().mesh().clone();
    // Let the first sleeping step settle the render buffers, then watch for mesh writes.
    run(&mut app, 2);
    let written = |app: &App| {
        app.world()
            .resource::<Assets<Mesh>>()
            .get(&mesh_handle)
            .unwrap()
            .attribute(Mesh::ATTRIBUTE_POSITION)
            .unwrap()
            .as_float3()
            .unwrap()
            .to_vec()
    };
    let mesh_before = written(&app);
    run(&mut app, 120);
    assert!(sim(&app, cloth).is_sleeping());
    assert!(sim(&app, cloth).slept_last_step());
    assert_eq!(sim(&app, cloth).positions(), &positions[..]);
    assert_eq!(written(&app), mesh_before);
    // The pose it sleeps in is the settled one: every free particle is nearly still.
    assert!(
        sim(&app, cloth)
            .velocities()
            .iter()
            .all(|v| v.length() < SolverSettings::default().sleep_speed)
    );
}

#[test]
fn a_weightless_cloth_far_from_the_origin_sleeps_despite_rounding_jitter() {
    // At 500 m one f32 step is 61 µm: the springs can never be exactly at rest length there, and
    // each substep's tiny corrections read as velocities of centimetres per second.
    let mut app = app();
    let cloth = app
        .world_mut()
        .spawn((
            Cloth::grid(GridSpec::new(32, 32, 1.0 / 31.0)),
            ClothPins::new([0, 31]),
            ClothConfig {
                solver: SolverSettings {
                    gravity: Vec3::ZERO,
                    ..default()
                },
                ..default()
            },
            Transform::from_xyz(500.0, 0.0, -300.0),
        ))
        .id();
    app.update();
    let steps = until_asleep(&mut app, cloth, 120);
    assert!(steps <= 40, "asleep only after {steps} steps");
}

#[test]
fn sleeping_can_be_switched_off() {
    let mut app = app();
    let cloth = hanging(
        &mut app,
        SolverSettings {
            sleep_speed: 0.0,
            ..default()
        },
    );
    run(&mut app, 900);
    assert!(!sim(&app, cloth).is_sleeping());
    assert!(!sim(&app, cloth).slept_last_step());
}

#[test]
fn a_moving_pin_wakes_the_cloth() {
    let mut app = app();
    let anchor = app
        .world_mut()
        .spawn(Transform::from_xyz(1.0, 2.0, 0.0))
        .id();
    let cloth = hanging(&mut app, SolverSettings::default());
    app.world_mut().get_mut::<ClothPins>(cloth).unwrap().pin(
        0,
        PinAnchor::Entity {
            entity: anchor,
            offset: Vec3::ZERO,
        },
    );
    until_asleep(&mut app, cloth, 900);
    run(&mut app, 10);
    assert!(sim(&app, cloth).slept_last_step());
    app.world_mut()
        .get_mut::<Transform>(anchor)
        .unwrap()
        .translation
        .x += 0.2;
    app.update();
    assert!(!sim(&app, cloth).is_sleeping());
    assert!(!sim(&app, cloth).slept_last_step());
    assert!(sim(&app, cloth).positions()[0].distance(Vec3::new(1.2, 2.0, 0.0)) < 1e-5);
}

#[test]
fn colliders_wake_the_cloth_when_they_move_arrive_or_leave() {
    let mut app = app();
    let cloth = hanging(&mut app, SolverSettings::default());
    until_asleep(&mut app, cloth, 900);
    // A collider far away changes nothing.
    let far = app
        .world_mut()
        .spawn((
            ClothCollider::sphere(0.2),
            Transform::from_xyz(50.0, 0.0, 0.0),
        ))
        .id();
    run(&mut app, 5);
    assert!(sim(&app, cloth).slept_last_step());
    // A sphere moving into the cloth wakes it and pushes it.
    app.world_mut()
        .get_mut::<Transform>(far)
        .unwrap()
        .translation = Vec3::new(0.0, 1.7, -0.5);
    app.world_mut()
        .entity_mut(far)
        .insert(bevy_cloth::scene::ConstantVelocity(Vec3::new(
            0.0, 0.0, 1.0,
        )));
    run(&mut app, 40);
    assert!(!sim(&app, cloth).is_sleeping());
    assert!(sim(&app, cloth).active_colliders() > 0);
    // Stop the sphere inside the cloth's reach: the cloth settles on it and sleeps again.
    app.world_mut()
        .entity_mut(far)
        .remove::<bevy_cloth::scene::ConstantVelocity>();
    until_asleep(&mut app, cloth, 1200);
    let resting = sim(&app, cloth).positions().to_vec();
    // Removing the sphere it leans on wakes it, and it swings back.
    app.world_mut().entity_mut(far).despawn();
    run(&mut app, 30);
    assert!(!sim(&app, cloth).slept_last_step());
    assert_ne!(sim(&app, cloth).positions(), &resting[..]);
}

#[test]
fn wind_and_edits_wake_the_cloth() {
    let mut app = app();
    let cloth = hanging(&mut app, SolverSettings::default());
    until_asleep(&mut app, cloth, 900);
    app.world_mut().insert_resource(Wind {
        velocity: Vec3::new(0.0, 0.0, 5.0),
        ..default()
    });
    app.update();
    assert!(!sim(&app, cloth).slept_last_step());
    // A cloth in wind never sleeps.
    run(&mut app, 300);
    assert!(!sim(&app, cloth).is_sleeping());
    app.world_mut().remove_resource::<Wind>();
    until_asleep(&mut app, cloth, 1200);
    // An edit to the configuration wakes it.
    app.world_mut()
        .get_mut::<ClothConfig>(cloth)
        .unwrap()
        .solver
        .gravity = Vec3::new(0.0, -9.81, -3.0);
    run(&mut app, 2);
    assert!(!sim(&app, cloth).slept_last_step());
}

#[test]
fn a_cloth_in_tolerance_mode_at_rest_sleeps() {
    // Tolerance mode runs Verlet, which has no numerical damping: the cloth's own damping must
    // still settle it below the sleep threshold, and asleep it costs no estimates.
    let mut app = app();
    let cloth = hanging(
        &mut app,
        SolverSettings {
            accuracy: bevy_cloth::sim::Accuracy::relative(1e-3, 256),
            ..default()
        },
    );
    let steps = until_asleep(&mut app, cloth, 900);
    let report = sim(&app, cloth).accuracy_report().unwrap();
    println!("asleep after {steps} steps; {report:?}");
    assert_eq!(report.integrator, bevy_cloth::sim::Integrator::Verlet);
    let estimates = report.estimates;
    run(&mut app, 120);
    assert!(sim(&app, cloth).is_sleeping());
    assert_eq!(
        sim(&app, cloth).accuracy_report().unwrap().estimates,
        estimates
    );
}

#[test]
fn a_moving_target_wakes_the_cloth() {
    // No pin: every particle held within 5 cm of its rest position under the cloth's transform
    // (targets, not pins), so only the targets can wake it.
    let mut app = app();
    let cloth = app
        .world_mut()
        .spawn((
            Cloth::grid(GridSpec::new(12, 12, 0.05).with_plane(GridPlane::Vertical)),
            ClothTargets {
                weights: TargetWeights::Values(vec![0.05; 144]),
            },
            ClothConfig {
                solver: SolverSettings {
                    damping: 4.0,
                    ..default()
                },
                ..default()
            },
            Transform::from_xyz(0.0, 2.0, 0.0),
        ))
        .id();
    app.update();
    assert_eq!(sim(&app, cloth).pinned().count(), 0);
    until_asleep(&mut app, cloth, 900);
    // The transform moves 1 m; the targets go with it, and the cloth after them.
    app.world_mut()
        .get_mut::<Transform>(cloth)
        .unwrap()
        .translation
        .x += 1.0;
    run(&mut app, 60);
    assert!(!sim(&app, cloth).slept_last_step());
    let state = state(&app, cloth);
    for t in state.targets() {
        let x = state.positions()[t.particle as usize];
        assert!(x.distance(t.position) < 0.051, "{x} vs {}", t.position);
    }
}

#[test]
fn a_sleeping_cloth_whose_entity_moves_is_drawn_where_it_is() {
    // Pinned in the world: moving the entity moves neither pins nor particles, so the cloth
    // sleeps on; its mesh, written in the entity's space, must be written again.
    let mut app = app();
    let cloth = hanging(&mut app, SolverSettings::default());
    let corners = [0, 11].map(|i| (i, sim(&app, cloth).positions()[i as usize]));
    app.world_mut().get_mut::<ClothPins>(cloth).unwrap().pins = corners
        .iter()
        .map(|&(particle, at)| ClothPin {
            particle,
            anchor: PinAnchor::World(at),
        })
        .collect();
    until_asleep(&mut app, cloth, 900);
    run(&mut app, 2);
    app.world_mut()
        .get_mut::<Transform>(cloth)
        .unwrap()
        .translation
        .x += 1.0;
    run(&mut app, 2);
    assert!(sim(&app, cloth).slept_last_step());
    let state = state(&app, cloth);
    let mesh = app
        .world()
        .resource::<Assets<Mesh>>()
        .get(state.mesh())
        .unwrap();
    let local = mesh
        .attribute(Mesh::ATTRIBUTE_POSITION)
        .unwrap()
        .as_float3()
        .unwrap();
    let to_local = app
        .world()
        .get::<GlobalTransform>(cloth)
        .unwrap()
        .affine()
        .inverse();
    for (p, x) in local.iter().zip(state.positions()) {
        assert!(
            (Vec3::from(*p) - to_local.transform_point3(*x)).length() < 1e-5,
            "{p:?} {x}"
        );
    }
}
