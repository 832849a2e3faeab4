//! The ECS: a bad cloth is reported once and skipped; the others keep running.

use super::*;

// ---------------------------------------------------------------------------------------------
// The ECS: a bad cloth is reported once and skipped; the others keep running
// ---------------------------------------------------------------------------------------------

#[test]
fn a_headless_app_with_a_bad_step_is_an_error() {
    use bevy_cloth::harness::try_headless_app;
    for dt in [0.0, -1.0 / 60.0, f32::NAN, f32::INFINITY, 1e-12, 1e30] {
        invalid_value(try_headless_app(dt).map(drop), "dt");
    }
    assert!(try_headless_app(1.0 / 60.0).is_ok());
}

fn steps(app: &App, e: Entity) -> u64 {
    app.world().get::<ClothState>(e).expect("built").steps()
}

pub(super) fn mesh(positions: Vec<[f32; 3]>, indices: Option<Vec<u32>>) -> Mesh {
    let mesh = Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::default(),
    )
    .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, positions);
    match indices {
        Some(i) => mesh.with_inserted_indices(Indices::U32(i)),
        None => mesh,
    }
}

#[test]
fn bad_cloths_are_reported_once_and_skipped_while_a_good_one_runs() {
    let mut app = app();
    let good = app
        .world_mut()
        .spawn((
            Cloth::grid(GridSpec::new(6, 6, 0.05)),
            ClothPins::new([0, 5]),
        ))
        .id();
    let square = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 1.0],
    ];
    let mut meshes = app.world_mut().resource_mut::<Assets<Mesh>>();
    let bad_meshes = [
        // No index buffer.
        (mesh(square.clone(), None), &["index buffer"][..]),
        // An index out of range.
        (
            mesh(square.clone(), Some(vec![0, 2, 1, 1, 2, 9])),
            &["index 9", "position 5"],
        ),
        // A degenerate triangle.
        (
            mesh(square.clone(), Some(vec![0, 2, 1, 1, 1, 3])),
            &["face 1", "degenerate"],
        ),
        // A zero-length edge: vertex 3 moved onto vertex 1.
        (
            mesh(
                vec![
                    [0.0, 0.0, 0.0],
                    [1.0, 0.0, 0.0],
                    [0.0, 0.0, 1.0],
                    [1.0, 0.0, 0.0],
                ],
                Some(vec![0, 2, 1, 1, 2, 3]),
            ),
            &["zero-length edge", "vertices"],
        ),
        // A line list is not a surface.
        (
            Mesh::new(PrimitiveTopology::LineList, RenderAssetUsages::default())
                .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, square.clone())
                .with_inserted_indices(Indices::U32(vec![0, 1, 1, 2])),
            &["TriangleList", "LineList"],
        ),
        // No positions at all.
        (
            Mesh::new(
                PrimitiveTopology::TriangleList,
                RenderAssetUsages::default(),
            )
            .with_inserted_indices(Indices::U32(vec![0, 1, 2])),
            &["no vertex positions"],
        ),
    ]
    .map(|(m, words)| (meshes.add(m), words));
    // A valid mesh with a bad config, and a grid with a bad config.
    let good_mesh = meshes.add(mesh(square, Some(vec![0, 2, 1, 1, 2, 3])));
    let mut bad: Vec<(Entity, &[&str])> = bad_meshes
        .into_iter()
        .map(|(handle, words)| (app.world_mut().spawn(Cloth::from_mesh(handle)).id(), words))
        .collect();
    let nan_mass = ClothConfig {
        solver: SolverSettings {
            particle_mass: f32::NAN,
            ..Default::default()
        },
        ..Default::default()
    };
    bad.push((
        app.world_mut()
            .spawn((Cloth::from_mesh(good_mesh), nan_mass))
            .id(),
        &["particle_mass"],
    ));
    bad.push((
        app.world_mut()
            .spawn((
                Cloth::grid(GridSpec::new(4, 4, 0.1)),
                ClothConfig {
                    solver: SolverSettings {
                        substeps: 0,
                        ..Default::default()
                    },
                    ..Default::default()
                },
            ))
            .id(),
        &["substeps"],
    ));
    // A pin anchored at a non-finite point, and a subdivision level out of range.
    let mut pins = ClothPins::default();
    pins.pin(0, PinAnchor::World(Vec3::NAN));
    bad.push((
        app.world_mut()
            .spawn((Cloth::grid(GridSpec::new(4, 4, 0.1)), pins))
            .id(),
        &["pin target", "finite"],
    ));
    bad.push((
        app.world_mut()
            .spawn((
                Cloth::grid(GridSpec::new(4, 4, 0.1)),
                ClothSubdivision {
                    level: 9,
                    ..Default::default()
                },
            ))
            .id(),
        &["subdivision.level", "9"],
    ));
    run(&mut app, 1);
    let reported: Vec<_> = bad
        .iter()
        .map(|&(e, words)| {
            let invalid = app
                .world()
                .entity(e)
                .get_ref::<ClothInvalid>()
                .unwrap_or_else(|| panic!("{words:?}: not reported"));
            let message = invalid.0.to_string();
            for w in words {
                assert!(message.contains(w), "{message:?} does not name {w:?}");
            }
            assert!(app.world().get::<ClothState>(e).is_none(), "{message}");
            invalid.last_changed()
        })
        .collect();

    // The good cloth keeps stepping; the bad ones are not rebuilt (nor reported) again.
    let before = steps(&app, good);
    run(&mut app, 10);
    assert_eq!(steps(&app, good), before + 10);
    for (&(e, words), tick) in bad.iter().zip(reported) {
        let invalid = app.world().entity(e).get_ref::<ClothInvalid>().unwrap();
        assert_eq!(invalid.last_changed(), tick, "{words:?} was reported again");
        assert!(app.world().get::<ClothState>(e).is_none());
    }
}

