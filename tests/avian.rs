//! Headless App tests of cloth in an avian3d world (feature `avian`): avian's primitives act as
//! the equivalent native colliders do, other shapes through parry without tunnelling, avian's
//! layers, sensors and the opt-out are honoured, kinematic bodies drag the cloth, and the
//! two-way coupling exchanges momentum without creating any; closed cloths with air hold up a
//! crate and bounce on avian's floor.

use avian3d::prelude::*;
use bevy::prelude::*;
use bevy_cloth::avian::{ClothAvianPlugin, ClothPushesBodies, NoClothContact};
use bevy_cloth::prelude::*;
use bevy_cloth::sim::ClothSim;

mod common;
use common::*;

/// A headless app at 60 Hz with avian's physics and the cloth coupling.
fn avian_app() -> App {
    bevy_cloth::harness::try_headless_app_with(DT, (PhysicsPlugins::default(), ClothAvianPlugin))
        .expect("a valid step")
}

/// A horizontal `n`×`n` cloth, 5 cm spacing, centred on `at`.
fn sheet(n: u32, at: Vec3) -> impl Bundle {
    (
        Cloth::grid(GridSpec::new(n, n, 0.05)),
        ClothConfig {
            solver: SolverSettings {
                damping: 0.5,
                ..Default::default()
            },
            ..Default::default()
        },
        Transform::from_translation(at),
    )
}

/// Particle positions after `steps` steps of a 12×12 cloth dropped from 0.6 m over the collider
/// that `spawn` adds to the app, a little off its centre.
fn drop_over(avian: bool, spawn: impl FnOnce(&mut World), steps: u32) -> Vec<Vec3> {
    let mut app = if avian { avian_app() } else { app() };
    spawn(app.world_mut());
    let cloth = spawn_valid(&mut app, sheet(12, Vec3::new(0.02, 0.6, -0.01)));
    run(&mut app, steps);
    sim(&app, cloth).positions().to_vec()
}

#[test]
fn avian_primitives_act_as_the_equivalent_native_colliders() {
    let tilted = Quat::from_rotation_z(0.3) * Quat::from_rotation_x(-0.2);
    let cases: Vec<(&str, ClothCollider, Collider, Transform)> = vec![
        (
            "ball",
            ClothCollider::sphere(0.3),
            Collider::sphere(0.3),
            Transform::from_xyz(0.05, 0.1, 0.0),
        ),
        (
            "scaled ball",
            ClothCollider::sphere(0.15),
            Collider::sphere(0.15),
            Transform::from_xyz(0.05, 0.1, 0.0).with_scale(Vec3::splat(2.0)),
        ),
        // Upright: a tilted one makes the result hang on rounding (the native collider's rotation
        // comes back from its `GlobalTransform`'s matrix, avian's straight from its `Transform`), and
        // a cloth sliding on a curved surface turns a 1e-7 difference into millimetres. The
        // mapping of tilted and offset capsules is tested through distances in the crate's unit
        // tests.
        (
            "capsule",
            ClothCollider::capsule(0.15, 0.3),
            Collider::capsule(0.15, 0.6),
            Transform::from_xyz(0.0, 0.0, 0.0),
        ),
        (
            "cuboid",
            ClothCollider::cuboid(Vec3::new(0.3, 0.1, 0.2)),
            Collider::cuboid(0.6, 0.2, 0.4),
            Transform::from_xyz(0.0, 0.2, 0.0).with_rotation(tilted),
        ),
        (
            "half-space",
            ClothCollider::half_space(Vec3::Y),
            Collider::half_space(Vec3::Y),
            Transform::from_xyz(0.0, 0.1, 0.0).with_rotation(tilted),
        ),
    ];
    for (name, native, avian, transform) in cases {
        let expected = drop_over(
            false,
            |w| {
                w.spawn((native, transform));
            },
            300,
        );
        let got = drop_over(
            true,
            |w| {
                w.spawn((RigidBody::Static, avian, transform));
            },
            300,
        );
        let worst = expected
            .iter()
            .zip(&got)
            .map(|(a, b)| a.distance(*b))
            .fold(0.0, f32::max);
        // The cloth touched the collider: it did not fall freely (0.5 · g · 5 s² ≫ 1 m).
        let lowest = got.iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
        assert!(lowest > -0.5, "{name}: the cloth fell past it ({lowest} m)");
        assert!(
            worst <= 1e-5,
            "{name}: {worst} m from the native collider's result"
        );
    }
}

