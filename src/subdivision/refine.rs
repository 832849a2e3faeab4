//! Uniform topology refinement (OpenSubdiv Far style): one level at a time,
//! producing the local refinement masks (new vertex in terms of the previous
//! level's vertices, i.e. factorized stencils), face-varying UVs, grid
//! coordinates, the composition of masks into stencils over the original
//! control vertices, and the direct level-by-level evaluation of a one-shot
//! refinement ([`refine_direct`]).
//!
//! This module holds mesh traversal, mask assembly and that one-shot
//! evaluation; the two apply the same rules and a test keeps them equal. It
//! must not hold the rule formulas (see `rules`) nor the per-frame evaluation
//! (see `stencil`).
//!
//! Refined vertices are ordered as OpenSubdiv orders them: face points (one
//! per parent face, in face order), then edge points (one per parent edge),
//! then vertex points (one per parent vertex, in vertex order).

use std::borrow::Cow;

use glam::{DVec3, Vec2};

use super::rules::{BoundaryMode, VertexRule};
use super::sparse_rows::{SparseRows, check_entries};
use super::topology::{LevelFaces, LevelTopology, NO_FACE};
use super::{MAX_LEVEL, MAX_REFINED_FACES, MAX_REFINED_VERTICES, SubdivisionError};

/// Output of refining a mesh to a given level.
#[derive(Debug, Clone)]
pub(crate) struct Refinement {
    /// The local masks of each level (rows: that level's vertices; columns: the previous level's),
    /// i.e. the factorized stencils. Empty at level 0.
    pub levels: Vec<SparseRows>,
    /// Topology of the final level.
    pub topology: LevelTopology,
    /// Face-varying UVs of the final level (parallel to its face indices).
    pub uvs: Option<Vec<Vec2>>,
    /// For each control vertex, the index of its descendant vertex point.
    pub control_vertex_map: Vec<u32>,
    /// Where each vertex of the final level lies on the refined grid, if the control mesh is a
    /// grid (see [`grid`](super::grid)).
    pub grid_coordinates: Option<Vec<[u32; 2]>>,
}

/// Checks `level` against [`MAX_LEVEL`], and the refined face and vertex counts against
/// [`MAX_REFINED_FACES`] and [`MAX_REFINED_VERTICES`], before any work is done.
fn check_level(base: &LevelFaces, level: u32) -> Result<(), SubdivisionError> {
    if level > MAX_LEVEL {
        return Err(SubdivisionError::LevelTooHigh {
            level,
            max: MAX_LEVEL,
        });
    }
    let (vertices, faces) = base.refined_counts(level);
    for (what, count, max) in [
        ("refined face", faces, MAX_REFINED_FACES),
        ("refined vertex", vertices, MAX_REFINED_VERTICES),
    ] {
        if level > 0 && count > max as u64 {
            return Err(SubdivisionError::TooLarge {
                what,
                count,
                max: max as u64,
            });
        }
    }
    Ok(())
}

/// Refines `base` uniformly `level` times, keeping each level's masks.
/// With `grid_coordinates` (the control vertices' places on a grid), their descendants' places on
/// the refined grid are carried along.
pub(crate) fn refine(
    base: &LevelTopology,
    uvs: Option<Vec<Vec2>>,
    grid_coordinates: Option<Vec<[u32; 2]>>,
    level: u32,
    rule: VertexRule,
    boundary: BoundaryMode,
) -> Result<Refinement, SubdivisionError> {
    check_level(base, level)?;
    let mut map: Vec<u32> = (0..base.num_vertices as u32).collect();
    let mut levels = Vec::with_capacity(level as usize);
    let mut topo = Cow::Borrowed(base);
    let (mut uvs, mut grid) = (uvs, grid_coordinates);
    for _ in 0..level {
        levels.push(level_masks(&topo, rule, boundary)?);
        let offset = (topo.face_count() + topo.edges.len()) as u32;
        for m in &mut map {
            *m += offset;
        }
        uvs = uvs.map(|u| child_uvs(&topo, &u));
        grid = grid.map(|g| child_coordinates(&topo, &g));
        topo = Cow::Owned(topo.refine_child());
    }
    Ok(Refinement {
        levels,
        topology: topo.into_owned(),
        uvs,
        control_vertex_map: map,
        grid_coordinates: grid,
    })
}

