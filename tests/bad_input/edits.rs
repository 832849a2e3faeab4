//! Runtime edits of running cloths are transactions: a rejected edit leaves the cloth running
//! where it was and is reported on the cloth; an edit that keeps the topology keeps the motion.

use bevy::mesh::{MeshVertexAttribute, VertexAttributeValues};

use super::ecs::mesh;
use super::*;

/// The rejection on cloth `e`, which must still be running.
#[track_caller]
fn rejection(app: &App, e: Entity) -> String {
    assert!(
        app.world().get::<ClothInvalid>(e).is_none(),
        "a rejected edit does not stop the cloth"
    );
    assert!(
        app.world().get::<ClothState>(e).is_some(),
        "a rejected edit keeps the cloth's state"
    );
    app.world()
        .get::<ClothEditRejected>(e)
        .expect("the rejection is reported on the cloth")
        .0
        .to_string()
}

fn pins_mut(app: &mut App, e: Entity) -> Mut<'_, ClothPins> {
    app.world_mut().get_mut::<ClothPins>(e).unwrap()
}

#[test]
fn a_rejected_pin_edit_on_a_cloth_with_targets_keeps_it_running_as_it_was() {
    let mut app = app();
    // The top row follows its targets (weight 0: held there), the rest hangs free.
    let weights = (0..64).map(|i| if i < 8 { 0.0 } else { -1.0 }).collect();
    let cloth = spawn_valid(
        &mut app,
        (
            Cloth::grid(GridSpec::new(8, 8, 0.05)),
            ClothTargets {
                weights: TargetWeights::Values(weights),
            },
            ClothPins::new([0]),
        ),
    );
    run(&mut app, 10);
    let top: Vec<Vec3> = state(&app, cloth).positions()[..8].to_vec();
    let steps_before = state(&app, cloth).steps();

    pins_mut(&mut app, cloth).pin(5000, PinAnchor::World(Vec3::splat(9.0)));
    run(&mut app, 1);
    let message = rejection(&app, cloth);
    assert!(message.contains("5000"), "{message}");
    run(&mut app, 9);
    assert_eq!(state(&app, cloth).steps(), steps_before + 10);
    // The top row is still held by its pin and its targets.
    for (p, q) in state(&app, cloth).positions()[..8].iter().zip(&top) {
        assert!(p.distance(*q) < 1e-4, "{p} left {q}");
    }

    // Undoing the edit is accepted and clears the report.
    *pins_mut(&mut app, cloth) = ClothPins::new([0]);
    run(&mut app, 1);
    assert!(app.world().get::<ClothEditRejected>(cloth).is_none());
    assert_eq!(state(&app, cloth).steps(), steps_before + 11);
}

#[test]
fn a_rejected_edit_leaves_the_cloth_where_it_was() {
    let mut app = app();
    let cloth = spawn_valid(
        &mut app,
        (
            Cloth::grid(GridSpec::new(16, 16, 0.05)),
            ClothPins::new([0]),
        ),
    );
    let rest = centre_of_mass(&app, cloth);
    run(&mut app, 40);
    assert!(centre_of_mass(&app, cloth).distance(rest) > 0.1, "it swung");

    // A pin out of range, then a bad mass: each is reported, and the cloth steps on from where
    // it was, with the pins and settings it had.
    type Edit = fn(&mut App, Entity);
    let edits: [(&str, Edit); 2] = [
        ("pin index 999", |app, e| {
            pins_mut(app, e).pin(999, PinAnchor::Rest);
        }),
        ("particle_mass", |app, e| {
            let mut config = app.world_mut().get_mut::<ClothConfig>(e).unwrap();
            config.solver.particle_mass = -1.0;
        }),
    ];
    for (words, edit) in edits {
        let before = centre_of_mass(&app, cloth);
        let steps = state(&app, cloth).steps();
        edit(&mut app, cloth);
        run(&mut app, 1);
        let message = rejection(&app, cloth);
        assert!(message.contains(words), "{message} does not name {words}");
        assert_eq!(state(&app, cloth).steps(), steps + 1);
        let after = centre_of_mass(&app, cloth);
        assert!(
            after.distance(before) < 0.05 && after.distance(rest) > 0.1,
            "{words}: the centre of mass went from {before} to {after} (rest {rest})"
        );
        assert_eq!(sim(&app, cloth).pinned().collect::<Vec<_>>(), [0]);
        assert_eq!(sim(&app, cloth).settings().particle_mass, 0.001);
    }

    // A valid edit is accepted, clears the report and also keeps the motion.
    let before = centre_of_mass(&app, cloth);
    *pins_mut(&mut app, cloth) = ClothPins::new([0, 1]);
    app.world_mut()
        .get_mut::<ClothConfig>(cloth)
        .unwrap()
        .solver
        .particle_mass = 0.002;
    run(&mut app, 1);
    assert!(app.world().get::<ClothEditRejected>(cloth).is_none());
    assert_eq!(sim(&app, cloth).pinned().collect::<Vec<_>>(), [0, 1]);
    assert_eq!(sim(&app, cloth).settings().particle_mass, 0.002);
    let after = centre_of_mass(&app, cloth);
    assert!(after.distance(before) < 0.05, "{before} -> {after}");
}