/// Whether a 6×6 cloth dropped 10 cm above a floor that `floor` spawns (with cloth mask `mask`)
/// still rests on it after a second.
fn rests_on(floor: impl Bundle, mask: u32) -> bool {
    let mut app = avian_app();
    app.world_mut().spawn(floor);
    let cloth = spawn_valid(
        &mut app,
        (
            Cloth::grid(GridSpec::new(6, 6, 0.05)),
            ClothConfig {
                collision_mask: mask,
                ..Default::default()
            },
            Transform::from_xyz(0.0, 0.1, 0.0),
        ),
    );
    run(&mut app, 60);
    centre_of_mass(&app, cloth).y > -0.1
}

#[test]
fn collision_layers_sensors_and_the_opt_out_are_honoured() {
    let floor = || (RigidBody::Static, Collider::half_space(Vec3::Y));
    assert!(rests_on(floor(), u32::MAX), "a plain floor holds the cloth");
    let layered = CollisionLayers::from_bits(0b10, u32::MAX);
    assert!(rests_on((floor(), layered), 0b10), "a shared membership");
    assert!(!rests_on((floor(), layered), 0b01), "no shared membership");
    let filtered = CollisionLayers::from_bits(0b01, 0b10);
    assert!(
        rests_on((floor(), filtered), 0b11),
        "filters that accept the cloth"
    );
    assert!(
        !rests_on((floor(), filtered), 0b01),
        "filters that refuse the cloth"
    );
    assert!(!rests_on((floor(), Sensor), u32::MAX), "a sensor");
    assert!(!rests_on((floor(), NoClothContact), u32::MAX), "opted out");
}

/// A platform moving at 2 m/s along X under a cloth.
#[derive(Clone, Copy, PartialEq)]
enum Platform {
    /// A native collider moved before each cloth step.
    Native,
    /// An avian kinematic body with the collider on it.
    Avian,
    /// The same rising at 1 m/s instead.
    AvianLift,
    /// The same lift, the collider on a child entity of a body 1 m beside it.
    AvianChildLift,
}

/// How far the cloth's centre of mass moved in a second on a platform (friction 1) of the given
/// kind.
fn ride(platform: Platform) -> Vec3 {
    let mut app = if platform == Platform::Native {
        app()
    } else {
        avian_app()
    };
    let cloth = spawn_valid(&mut app, sheet(10, Vec3::new(0.0, 0.011, 0.0)));
    let speed = Vec3::new(2.0, 0.0, 0.0);
    let at = Transform::from_xyz(0.0, -0.1, 0.0);
    let collider = || {
        (
            Collider::cuboid(1.0, 0.2, 1.0),
            avian3d::prelude::Friction::new(1.0),
        )
    };
    let up = Vec3::new(0.0, 1.0, 0.0);
    match platform {
        Platform::Avian => {
            app.world_mut()
                .spawn((RigidBody::Kinematic, LinearVelocity(speed), collider(), at));
        }
        Platform::AvianLift => {
            app.world_mut()
                .spawn((RigidBody::Kinematic, LinearVelocity(up), collider(), at));
        }
        Platform::AvianChildLift => {
            let beside = Vec3::new(1.0, 0.0, 0.0);
            app.world_mut()
                .spawn((
                    RigidBody::Kinematic,
                    LinearVelocity(up),
                    Transform::from_translation(at.translation + beside),
                ))
                .with_child((collider(), Transform::from_translation(-beside)));
        }
        Platform::Native => {
            app.world_mut().spawn((
                ClothCollider::cuboid(Vec3::new(0.5, 0.1, 0.5))
                    .with_friction(bevy_cloth::sim::Friction::new(1.0)),
                at,
            ));
            app.add_systems(
                FixedUpdate,
                (move |mut q: Query<&mut Transform, With<ClothCollider>>, time: Res<Time>| {
                    for mut t in &mut q {
                        t.translation += speed * time.delta_secs();
                    }
                })
                .before(ClothSystems::Prepare),
            );
        }
    }
    let start = centre_of_mass(&app, cloth);
    run(&mut app, 60);
    centre_of_mass(&app, cloth) - start
}