#[test]
fn a_mesh_cloth_that_subdivision_rejects_is_reported_with_the_reason() {
    // Two triangles wound against each other: fine as a cloth, but not as a subdivision surface.
    let mut app = app();
    let handle = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh(
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
        ],
        Some(vec![0, 2, 1, 1, 3, 2]),
    ));
    let plain = app.world_mut().spawn(Cloth::from_mesh(handle.clone())).id();
    let smooth = app
        .world_mut()
        .spawn((Cloth::from_mesh(handle), ClothSubdivision::default()))
        .id();
    run(&mut app, 3);
    assert!(steps(&app, plain) > 0);
    let e = &app.world().get::<ClothInvalid>(smooth).expect("reported").0;
    assert!(
        matches!(
            e,
            ClothError::Subdivision(SubdivisionError::InconsistentOrientation { .. })
        ),
        "{e:?}"
    );
    assert!(e.to_string().contains("edge (1, 2)"), "{e}");
}

#[test]
fn bad_colliders_and_wind_are_ignored_while_cloths_keep_running() {
    let mut app = app();
    let cloth = app
        .world_mut()
        .spawn((
            Cloth::grid(GridSpec::new(6, 6, 0.05)),
            ClothPins::new([0, 5]),
        ))
        .id();
    app.world_mut().spawn((
        ClothCollider::sphere(f32::NAN),
        Transform::from_xyz(0.0, -0.2, 0.0),
    ));
    app.world_mut().spawn((
        ClothCollider::cuboid(Vec3::ONE).with_margin(-1.0),
        Transform::from_xyz(0.0, -0.5, 0.0),
    ));
    app.insert_resource(Wind {
        velocity: Vec3::new(f32::NAN, 0.0, 0.0),
        ..Default::default()
    });
    app.world_mut().spawn((
        WindZone {
            shape: WindZoneShape::Sphere(1.0),
            velocity: Vec3::X,
            gusts: None,
            falloff: 3.0,
        },
        Transform::default(),
    ));
    run(&mut app, 20);
    assert!(app.world().get::<ClothInvalid>(cloth).is_none());
    assert_eq!(steps(&app, cloth), 20 - 1);
    let state = app.world().get::<ClothState>(cloth).unwrap();
    assert!(state.positions().iter().all(|p| p.is_finite()));
    assert_eq!(
        state.sim().active_colliders(),
        0,
        "bad colliders are skipped"
    );
}

/// Whether every position in cloth `e`'s render mesh is finite.
fn mesh_is_finite(app: &App, e: Entity) -> bool {
    let handle = app.world().get::<ClothState>(e).unwrap().mesh();
    let mesh = app.world().resource::<Assets<Mesh>>().get(handle).unwrap();
    match mesh.attribute(Mesh::ATTRIBUTE_POSITION) {
        Some(bevy::mesh::VertexAttributeValues::Float32x3(p)) => {
            p.iter().flatten().all(|c| c.is_finite())
        }
        _ => false,
    }
}

#[test]
fn a_cloth_scaled_to_zero_is_an_error_at_build_and_holds_its_mesh_when_scaled_later() {
    let mut app = app();
    let flat = spawn(
        &mut app,
        (
            Cloth::grid(GridSpec::new(4, 4, 0.1)),
            Transform::from_scale(Vec3::new(1.0, 0.0, 1.0)),
        ),
    );
    let e = &app.world().get::<ClothInvalid>(flat).expect("reported").0;
    assert!(e.to_string().contains("GlobalTransform determinant"), "{e}");

    let cloth = spawn_valid(
        &mut app,
        (
            Cloth::grid(GridSpec::new(6, 6, 0.05)),
            ClothPins::new([0, 5]),
        ),
    );
    run(&mut app, 5);
    // Scaled to zero, then moved to a point that is not finite: the cloth steps on, its mesh keeps
    // its last finite shape.
    let edits: [fn(&mut Transform); 2] = [|t| t.scale = Vec3::ZERO, |t| t.translation = Vec3::NAN];
    for edit in edits {
        let before = steps(&app, cloth);
        edit(&mut app.world_mut().get_mut::<Transform>(cloth).unwrap());
        run(&mut app, 5);
        assert!(app.world().get::<ClothInvalid>(cloth).is_none());
        assert_eq!(steps(&app, cloth), before + 5);
        assert!(state(&app, cloth).positions().iter().all(|p| p.is_finite()));
        assert!(mesh_is_finite(&app, cloth));
    }
}
