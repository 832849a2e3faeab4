//! Bad input everywhere it enters the crate: solver settings, grid specs, meshes (for the
//! simulation and for subdivision), OBJ text, RON scenes, colliders, wind and pins. Each class of
//! bad input gets a typed error whose message names the field or problem and where it is; in the
//! ECS a bad cloth is reported once and skipped while the others keep running. Headless.

use bevy::asset::RenderAssetUsages;
use bevy::mesh::{Indices, PrimitiveTopology};
use bevy::prelude::*;
use bevy_cloth::ClothError;
use bevy_cloth::prelude::*;
use bevy_cloth::scene::ClothScene;
use bevy_cloth::sim::{
    ClothModel, ClothSim, Collider, Environment, MAX_ITERATIONS, MAX_PARTICLES, MAX_SUBSTEPS,
    PlacedWindZone, Pose, ScopedThread, SpringKind, WindField,
};
use bevy_cloth::subdivision::{
    BoundaryMode, PolyMesh, Subdivider, SubdivisionError, VertexRule, parse_obj,
};
use glam::{Affine3A, DVec3};

mod common;
use common::*;

/// Asserts that `result` failed and that its message contains every one of `words`; returns the
/// error for further checks.
#[track_caller]
fn err_naming<T: std::fmt::Debug, E: std::fmt::Display>(result: Result<T, E>, words: &[&str]) -> E {
    let e = result.expect_err("bad input must be an error");
    let message = e.to_string();
    for w in words {
        assert!(message.contains(w), "{message:?} does not name {w:?}");
    }
    e
}

/// Asserts an `InvalidValue` error for `field`.
#[track_caller]
fn invalid_value(result: Result<(), ClothError>, field: &str) {
    let e = err_naming(result, &[field]);
    assert!(
        matches!(e.innermost(), ClothError::InvalidValue { field: f, .. } if *f == field),
        "{e:?}"
    );
}

// ---------------------------------------------------------------------------------------------
// ClothConfig / SolverSettings
// ---------------------------------------------------------------------------------------------

/// Sets one field of the settings.
type Setter<T> = fn(&mut SolverSettings, T);

/// Every float field of the solver settings, with a setter.
fn float_fields() -> Vec<(&'static str, Setter<f32>)> {
    vec![
        ("stiffness.structural", |s, v| s.stiffness.structural = v),
        ("stiffness.shear", |s, v| s.stiffness.shear = v),
        ("stiffness.bend", |s, v| s.stiffness.bend = v),
        ("particle_mass", |s, v| s.particle_mass = v),
        ("damping", |s, v| s.damping = v),
        ("drag_coefficient", |s, v| s.drag_coefficient = v),
        ("lift_coefficient", |s, v| s.lift_coefficient = v),
        ("gravity.x", |s, v| s.gravity.x = v),
        ("gravity.y", |s, v| s.gravity.y = v),
        ("gravity.z", |s, v| s.gravity.z = v),
        ("accuracy.tolerance", |s, v| s.accuracy.tolerance = Some(v)),
    ]
}

#[test]
fn solver_settings_reject_nan_infinite_negative_and_zero_where_meaningless() {
    for (field, set) in float_fields() {
        let gravity = field.starts_with("gravity");
        for value in [
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            -1.0,
            -0.0,
            0.0,
            1.0,
        ] {
            let mut s = SolverSettings::default();
            set(&mut s, value);
            // What is legal: any finite gravity; zero stiffness, damping and aerodynamic
            // coefficients (the term is switched off); a mass and a tolerance must be positive.
            let legal = value.is_finite()
                && (gravity || value >= 0.0)
                && !(matches!(field, "particle_mass" | "accuracy.tolerance") && value <= 0.0);
            match s.validate() {
                Ok(()) => assert!(legal, "{field} = {value} was accepted"),
                Err(e) => {
                    assert!(!legal, "{field} = {value} was rejected: {e}");
                    assert!(
                        matches!(e, ClothError::InvalidValue { field: f, .. } if f == field),
                        "{field} = {value}: {e:?}"
                    );
                    let message = e.to_string();
                    assert!(message.contains(field), "{message}");
                    if !value.is_nan() {
                        assert!(message.contains(&value.to_string()), "{message}");
                    }
                }
            }
        }
    }
}

#[test]
fn solver_counts_out_of_range_name_the_field_and_bounds() {
    let cases: [(&str, u32, Setter<u32>); 6] = [
        ("substeps", 0, |s, v| s.substeps = v),
        ("substeps", MAX_SUBSTEPS + 1, |s, v| s.substeps = v),
        ("iterations", 0, |s, v| s.iterations = v),
        ("iterations", MAX_ITERATIONS + 1, |s, v| s.iterations = v),
        ("accuracy.max_substeps", 1, |s, v| {
            s.accuracy.max_substeps = v
        }),
        ("accuracy.max_substeps", MAX_SUBSTEPS + 1, |s, v| {
            s.accuracy.max_substeps = v
        }),
    ];
    for (field, value, set) in cases {
        let mut s = SolverSettings::default();
        set(&mut s, value);
        let e = err_naming(s.validate(), &[field, &value.to_string()]);
        assert!(
            matches!(e, ClothError::CountOutOfRange { field: f, value: v, .. } if f == field && v == value),
            "{e:?}"
        );
    }
    // The bounds themselves are fine.
    let s = SolverSettings {
        substeps: MAX_SUBSTEPS,
        iterations: MAX_ITERATIONS,
        ..Default::default()
    };
    assert!(s.validate().is_ok());
}

