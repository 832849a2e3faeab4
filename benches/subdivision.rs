//! Catmull-Clark timings (the source paper's Tables 2–3, and the subdivision issue's goals), for
//! each vertex rule at levels 1–3, on a 16×16-vertex quad grid and on meshes with extraordinary
//! vertices (the cube and the valence-5/6 discs of the test data in `tests/data/subdivision`):
//! - `subdivision_scratch`: refinement from scratch, control mesh in, refined mesh out
//!   (`refine_positions`: topology, positions and UVs, level by level) — the paper's experiment;
//! - `subdivision_refine`: building a `Subdivider` (topology, factorized stencil tables, render
//!   layout), done once per cloth;
//! - `subdivision_apply`: one per-frame evaluation (`Subdivider::apply`), plus the per-frame goal
//!   case, a 64×64 cloth at level 2.

use std::hint::black_box;

use bevy_cloth::sim::{ClothModel, GridSpec};
use bevy_cloth::subdivision::{
    BoundaryMode, PolyMesh, Subdivider, VertexRule, parse_obj, refine_positions,
};
use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use glam::Vec3;

fn grid(n: u32) -> PolyMesh {
    ClothModel::grid(&GridSpec::new(n, n, 0.1))
        .unwrap()
        .control_mesh()
        .unwrap()
}

fn shape(name: &str) -> PolyMesh {
    let path = format!(
        "{}/tests/data/subdivision/shapes/{name}.obj",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    parse_obj(&text).unwrap()
}

fn meshes() -> Vec<(&'static str, PolyMesh)> {
    vec![
        ("grid16", grid(16)),
        ("cube", shape("cube")),
        ("star5", shape("star5")),
        ("star6", shape("star6")),
    ]
}

const RULES: [VertexRule; 3] = [
    VertexRule::Original,
    VertexRule::Enhanced,
    VertexRule::Tuned,
];

/// Times `refine(mesh, level, rule)` for every mesh, rule and level 1–3 in group `group`.
fn refinement_group<T>(
    c: &mut Criterion,
    group: &str,
    refine: impl Fn(&PolyMesh, u32, VertexRule) -> T,
) {
    let mut group = c.benchmark_group(group);
    for (name, mesh) in meshes() {
        for rule in RULES {
            for level in 1..=3 {
                let id = BenchmarkId::new(format!("{name}/{rule:?}"), level);
                group.bench_with_input(id, &level, |b, &level| {
                    b.iter(|| refine(black_box(&mesh), level, rule))
                });
            }
        }
    }
    group.finish();
}

fn scratch(c: &mut Criterion) {
    refinement_group(c, "subdivision_scratch", |mesh, level, rule| {
        refine_positions(mesh, level, rule, BoundaryMode::EdgeOnly).unwrap()
    });
}

fn refine(c: &mut Criterion) {
    refinement_group(c, "subdivision_refine", |mesh, level, rule| {
        Subdivider::new(mesh, level, rule, BoundaryMode::EdgeOnly).unwrap()
    });
}

fn apply(c: &mut Criterion) {
    let mut group = c.benchmark_group("subdivision_apply");
    let mut cases = meshes();
    cases.push(("grid64", grid(64)));
    for (name, mesh) in cases {
        let control = mesh.positions_f32();
        for rule in RULES {
            let levels = if name == "grid64" { 2..=2 } else { 1..=3 };
            for level in levels {
                let mut sub = Subdivider::new(&mesh, level, rule, BoundaryMode::EdgeOnly).unwrap();
                let mut out = vec![Vec3::ZERO; sub.refined_vertex_count()];
                let id = BenchmarkId::new(format!("{name}/{rule:?}"), level);
                group.bench_with_input(id, &level, |b, _| {
                    b.iter(|| sub.apply(black_box(&control), &mut out).unwrap())
                });
                if name == "grid64" {
                    // The same surface through the composed table (one wide row per refined
                    // vertex over the control vertices), for a ratio measured in the same run.
                    let composed = sub.composed_stencils().unwrap();
                    let id = BenchmarkId::new(format!("{name}/{rule:?}/composed"), level);
                    group.bench_with_input(id, &level, |b, _| {
                        b.iter(|| composed.apply(black_box(&control), &mut out).unwrap())
                    });
                }
            }
        }
    }
    group.finish();
}

criterion_group!(benches, scratch, refine, apply);
criterion_main!(benches);
