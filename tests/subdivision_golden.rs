//! Golden test: `VertexRule::Original` against OpenSubdiv 3.7 uniform
//! Catmull-Clark refinement of every test shape in `tests/data/subdivision`, levels 1-3, both
//! boundary modes. Vertex order may differ, so positions are compared as
//! matched point sets (nearest neighbour both ways, tolerance 1e-5 of the
//! bounding-box diagonal), then faces are compared through the matching.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use bevy_cloth::subdivision::{BoundaryMode, PolyMesh, VertexRule, parse_obj, refine_positions};
use glam::DVec3;

const SHAPES: [&str; 8] = [
    "cube", "grid4x3", "nonquads", "pyramid", "star5", "star6", "star8", "torus",
];

/// The subdivision test data, kept in the repository (`tests/data/subdivision`): the control
/// meshes and OpenSubdiv's refinements of them.
fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/subdivision")
}

fn load(path: &Path) -> PolyMesh {
    let text = std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    parse_obj(&text).unwrap_or_else(|e| panic!("cannot parse {}: {e}", path.display()))
}

/// Index of the point of `sorted` (sorted by x, with original indices)
/// nearest to `p`, and its distance; searches only |dx| <= `radius`.
fn nearest(sorted: &[(DVec3, usize)], p: DVec3, radius: f64) -> Option<(usize, f64)> {
    let start = sorted.partition_point(|(q, _)| q.x < p.x - radius);
    sorted[start..]
        .iter()
        .take_while(|(q, _)| q.x <= p.x + radius)
        .map(|&(q, i)| (i, q.distance(p)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

fn sorted_by_x(points: &[DVec3]) -> Vec<(DVec3, usize)> {
    let mut v: Vec<(DVec3, usize)> = points.iter().copied().zip(0..).collect();
    v.sort_by(|a, b| a.0.x.total_cmp(&b.0.x));
    v
}

/// Canonical form of a face: rotated so that its smallest index comes first.
fn canonical(face: impl Iterator<Item = usize>) -> Vec<usize> {
    let f: Vec<usize> = face.collect();
    let k = (0..f.len()).min_by_key(|&i| f[i]).unwrap_or(0);
    f[k..].iter().chain(&f[..k]).copied().collect()
}

/// Compares `ours` with `golden`; returns the largest matched distance
/// relative to the bounding-box diagonal.
fn compare(name: &str, ours: &PolyMesh, golden: &PolyMesh) -> f64 {
    assert_eq!(
        ours.vertex_count(),
        golden.vertex_count(),
        "{name}: vertex count"
    );
    assert_eq!(ours.face_count(), golden.face_count(), "{name}: face count");
    let (lo, hi) = golden.bounding_box();
    let diag = (hi - lo).length();
    let tol = 1e-5 * diag;

    let gs = sorted_by_x(golden.positions());
    let os = sorted_by_x(ours.positions());
    let mut worst = 0.0f64;
    let mut map = vec![usize::MAX; ours.vertex_count()];
    for (i, &p) in ours.positions().iter().enumerate() {
        let (j, d) = nearest(&gs, p, tol)
            .unwrap_or_else(|| panic!("{name}: our vertex {i} at {p} has no golden match"));
        assert!(d <= tol, "{name}: our vertex {i} off by {d}");
        worst = worst.max(d);
        map[i] = j;
    }
    for (j, &p) in golden.positions().iter().enumerate() {
        let (_, d) = nearest(&os, p, tol)
            .unwrap_or_else(|| panic!("{name}: golden vertex {j} at {p} has no match of ours"));
        assert!(d <= tol, "{name}: golden vertex {j} off by {d}");
    }
    let distinct: HashSet<usize> = map.iter().copied().collect();
    assert_eq!(
        distinct.len(),
        map.len(),
        "{name}: matching is not one-to-one"
    );

    let golden_faces: HashSet<Vec<usize>> = golden
        .faces()
        .map(|f| canonical(f.iter().map(|&v| v as usize)))
        .collect();
    for (fi, f) in ours.faces().enumerate() {
        let c = canonical(f.iter().map(|&v| map[v as usize]));
        assert!(
            golden_faces.contains(&c),
            "{name}: our face {fi} {f:?} (mapped {c:?}) is not a golden face with the same orientation"
        );
    }
    worst / diag
}

#[test]
fn original_matches_opensubdiv_goldens() {
    let dir = data_dir();
    let mut checked = 0;
    let mut worst_overall = 0.0f64;
    for shape in SHAPES {
        let control = load(&dir.join("shapes").join(format!("{shape}.obj")));
        for (mode, tag) in [
            (BoundaryMode::EdgeOnly, "edge-only"),
            (BoundaryMode::EdgeAndCorner, "edge-and-corner"),
        ] {
            for level in 1..=3u32 {
                let name = format!("{shape}_L{level}_{tag}");
                let golden = load(&dir.join("opensubdiv").join(format!("{name}.obj")));
                let ours = refine_positions(&control, level, VertexRule::Original, mode)
                    .unwrap_or_else(|e| panic!("{name}: refinement failed: {e}"));
                let worst = compare(&name, &ours, &golden);
                eprintln!(
                    "{name}: {} vertices, {} faces, max deviation {worst:.2e} of bbox diagonal",
                    ours.vertex_count(),
                    ours.face_count()
                );
                worst_overall = worst_overall.max(worst);
                checked += 1;
            }
        }
    }
    assert_eq!(checked, SHAPES.len() * 6);
    eprintln!(
        "{checked} golden files matched; worst deviation {worst_overall:.2e} of bbox diagonal"
    );
}

#[test]
fn every_test_shape_is_covered() {
    let dir = data_dir().join("shapes");
    let found: HashSet<String> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("cannot list {}: {e}", dir.display()))
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let name = e.file_name().into_string().ok()?;
            name.strip_suffix(".obj").map(str::to_owned)
        })
        .collect();
    let listed: HashSet<String> = SHAPES.iter().map(|s| s.to_string()).collect();
    assert_eq!(found, listed, "test shapes and the golden test list differ");
}

