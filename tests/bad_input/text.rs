//! Polygon meshes for subdivision, OBJ text and RON scenes.

use super::*;

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
