//! Uniform topology refinement (OpenSubdiv Far style): one level at a time,
//! producing the child faces, the local refinement masks (new vertex in terms
//! of the previous level's vertices), face-varying UVs, and the composition of
//! masks into stencils over the original control vertices.
//!
//! This module holds mesh traversal and mask assembly. It must not hold the
//! rule formulas (see `rules`) nor evaluate positions (see `stencil`).
//!
//! Refined vertices are ordered as OpenSubdiv orders them: face points (one
//! per parent face, in face order), then edge points (one per parent edge),
//! then vertex points (one per parent vertex, in vertex order).

use glam::Vec2;

use super::rules::{BoundaryMode, VertexRule};
use super::topology::LevelTopology;
use super::{MAX_LEVEL, MAX_REFINED_FACES, MAX_STENCIL_ENTRIES, SubdivisionError};

/// Sparse rows in CSR form: row `r` is `(index, weight)` pairs
/// `entries[offsets[r]..offsets[r + 1]]`.
#[derive(Debug, Clone, Default)]
pub(crate) struct SparseRows {
    pub offsets: Vec<u32>,
    pub indices: Vec<u32>,
    pub weights: Vec<f64>,
}

impl SparseRows {
    fn identity(n: usize) -> Self {
        SparseRows {
            offsets: (0..=n as u32).collect(),
            indices: (0..n as u32).collect(),
            weights: vec![1.0; n],
        }
    }

    fn row(&self, r: usize) -> (&[u32], &[f64]) {
        let s = self.offsets[r] as usize;
        let e = self.offsets[r + 1] as usize;
        (&self.indices[s..e], &self.weights[s..e])
    }

    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.offsets.len() - 1
    }

    /// Appends a row from unsorted, possibly repeated `(index, weight)` pairs,
    /// merging repeats, sorting by index and dropping exact zeros.
    fn push_merged(&mut self, scratch: &mut [(u32, f64)]) -> Result<(), SubdivisionError> {
        scratch.sort_unstable_by_key(|&(i, _)| i);
        let mut k = 0;
        while k < scratch.len() {
            let idx = scratch[k].0;
            let mut w = 0.0;
            while k < scratch.len() && scratch[k].0 == idx {
                w += scratch[k].1;
                k += 1;
            }
            if w != 0.0 {
                self.indices.push(idx);
                self.weights.push(w);
            }
        }
        self.offsets.push(check_entries(self.indices.len())?);
        Ok(())
    }
}

/// Checks the running stencil entry count against [`MAX_STENCIL_ENTRIES`].
fn check_entries(len: usize) -> Result<u32, SubdivisionError> {
    if len > MAX_STENCIL_ENTRIES {
        return Err(SubdivisionError::TooLarge {
            what: "stencil entry",
            count: len as u64,
            max: MAX_STENCIL_ENTRIES as u64,
        });
    }
    Ok(len as u32)
}

/// Output of refining a mesh to a given level.
#[derive(Debug, Clone)]
pub(crate) struct Refinement {
    /// Stencils of the final level over the control vertices.
    pub stencils: SparseRows,
    /// Topology of the final level.
    pub topology: LevelTopology,
    /// Face-varying UVs of the final level (parallel to its face indices).
    pub uvs: Option<Vec<Vec2>>,
    /// For each control vertex, the index of its descendant vertex point.
    pub control_vertex_map: Vec<u32>,
}

/// Refines `base` uniformly `level` times.
pub(crate) fn refine(
    base: LevelTopology,
    uvs: Option<Vec<Vec2>>,
    level: u32,
    rule: VertexRule,
    boundary: BoundaryMode,
) -> Result<Refinement, SubdivisionError> {
    if level > MAX_LEVEL {
        return Err(SubdivisionError::LevelTooHigh {
            level,
            max: MAX_LEVEL,
        });
    }
    if level > 0 {
        // Faces at level L: corners(base) * 4^(L-1).
        let faces = (base.face_indices.len() as u64).saturating_mul(1u64 << (2 * (level - 1)));
        if faces > MAX_REFINED_FACES as u64 {
            return Err(SubdivisionError::TooLarge {
                what: "refined face",
                count: faces,
                max: MAX_REFINED_FACES as u64,
            });
        }
    }
    let control = base.num_vertices;
    let mut stencils = SparseRows::identity(control);
    let mut map: Vec<u32> = (0..control as u32).collect();
    let mut topo = base;
    let mut uvs = uvs;
    for _ in 0..level {
        let step = refine_level(&topo, rule, boundary, uvs.as_deref())?;
        let offset = (topo.face_count() + topo.edges.len()) as u32;
        for m in &mut map {
            *m += offset;
        }
        stencils = compose(&stencils, &step.masks, control)?;
        uvs = step.uvs;
        topo = LevelTopology::build(step.num_vertices, step.face_offsets, step.face_indices)?;
    }
    Ok(Refinement {
        stencils,
        topology: topo,
        uvs,
        control_vertex_map: map,
    })
}