#[test]
fn a_kinematic_body_drags_the_cloth_as_a_native_moving_collider_does() {
    let (avian, native) = (ride(Platform::Avian), ride(Platform::Native));
    // The platform moves 2 m in the second; friction (μ = 1, at most g) takes 0.2 s to bring the
    // cloth up to its speed, so the cloth trails it by about 0.2 m.
    assert!(native.x > 1.7 && native.x < 2.0, "native: {native}");
    // The native collider's first step starts where it stands (it has no earlier pose), the
    // avian body's at its velocity: a step of platform motion apart at most.
    assert!(
        avian.distance(native) < 2.0 / 60.0 + 0.005,
        "{avian} vs {native}"
    );
    assert!(avian.y.abs() < 0.01, "it stays on the platform: {avian}");
    // A collider on a child of the moving body is where the body puts it now (its own `Position`
    // is a step behind until avian's next step): a rising one lifts the cloth as high.
    let (on_body, on_child) = (ride(Platform::AvianLift), ride(Platform::AvianChildLift));
    assert!(on_body.y > 0.9, "the lift raised the cloth: {on_body}");
    assert!(on_child.distance(on_body) < 1e-4, "{on_child} vs {on_body}");
}

/// Height of the test terrain at `(x, z)`: gentle bumps.
fn terrain_height(x: f32, z: f32) -> f32 {
    0.08 * (3.0 * x).sin() * (2.0 * z).cos()
}

/// A 1.6 m × 1.6 m triangle mesh of `terrain_height` (11 × 11 vertices: 200 triangles).
fn terrain() -> Collider {
    let (vertices, triangles) = bevy_cloth::harness::heightfield_mesh(11, 1.6, terrain_height);
    assert_eq!(triangles.len(), 200);
    Collider::trimesh(vertices, triangles)
}

/// The terrain's height under `(x, z)` as the mesh has it (linear across each triangle).
fn mesh_height(x: f32, z: f32) -> Option<f32> {
    let (fi, fj) = ((x + 0.8) / 0.16, (z + 0.8) / 0.16);
    if !(0.0..10.0).contains(&fi) || !(0.0..10.0).contains(&fj) {
        return None;
    }
    let (i, j) = (fi.floor(), fj.floor());
    let (u, w) = (fi - i, fj - j);
    let h = |a: f32, b: f32| terrain_height(-0.8 + 0.16 * a, -0.8 + 0.16 * b);
    let (h00, h10, h01, h11) = (h(i, j), h(i + 1.0, j), h(i, j + 1.0), h(i + 1.0, j + 1.0));
    // The quad's diagonal runs from (i + 1, j) to (i, j + 1).
    Some(if u + w <= 1.0 {
        h00 + (h10 - h00) * u + (h01 - h00) * w
    } else {
        h11 + (h01 - h11) * (1.0 - u) + (h10 - h11) * (1.0 - w)
    })
}

#[test]
fn a_cloth_on_a_trimesh_terrain_and_a_convex_rock_never_tunnels() {
    let mut app = avian_app();
    app.world_mut().spawn((RigidBody::Static, terrain()));
    let rock_at = Transform::from_xyz(0.1, 0.05, -0.05);
    let rock_points = vec![
        Vec3::new(-0.2, 0.0, -0.15),
        Vec3::new(0.25, 0.0, -0.1),
        Vec3::new(0.0, 0.0, 0.25),
        Vec3::new(0.05, 0.3, 0.0),
        Vec3::new(-0.1, 0.15, 0.1),
    ];
    let rock = Collider::convex_hull(rock_points).expect("a hull");
    app.world_mut()
        .spawn((RigidBody::Static, rock.clone(), rock_at));
    let cloth = spawn_valid(
        &mut app,
        (
            Cloth::grid(GridSpec::new(32, 32, 0.04)),
            Transform::from_xyz(0.0, 0.5, 0.0),
        ),
    );
    let margin = bevy_cloth::DEFAULT_COLLIDER_MARGIN;
    let (rock_pos, rock_rot) = (rock_at.translation, rock_at.rotation);
    let mut deepest = (0.0f32, 0.0f32);
    for tick in 0..300 {
        app.update();
        let positions = sim(&app, cloth).positions();
        for p in positions {
            if let Some(h) = mesh_height(p.x, p.z) {
                let below = h - p.y;
                assert!(
                    below < 0.02,
                    "tick {tick}: a particle is {below} m under the terrain"
                );
                deepest.0 = deepest.0.max(below + margin);
            }
            if rock.contains_point(rock_pos, rock_rot, *p) {
                let (surface, _) = rock.project_point(rock_pos, rock_rot, *p, false);
                let depth = surface.distance(*p);
                assert!(
                    depth < 0.02,
                    "tick {tick}: a particle is {depth} m inside the rock"
                );
            }
            let d = rock.distance_to_point(rock_pos, rock_rot, *p, true);
            if d == 0.0 {
                deepest.1 = deepest.1.max(margin);
            } else {
                deepest.1 = deepest.1.max(margin - d);
            }
        }
    }
    // At the end (5 s), within the margin plus 2 mm of both surfaces.
    let positions = sim(&app, cloth).positions();
    for p in positions {
        if let Some(h) = mesh_height(p.x, p.z) {
            assert!(
                p.y >= h + margin - 0.002,
                "{p} is within {} of the terrain",
                p.y - h
            );
        }
        let d = rock.distance_to_point(rock_pos, rock_rot, *p, true);
        assert!(d >= margin - 0.002, "{p} is {d} m from the rock");
    }
    let lowest = positions.iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
    assert!(lowest > -0.2, "the cloth lies on the terrain ({lowest} m)");
}