#[test]
fn an_edit_that_keeps_the_topology_keeps_the_motion() {
    let mut app = app();
    let cloth = spawn_valid(
        &mut app,
        (Cloth::grid(GridSpec::new(8, 8, 0.05)), ClothPins::new([0])),
    );
    run(&mut app, 30);
    let positions = state(&app, cloth).positions().to_vec();
    let velocities = sim(&app, cloth).velocities().to_vec();
    let steps = state(&app, cloth).steps();
    assert!(velocities.iter().any(|v| v.length() > 0.1), "it swings");
    // Targets added (the cloth is rebuilt around them) leave every particle where it was.
    let weights = (0..64).map(|i| if i == 0 { 0.0 } else { -1.0 }).collect();
    app.world_mut().entity_mut(cloth).insert(ClothTargets {
        weights: TargetWeights::Values(weights),
    });
    app.world_mut().run_schedule(PostUpdate);
    assert!(app.world().get::<ClothEditRejected>(cloth).is_none());
    assert!(sim(&app, cloth).model().particle_count() == 64);
    assert_eq!(state(&app, cloth).positions(), &positions[..]);
    assert_eq!(sim(&app, cloth).velocities(), &velocities[..]);
    assert_eq!(state(&app, cloth).steps(), steps);
}

/// Two triangles: a unit square in the XZ plane, scaled by `scale`.
fn square(scale: f32) -> Mesh {
    let p = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 1.0],
    ];
    let scaled = p.map(|v| v.map(|c| c * scale)).to_vec();
    mesh(scaled, Some(vec![0, 2, 1, 1, 2, 3]))
}

#[test]
fn every_mesh_attribute_shorter_or_longer_than_the_positions_is_an_error() {
    let mut app = app();
    let short_and_long: [(MeshVertexAttribute, VertexAttributeValues); 6] = [
        (Mesh::ATTRIBUTE_NORMAL, vec![[0.0, 1.0, 0.0]; 3].into()),
        (Mesh::ATTRIBUTE_NORMAL, vec![[0.0, 1.0, 0.0]; 5].into()),
        (Mesh::ATTRIBUTE_UV_0, vec![[0.0, 0.0]; 3].into()),
        (Mesh::ATTRIBUTE_UV_1, vec![[0.0, 0.0]; 2].into()),
        (Mesh::ATTRIBUTE_COLOR, vec![[1.0; 4]; 3].into()),
        (
            Mesh::ATTRIBUTE_TANGENT,
            vec![[1.0, 0.0, 0.0, 1.0]; 1].into(),
        ),
    ];
    let cloths: Vec<_> = short_and_long
        .into_iter()
        .map(|(attribute, values)| {
            let count = values.len();
            let name = attribute.name;
            let handle = app
                .world_mut()
                .resource_mut::<Assets<Mesh>>()
                .add(square(1.0).with_inserted_attribute(attribute, values));
            let e = app.world_mut().spawn(Cloth::from_mesh(handle)).id();
            (e, name, count)
        })
        .collect();
    run(&mut app, 2);
    for (e, name, count) in cloths {
        let invalid = app.world().get::<ClothInvalid>(e);
        let message = invalid.map(|i| i.0.to_string()).unwrap_or_default();
        for w in [
            name.to_string(),
            format!("{count} values"),
            "4 vertex".into(),
        ] {
            assert!(
                message.contains(&w),
                "{name}: {message:?} does not name {w:?}"
            );
        }
    }
}

