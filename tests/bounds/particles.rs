//! The particle bound, `MAX_PARTICLES`, on every path that makes particles: grid and disc specs,
//! meshes, hand-built models, subdivision before simulating and, for the render side, the
//! refined vertex and face counts.

use std::time::Instant;

use bevy::asset::RenderAssetUsages;
use bevy::mesh::{Indices, Mesh, PrimitiveTopology};
use bevy::prelude::*;
use bevy_cloth::ClothError;
use bevy_cloth::sim::{
    ClothModel, DiscSpec, GridSpec, MAX_DISC_RINGS, MAX_DISC_SECTORS, MAX_PARTICLES, SpringKind,
};
use bevy_cloth::subdivision::{
    BoundaryMode, MAX_CONTROL_VERTICES, MAX_REFINED_FACES, MAX_REFINED_VERTICES, PolyMesh,
    Subdivider, SubdivisionError, VertexRule,
};
use glam::DVec3;

use super::common;
use super::{error, names};

/// A `ClothError::TooMany` on particles, bound `MAX_PARTICLES`, counting `count`.
fn too_many_particles(e: &ClothError, count: u64) {
    assert!(
        matches!(e, ClothError::TooMany { field: "particles", count: c, bound, .. }
            if *c == count && *bound == MAX_PARTICLES as u64),
        "{e:?}"
    );
    names(
        e,
        &["particles", &count.to_string(), &MAX_PARTICLES.to_string()],
    );
}

#[test]
fn a_grid_of_max_particles_is_accepted_and_one_row_more_is_not() {
    // At the bound the spec is validated, not built (a 1024 × 1024 cloth takes seconds to build
    // in the test profile).
    assert_eq!(MAX_PARTICLES, 1024 * 1024);
    assert_eq!(GridSpec::new(1024, 1024, 0.001).validate(), Ok(()));
    let e = error(GridSpec::new(1024, 1025, 0.001).validate());
    assert_eq!(e, ClothError::GridTooLarge { nx: 1024, ny: 1025 });
    names(&e, &["1024×1025", "1049600", &MAX_PARTICLES.to_string()]);
}

#[test]
fn a_4096_square_grid_is_refused_at_once() {
    let start = Instant::now();
    let e = error(ClothModel::grid(&GridSpec::new(4096, 4096, 0.001)));
    let took = start.elapsed();
    assert_eq!(e, ClothError::GridTooLarge { nx: 4096, ny: 4096 });
    names(&e, &["4096×4096", "16777216", &MAX_PARTICLES.to_string()]);
    eprintln!("a 4096 × 4096 grid was refused in {took:?}");
    // Nothing was allocated: far below what building it would take (seconds).
    assert!(took.as_secs_f64() < 1.0, "{took:?}");
}

#[test]
fn a_disc_within_max_particles_is_accepted_and_one_ring_more_is_not() {
    // 1 + 16 · 255 · 256 = 1,044,481 particles (validated, not built).
    let at = DiscSpec::new(MAX_DISC_SECTORS, 255, 1.0);
    assert!(at.particle_count() <= MAX_PARTICLES);
    assert_eq!(at.validate(), Ok(()));
    let past = DiscSpec::new(MAX_DISC_SECTORS, 256, 1.0);
    let e = error(ClothModel::disc(&past));
    too_many_particles(&e, past.particle_count() as u64);
    names(&e, &["sectors = 16", "rings = 256"]);
    // The ring bound itself: 3 sectors of MAX_DISC_RINGS rings are within the particle bound.
    assert_eq!(DiscSpec::new(3, MAX_DISC_RINGS, 1.0).validate(), Ok(()));
    let e = error(DiscSpec::new(3, MAX_DISC_RINGS + 1, 1.0).validate());
    assert!(matches!(
        e,
        ClothError::CountOutOfRange { field: "rings", .. }
    ));
    names(&e, &["rings", "513", "512"]);
    let e = error(DiscSpec::new(MAX_DISC_SECTORS + 1, 4, 1.0).validate());
    assert!(matches!(
        e,
        ClothError::CountOutOfRange {
            field: "sectors",
            ..
        }
    ));
    names(&e, &["sectors", "17", "16"]);
}