/// Total linear momentum of a cloth's particles.
fn cloth_momentum(sim: &ClothSim) -> Vec3 {
    sim.velocities()
        .iter()
        .zip(sim.masses())
        .map(|(v, m)| *v * *m)
        .sum()
}

#[test]
fn two_way_coupling_exchanges_momentum_without_creating_any() {
    // A 0.5 kg ball thrown at 2 m/s into a free 16×16 cloth of 2.56 kg, in zero gravity and in
    // free fall (both under the same gravity: only their exchange and gravity change the total).
    for g in [Vec3::ZERO, Vec3::new(0.0, -9.81, 0.0)] {
        let mut app = avian_app();
        app.insert_resource(Gravity(g));
        let cloth = spawn_valid(
            &mut app,
            (
                Cloth::grid(GridSpec::new(16, 16, 0.05)),
                ClothConfig {
                    solver: SolverSettings {
                        gravity: g,
                        damping: 0.0,
                        particle_mass: 0.01,
                        ..Default::default()
                    },
                    ..Default::default()
                },
                ClothPushesBodies,
                Transform::IDENTITY,
            ),
        );
        let ball = app
            .world_mut()
            .spawn((
                RigidBody::Dynamic,
                Collider::sphere(0.1),
                Mass(0.5),
                LinearVelocity(Vec3::new(0.0, -2.0, 0.0)),
                Transform::from_xyz(0.0, 0.3, 0.0),
            ))
            .id();
        let momenta = |app: &App| {
            let v = app.world().get::<LinearVelocity>(ball).unwrap().0;
            let m = app.world().get::<ComputedMass>(ball).unwrap().value();
            (v * m, cloth_momentum(sim(app, cloth)))
        };
        let cloth_mass: f32 = sim(&app, cloth).masses().iter().sum();
        let (ball0, cloth0) = momenta(&app);
        let steps = 60;
        run(&mut app, steps);
        let (ball1, cloth1) = momenta(&app);
        let t = steps as f32 * DT;
        let ball_mass = 0.5;
        // The ball hit the cloth and gave it a good part of its momentum...
        let given = cloth1 - cloth0 - cloth_mass * g * t;
        assert!(given.y < 0.3 * ball0.y, "g {g}: the cloth took {given}");
        // ...which the ball lost: the sum changed by gravity's impulse alone.
        let drift = (ball1 + cloth1) - (ball0 + cloth0) - (ball_mass + cloth_mass) * g * t;
        assert!(
            drift.length() <= 0.01 * ball0.length(),
            "g {g}: momentum drifted by {drift} (ball {ball0} → {ball1}, cloth {cloth0} → {cloth1})"
        );
    }
}

