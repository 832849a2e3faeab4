//! Closed meshes split along their seams (as exporters and Bevy's own shapes give them): simulated
//! welded, rendered with their seams, holding air as a mesh welded beforehand does.

use bevy::mesh::VertexAttributeValues;

use super::*;
use bevy_cloth::sim::ClothModel;

/// Bevy's UV sphere: 16 sectors, 8 stacks, each seam vertex and pole one copy per texture
/// coordinate (17 × 9 vertices for 16 × 7 + 2 points).
fn uv_sphere() -> Mesh {
    Sphere::new(0.3).mesh().uv(16, 8)
}

fn positions(mesh: &Mesh) -> Vec<Vec3> {
    match mesh.attribute(Mesh::ATTRIBUTE_POSITION) {
        Some(VertexAttributeValues::Float32x3(p)) => p.iter().map(|p| Vec3::from(*p)).collect(),
        _ => panic!("no positions"),
    }
}

fn model_of(mesh: &Mesh) -> ClothModel {
    let indices: Vec<u32> = mesh.indices().unwrap().iter().map(|i| i as u32).collect();
    ClothModel::from_mesh(&positions(mesh), None, &indices, 3).unwrap()
}

#[test]
fn a_sphere_split_along_its_seams_is_welded_closed_and_an_open_sheet_is_not() {
    let split = model_of(&uv_sphere());
    assert_eq!(split.particle_count(), 17 * 9);
    let e = split.check_closed().unwrap_err();
    assert!(e.to_string().contains("borders only triangle"), "{e}");
    let (welded, particle_of) = split.weld_seams().expect("welded");
    assert_eq!(welded.particle_count(), 16 * 7 + 2);
    assert_eq!(particle_of.len(), 17 * 9);
    for (v, &p) in particle_of.iter().enumerate() {
        let d = split.rest_positions[v].distance(welded.rest_positions[p as usize]);
        assert!(d < 1e-5, "vertex {v} is {d} m from its particle");
    }
    let v = welded.check_closed().unwrap();
    assert!(
        v > 0.95 * 4.0 / 3.0 * std::f32::consts::PI * 0.027 * 0.9,
        "{v}"
    );
    // An open sheet is left as it is, seams or not.
    let sheet = model_of(
        &Plane3d::default()
            .mesh()
            .size(1.0, 1.0)
            .subdivisions(3)
            .build(),
    );
    assert!(sheet.weld_seams().is_none());
}

/// A gas ball 1 m up from `source`, 2 kPa above the air outside at its built volume.
fn ball(app: &mut App, source: Cloth, volume: f32) -> Entity {
    spawn_valid(
        app,
        (
            source,
            ClothConfig {
                solver: SolverSettings {
                    pressure: Pressure::gas(volume, 2000.0),
                    ..Default::default()
                },
                // The mesh shows the last step, not a blend of the last two.
                interpolate: false,
                ..Default::default()
            },
            ClothPins::new([0]),
            Transform::from_xyz(0.0, 1.0, 0.0),
        ),
    )
}

#[test]
fn a_split_sphere_mesh_holds_air_as_the_welded_one_does_and_renders_its_seams() {
    let mut app = app();
    let split = model_of(&uv_sphere());
    let (welded, particle_of) = split.weld_seams().unwrap();
    let volume = welded.check_closed().unwrap();
    let mesh = app
        .world_mut()
        .resource_mut::<Assets<Mesh>>()
        .add(uv_sphere());
    let from_mesh = ball(&mut app, Cloth::from_mesh(mesh), volume);
    let mut other = super::common::app();
    let from_model = ball(&mut other, Cloth::from_model(welded), volume);
    run(&mut app, 60);
    run(&mut other, 60);
    // The same particles, pinned at the same pole: the same motion, bit for bit.
    let (a, b) = (sim(&app, from_mesh), sim(&other, from_model));
    assert_eq!(a.steps(), b.steps());
    assert_eq!(a.positions(), b.positions());
    assert!(a.volume().unwrap() > 0.98 * volume, "{:?}", a.volume());
    // The render mesh keeps every split vertex, each where its particle is.
    let meshes = app.world().resource::<Assets<Mesh>>();
    let rendered = positions(meshes.get(state(&app, from_mesh).mesh()).unwrap());
    assert_eq!(rendered.len(), particle_of.len());
    let to_world = app
        .world()
        .get::<GlobalTransform>(from_mesh)
        .unwrap()
        .affine();
    for (v, &p) in particle_of.iter().enumerate() {
        let d = to_world
            .transform_point3(rendered[v])
            .distance(a.positions()[p as usize]);
        assert!(d < 1e-5, "vertex {v} drawn {d} m from its particle");
    }
    // Pins index the mesh's vertices: the pole's copies are one particle.
    let last_pole = *particle_of.last().unwrap() as usize;
    assert_eq!(state(&app, from_mesh).particle(17 * 9 - 1), Some(last_pole));
}