/// `count` points along a line, 1 mm apart.
fn points(count: usize) -> Vec<Vec3> {
    (0..count)
        .map(|i| Vec3::new(i as f32 * 1e-3, 0.0, 0.0))
        .collect()
}

/// `count` points, the first three a triangle.
fn triangle_and_points(count: usize) -> Vec<Vec3> {
    let mut p = points(count);
    p[2] = Vec3::new(0.0, 0.0, 1e-3);
    p
}

#[test]
fn a_mesh_of_max_particles_vertices_is_accepted_and_one_more_is_not() {
    let at = ClothModel::from_mesh(&triangle_and_points(MAX_PARTICLES), None, &[0, 1, 2], 3)
        .expect("a mesh at the bound");
    assert_eq!(at.particle_count(), MAX_PARTICLES);
    assert_eq!(at.validate(), Ok(()));
    let e = error(ClothModel::from_mesh(
        &triangle_and_points(MAX_PARTICLES + 1),
        None,
        &[0, 1, 2],
        3,
    ));
    too_many_particles(&e, MAX_PARTICLES as u64 + 1);
    let chain = [(0, 1, SpringKind::Structural)];
    assert!(ClothModel::from_springs(&points(MAX_PARTICLES), &chain).is_ok());
    let e = error(ClothModel::from_springs(&points(MAX_PARTICLES + 1), &chain));
    too_many_particles(&e, MAX_PARTICLES as u64 + 1);
}

#[test]
fn a_hand_built_model_past_max_particles_is_refused_by_validate() {
    let mut model =
        ClothModel::from_springs(&points(4), &[(0, 1, SpringKind::Structural)]).unwrap();
    model.rest_positions = points(MAX_PARTICLES);
    model.uvs = vec![Vec2::ZERO; MAX_PARTICLES];
    assert_eq!(model.validate(), Ok(()));
    model.rest_positions.push(Vec3::ONE);
    model.uvs.push(Vec2::ZERO);
    too_many_particles(&error(model.validate()), MAX_PARTICLES as u64 + 1);
}

#[test]
fn a_bevy_mesh_past_max_particles_makes_an_invalid_cloth() {
    let mut app = common::app();
    let positions: Vec<[f32; 3]> = triangle_and_points(MAX_PARTICLES + 1)
        .iter()
        .map(|p| p.to_array())
        .collect();
    let mesh = Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::default(),
    )
    .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, positions)
    .with_inserted_indices(Indices::U32(vec![0, 1, 2]));
    let handle = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
    let e = common::spawn(&mut app, bevy_cloth::Cloth::from_mesh(handle));
    let invalid = app
        .world()
        .get::<bevy_cloth::ClothInvalid>(e)
        .expect("the cloth is invalid");
    too_many_particles(&invalid.0, MAX_PARTICLES as u64 + 1);
}

#[test]
fn subdivision_before_simulating_counts_its_particles_before_refining() {
    // A 512 × 512 grid refined once has 1023² particles, within the bound (predicted, not
    // built); the prediction is exact, as a small grid shows.
    let control = |n: u32| {
        ClothModel::grid(&GridSpec::new(n, n, 0.01))
            .unwrap()
            .control_mesh()
            .unwrap()
    };
    assert_eq!(control(512).refined_vertex_count(1), Ok(1023 * 1023));
    const { assert!(1023 * 1023 <= MAX_PARTICLES) };
    let small = ClothModel::grid(&GridSpec::new(5, 4, 0.01)).unwrap();
    let refined = small
        .subdivided(2, VertexRule::Original, BoundaryMode::EdgeAndCorner)
        .unwrap();
    assert_eq!(
        refined.model.particle_count() as u64,
        small
            .control_mesh()
            .unwrap()
            .refined_vertex_count(2)
            .unwrap()
    );
    // 513 × 513 refined once is 1025² = 1,050,625 particles: refused before refining.
    let past = ClothModel::grid(&GridSpec::new(513, 513, 0.01)).unwrap();
    let start = Instant::now();
    let e = error(past.subdivided(1, VertexRule::Original, BoundaryMode::EdgeAndCorner));
    assert!(start.elapsed().as_secs_f64() < 1.0, "{:?}", start.elapsed());
    too_many_particles(&e, 1025 * 1025);
    names(&e, &["subdivision level 1", "263169"]);
}