#[test]
fn a_rejected_settings_edit_leaves_the_simulation_as_it_was() {
    let model = ClothModel::grid(&GridSpec::new(3, 3, 0.1)).unwrap();
    let mut sim = ClothSim::new(model.clone(), SolverSettings::default(), |p| p).unwrap();
    let bad = SolverSettings {
        particle_mass: f32::NAN,
        ..Default::default()
    };
    err_naming(sim.set_settings(bad), &["particle_mass"]);
    assert_eq!(sim.settings(), &SolverSettings::default());
    err_naming(ClothSim::new(model, bad, |p| p), &["particle_mass"]);
}

#[test]
fn a_velocity_that_is_not_finite_is_refused_and_changes_nothing() {
    let model = ClothModel::grid(&GridSpec::new(3, 3, 0.1)).unwrap();
    let mut sim = ClothSim::new(model, SolverSettings::default(), |p| p).unwrap();
    for bad in [
        Vec3::new(f32::NAN, 0.0, 0.0),
        Vec3::new(0.0, f32::INFINITY, 0.0),
        Vec3::new(0.0, 0.0, f32::NEG_INFINITY),
    ] {
        invalid_value(sim.set_velocities(bad), "velocity");
        assert!(sim.velocities().iter().all(|v| *v == Vec3::ZERO));
    }
    sim.set_velocities(Vec3::X).unwrap();
    assert!(sim.velocities().iter().all(|v| *v == Vec3::X));
}

// ---------------------------------------------------------------------------------------------
// Grid specs
// ---------------------------------------------------------------------------------------------

#[test]
fn grid_specs_name_the_bad_field() {
    for (nx, ny, field) in [(0, 4, "nx"), (1, 4, "nx"), (4, 0, "ny"), (4, 1, "ny")] {
        let e = err_naming(ClothModel::grid(&GridSpec::new(nx, ny, 0.1)), &[field]);
        assert!(matches!(e, ClothError::GridTooSmall { field: f, .. } if f == field));
    }
    for (nx, ny) in [(u32::MAX, u32::MAX), (4097, 4096), (u32::MAX, 2)] {
        let e = err_naming(
            ClothModel::grid(&GridSpec::new(nx, ny, 0.1)),
            &[&nx.to_string(), &MAX_PARTICLES.to_string()],
        );
        assert_eq!(e, ClothError::GridTooLarge { nx, ny });
    }
    assert!(GridSpec::new(1024, 1024, 0.1).validate().is_ok());
    for h in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -0.1, 0.0, -0.0] {
        invalid_value(GridSpec::new(4, 4, h).validate(), "spacing");
    }
    // Finite, but the grid's springs would be longer than f32 can measure.
    let e = err_naming(
        ClothModel::grid(&GridSpec::new(4, 4, 1e20)),
        &["spacing", "diagonal"],
    );
    assert!(matches!(
        e,
        ClothError::InvalidValue {
            field: "spacing",
            ..
        }
    ));
    // Large but measurable: every spring has a finite, positive rest length.
    let m = ClothModel::grid(&GridSpec::new(4, 4, 1e15)).unwrap();
    assert!(m.springs.rest.iter().all(|r| r.is_finite() && *r > 0.0));
}

// ---------------------------------------------------------------------------------------------
// Meshes as cloth (ClothModel::from_mesh)
// ---------------------------------------------------------------------------------------------

/// Two triangles forming the unit square in the XZ plane (vertex 0 at the origin, 3 opposite).
fn square() -> Vec<Vec3> {
    vec![Vec3::ZERO, Vec3::X, Vec3::Z, Vec3::new(1.0, 0.0, 1.0)]
}
const SQUARE: [u32; 6] = [0, 2, 1, 1, 2, 3];

#[test]
fn mesh_buffers_and_values_are_checked() {
    let p = square();
    let cases: Vec<(Result<ClothModel, ClothError>, &[&str])> = vec![
        (
            ClothModel::from_mesh(&[], None, &SQUARE, 3),
            &["no vertex positions"],
        ),
        (ClothModel::from_mesh(&p, None, &[], 3), &["no indices"]),
        (
            ClothModel::from_mesh(&p, None, &SQUARE, 2),
            &["3 or 4", "2"],
        ),
        (
            ClothModel::from_mesh(&p, None, &SQUARE, 5),
            &["3 or 4", "5"],
        ),
        (
            ClothModel::from_mesh(&p, None, &SQUARE[..5], 3),
            &["index count 5", "face size 3"],
        ),
        (
            ClothModel::from_mesh(&[p[0], Vec3::NAN, p[2], p[3]], None, &SQUARE, 3),
            &["vertex 1", "non-finite position"],
        ),
        (
            ClothModel::from_mesh(&p, Some(&[Vec2::ZERO; 3]), &SQUARE, 3),
            &["3 texture coordinates", "4 vertices"],
        ),
        (
            ClothModel::from_mesh(
                &p,
                Some(&[Vec2::ZERO, Vec2::ONE, Vec2::INFINITY, Vec2::ONE]),
                &SQUARE,
                3,
            ),
            &["vertex 2", "non-finite texture coordinate"],
        ),
        (
            ClothModel::from_mesh(
                &[Vec3::splat(-3e38), Vec3::X, Vec3::Z, Vec3::splat(3e38)],
                None,
                &SQUARE,
                3,
            ),
            &["too large", "overflow"],
        ),
    ];
    for (result, words) in cases {
        let e = err_naming(result, words);
        assert!(matches!(e, ClothError::InvalidMesh { .. }), "{e:?}");
    }
    assert_eq!(
        ClothModel::from_mesh(&p, None, &[0, 2, 1, 1, 2, 4], 3).unwrap_err(),
        ClothError::MeshIndexOutOfRange {
            index: 4,
            position: 5,
            count: 4
        }
    );
    err_naming(
        ClothModel::from_mesh(&p, None, &[0, 2, u32::MAX], 3),
        &["4294967295", "position 2", "4 vertices"],
    );
}