/// Refines `base` with positions `positions` uniformly `level` times, evaluating each level
/// directly from the previous one (face points are computed once and reused by the edge and vertex
/// points) instead of building masks.
pub(crate) fn refine_direct(
    base: &LevelTopology,
    positions: &[DVec3],
    uvs: Option<Vec<Vec2>>,
    level: u32,
    rule: VertexRule,
    boundary: BoundaryMode,
) -> Result<RefinedFaces, SubdivisionError> {
    check_level(base, level)?;
    if level == 0 {
        return Ok(RefinedFaces {
            face_offsets: base.face_offsets.clone(),
            face_indices: base.face_indices.clone(),
            positions: positions.to_vec(),
            uvs,
        });
    }
    let mut topo = Cow::Borrowed(&base.faces);
    let mut points = interpolate_level(&topo, rule, boundary, positions);
    let mut uvs = uvs.map(|u| child_uvs(&topo, &u));
    for _ in 1..level {
        topo = Cow::Owned(topo.refine_child());
        points = interpolate_level(&topo, rule, boundary, &points);
        uvs = uvs.map(|u| child_uvs(&topo, &u));
    }
    // The last level needs its faces only.
    let face_indices = topo.child_faces();
    Ok(RefinedFaces {
        face_offsets: (0..=face_indices.len() as u32).step_by(4).collect(),
        face_indices,
        positions: points,
        uvs,
    })
}

/// A refined mesh as plain arrays (see [`refine_direct`]).
pub(crate) struct RefinedFaces {
    pub face_offsets: Vec<u32>,
    pub face_indices: Vec<u32>,
    pub positions: Vec<DVec3>,
    pub uvs: Option<Vec<Vec2>>,
}

/// Which rule forms the vertex point of a vertex.
#[derive(Debug, Clone, Copy)]
enum VertexKind {
    /// No face: the vertex is copied.
    Isolated,
    /// A corner kept in place ([`BoundaryMode::EdgeAndCorner`]).
    Corner,
    /// A boundary vertex on the B-spline boundary curve through its two boundary neighbours.
    Boundary([u32; 2]),
    /// An interior vertex with this many faces and edges: the [`VertexRule`].
    Interior { faces: u32, edges: u32 },
}

/// What decides a vertex's rule: how many faces and edges it has, and how many of those edges are
/// boundary edges, with the far ends of the first two.
#[derive(Debug, Clone, Copy, Default)]
struct VertexRing {
    faces: u32,
    edges: u32,
    boundary_edges: u32,
    boundary_ends: [u32; 2],
}

impl VertexRing {
    fn kind(self, boundary: BoundaryMode) -> VertexKind {
        match (self.faces, self.boundary_edges) {
            (0, _) => VertexKind::Isolated,
            (faces, 0) => VertexKind::Interior {
                faces,
                edges: self.edges,
            },
            (1, _) if boundary == BoundaryMode::EdgeAndCorner => VertexKind::Corner,
            _ => VertexKind::Boundary(self.boundary_ends),
        }
    }
}

/// The [`VertexRing`] of every vertex of `topo`, counted over the faces and edges in order (so a
/// boundary vertex's neighbours come in the order of its edges).
fn vertex_rings(topo: &LevelFaces) -> Vec<VertexRing> {
    let mut rings = vec![VertexRing::default(); topo.num_vertices];
    for &v in &topo.face_indices {
        rings[v as usize].faces += 1;
    }
    for (e, &[a, b]) in topo.edges.iter().enumerate() {
        let boundary = topo.is_boundary_edge(e);
        for (v, other) in [(a, b), (b, a)] {
            let ring = &mut rings[v as usize];
            ring.edges += 1;
            if boundary {
                if let Some(end) = ring.boundary_ends.get_mut(ring.boundary_edges as usize) {
                    *end = other;
                }
                ring.boundary_edges += 1;
            }
        }
    }
    rings
}