#[test]
fn the_predicted_refined_vertex_count_is_the_refined_count() {
    let disc = ClothModel::disc(&DiscSpec::new(5, 3, 1.0))
        .unwrap()
        .control_mesh()
        .unwrap();
    let fan = PolyMesh::from_triangles(
        [DVec3::ZERO, DVec3::X, DVec3::Z, DVec3::new(-1.0, 0.0, 0.5)],
        &[0, 1, 2, 0, 2, 3],
    )
    .unwrap();
    for mesh in [disc, fan] {
        for level in 0..=3 {
            let sub = Subdivider::new(&mesh, level, VertexRule::Original, BoundaryMode::EdgeOnly)
                .unwrap();
            assert_eq!(
                mesh.refined_vertex_count(level),
                Ok(sub.refined_vertex_count() as u64)
            );
        }
    }
}

/// A closed torus of `n` × `m` quads (as many vertices as faces).
fn torus(n: u32, m: u32) -> PolyMesh {
    let positions = (0..n * m).map(|k| {
        let (u, v) = (
            f64::from(k % n) / f64::from(n) * std::f64::consts::TAU,
            f64::from(k / n) / f64::from(m) * std::f64::consts::TAU,
        );
        let r = 1.0 + 0.3 * v.cos();
        DVec3::new(r * u.cos(), 0.3 * v.sin(), r * u.sin())
    });
    let id = |i: u32, j: u32| (j % m) * n + i % n;
    let quads: Vec<u32> = (0..m)
        .flat_map(|j| {
            (0..n).flat_map(move |i| [id(i, j), id(i, j + 1), id(i + 1, j + 1), id(i + 1, j)])
        })
        .collect();
    PolyMesh::from_quads(positions, &quads).unwrap()
}

#[test]
fn a_render_refinement_of_max_refined_faces_is_accepted_and_more_are_not() {
    // 32 × 32 quads refined 6 times are exactly MAX_REFINED_FACES faces and as many vertices:
    // at the bound (predicted; building them takes seconds in the test profile). Twice the
    // quads are refused before anything is refined.
    let at = torus(32, 32);
    assert_eq!(at.face_count() * 4usize.pow(6), MAX_REFINED_FACES);
    assert_eq!(at.refined_vertex_count(6), Ok(MAX_REFINED_FACES as u64));
    const { assert!(MAX_REFINED_FACES <= MAX_REFINED_VERTICES) };
    let start = Instant::now();
    assert_eq!(
        Subdivider::new(
            &torus(32, 64),
            6,
            VertexRule::Original,
            BoundaryMode::EdgeOnly
        )
        .unwrap_err(),
        SubdivisionError::TooLarge {
            what: "refined face",
            count: 2 * MAX_REFINED_FACES as u64,
            max: MAX_REFINED_FACES as u64,
        }
    );
    assert!(start.elapsed().as_secs_f64() < 1.0, "{:?}", start.elapsed());
}

#[test]
fn a_control_mesh_of_max_control_vertices_is_accepted_and_one_more_is_not() {
    // The positions come from an iterator, which is not collected past the bound.
    let corners = [DVec3::ZERO, DVec3::X, DVec3::new(1.0, 0.0, 1.0), DVec3::Z];
    let positions = |count: usize| {
        corners
            .into_iter()
            .chain(std::iter::repeat(DVec3::ONE))
            .take(count)
    };
    let at = PolyMesh::from_quads(positions(MAX_CONTROL_VERTICES), &[0, 3, 2, 1]).unwrap();
    assert_eq!(at.vertex_count(), MAX_CONTROL_VERTICES);
    let e = PolyMesh::from_quads(positions(usize::MAX), &[0, 3, 2, 1]).unwrap_err();
    assert_eq!(
        e,
        SubdivisionError::TooLarge {
            what: "control vertex",
            count: MAX_CONTROL_VERTICES as u64 + 1,
            max: MAX_CONTROL_VERTICES as u64,
        }
    );
}