/// An `n`×`n` hammock 1 m up, pinned at its corners, pushing bodies back (4 cm spacing, 5 g
/// particles damped as a heavy canvas, sleeping below `sleep_speed`), and a dynamic crate above
/// it: `(side, mass, height)`. Returns the cloth and the crate.
fn hammock_with_crate(
    app: &mut App,
    n: u32,
    sleep_speed: f32,
    (side, mass, height): (f32, f32, f32),
) -> (Entity, Entity) {
    let cloth = spawn_valid(
        app,
        (
            Cloth::grid(GridSpec::new(n, n, 0.04)),
            ClothConfig {
                solver: SolverSettings {
                    particle_mass: 0.005,
                    damping: 5.0,
                    sleep_speed,
                    ..Default::default()
                },
                ..Default::default()
            },
            ClothPins::new([0, n - 1, n * (n - 1), n * n - 1]),
            ClothPushesBodies,
            Transform::from_xyz(0.0, 1.0, 0.0),
        ),
    );
    let crate_ = app
        .world_mut()
        .spawn((
            RigidBody::Dynamic,
            Collider::cuboid(side, side, side),
            Mass(mass),
            Transform::from_xyz(0.0, height, 0.0),
        ))
        .id();
    (cloth, crate_)
}

#[test]
fn a_box_dropped_on_a_hammock_comes_to_rest_on_it() {
    let mut app = avian_app();
    let (cloth, crate_) = hammock_with_crate(
        &mut app,
        32,
        SolverSettings::default().sleep_speed,
        (0.3, 2.0, 1.5),
    );
    let mut slow_since = None;
    // What the cloth took from the crate, summed over the steps: the crate must take the opposite.
    let mut taken = Vec3::ZERO;
    let v0 = app.world().get::<LinearVelocity>(crate_).unwrap().0;
    let ticks = 180;
    for tick in 0..ticks {
        app.update();
        taken += sim(&app, cloth)
            .reactions()
            .map(|r| r.impulse)
            .sum::<Vec3>();
        let at = app.world().get::<Position>(crate_).unwrap().0;
        let lowest = sim(&app, cloth)
            .positions()
            .iter()
            .map(|p| p.y)
            .fold(f32::INFINITY, f32::min);
        assert!(
            at.y - 0.15 > lowest - 0.02,
            "tick {tick}: the crate went through ({at})"
        );
        let speed = app
            .world()
            .get::<LinearVelocity>(crate_)
            .unwrap()
            .0
            .length();
        if speed < 0.01 {
            slow_since.get_or_insert(tick);
        } else {
            slow_since = None;
        }
    }
    assert!(
        slow_since.is_some(),
        "the crate still moves after 3 s: {} m/s",
        app.world()
            .get::<LinearVelocity>(crate_)
            .unwrap()
            .0
            .length()
    );
    let at = app.world().get::<Position>(crate_).unwrap().0;
    assert!(at.y > 0.3 && at.y < 1.1, "it rests in the hammock: {at}");
    // The crate's momentum changed by gravity's impulse and the opposite of what the cloth took
    // from it (the pins' share stays in the cloth and its anchors).
    let v1 = app.world().get::<LinearVelocity>(crate_).unwrap().0;
    let gravity = 2.0 * Vec3::new(0.0, -9.81, 0.0) * (ticks as f32 * DT);
    let change = 2.0 * (v1 - v0);
    let expected = gravity - taken;
    assert!(
        (change - expected).length() <= 0.01 * gravity.length(),
        "the crate's momentum changed by {change}, gravity and the cloth account for {expected}"
    );
}

#[test]
fn a_cloth_holding_up_a_body_does_not_fall_asleep_under_it() {
    // A cloth quick to sleep (below 5 cm/s for 30 steps) with a crate resting in it: asleep, it
    // would stop pushing back and the crate would fall through.
    let mut app = avian_app();
    let (cloth, crate_) = hammock_with_crate(&mut app, 24, 0.05, (0.2, 1.0, 1.2));
    for tick in 0..240 {
        app.update();
        let at = app.world().get::<Position>(crate_).unwrap().0;
        let lowest = sim(&app, cloth)
            .positions()
            .iter()
            .map(|p| p.y)
            .fold(f32::INFINITY, f32::min);
        assert!(
            at.y - 0.1 > lowest - 0.02,
            "tick {tick}: the crate went through ({at}; cloth asleep: {})",
            sim(&app, cloth).is_sleeping()
        );
    }
}

