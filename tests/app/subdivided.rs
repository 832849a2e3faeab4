//! Subdivided cloths, and meshes whose buffers were replaced.

use super::*;

pub(super) fn vertex_count(app: &App, e: Entity) -> usize {
    let meshes = app.world().resource::<Assets<Mesh>>();
    meshes.get(state(app, e).mesh()).unwrap().count_vertices()
}

#[test]
fn subdivided_cloth_renders_the_refined_surface_and_changes_level_live() {
    let mut app = app();
    let n = 8u32;
    let e = spawn(
        &mut app,
        (
            hanging(n),
            ClothSubdivision {
                level: 2,
                ..default()
            },
        ),
    );
    // A quad grid of (n-1)² faces refined twice: (4(n-1)+1)² vertices.
    let refined = (4 * (n as usize - 1) + 1).pow(2);
    assert_eq!(vertex_count(&app, e), refined);
    run(&mut app, 10);
    let steps = state(&app, e).steps();
    let mesh = app
        .world()
        .resource::<Assets<Mesh>>()
        .get(state(&app, e).mesh())
        .unwrap();
    let Some(VertexAttributeValues::Float32x3(p)) = mesh.attribute(Mesh::ATTRIBUTE_POSITION) else {
        panic!("positions")
    };
    assert!(p.iter().flatten().all(|v| v.is_finite()));
    // The refined surface of a hanging cloth hangs too: its lowest point is below the pins.
    assert!(
        p.iter().any(|v| v[1] < -0.1),
        "refined surface did not move"
    );

    app.world_mut()
        .get_mut::<ClothSubdivision>(e)
        .unwrap()
        .level = 1;
    run(&mut app, 1);
    assert_eq!(vertex_count(&app, e), (2 * (n as usize - 1) + 1).pow(2));
    assert_eq!(
        state(&app, e).steps(),
        steps + 1,
        "changing the level must not reset the cloth"
    );

    app.world_mut().entity_mut(e).remove::<ClothSubdivision>();
    run(&mut app, 1);
    assert_eq!(vertex_count(&app, e), (n * n) as usize);

    app.world_mut().entity_mut(e).insert(ClothSubdivision {
        level: 9,
        ..default()
    });
    run(&mut app, 1);
    let err = &app
        .world()
        .get::<ClothEditRejected>(e)
        .expect("level 9 is rejected")
        .0;
    assert!(err.to_string().contains("subdivision.level"), "{err}");
}

#[test]
fn a_cloth_simulated_at_a_subdivided_resolution_keeps_its_pins_mass_and_shape() {
    let mut app = app();
    let n = 8u32;
    let at = Vec3::new(0.0, 2.0, 0.0);
    let plain = spawn(&mut app, hanging_at(n, at));
    let refined = spawn(
        &mut app,
        (
            hanging_at(n, at),
            ClothSubdivision {
                level: 1,
                target: SubdivisionTarget::Simulation,
                ..default()
            },
        ),
    );
    // One level: (2(n-1)+1)² particles, simulated and rendered as they are.
    let count = (2 * (n as usize - 1) + 1).pow(2);
    assert_eq!(state(&app, refined).positions().len(), count);
    assert_eq!(vertex_count(&app, refined), count);
    let total = |e: Entity| -> f32 { state(&app, e).sim().masses().iter().sum() };
    assert!(
        (total(refined) / total(plain) - 1.0).abs() < 1e-5,
        "total mass {} vs {}",
        total(refined),
        total(plain)
    );
    // Pins name the unrefined particles and hold the particles they became (the corners stay
    // put with the default edge-and-corner boundary).
    let pinned = |app: &App, e: Entity, p: u32| {
        let s = state(app, e);
        s.positions()[s.particle(p).expect("pinned particle exists")]
    };
    for p in [0, n - 1] {
        assert_eq!(pinned(&app, refined, p), pinned(&app, plain, p));
    }
    run(&mut app, 60);
    for p in [0, n - 1] {
        assert_eq!(pinned(&app, refined, p), pinned(&app, plain, p), "pin {p}");
    }
    // Both hang; the finer cloth's lowest point is close to the coarse one's (same material).
    let lowest = |e: Entity| {
        state(&app, e)
            .positions()
            .iter()
            .map(|p| p.y)
            .fold(f32::INFINITY, f32::min)
    };
    assert!(lowest(plain) < at.y - 0.2, "{}", lowest(plain));
    assert!(
        (lowest(refined) - lowest(plain)).abs() < 0.1,
        "refined {} vs plain {}",
        lowest(refined),
        lowest(plain)
    );

    // A new level restarts the cloth at the new resolution; back to Render, the simulation
    // is coarse again and only the surface is refined.
    let mut sub = app
        .world_mut()
        .get_mut::<ClothSubdivision>(refined)
        .unwrap();
    sub.level = 2;
    run(&mut app, 1);
    assert_eq!(
        state(&app, refined).positions().len(),
        (4 * (n as usize - 1) + 1).pow(2)
    );
    assert!(state(&app, refined).steps() <= 1, "restarted");
    app.world_mut()
        .get_mut::<ClothSubdivision>(refined)
        .unwrap()
        .target = SubdivisionTarget::Render;
    run(&mut app, 1);
    assert_eq!(state(&app, refined).positions().len(), (n * n) as usize);
    assert_eq!(
        vertex_count(&app, refined),
        (4 * (n as usize - 1) + 1).pow(2)
    );
    // Out-of-range pins are reported against the unrefined cloth's particle count.
    app.world_mut()
        .get_mut::<ClothSubdivision>(refined)
        .unwrap()
        .target = SubdivisionTarget::Simulation;
    app.world_mut()
        .get_mut::<ClothPins>(refined)
        .unwrap()
        .pin(n * n, PinAnchor::Rest);
    run(&mut app, 1);
    let err = &app
        .world()
        .get::<ClothEditRejected>(refined)
        .expect("bad pin")
        .0;
    assert!(
        err.to_string()
            .contains(&format!("has {} particles", n * n)),
        "{err}"
    );
}

#[test]
fn a_mesh_whose_buffers_were_replaced_stops_the_cloth_once() {
    let mut app = app();
    let e = spawn(&mut app, hanging(6));
    let mesh = state(&app, e).mesh().clone();
    // Someone shrinks the position buffer behind the plugin's back.
    app.world_mut()
        .resource_mut::<Assets<Mesh>>()
        .get_mut(&mesh)
        .unwrap()
        .insert_attribute(Mesh::ATTRIBUTE_POSITION, vec![[0.0f32; 3]; 3]);
    run(&mut app, 3);
    let err = &app.world().get::<ClothInvalid>(e).expect("stopped").0;
    assert!(err.to_string().contains("buffer has 3 entries"), "{err}");
}