/// One level of refinement: child faces plus local masks.
struct LevelStep {
    num_vertices: usize,
    face_offsets: Vec<u32>,
    face_indices: Vec<u32>,
    uvs: Option<Vec<Vec2>>,
    masks: SparseRows,
}

fn refine_level(
    topo: &LevelTopology,
    rule: VertexRule,
    boundary: BoundaryMode,
    uvs: Option<&[Vec2]>,
) -> Result<LevelStep, SubdivisionError> {
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
    for v in 0..nv {
        let vu = v as u32;
        let faces = topo.faces_of(v);
        let edges = topo.edges_of(v);
        scratch.clear();
        let mut boundary_nbrs = [0u32; 2];
        let mut nb = 0;
        for &e in edges {
            if topo.is_boundary_edge(e as usize) {
                if nb < 2 {
                    boundary_nbrs[nb] = topo.other_end(e as usize, vu);
                }
                nb += 1;
            }
        }
        if faces.is_empty() {
            scratch.push((vu, 1.0));
        } else if nb == 2 {
            if boundary == BoundaryMode::EdgeAndCorner && faces.len() == 1 {
                scratch.push((vu, 1.0));
            } else {
                scratch.push((vu, 0.75));
                scratch.push((boundary_nbrs[0], 0.125));
                scratch.push((boundary_nbrs[1], 0.125));
            }
        } else {
            // Interior: v' = w_F F̄ + w_R R̄ + w_S S (R̄: mean edge midpoint).
            let w = rule.weights(faces.len() as u32);
            scratch.push((vu, w.vertex + 0.5 * w.midpoint));
            let we = 0.5 * w.midpoint / edges.len() as f64;
            scratch.extend(edges.iter().map(|&e| (topo.other_end(e as usize, vu), we)));
            let nfaces = faces.len() as f64;
            for &f in faces {
                let face = topo.face(f as usize);
                let wf = w.face / (nfaces * face.len() as f64);
                scratch.extend(face.iter().map(|&c| (c, wf)));
            }
        }
        masks.push_merged(&mut scratch)?;
    }

    // Child faces: one quad per parent corner.
    let corners = topo.face_indices.len();
    let mut face_offsets = Vec::with_capacity(corners + 1);
    let mut face_indices = Vec::with_capacity(4 * corners);
    let mut child_uvs = uvs.map(|_| Vec::with_capacity(4 * corners));
    let edge_base = nf as u32;
    let vert_base = (nf + ne) as u32;
    face_offsets.push(0u32);
    for f in 0..nf {
        let range = topo.face_range(f);
        let k = range.len();
        let s = range.start;
        let centre_uv = uvs.map(|u| u[range.clone()].iter().copied().sum::<Vec2>() / k as f32);
        for j in 0..k {
            let prev = s + (j + k - 1) % k;
            let next = s + (j + 1) % k;
            let c = s + j;
            face_indices.extend_from_slice(&[
                vert_base + topo.face_indices[c],
                edge_base + topo.corner_edges[c],
                f as u32,
                edge_base + topo.corner_edges[prev],
            ]);
            face_offsets.push(face_indices.len() as u32);
            if let (Some(out), Some(u), Some(centre)) = (child_uvs.as_mut(), uvs, centre_uv) {
                out.extend_from_slice(&[
                    u[c],
                    (u[c] + u[next]) * 0.5,
                    centre,
                    (u[prev] + u[c]) * 0.5,
                ]);
            }
        }
    }

    Ok(LevelStep {
        num_vertices: nf + ne + nv,
        face_offsets,
        face_indices,
        uvs: child_uvs,
        masks,
    })
}

/// Upper bound on the number of mask entries of one level (before merging
/// repeated indices), computed in O(corners) so that pathological inputs (huge
/// polygons) are rejected before any allocation.
fn mask_entry_bound(topo: &LevelTopology) -> usize {
    let face_len = |f: u32| -> usize {
        if f == super::topology::NO_FACE {
            0
        } else {
            topo.face(f as usize).len()
        }
    };
    let faces = topo.face_indices.len();
    let edges: usize = topo
        .edge_faces
        .iter()
        .map(|&[a, b]| {
            2usize
                .saturating_add(face_len(a))
                .saturating_add(face_len(b))
        })
        .fold(0, usize::saturating_add);
    let vertices: usize = (0..topo.num_vertices)
        .map(|v| {
            let ring: usize = topo.faces_of(v).iter().map(|&f| face_len(f)).sum();
            3 + topo.edges_of(v).len() + ring
        })
        .fold(0, usize::saturating_add);
    faces.saturating_add(edges).saturating_add(vertices)
}

/// Composes level masks with the previous stencils: row `r` of the result is
/// `Σ_j masks[r][j].w · prev[masks[r][j].idx]`, over `control` columns.
fn compose(
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