/// A closed box cloth keeping its volume (`bulk_modulus`, Pa) on avian's floor, pushing bodies
/// back, and a 10 kg, 30 cm crate dropped on it from `height`. Returns the cloth and the crate.
fn cushion_with_crate(app: &mut App, bulk_modulus: f32, height: f32) -> (Entity, Entity) {
    app.world_mut()
        .spawn((RigidBody::Static, Collider::half_space(Vec3::Y)));
    let size = Vec3::new(0.8, 0.2, 0.8);
    let cloth = spawn_valid(
        app,
        (
            Cloth::from_model(ClothModel::cuboid(size, 0.05).unwrap()),
            ClothConfig {
                solver: SolverSettings {
                    pressure: Pressure::Volume {
                        scale: 1.0,
                        bulk_modulus,
                    },
                    particle_mass: 0.002,
                    damping: 4.0,
                    ..Default::default()
                },
                ..Default::default()
            },
            ClothPushesBodies,
            Transform::from_xyz(0.0, 0.5 * size.y + 0.005, 0.0),
        ),
    );
    let crate_ = app
        .world_mut()
        .spawn((
            RigidBody::Dynamic,
            Collider::cuboid(0.3, 0.3, 0.3),
            Mass(10.0),
            Transform::from_xyz(0.0, height, 0.0),
        ))
        .id();
    (cloth, crate_)
}

#[test]
fn a_cushion_holds_up_a_crate_dropped_on_it() {
    let mut app = avian_app();
    let (cloth, crate_) = cushion_with_crate(&mut app, 1.0e5, 0.45);
    let built = sim(&app, cloth).built_volume().unwrap();
    // The crate lands within the first second and then bobs on the air (nothing damps it but
    // the cloth): its bottom must stay in the cushion's upper half, the volume kept.
    run(&mut app, 60);
    let (mut lowest, mut volume_off) = (f32::INFINITY, 0.0f32);
    for _ in 0..180 {
        run(&mut app, 1);
        let at = app.world().get::<Position>(crate_).unwrap().0;
        lowest = lowest.min(at.y - 0.15);
        let v = sim(&app, cloth).volume().unwrap();
        volume_off = volume_off.max((v - built).abs() / built);
        assert!(at.xz().length() < 0.2, "the crate left the cushion: {at}");
    }
    eprintln!(
        "the crate's bottom at least {lowest} m up on a 0.2 m cushion; volume within {:.2}%",
        100.0 * volume_off
    );
    assert!(lowest > 0.1, "the crate sank to {lowest} m");
    assert!(
        volume_off < 0.03,
        "volume off by {:.2}%",
        100.0 * volume_off
    );
}

#[test]
fn a_ball_bounces_on_avians_floor() {
    let mut app = avian_app();
    app.world_mut()
        .spawn((RigidBody::Static, Collider::half_space(Vec3::Y)));
    let model = ClothModel::icosphere(0.2, 2).unwrap();
    let volume = model.check_closed().unwrap();
    let ball = spawn_valid(
        &mut app,
        (
            Cloth::from_model(model),
            ClothConfig {
                solver: SolverSettings {
                    pressure: Pressure::gas(volume, 3000.0),
                    damping: 0.0,
                    ..Default::default()
                },
                ..Default::default()
            },
            Transform::from_xyz(0.0, 0.8, 0.0),
        ),
    );
    let centre = |app: &App| {
        let p = sim(app, ball).positions();
        p.iter().map(|p| p.y).sum::<f32>() / p.len() as f32
    };
    // Down to the floor, then up again: the lowest centre, and the highest after it.
    let (mut low, mut high_after) = (f32::INFINITY, f32::NEG_INFINITY);
    for _ in 0..90 {
        run(&mut app, 1);
        let (y, floor) = (
            centre(&app),
            sim(&app, ball)
                .positions()
                .iter()
                .map(|p| p.y)
                .fold(f32::INFINITY, f32::min),
        );
        assert!(floor > -0.01, "the ball went into the floor: {floor}");
        if y < low {
            (low, high_after) = (y, y);
        }
        high_after = high_after.max(y);
    }
    eprintln!("the ball's centre came down to {low} m and bounced back to {high_after} m");
    assert!(low < 0.21, "it never reached the floor: {low}");
    assert!(
        high_after > low + 0.1,
        "it did not bounce: {low} → {high_after}"
    );
}