#[test]
fn degenerate_faces_are_errors_naming_face_and_vertices() {
    let p = square();
    // A repeated index in the second face.
    let e = err_naming(
        ClothModel::from_mesh(&p, None, &[0, 2, 1, 1, 2, 2], 3),
        &["face 1", "[1, 2, 2]", "vertex 2 more than once"],
    );
    assert!(
        matches!(e, ClothError::DegenerateFace { face: 1, .. }),
        "{e:?}"
    );
    // Zero area: three distinct, collinear vertices.
    let line = [Vec3::ZERO, Vec3::X, Vec3::new(2.0, 0.0, 0.0), Vec3::Z];
    let e = err_naming(
        ClothModel::from_mesh(&line, None, &[0, 3, 1, 0, 1, 2], 3),
        &["face 1", "[0, 1, 2]", "zero area"],
    );
    assert_eq!(
        e,
        ClothError::DegenerateFace {
            face: 1,
            vertices: vec![0, 1, 2],
            reason: "it has zero area (its corners are collinear)".into()
        }
    );
    // Nearly collinear counts too (height a ten-millionth of the longest edge)...
    let sliver = [Vec3::ZERO, Vec3::X, Vec3::new(2.0, 1e-7, 0.0)];
    err_naming(
        ClothModel::from_mesh(&sliver, None, &[0, 1, 2], 3),
        &["zero area"],
    );
    // ...but a thin, honest triangle does not.
    let thin = [Vec3::ZERO, Vec3::X, Vec3::new(2.0, 1e-4, 0.0)];
    assert!(ClothModel::from_mesh(&thin, None, &[0, 1, 2], 3).is_ok());
    // Quads: a repeated corner, and a quad whose first split triangle is flat.
    let quad = [Vec3::ZERO, Vec3::X, Vec3::new(2.0, 0.0, 0.0), Vec3::Z];
    err_naming(
        ClothModel::from_mesh(&quad, None, &[0, 3, 3, 1], 4),
        &["face 0", "vertex 3 more than once"],
    );
    let e = err_naming(
        ClothModel::from_mesh(&quad, None, &[0, 1, 2, 3], 4),
        &["face 0", "[0, 1, 2, 3]", "triangle [0, 1, 2]", "zero area"],
    );
    assert!(matches!(e, ClothError::DegenerateFace { face: 0, .. }));
}

#[test]
fn zero_length_edges_are_errors_naming_both_vertices() {
    // Vertex 3 sits exactly on vertex 1 and an edge joins them.
    let p = [Vec3::ZERO, Vec3::X, Vec3::Z, Vec3::X];
    let e = err_naming(
        ClothModel::from_mesh(&p, None, &[0, 2, 1, 1, 2, 3], 3),
        &["face 1", "zero-length edge", "vertices 3 and 1"],
    );
    assert_eq!(
        e,
        ClothError::ZeroLengthEdge {
            face: 1,
            a: 3,
            b: 1,
            position: Vec3::X
        }
    );
    // -0.0 and 0.0 are the same place.
    let p = [Vec3::ZERO, Vec3::X, Vec3::new(-0.0, 0.0, -0.0)];
    assert!(matches!(
        ClothModel::from_mesh(&p, None, &[0, 1, 2], 3),
        Err(ClothError::ZeroLengthEdge { face: 0, .. })
    ));
}

#[test]
fn non_manifold_edges_are_errors_naming_the_edge_and_its_faces() {
    // Three triangles hinge on edge (0, 1), like pages of a book.
    let p = [
        Vec3::ZERO,
        Vec3::X,
        Vec3::Z,
        Vec3::Y,
        Vec3::new(0.5, -1.0, 0.0),
    ];
    let e = err_naming(
        ClothModel::from_mesh(&p, None, &[0, 1, 2, 1, 0, 3, 0, 1, 4], 3),
        &["edge (0, 1)", "3 faces", "[0, 1, 2]"],
    );
    assert_eq!(
        e,
        ClothError::NonManifoldEdge {
            a: 0,
            b: 1,
            faces: vec![0, 1, 2]
        }
    );
    // Two faces on an edge are fine, whichever way they wind.
    assert!(ClothModel::from_mesh(&p, None, &[0, 1, 2, 0, 1, 3], 3).is_ok());
}