/// One level of direct evaluation: the child points of `topo` (face points, edge points, vertex
/// points, in that order) from its vertex positions `parent`. Each vertex's sums over its faces
/// and edges are scattered from the faces and edges in order, so no vertex incidence is needed.
fn interpolate_level(
    topo: &LevelFaces,
    rule: VertexRule,
    boundary: BoundaryMode,
    parent: &[DVec3],
) -> Vec<DVec3> {
    let nf = topo.face_count();
    let ne = topo.edges.len();
    let mut child = vec![DVec3::ZERO; nf + ne + topo.num_vertices];
    let (face_points, rest) = child.split_at_mut(nf);
    let (edge_points, vertex_points) = rest.split_at_mut(ne);
    // Face points, each also added where its corners' vertex points go (the vertex rule's sum
    // over its faces, in face order).
    topo.for_each_face(&topo.face_indices, |f, face| {
        let sum: DVec3 = face.iter().map(|&v| parent[v as usize]).sum();
        let point = sum / face.len() as f64;
        face_points[f] = point;
        for &v in face {
            vertex_points[v as usize] += point;
        }
    });
    for ((&[a, b], &faces), out) in topo.edges.iter().zip(&topo.edge_faces).zip(edge_points) {
        let ends = parent[a as usize] + parent[b as usize];
        *out = match faces {
            [_, NO_FACE] => ends * 0.5,
            [f0, f1] => (ends + face_points[f0 as usize] + face_points[f1 as usize]) * 0.25,
        };
    }
    // Each vertex's neighbours summed in edge order.
    let mut neighbours = vec![DVec3::ZERO; topo.num_vertices];
    for &[a, b] in &topo.edges {
        neighbours[a as usize] += parent[b as usize];
        neighbours[b as usize] += parent[a as usize];
    }
    let mut weights = ValenceWeights::new(rule);
    for (v, (out, ring_v)) in vertex_points.iter_mut().zip(vertex_rings(topo)).enumerate() {
        let s = parent[v];
        *out = match ring_v.kind(boundary) {
            VertexKind::Isolated | VertexKind::Corner => s,
            VertexKind::Boundary([a, b]) => {
                s * 0.75 + (parent[a as usize] + parent[b as usize]) * 0.125
            }
            VertexKind::Interior { faces, edges } => {
                let [ws, wr, wf] = weights.get(faces as usize, edges as usize);
                s * ws + neighbours[v] * wr + *out * wf
            }
        };
    }
    child
}

/// The weights of an interior vertex point `v' = w_S S + w_R Σ neighbours + w_F Σ face points`
/// (the rule's `w_F F̄ + w_R R̄ + w_S S` with the means expanded and R̄ = S/2 + mean neighbour/2),
/// shared by the masks and the direct evaluation and cached for the common valences.
struct ValenceWeights {
    rule: VertexRule,
    cache: [Option<[f64; 3]>; 16],
}

impl ValenceWeights {
    fn new(rule: VertexRule) -> Self {
        Self {
            rule,
            cache: [None; 16],
        }
    }

    fn get(&mut self, faces: usize, edges: usize) -> [f64; 3] {
        let compute = |rule: VertexRule| {
            let w = rule.weights(faces as u32);
            [
                w.vertex + 0.5 * w.midpoint,
                0.5 * w.midpoint / edges as f64,
                w.face / faces as f64,
            ]
        };
        match self.cache.get_mut(faces) {
            // Interior vertices have as many edges as faces.
            Some(slot) if faces == edges => *slot.get_or_insert_with(|| compute(self.rule)),
            _ => compute(self.rule),
        }
    }
}

