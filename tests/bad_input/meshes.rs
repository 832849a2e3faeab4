//! Meshes as cloth, and hand-made models given to the solver: the invariants its vector
//! kernels and threads rely on.

use super::*;

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
fn a_face_on_the_corners_of_another_is_an_error_naming_both() {
    let p = square();
    // The same triangle twice, once wound the other way (two faces sealed onto each other pass
    // the edge checks: every edge borders two faces).
    let e = err_naming(
        ClothModel::from_mesh(&p, None, &[0, 2, 1, 1, 2, 3, 1, 2, 0], 3),
        &["face 2", "[1, 2, 0]", "same corners as face 0"],
    );
    assert!(
        matches!(e, ClothError::DegenerateFace { face: 2, .. }),
        "{e:?}"
    );
    let quad = [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 0.0, 1.0), Vec3::Z];
    err_naming(
        ClothModel::from_mesh(&quad, None, &[0, 1, 2, 3, 3, 2, 1, 0], 4),
        &["face 1", "same corners as face 0"],
    );
    // Sharing three of four corners is not the same face.
    let five = [
        Vec3::ZERO,
        Vec3::X,
        Vec3::new(1.0, 0.0, 1.0),
        Vec3::Z,
        Vec3::new(0.5, 0.0, 2.0),
    ];
    let r = ClothModel::from_mesh(&five, None, &[0, 1, 2, 3, 3, 2, 4, 0], 4);
    assert!(
        !matches!(&r, Err(e) if e.to_string().contains("same corners")),
        "{r:?}"
    );
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