/// Two unit squares side by side (x in 0..1 and 1..2), as four triangles. With `welded`, they
/// share the vertices on x = 1; without, the right square has its own copies there (a seam: same
/// positions, different vertices).
fn two_squares(welded: bool) -> (Vec<Vec3>, Vec<u32>) {
    let mut p: Vec<Vec3> = (0..6)
        .map(|i| Vec3::new((i % 3) as f32, 0.0, (i / 3) as f32))
        .collect();
    // Left square: 0 1 / 3 4; right square: 1 2 / 4 5.
    let mut right = [1u32, 2, 4, 5];
    if !welded {
        p.push(p[1]); // 6 duplicates 1
        p.push(p[4]); // 7 duplicates 4
        right = [6, 2, 7, 5];
    }
    let [a, b, c, d] = right;
    let indices = vec![0, 3, 1, 1, 3, 4, a, c, b, b, c, d];
    (p, indices)
}

#[test]
fn duplicate_vertices_not_joined_by_an_edge_are_a_seam_that_can_open() {
    let (welded_p, welded_i) = two_squares(true);
    let (seam_p, seam_i) = two_squares(false);
    let welded = ClothModel::from_mesh(&welded_p, None, &welded_i, 3).unwrap();
    let seam = ClothModel::from_mesh(&seam_p, None, &seam_i, 3).unwrap();
    // Coincident vertices are legal: each is its own particle.
    assert_eq!(seam.particle_count(), welded.particle_count() + 2);
    // No spring crosses the seam: every spring joins two vertices of the left square (0, 1, 3,
    // 4) or two of the right square (2, 5 and the copies 6, 7), and the bend spring across the
    // shared edge (1, 4) of the welded mesh is gone.
    let s = &seam.springs;
    for k in 0..s.len() {
        let (a, b) = (s.a[k].min(s.b[k]), s.a[k].max(s.b[k]));
        let left = |v| [0, 1, 3, 4].contains(&v);
        assert_eq!(left(a), left(b), "spring ({a}, {b}) crosses the seam");
    }
    assert_eq!(welded.springs.count_by_kind()[SpringKind::Bend as usize], 3);
    assert_eq!(seam.springs.count_by_kind()[SpringKind::Bend as usize], 2);

    // Pin the left square's outer edge (0, 3) and let go for half a second: welded, the right
    // square hangs from the left one; with the seam it falls away freely and the seam opens.
    let drop = |model: ClothModel| {
        let mut sim = ClothSim::new(model, SolverSettings::default(), |p| p).unwrap();
        sim.set_pins([(0, Vec3::ZERO), (3, Vec3::Z)]).unwrap();
        for _ in 0..30 {
            sim.step(1.0 / 60.0).unwrap();
        }
        sim.positions().to_vec()
    };
    let free_fall = -0.5 * 9.81 * 0.5f32.powi(2);
    let (hanging, falling) = (drop(welded), drop(seam));
    assert!(hanging[5].y > -2.1, "welded: far corner at {}", hanging[5]);
    assert!(
        falling[5].y < 0.8 * free_fall,
        "seam: the right square falls, far corner at {} (free fall {free_fall})",
        falling[5]
    );
    let gap = falling[1].distance(falling[6]);
    assert!(
        gap > 0.5,
        "seam: vertices 1 and 6 started together, now {gap} m apart"
    );
}

#[test]
fn spring_models_reject_bad_springs() {
    let p = [Vec3::ZERO, Vec3::X, Vec3::X];
    let ok = ClothModel::from_springs(&p[..2], &[(0, 1, SpringKind::Structural)]).unwrap();
    assert_eq!(ok.springs.len(), 1);
    assert_eq!(
        ClothModel::from_springs(
            &p,
            &[(0, 1, SpringKind::Structural), (1, 3, SpringKind::Bend)]
        )
        .unwrap_err(),
        ClothError::MeshIndexOutOfRange {
            index: 3,
            position: 3,
            count: 3
        }
    );
    err_naming(
        ClothModel::from_springs(&p, &[(1, 1, SpringKind::Structural)]),
        &["spring 0 (1, 1)", "zero length"],
    );
    err_naming(
        ClothModel::from_springs(&p, &[(0, 1, SpringKind::Shear), (1, 2, SpringKind::Shear)]),
        &["spring 1 (1, 2)", "zero length"],
    );
    err_naming(
        ClothModel::from_springs(&[Vec3::ZERO, Vec3::NAN], &[]),
        &["vertex 1", "non-finite"],
    );
}

// ---------------------------------------------------------------------------------------------
// Hand-made models given to the solver: the invariants its vector kernels and threads rely on
// ---------------------------------------------------------------------------------------------

/// `ClothSim::new` on `model` (a 64×64 grid, large enough that XPBD shares its colours between two
/// threads), which must fail naming every one of `words`.
#[track_caller]
fn solver_rejects(model: ClothModel, words: &[&str]) {
    let settings = SolverSettings {
        integrator: Integrator::Xpbd,
        ..Default::default()
    };
    let built = ClothSim::new(model, settings, |p| p);
    err_naming(built.map(drop), words);
}

fn grid64() -> ClothModel {
    ClothModel::grid(&GridSpec::new(64, 64, 0.02)).unwrap()
}