/// The local refinement masks of one level: a row per child vertex (face points, edge points,
/// vertex points) over the vertices of `topo`.
fn level_masks(
    topo: &LevelTopology,
    rule: VertexRule,
    boundary: BoundaryMode,
) -> Result<SparseRows, SubdivisionError> {
    let nf = topo.face_count();
    let ne = topo.edges.len();
    let nv = topo.num_vertices;
    check_entries(mask_entry_bound(topo))?;
    let mut masks = SparseRows {
        offsets: Vec::with_capacity(nf + ne + nv + 1),
        indices: Vec::with_capacity(4 * (nf + ne + nv)),
        weights: Vec::with_capacity(4 * (nf + ne + nv)),
    };
    masks.offsets.push(0);
    let mut scratch: Vec<(u32, f64)> = Vec::with_capacity(64);

    // Face points: centroids.
    for f in 0..nf {
        let face = topo.face(f);
        let w = 1.0 / face.len() as f64;
        scratch.clear();
        scratch.extend(face.iter().map(|&v| (v, w)));
        masks.push_merged(&mut scratch)?;
    }

    // Edge points.
    for e in 0..ne {
        let [a, b] = topo.edges[e];
        scratch.clear();
        if topo.is_boundary_edge(e) {
            scratch.push((a, 0.5));
            scratch.push((b, 0.5));
        } else {
            scratch.push((a, 0.25));
            scratch.push((b, 0.25));
            for &f in &topo.edge_faces[e] {
                let face = topo.face(f as usize);
                let w = 0.25 / face.len() as f64;
                scratch.extend(face.iter().map(|&v| (v, w)));
            }
        }
        masks.push_merged(&mut scratch)?;
    }

    // Vertex points.
    let mut weights = ValenceWeights::new(rule);
    for (v, ring) in vertex_rings(topo).into_iter().enumerate() {
        let vu = v as u32;
        scratch.clear();
        match ring.kind(boundary) {
            VertexKind::Isolated | VertexKind::Corner => scratch.push((vu, 1.0)),
            VertexKind::Boundary([a, b]) => {
                scratch.push((vu, 0.75));
                scratch.push((a, 0.125));
                scratch.push((b, 0.125));
            }
            VertexKind::Interior { faces, edges } => {
                // The face points expanded into their corners.
                let [ws, wr, wf] = weights.get(faces as usize, edges as usize);
                let (faces, edges) = (topo.faces_of(v), topo.edges_of(v));
                scratch.push((vu, ws));
                scratch.extend(edges.iter().map(|&e| (topo.other_end(e as usize, vu), wr)));
                for &f in faces {
                    let face = topo.face(f as usize);
                    let corner = wf / face.len() as f64;
                    scratch.extend(face.iter().map(|&c| (c, corner)));
                }
            }
        }
        masks.push_merged(&mut scratch)?;
    }
    Ok(masks)
}

/// Face-varying UVs of the child faces of `topo` (linear): a child corner on a parent corner keeps
/// its UV, one on a parent edge gets the edge's mean UV, and the face point the face's mean UV.
fn child_uvs(topo: &LevelFaces, uvs: &[Vec2]) -> Vec<Vec2> {
    let mut out = Vec::with_capacity(4 * topo.face_indices.len());
    topo.for_each_face(uvs, |_, face| {
        let centre = face.iter().copied().sum::<Vec2>() / face.len() as f32;
        let mut prev = face[face.len() - 1];
        for (j, &uv) in face.iter().enumerate() {
            let next = face[if j + 1 == face.len() { 0 } else { j + 1 }];
            out.extend_from_slice(&[uv, (uv + next) * 0.5, centre, (prev + uv) * 0.5]);
            prev = uv;
        }
    });
    out
}

/// The `(row, column)` of each vertex of the level after `topo`, in that level's units, from those
/// of `topo`'s vertices: face points at the mean of their corners, edge points at the mean of their
/// ends, vertex points where their vertex was (see `LevelFaces::refine_child` for the order).
fn child_coordinates(topo: &LevelFaces, coords: &[[u32; 2]]) -> Vec<[u32; 2]> {
    let sum = |vs: &mut dyn Iterator<Item = u32>| {
        vs.fold([0, 0], |s, v| {
            let c = coords[v as usize];
            [s[0] + c[0], s[1] + c[1]]
        })
    };
    let mut out = Vec::with_capacity(topo.face_count() + topo.edges.len() + coords.len());
    // A cell's four corners sum to 4 × its centre, which lies at twice the coordinates one
    // level down.
    out.extend((0..topo.face_count()).map(|f| {
        let s = sum(&mut topo.face(f).iter().copied());
        [s[0] / 2, s[1] / 2]
    }));
    out.extend(topo.edges.iter().map(|e| sum(&mut e.iter().copied())));
    out.extend(coords.iter().map(|c| [2 * c[0], 2 * c[1]]));
    out
}