#[test]
fn boundary_modes_differ_where_corners_exist() {
    let dir = data_dir();
    for shape in ["grid4x3", "nonquads"] {
        let control = load(&dir.join("shapes").join(format!("{shape}.obj")));
        let a = refine_positions(&control, 1, VertexRule::Original, BoundaryMode::EdgeOnly)
            .expect("refine");
        let b = refine_positions(
            &control,
            1,
            VertexRule::Original,
            BoundaryMode::EdgeAndCorner,
        )
        .expect("refine");
        let moved = a
            .positions()
            .iter()
            .zip(b.positions())
            .filter(|(p, q)| p.distance(**q) > 1e-9)
            .count();
        assert!(moved > 0, "{shape}: corner mode changed nothing");
    }
}

#[test]
fn stencils_sum_to_one_for_every_shape_level_rule() {
    use bevy_cloth::subdivision::Subdivider;
    let dir = data_dir();
    for shape in SHAPES {
        let control = load(&dir.join("shapes").join(format!("{shape}.obj")));
        for rule in VertexRule::ALL {
            for mode in [BoundaryMode::EdgeOnly, BoundaryMode::EdgeAndCorner] {
                for level in 0..=3 {
                    let sub = Subdivider::new(&control, level, rule, mode).expect("subdivide");
                    let st = sub.composed_stencils().expect("compose");
                    for r in 0..st.len() {
                        let (_, w) = st.stencil(r).expect("row");
                        let sum: f64 = w.iter().sum();
                        assert!(
                            (sum - 1.0).abs() < 1e-12,
                            "{shape} {rule:?} {mode:?} L{level} row {r}: sum {sum}"
                        );
                    }
                }
            }
        }
    }
}