#[test]
fn a_model_whose_colouring_shares_a_particle_is_an_error_not_a_data_race() {
    let good = grid64();
    let mut sim = ClothSim::new(good.clone(), SolverSettings::default(), |p| p).unwrap();
    sim.step_in_parallel(1.0 / 60.0, &Environment::default(), &ScopedThread)
        .unwrap();
    // Two springs of colour 0 made to share a particle: the two threads (or two lanes of one
    // batch) would write it at once.
    let mut bad = good.clone();
    bad.springs.b[1] = bad.springs.a[0];
    solver_rejects(bad, &["colour 0", "twice"]);
    // The colouring's offsets no longer partition the springs.
    let mut bad = good;
    bad.springs.color_offsets.pop();
    solver_rejects(bad, &["partition"]);
}

#[test]
fn a_model_whose_grid_does_not_match_its_particles_is_an_error() {
    for (nx, ny) in [(65, 64), (64, 63), (1024, 1024)] {
        let mut bad = grid64();
        bad.grid = Some(GridSpec::new(nx, ny, 0.02));
        solver_rejects(bad, &["grid", "4096 particles"]);
    }
    let mut bad = grid64();
    bad.grid = Some(GridSpec::new(1, 4096, 0.02));
    solver_rejects(bad, &["nx"]);
}

#[test]
fn a_model_with_out_of_range_indices_is_an_error() {
    let mut bad = grid64();
    bad.springs.b[7] = 1_000_000;
    solver_rejects(bad, &["1000000"]);
    let mut bad = grid64();
    bad.triangles[5] = 4096;
    solver_rejects(bad, &["4096"]);
    let mut bad = grid64();
    bad.springs.rest.pop();
    solver_rejects(bad, &["rest lengths"]);
}

// ---------------------------------------------------------------------------------------------
// Polygon meshes for subdivision (PolyMesh) and refinement
// ---------------------------------------------------------------------------------------------

#[test]
fn poly_mesh_errors_name_face_and_vertex() {
    let sq = [
        DVec3::ZERO,
        DVec3::X,
        DVec3::new(1.0, 0.0, 1.0),
        DVec3::Z,
        DVec3::new(0.5, 1.0, 0.0),
    ];
    let cases: Vec<(Result<PolyMesh, SubdivisionError>, &[&str])> = vec![
        (
            PolyMesh::from_quads(Vec::<DVec3>::new(), &[]),
            &["empty", "0 vertices"],
        ),
        (
            PolyMesh::from_quads(sq, &[0, 3, 2]),
            &["3 indices", "multiple of 4"],
        ),
        (
            PolyMesh::from_polygons(sq, &[vec![0u32, 1]]),
            &["face 0", "2 vertices"],
        ),
        (
            PolyMesh::from_quads(sq, &[0, 3, 2, 7]),
            &["face 0", "vertex 7", "5 vertices"],
        ),
        (
            PolyMesh::from_quads(sq, &[0, 3, 3, 1]),
            &["face 0", "vertex 3", "more than once"],
        ),
        (
            PolyMesh::from_triangles(sq, &[0, 1, 2, 1, 0, 3, 0, 1, 4]),
            &["edge (0, 1)", "3 faces"],
        ),
        (
            PolyMesh::from_triangles(sq, &[0, 2, 1, 0, 2, 3]),
            &["faces 0 and 1", "edge (0, 2)", "same direction"],
        ),
        (
            PolyMesh::new(sq, vec![0, 3, 2], vec![0, 2, 1], None),
            &["face_offsets[2]", "must not decrease"],
        ),
        (
            PolyMesh::from_quads([DVec3::ZERO, DVec3::X, DVec3::NAN, DVec3::Z], &[0, 3, 2, 1]),
            &["vertex 2", "non-finite"],
        ),
    ];
    for (result, words) in cases {
        err_naming(result, words);
    }
    let quad = PolyMesh::from_quads(sq, &[0, 3, 2, 1]).unwrap();
    err_naming(
        quad.clone().with_vertex_uvs(&[Vec2::ZERO; 2]),
        &["2 uvs", "5 vertices"],
    );
    err_naming(
        quad.clone()
            .with_corner_uvs(vec![Vec2::ZERO, Vec2::NAN, Vec2::ZERO, Vec2::ZERO]),
        &["corner 1", "non-finite"],
    );
    err_naming(
        Subdivider::new(&quad, 7, VertexRule::Tuned, BoundaryMode::EdgeOnly),
        &["level 7", "maximum 6"],
    );
}

// ---------------------------------------------------------------------------------------------
// OBJ text
// ---------------------------------------------------------------------------------------------

const TRI: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";