/// Upper bound on the number of mask entries of one level (before merging
/// repeated indices), computed in O(corners) so that pathological inputs (huge
/// polygons) are rejected before any allocation.
fn mask_entry_bound(topo: &LevelTopology) -> usize {
    let face_len = |f: u32| -> usize {
        if f == NO_FACE {
            0
        } else {
            topo.face(f as usize).len()
        }
    };
    let faces = topo.face_indices.len();
    let edges: usize = topo
        .edge_faces
        .iter()
        .map(|&[a, b]| match b {
            NO_FACE => 2,
            _ => 2usize
                .saturating_add(face_len(a))
                .saturating_add(face_len(b)),
        })
        .fold(0, usize::saturating_add);
    let vertices: usize = (0..topo.num_vertices)
        .map(|v| {
            let edges = topo.edges_of(v);
            if edges.iter().any(|&e| topo.is_boundary_edge(e as usize)) {
                return 3;
            }
            let ring: usize = topo.faces_of(v).iter().map(|&f| face_len(f)).sum();
            1 + edges.len() + ring
        })
        .fold(0, usize::saturating_add);
    faces.saturating_add(edges).saturating_add(vertices)
}

/// Composes level masks with the previous stencils: row `r` of the result is
/// `Σ_j masks[r][j].w · prev[masks[r][j].idx]`, over `control` columns.
pub(crate) fn compose(
    prev: &SparseRows,
    masks: &SparseRows,
    control: usize,
) -> Result<SparseRows, SubdivisionError> {
    let rows = masks.rows();
    let mut out = SparseRows {
        offsets: Vec::with_capacity(rows + 1),
        indices: Vec::with_capacity(prev.indices.len() * 4),
        weights: Vec::with_capacity(prev.indices.len() * 4),
    };
    out.offsets.push(0);
    let mut acc = vec![0.0f64; control];
    let mut seen = vec![false; control];
    let mut touched: Vec<u32> = Vec::with_capacity(64);
    for r in 0..rows {
        let (midx, mw) = masks.row(r);
        for (&old, &w) in midx.iter().zip(mw) {
            let (pidx, pw) = prev.row(old as usize);
            for (&c, &cw) in pidx.iter().zip(pw) {
                let cu = c as usize;
                if !seen[cu] {
                    seen[cu] = true;
                    touched.push(c);
                }
                acc[cu] += w * cw;
            }
        }
        touched.sort_unstable();
        for &c in &touched {
            let cu = c as usize;
            let w = acc[cu];
            if w != 0.0 {
                out.indices.push(c);
                out.weights.push(w);
            }
            acc[cu] = 0.0;
            seen[cu] = false;
        }
        touched.clear();
        out.offsets.push(check_entries(out.indices.len())?);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Counts like a mesh of one quad and `unused` vertices no face uses (only counts are read).
    fn one_quad_and(unused: usize) -> LevelFaces {
        LevelFaces {
            num_vertices: 4 + unused,
            face_offsets: vec![0, 4],
            face_indices: vec![0, 1, 2, 3],
            edges: vec![[0, 1], [1, 2], [2, 3], [0, 3]],
            edge_faces: vec![[0, NO_FACE]; 4],
            corner_edges: vec![0, 1, 2, 3],
            quads: true,
        }
    }

    #[test]
    fn the_refined_vertex_count_is_checked_before_refining() {
        // One level adds an edge point per edge and a face point: 5 vertices.
        let at = one_quad_and(MAX_REFINED_VERTICES - 4 - 5);
        assert_eq!(at.refined_counts(1), (MAX_REFINED_VERTICES as u64, 4));
        assert_eq!(check_level(&at, 1), Ok(()));
        let past = one_quad_and(MAX_REFINED_VERTICES - 4 - 4);
        assert_eq!(
            check_level(&past, 1),
            Err(SubdivisionError::TooLarge {
                what: "refined vertex",
                count: MAX_REFINED_VERTICES as u64 + 1,
                max: MAX_REFINED_VERTICES as u64,
            })
        );
        // Level 0 refines nothing.
        assert_eq!(check_level(&past, 0), Ok(()));
    }
}