#[test]
fn a_replaced_source_mesh_rebuilds_the_cloth_and_a_bad_one_is_rejected() {
    let mut app = app();
    let handle = app
        .world_mut()
        .resource_mut::<Assets<Mesh>>()
        .add(square(1.0));
    let cloth = spawn_valid(
        &mut app,
        (Cloth::from_mesh(handle.clone()), ClothPins::new([0, 1])),
    );
    run(&mut app, 20);
    let replace = |app: &mut App, mesh: Mesh| {
        let mut meshes = app.world_mut().resource_mut::<Assets<Mesh>>();
        meshes.insert(handle.id(), mesh).unwrap();
        run(app, 2);
    };

    // The same topology, twice as large: the new rest shape, and the cloth moves on from where it
    // was rather than restarting.
    let steps = state(&app, cloth).steps();
    replace(&mut app, square(2.0));
    assert!(app.world().get::<ClothEditRejected>(cloth).is_none());
    assert_eq!(
        sim(&app, cloth).model().rest_positions[3],
        Vec3::new(2.0, 0.0, 2.0)
    );
    assert_eq!(state(&app, cloth).steps(), steps + 2);

    // Another topology (a strip of three quads) starts from its rest shape.
    let strip: Vec<[f32; 3]> = (0..8)
        .map(|i| [(i / 2) as f32, 0.0, (i % 2) as f32])
        .collect();
    let indices = (0..3u32)
        .flat_map(|q| [2 * q, 2 * q + 1, 2 * q + 2, 2 * q + 2, 2 * q + 1, 2 * q + 3])
        .collect();
    replace(&mut app, mesh(strip, Some(indices)));
    assert_eq!(sim(&app, cloth).model().particle_count(), 8);
    assert!(state(&app, cloth).steps() < 3);

    // A bad replacement (an index out of range) is rejected: the strip runs on.
    let steps = state(&app, cloth).steps();
    replace(&mut app, mesh(vec![[0.0; 3]; 3], Some(vec![0, 1, 7])));
    let message = rejection(&app, cloth);
    assert!(message.contains("index 7"), "{message}");
    assert_eq!(sim(&app, cloth).model().particle_count(), 8);
    assert_eq!(state(&app, cloth).steps(), steps + 2);
}

#[test]
fn a_removed_config_or_pin_set_is_replaced_by_the_default_and_the_cloth_runs_on() {
    let mut app = app();
    let mut config = ClothConfig::default();
    config.solver.particle_mass = 0.002;
    let cloth = spawn_valid(
        &mut app,
        (
            Cloth::grid(GridSpec::new(8, 8, 0.05)),
            ClothPins::new([0, 7]),
            config,
        ),
    );
    run(&mut app, 5);
    let steps = state(&app, cloth).steps();
    app.world_mut().entity_mut(cloth).remove::<ClothPins>();
    run(&mut app, 1);
    assert_eq!(
        app.world().get::<ClothPins>(cloth),
        Some(&ClothPins::default())
    );
    assert_eq!(sim(&app, cloth).pinned().count(), 0, "released");
    app.world_mut().entity_mut(cloth).remove::<ClothConfig>();
    run(&mut app, 1);
    assert!(app.world().get::<ClothConfig>(cloth).is_some());
    assert_eq!(sim(&app, cloth).settings().particle_mass, 0.001);
    assert_eq!(state(&app, cloth).steps(), steps + 2, "it never stopped");
}

#[test]
fn a_cloth_refused_at_spawn_is_built_once_its_bad_targets_or_subdivision_are_removed() {
    let mut app = app();
    let nan = (0..64)
        .map(|i| if i == 3 { f32::NAN } else { 0.5 })
        .collect();
    let targeted = app
        .world_mut()
        .spawn((
            Cloth::grid(GridSpec::new(8, 8, 0.05)),
            ClothTargets {
                weights: TargetWeights::Values(nan),
            },
        ))
        .id();
    let subdivided = app
        .world_mut()
        .spawn((
            Cloth::grid(GridSpec::new(8, 8, 0.05)),
            ClothSubdivision {
                level: bevy_cloth::components::MAX_CLOTH_SUBDIVISION_LEVEL + 1,
                ..Default::default()
            },
        ))
        .id();
    run(&mut app, 2);
    for e in [targeted, subdivided] {
        assert!(app.world().get::<ClothInvalid>(e).is_some());
    }
    app.world_mut()
        .entity_mut(targeted)
        .remove::<ClothTargets>();
    app.world_mut()
        .entity_mut(subdivided)
        .remove::<ClothSubdivision>();
    run(&mut app, 2);
    for e in [targeted, subdivided] {
        assert!(
            app.world().get::<ClothInvalid>(e).is_none(),
            "{e} still invalid"
        );
        assert!(state(&app, e).steps() > 0, "{e} not stepping");
    }
}