#[test]
fn malformed_obj_names_the_line_and_problem() {
    let cases: Vec<(String, &[&str])> = vec![
        // Malformed numbers.
        ("v 0 0 zero\n".into(), &["line 1", "'zero' is not a number"]),
        ("v 0 0 1e999\n".into(), &["line 1", "not a finite number"]),
        ("v 0 0 NaN\n".into(), &["line 1", "not a finite number"]),
        (
            format!("{TRI}vt 0.5 x\n"),
            &["line 4", "'x' is not a number"],
        ),
        (
            format!("{TRI}f 1 2 3.0\n"),
            &["line 4", "'3.0' is not an integer"],
        ),
        (
            format!("{TRI}f 1 2 3//n\n"),
            &["line 4", "normal index 'n'"],
        ),
        // Missing vertices: a face before its vertices, or past the last one.
        (
            "f 1 2 3\nv 0 0 0\n".into(),
            &["line 1", "vertex index 1", "0 defined"],
        ),
        (
            format!("{TRI}f 1 2 4\n"),
            &["line 4", "vertex index 4", "3 defined"],
        ),
        // Index 0 does not exist in OBJ (indices are 1-based).
        (format!("{TRI}f 0 1 2\n"), &["line 4", "vertex index 0"]),
        // Negative (relative) indices past the start.
        (
            format!("{TRI}f -1 -2 -4\n"),
            &["line 4", "vertex index -4", "3 defined"],
        ),
        // Faces with fewer than 3 vertices.
        (
            format!("{TRI}f 1 2\n"),
            &["line 4", "2 vertices", "at least 3"],
        ),
        (format!("{TRI}f\n"), &["line 4", "0 vertices"]),
        // Truncated files: a vertex cut short, a face cut short.
        (
            "v 0 0 0\nv 1 0".into(),
            &["line 2", "3 coordinates, found 2"],
        ),
        (format!("{TRI}f 1 2 3\nf 1 3"), &["line 5", "2 vertices"]),
        // Texture coordinates on some corners only.
        (
            format!("{TRI}vt 0 0\nf 1/1 2 3\n"),
            &["line 5", "mixes corners"],
        ),
        // Empty files: no mesh.
        (String::new(), &["empty", "0 vertices"]),
        ("# only a comment\n".into(), &["empty"]),
        // Topology errors come through with the face.
        (
            format!("{TRI}f 1 2 2\n"),
            &["face 0", "vertex 1 more than once"],
        ),
    ];
    for (text, words) in cases {
        err_naming(parse_obj(&text), words);
    }
    // Relative indices that stay in range are fine.
    assert_eq!(
        parse_obj(&format!("{TRI}f -3 -2 -1\n"))
            .unwrap()
            .face_count(),
        1
    );
}

#[test]
fn obj_bytes_that_are_not_utf8_are_the_callers_to_decode() {
    // `parse_obj` takes text; a caller holding bytes decodes them first. Lossy decoding turns a
    // bad byte into U+FFFD, which then fails to parse as a number, with its line.
    let bytes = b"v 0 0 0\nv 1 0 \xff\n";
    err_naming(
        parse_obj(&String::from_utf8_lossy(bytes)),
        &["line 2", "not a number"],
    );
}

#[test]
fn every_prefix_of_an_obj_file_parses_or_fails_cleanly() {
    let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 1\nf 1/1 2/2 3/1 4/2\n";
    for cut in 0..=text.len() {
        if let Ok(mesh) = parse_obj(&text[..cut]) {
            assert_eq!(mesh.face_count(), 1, "{:?}", &text[..cut]);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// RON scenes
// ---------------------------------------------------------------------------------------------

const GRID: &str = "cloth: Grid((nx: 4, ny: 3, spacing: 0.1))";

fn scene(rest: &str) -> Result<ClothScene, ClothError> {
    ClothScene::from_ron(&format!("({GRID}{rest})"))
}

#[test]
fn scenes_with_unknown_fields_are_errors_naming_the_field() {
    for (text, field) in [
        (format!("({GRID}, colour: 3)"), "colour"),
        (
            "(cloth: Grid((nx: 4, ny: 3, spacing: 0.1, sapcing: 0.2)))".to_string(),
            "sapcing",
        ),
        (format!("({GRID}, solver: (substep: 3))"), "substep"),
        (
            format!("({GRID}, solver: (stiffness: (structural: 1.0, bending: 2.0)))"),
            "bending",
        ),
        (
            format!("({GRID}, colliders: [(shape: Sphere(radius: 1.0), mass: 2.0)])"),
            "mass",
        ),
        (
            format!("({GRID}, colliders: [(shape: Sphere(radius: 1.0, height: 2.0))])"),
            "height",
        ),
        (
            format!("({GRID}, colliders: [(shape: Sphere(radius: 1.0), friction: (static: 0.5))])"),
            "static",
        ),
        ("(cloth: Disk((nx: 4)))".to_string(), "Disk"),
    ] {
        let e = err_naming(ClothScene::from_ron(&text), &[field]);
        assert!(matches!(e, ClothError::Scene(_)), "{text}: {e:?}");
    }
}

#[test]
fn scenes_with_missing_fields_or_wrong_types_are_parse_errors() {
    for (text, words) in [
        ("()", &["cloth"][..]),
        ("(translation: (0.0, 1.0, 0.0))", &["cloth"]),
        ("(cloth: Grid((nx: 4, spacing: 0.1)))", &["ny"]),
        (
            "(cloth: Grid((nx: \"four\", ny: 3, spacing: 0.1)))",
            &["1:"],
        ),
        ("(cloth: Grid((nx: -4, ny: 3, spacing: 0.1)))", &["1:"]),
        ("(cloth: Grid((nx: 4.5, ny: 3, spacing: 0.1)))", &["1:"]),
        (
            "(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)), pins: 3)",
            &["1:"],
        ),
        (
            "(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)), solver: (integrator: Rk4))",
            &["Rk4"],
        ),
        (
            "(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)), wind: Some((velocity: 3.0)))",
            &["1:"],
        ),
        // Truncated and garbage text.
        ("(cloth: Grid((nx: 4, ny: 3", &["1:"]),
        ("", &["1:"]),
        ("\u{0}\u{1}", &["1:"]),
    ] {
        let e = err_naming(ClothScene::from_ron(text), words);
        assert!(matches!(e, ClothError::Scene(_)), "{text}: {e:?}");
    }
}

#[test]
fn scene_files_that_are_missing_or_not_utf8_name_the_file() {
    let dir = std::env::temp_dir().join(format!("bevy_cloth_bad_input_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let binary = dir.join("binary.ron");
    std::fs::write(&binary, b"(cloth: Grid((nx: 4, ny: 3, spacing: 0.\xff)))").unwrap();
    let e = err_naming(ClothScene::load(&binary), &["binary.ron", "UTF-8"]);
    assert!(matches!(e, ClothError::Scene(_)));
    let truncated = dir.join("truncated.ron");
    std::fs::write(&truncated, "(cloth: Grid((nx: 4, ny: 3, spac").unwrap();
    err_naming(ClothScene::load(&truncated), &["truncated.ron", "1:"]);
    err_naming(
        ClothScene::load(dir.join("missing.ron")),
        &["missing.ron", "cannot read"],
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn scenes_with_out_of_range_values_name_the_field() {
    invalid_value(scene(", dt: 0.0").map(drop), "dt");
    invalid_value(scene(", dt: -0.01").map(drop), "dt");
    invalid_value(scene(", dt: inf").map(drop), "dt");
    invalid_value(scene(", dt: NaN").map(drop), "dt");
    // Bevy's fixed clock counts nanoseconds and overflows past 1.8e19 s: steps stay in 1 µs..1 s.
    invalid_value(scene(", dt: 1e-9").map(drop), "dt");
    invalid_value(scene(", dt: 1e30").map(drop), "dt");
    invalid_value(scene(", dt: 1.5").map(drop), "dt");
    assert!(scene(", dt: 1.0").is_ok() && scene(", dt: 0.000001").is_ok());
    invalid_value(
        scene(", solver: (particle_mass: 0.0)").map(drop),
        "particle_mass",
    );
    invalid_value(scene(", solver: (damping: -1.0)").map(drop), "damping");
    invalid_value(
        scene(", solver: (gravity: (0.0, -inf, 0.0))").map(drop),
        "gravity.y",
    );
    err_naming(
        scene(", solver: (substeps: 5000)"),
        &["substeps", "5000", "1..=1024"],
    );
    err_naming(
        ClothScene::from_ron("(cloth: Grid((nx: 1, ny: 3, spacing: 0.1)))"),
        &["nx", "1"],
    );
    invalid_value(
        ClothScene::from_ron("(cloth: Grid((nx: 4, ny: 3, spacing: 1e30)))").map(drop),
        "spacing",
    );
    err_naming(scene(", pins: [0, 12]"), &["pin index 12", "12 particles"]);
    invalid_value(
        scene(", translation: (0.0, NaN, 0.0)").map(drop),
        "translation.y",
    );
    invalid_value(
        scene(", rotation_degrees: (0.0, 0.0, -inf)").map(drop),
        "rotation_degrees.z",
    );
    invalid_value(
        scene(", solver: (inertia: (linear: 1.5))").map(drop),
        "inertia.linear",
    );
    invalid_value(
        scene(", solver: (tethers: (enabled: true, slack: -0.1))").map(drop),
        "tethers.slack",
    );
    invalid_value(
        scene(", solver: (targets: (backstop_radius: -1.0))").map(drop),
        "targets.backstop_radius",
    );
    err_naming(
        scene(", target_weights: Some([0.0, 1.0])"),
        &["target_weights", "2 weights", "12 particles"],
    );
    invalid_value(
        scene(
            ", target_weights: Some([0.0, 0.1, 0.2, 0.3, 0.4, NaN, 0.6, 0.7, 0.8, 0.9, 1.0, 1.0])",
        )
        .map(drop),
        "target_weights",
    );
    scene(", target_weights: Some([0.0, 0.0, 0.0, 0.0, 0.5, 0.5, 0.5, 0.5, 1.0, 1.0, 1.0, -1.0]), solver: (tethers: (enabled: true), inertia: (linear: 0.5, angular: 0.0), targets: (max_distance_scale: 0.2, backstop_radius: 0.5))")
        .unwrap();
}

#[test]
fn scene_collider_errors_say_which_collider() {
    let colliders = |c: &str| {
        scene(&format!(
            ", colliders: [(shape: Sphere(radius: 0.5)), (shape: Sphere(radius: 0.5)), {c}]"
        ))
    };
    for (collider, field) in [
        ("(shape: Sphere(radius: -1.0))", "collider.radius"),
        ("(shape: Sphere(radius: 0.0))", "collider.radius"),
        (
            "(shape: Capsule(radius: 0.1, half_length: -1.0))",
            "collider.half_length",
        ),
        (
            "(shape: Cuboid(half_size: (1.0, 0.0, 1.0)))",
            "collider.half_size.y",
        ),
        ("(shape: Plane(normal: (0.0, 0.0, 0.0)))", "collider.normal"),
        ("(shape: Plane(normal: (NaN, 1.0, 0.0)))", "collider.normal"),
        (
            "(shape: Sphere(radius: 0.5), margin: -0.01)",
            "collider.margin",
        ),
        (
            "(shape: Sphere(radius: 0.5), friction: (static_coefficient: NaN, kinetic_coefficient: 0.1))",
            "friction.static_coefficient",
        ),
        (
            "(shape: Sphere(radius: 0.5), translation: (inf, 0.0, 0.0))",
            "translation.x",
        ),
        (
            "(shape: Sphere(radius: 0.5), velocity: (0.0, 0.0, NaN))",
            "velocity.z",
        ),
    ] {
        let e = colliders(collider).expect_err(collider);
        let message = e.to_string();
        assert!(message.starts_with("colliders[2]: "), "{message}");
        assert!(message.contains(field), "{message} does not name {field}");
        assert!(
            matches!(&e, ClothError::InScene { location, .. } if location == "colliders[2]"),
            "{e:?}"
        );
        assert!(
            matches!(e.innermost(), ClothError::InvalidValue { field: f, .. } if *f == field),
            "{e:?}"
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Colliders and wind
// ---------------------------------------------------------------------------------------------

#[test]
fn collider_validation_names_the_field() {
    let ok = ClothCollider::sphere(0.5);
    let pose = Pose::IDENTITY;
    let collider =
        |c: ClothCollider| Collider::fixed(c.shape, pose, c.friction, c.margin).validate();
    assert!(collider(ok).is_ok());
    for (c, field) in [
        (ClothCollider::sphere(f32::NAN), "collider.radius"),
        (ClothCollider::sphere(-1.0), "collider.radius"),
        (ClothCollider::capsule(0.0, 1.0), "collider.radius"),
        (
            ClothCollider::capsule(0.1, f32::INFINITY),
            "collider.half_length",
        ),
        (
            ClothCollider::cuboid(Vec3::new(1.0, 1.0, -1.0)),
            "collider.half_size.z",
        ),
        (ok.with_margin(-0.1), "collider.margin"),
        (ok.with_margin(f32::NAN), "collider.margin"),
        (
            ok.with_friction(Friction::new(-0.5)),
            "friction.static_coefficient",
        ),
        (
            ok.with_friction(Friction {
                static_coefficient: 0.5,
                kinetic_coefficient: f32::INFINITY,
            }),
            "friction.kinetic_coefficient",
        ),
    ] {
        invalid_value(collider(c), field);
    }
    // A zero or non-finite half-space normal becomes +Y (documented); a pose must be finite.
    assert_eq!(
        ClothCollider::half_space(Vec3::ZERO).shape,
        ClothCollider::half_space(Vec3::Y).shape
    );
    let mut moving = Collider::fixed(ok.shape, pose, Friction::default(), 0.01);
    moving.end.translation.x = f32::NAN;
    invalid_value(moving.validate(), "collider transform");
}

fn zone() -> PlacedWindZone {
    PlacedWindZone {
        shape: WindZoneShape::Sphere(1.0),
        to_local: Affine3A::IDENTITY,
        velocity: Vec3::X,
        gusts: None,
        falloff: 0.5,
    }
}

#[test]
fn wind_validation_names_the_field() {
    let field = |f: fn(&mut WindField)| {
        let mut w = WindField {
            air_density: 1.2,
            zones: vec![zone()],
            ..Default::default()
        };
        f(&mut w);
        w.validate()
    };
    assert!(field(|_| {}).is_ok());
    assert!(field(|w| w.air_density = 0.0).is_ok(), "no air, no force");
    assert!(field(|w| w.zones[0].falloff = 1.0).is_ok());
    type Edit = fn(&mut WindField);
    let cases: [(Edit, &str); 13] = [
        (|w| w.air_density = -1.0, "wind.air_density"),
        (|w| w.air_density = f32::NAN, "wind.air_density"),
        (|w| w.velocity.y = f32::INFINITY, "wind.velocity.y"),
        (
            |w| {
                w.gusts = Some(Gusts {
                    strength: f32::NAN,
                    ..Default::default()
                })
            },
            "gusts.strength",
        ),
        (
            |w| {
                w.gusts = Some(Gusts {
                    frequency: -1.0,
                    ..Default::default()
                })
            },
            "gusts.frequency",
        ),
        (
            |w| {
                w.gusts = Some(Gusts {
                    turbulence: f32::INFINITY,
                    ..Default::default()
                })
            },
            "gusts.turbulence",
        ),
        (
            |w| w.zones[0].shape = WindZoneShape::Sphere(0.0),
            "wind_zone.radius",
        ),
        (
            |w| w.zones[0].shape = WindZoneShape::Cuboid(Vec3::new(1.0, f32::NAN, 1.0)),
            "wind_zone.half_size.y",
        ),
        (|w| w.zones[0].velocity.x = f32::NAN, "wind_zone.velocity.x"),
        (|w| w.zones[0].falloff = -0.5, "wind_zone.falloff"),
        (|w| w.zones[0].falloff = 1.5, "wind_zone.falloff"),
        (
            |w| {
                w.zones[0].gusts = Some(Gusts {
                    strength: -1.0,
                    ..Default::default()
                })
            },
            "gusts.strength",
        ),
        (
            |w| w.zones[0].to_local = Affine3A::from_scale(Vec3::ZERO).inverse(),
            "wind_zone transform",
        ),
    ];
    for (f, name) in cases {
        invalid_value(field(f), name);
    }
}

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

fn mesh(positions: Vec<[f32; 3]>, indices: Option<Vec<u32>>) -> Mesh {
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
