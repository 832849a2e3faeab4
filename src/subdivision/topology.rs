//! Connectivity of one refinement level: edges, edge-face and vertex-face
//! incidence, and the manifold checks that guard them.
//!
//! This module holds integer topology only. It must not hold positions,
//! weights or subdivision rules; those live in `rules` and `refine`.

use super::SubdivisionError;

/// Marker for "no second face" on a boundary edge.
pub(crate) const NO_FACE: u32 = u32::MAX;

/// The faces and edges of one refinement level, without vertex incidence: what the direct
/// level-by-level evaluation needs ([`LevelTopology`] adds the vertex-face and vertex-edge lists).
#[derive(Debug, Clone)]
pub(crate) struct LevelFaces {
    /// Number of vertices of this level.
    pub num_vertices: usize,
    /// CSR offsets into `face_indices`, length `faces + 1`.
    pub face_offsets: Vec<u32>,
    /// Corner vertices of all faces, concatenated.
    pub face_indices: Vec<u32>,
    /// Edge endpoints, smaller index first.
    pub edges: Vec<[u32; 2]>,
    /// The one or two faces of each edge; the second is [`NO_FACE`] on a boundary.
    pub edge_faces: Vec<[u32; 2]>,
    /// For each face corner `c` (parallel to `face_indices`), the edge from
    /// corner `c` to the next corner of the same face.
    pub corner_edges: Vec<u32>,
    /// Whether every face is a quad (as on every refined level), so that face `f`'s corners are
    /// `4f .. 4f + 4`.
    pub quads: bool,
}

/// Validated connectivity of a polygon mesh at one refinement level: its [`LevelFaces`] (reached
/// through `Deref`) and the incidence of each vertex.
#[derive(Debug, Clone)]
pub(crate) struct LevelTopology {
    /// Faces and edges.
    pub faces: LevelFaces,
    /// CSR offsets of `vertex_faces`, length `num_vertices + 1`.
    pub vertex_face_offsets: Vec<u32>,
    /// Faces incident to each vertex (with multiplicity one per corner).
    pub vertex_faces: Vec<u32>,
    /// CSR offsets of `vertex_edges`, length `num_vertices + 1`.
    pub vertex_edge_offsets: Vec<u32>,
    /// Edges incident to each vertex.
    pub vertex_edges: Vec<u32>,
}

impl std::ops::Deref for LevelTopology {
    type Target = LevelFaces;

    fn deref(&self) -> &LevelFaces {
        &self.faces
    }
}

impl LevelFaces {
    /// The numbers of vertices and faces after refining uniformly `level` times, from the counts
    /// alone (saturating at `u64::MAX`). Each level has a face point per face, an edge point per
    /// edge and a vertex point per vertex (unused ones too); each edge splits in two and each face
    /// of `c` corners into `c` quads joined by `c` new edges.
    pub fn refined_counts(&self, level: u32) -> (u64, u64) {
        let (mut v, mut e) = (self.num_vertices as u64, self.edges.len() as u64);
        let (mut f, mut c) = (self.face_count() as u64, self.face_indices.len() as u64);
        for _ in 0..level {
            (v, e, f, c) = (
                v.saturating_add(e).saturating_add(f),
                e.saturating_mul(2).saturating_add(c),
                c,
                c.saturating_mul(4),
            );
        }
        (v, f)
    }

    /// Number of faces.
    pub fn face_count(&self) -> usize {
        self.face_offsets.len() - 1
    }

    /// Corner vertices of face `f` (caller guarantees `f < face_count()`).
    pub fn face(&self, f: usize) -> &[u32] {
        let s = self.face_offsets[f] as usize;
        let e = self.face_offsets[f + 1] as usize;
        &self.face_indices[s..e]
    }

    /// Whether edge `e` has only one face.
    pub fn is_boundary_edge(&self, e: usize) -> bool {
        self.edge_faces[e][1] == NO_FACE
    }

    /// The other endpoint of edge `e` seen from vertex `v`.
    pub fn other_end(&self, e: usize, v: u32) -> u32 {
        let [a, b] = self.edges[e];
        if a == v { b } else { a }
    }

    /// Calls `visit(f, &per_corner[corners of face f])` for every face in order, where
    /// `per_corner` is parallel to `face_indices` (the corners' vertices, their UVs, …). Quads
    /// take a path of fixed-length slices.
    pub fn for_each_face<T>(&self, per_corner: &[T], mut visit: impl FnMut(usize, &[T])) {
        if self.quads {
            for (f, face) in per_corner.chunks_exact(4).enumerate() {
                visit(f, face);
            }
        } else {
            for (f, w) in self.face_offsets.windows(2).enumerate() {
                visit(f, &per_corner[w[0] as usize..w[1] as usize]);
            }
        }
    }

    /// Calls `visit(face, corner, previous corner of the face)` for every face corner in order.
    fn for_each_corner(&self, mut visit: impl FnMut(usize, usize, usize)) {
        if self.quads {
            for f in 0..self.face_count() {
                let c = 4 * f;
                for (corner, prev) in [(c, c + 3), (c + 1, c), (c + 2, c + 1), (c + 3, c + 2)] {
                    visit(f, corner, prev);
                }
            }
            return;
        }
        for (f, w) in self.face_offsets.windows(2).enumerate() {
            let (s, e) = (w[0] as usize, w[1] as usize);
            for c in s..e {
                visit(f, c, if c == s { e - 1 } else { c - 1 });
            }
        }
    }

    /// The corners of the child quads of the next level, 4 per parent corner (see
    /// [`refine_child`](Self::refine_child)), without the rest of its topology.
    pub fn child_faces(&self) -> Vec<u32> {
        let edge_base = self.face_count() as u32;
        let vertex_base = edge_base + self.edges.len() as u32;
        let mut face_indices = Vec::with_capacity(4 * self.face_indices.len());
        self.for_each_corner(|f, c, prev| {
            face_indices.extend_from_slice(&[
                vertex_base + self.face_indices[c],
                edge_base + self.corner_edges[c],
                f as u32,
                edge_base + self.corner_edges[prev],
            ]);
        });
        face_indices
    }

    /// The faces and edges of the next uniform Catmull-Clark level, derived in linear time
    /// without sorting or re-validating (a refined valid mesh is valid).
    ///
    /// Child vertices are the face points `0..F`, then the edge points `F..F+E`, then the vertex
    /// points. Child face `c` is the quad of parent corner `c` (vertex `v`, face `f`):
    /// `[vertex point of v, edge point of the edge leaving v, face point of f, edge point of the
    /// edge entering v]`. Child edges are the `C` face-interior edges (corner `c`: face point to
    /// the edge point of the edge leaving it), then two halves per parent edge `[a, b]`: `C + 2e`
    /// ends at `a`, `C + 2e + 1` at `b`.
    pub fn refine_child(&self) -> Self {
        let nf = self.face_count() as u32;
        let ne = self.edges.len() as u32;
        let corners = self.face_indices.len();
        let (edge_base, vertex_base) = (nf, nf + ne);
        let half_base = corners as u32;
        // The half of parent edge `e` that touches its end `v`.
        let half = |e: u32, v: u32| half_base + 2 * e + u32::from(self.edges[e as usize][0] != v);

        let face_indices = self.child_faces();
        let mut corner_edges = Vec::with_capacity(4 * corners);
        self.for_each_corner(|_, c, prev| {
            let v = self.face_indices[c];
            corner_edges.extend_from_slice(&[
                half(self.corner_edges[c], v),
                c as u32,
                prev as u32,
                half(self.corner_edges[prev], v),
            ]);
        });

        let mut edges = Vec::with_capacity(corners + 2 * ne as usize);
        self.for_each_corner(|f, c, _| edges.push([f as u32, edge_base + self.corner_edges[c]]));
        for (e, &[a, b]) in self.edges.iter().enumerate() {
            edges.push([edge_base + e as u32, vertex_base + a]);
            edges.push([edge_base + e as u32, vertex_base + b]);
        }

        let mut edge_faces = vec![[NO_FACE; 2]; edges.len()];
        for (face, quad) in corner_edges.chunks_exact(4).enumerate() {
            for &e in quad {
                let slot = &mut edge_faces[e as usize];
                slot[usize::from(slot[0] != NO_FACE)] = face as u32;
            }
        }

        LevelFaces {
            num_vertices: (nf + ne) as usize + self.num_vertices,
            face_offsets: (0..=corners as u32).map(|c| 4 * c).collect(),
            face_indices,
            edges,
            edge_faces,
            corner_edges,
            quads: true,
        }
    }
}

impl LevelTopology {
    /// Faces around vertex `v`.
    pub fn faces_of(&self, v: usize) -> &[u32] {
        let s = self.vertex_face_offsets[v] as usize;
        let e = self.vertex_face_offsets[v + 1] as usize;
        &self.vertex_faces[s..e]
    }

    /// Edges around vertex `v`.
    pub fn edges_of(&self, v: usize) -> &[u32] {
        let s = self.vertex_edge_offsets[v] as usize;
        let e = self.vertex_edge_offsets[v + 1] as usize;
        &self.vertex_edges[s..e]
    }

    /// Validates a face list and derives all connectivity.
    ///
    /// Checks, in order: non-empty, offsets well formed, faces of at least
    /// three corners, indices in range, no repeated vertex in a face, at most
    /// two faces per edge with opposite orientation, and 0 or 2 boundary edges
    /// per vertex.
    pub fn build(
        num_vertices: usize,
        face_offsets: Vec<u32>,
        face_indices: Vec<u32>,
    ) -> Result<Self, SubdivisionError> {
        let faces = face_offsets.len().saturating_sub(1);
        if num_vertices == 0 || faces == 0 {
            return Err(SubdivisionError::EmptyMesh {
                vertices: num_vertices,
                faces,
            });
        }
        if num_vertices > u32::MAX as usize - 1 {
            return Err(SubdivisionError::TooLarge {
                what: "vertex",
                count: num_vertices as u64,
                max: u32::MAX as u64 - 1,
            });
        }
        corner_count(face_indices.len())?;
        validate_offsets(&face_offsets, face_indices.len())?;

        let mut scratch: Vec<u32> = Vec::new();
        for f in 0..faces {
            let s = face_offsets[f] as usize;
            let e = face_offsets[f + 1] as usize;
            let face = &face_indices[s..e];
            if face.len() < 3 {
                return Err(SubdivisionError::FaceTooSmall {
                    face: f,
                    len: face.len(),
                });
            }
            if let Some(&bad) = face.iter().find(|&&v| v as usize >= num_vertices) {
                return Err(SubdivisionError::IndexOutOfRange {
                    face: f,
                    vertex: bad as u64,
                    vertex_count: num_vertices,
                });
            }
            let repeated = if face.len() <= 8 {
                // Small faces (nearly all): compare pairs, no sorting.
                (1..face.len()).find_map(|j| face[..j].contains(&face[j]).then_some(face[j]))
            } else {
                scratch.clear();
                scratch.extend_from_slice(face);
                scratch.sort_unstable();
                scratch.windows(2).find(|w| w[0] == w[1]).map(|w| w[0])
            };
            if let Some(vertex) = repeated {
                return Err(SubdivisionError::RepeatedVertex { face: f, vertex });
            }
        }

        // Collect half-edges keyed by their undirected endpoints, ordered by (smaller end, larger
        // end, face, corner): a counting sort on the smaller end, then an insertion sort of each
        // (short) bucket on the larger end, which keeps face order within equal keys.
        let corners = face_indices.len();
        let mut unsorted: Vec<(u64, u32, u32)> = Vec::with_capacity(corners); // (key, face, corner)
        let mut bucket_offsets = vec![0u32; num_vertices + 1];
        for f in 0..faces {
            let s = face_offsets[f] as usize;
            let e = face_offsets[f + 1] as usize;
            for c in s..e {
                let (a, b) = (
                    face_indices[c],
                    face_indices[if c + 1 == e { s } else { c + 1 }],
                );
                unsorted.push((
                    ((a.min(b) as u64) << 32) | a.max(b) as u64,
                    f as u32,
                    c as u32,
                ));
                bucket_offsets[a.min(b) as usize + 1] += 1;
            }
        }
        prefix_sum(&mut bucket_offsets);
        let mut fill = bucket_offsets.clone();
        let mut half = vec![(0u64, 0u32, 0u32); corners];
        for &h in &unsorted {
            let slot = &mut fill[(h.0 >> 32) as usize];
            half[*slot as usize] = h;
            *slot += 1;
        }
        for w in bucket_offsets.windows(2) {
            let bucket = &mut half[w[0] as usize..w[1] as usize];
            if bucket.len() > 16 {
                bucket.sort_unstable();
                continue;
            }
            for i in 1..bucket.len() {
                let mut j = i;
                while j > 0 && bucket[j - 1].0 > bucket[j].0 {
                    bucket.swap(j - 1, j);
                    j -= 1;
                }
            }
        }

        let mut edges: Vec<[u32; 2]> = Vec::with_capacity(corners / 2 + 4);
        let mut edge_faces: Vec<[u32; 2]> = Vec::with_capacity(corners / 2 + 4);
        let mut corner_edges = vec![0u32; corners];
        let mut i = 0;
        while i < half.len() {
            let key = half[i].0;
            let mut j = i + 1;
            while j < half.len() && half[j].0 == key {
                j += 1;
            }
            let a = (key >> 32) as u32;
            let b = key as u32;
            let count = j - i;
            if count > 2 {
                return Err(SubdivisionError::NonManifoldEdge { a, b, faces: count });
            }
            let edge = edges.len() as u32;
            if count == 2 {
                let (_, fa, ca) = half[i];
                let (_, fb, cb) = half[i + 1];
                // Same direction iff both corners start at the same vertex.
                if face_indices[ca as usize] == face_indices[cb as usize] {
                    return Err(SubdivisionError::InconsistentOrientation {
                        a,
                        b,
                        face_a: fa as usize,
                        face_b: fb as usize,
                    });
                }
                edge_faces.push([fa, fb]);
                corner_edges[ca as usize] = edge;
                corner_edges[cb as usize] = edge;
            } else {
                let (_, fa, ca) = half[i];
                edge_faces.push([fa, NO_FACE]);
                corner_edges[ca as usize] = edge;
            }
            edges.push([a, b]);
            i = j;
        }

        let quads = face_offsets.windows(2).all(|w| w[1] - w[0] == 4);
        let topo = Self::assemble(LevelFaces {
            quads,
            num_vertices,
            face_offsets,
            face_indices,
            edges,
            edge_faces,
            corner_edges,
        });
        for v in 0..num_vertices {
            let boundary = topo
                .edges_of(v)
                .iter()
                .filter(|&&e| topo.is_boundary_edge(e as usize))
                .count();
            if boundary != 0 && boundary != 2 {
                return Err(SubdivisionError::NonManifoldVertex {
                    vertex: v as u32,
                    boundary_edges: boundary,
                });
            }
        }
        Ok(topo)
    }

    /// The topology of the next uniform Catmull-Clark level (see [`LevelFaces::refine_child`]).
    pub fn refine_child(&self) -> Self {
        Self::assemble(self.faces.refine_child())
    }

    /// Completes a topology from its faces and edges by deriving the vertex-face and vertex-edge
    /// incidence. The inputs must already be consistent.
    fn assemble(faces: LevelFaces) -> Self {
        let LevelFaces {
            num_vertices,
            ref face_offsets,
            ref face_indices,
            ref edges,
            ..
        } = faces;
        // Vertex -> faces (one entry per corner).
        let mut vertex_face_offsets = vec![0u32; num_vertices + 1];
        for &v in face_indices {
            vertex_face_offsets[v as usize + 1] += 1;
        }
        prefix_sum(&mut vertex_face_offsets);
        let mut fill = vertex_face_offsets.clone();
        let mut vertex_faces = vec![0u32; face_indices.len()];
        for (f, w) in face_offsets.windows(2).enumerate() {
            for &v in &face_indices[w[0] as usize..w[1] as usize] {
                let slot = &mut fill[v as usize];
                vertex_faces[*slot as usize] = f as u32;
                *slot += 1;
            }
        }

        // Vertex -> edges.
        let mut vertex_edge_offsets = vec![0u32; num_vertices + 1];
        for &[a, b] in edges {
            vertex_edge_offsets[a as usize + 1] += 1;
            vertex_edge_offsets[b as usize + 1] += 1;
        }
        prefix_sum(&mut vertex_edge_offsets);
        let mut fill = vertex_edge_offsets.clone();
        let mut vertex_edges = vec![0u32; edges.len() * 2];
        for (e, &[a, b]) in edges.iter().enumerate() {
            for v in [a as usize, b as usize] {
                vertex_edges[fill[v] as usize] = e as u32;
                fill[v] += 1;
            }
        }

        LevelTopology {
            faces,
            vertex_face_offsets,
            vertex_faces,
            vertex_edge_offsets,
            vertex_edges,
        }
    }
}

/// `len` face corners as a `u32` offset, or [`SubdivisionError::TooLarge`] when indices would not fit.
pub(super) fn corner_count(len: usize) -> Result<u32, SubdivisionError> {
    u32::try_from(len)
        .ok()
        .filter(|&n| n < u32::MAX)
        .ok_or(SubdivisionError::TooLarge {
            what: "face corner",
            count: len as u64,
            max: u32::MAX as u64 - 1,
        })
}

/// Checks that `offsets` starts at 0, never decreases and ends at `len`.
pub(crate) fn validate_offsets(offsets: &[u32], len: usize) -> Result<(), SubdivisionError> {
    match offsets.first() {
        None => {
            return Err(SubdivisionError::EmptyMesh {
                vertices: 0,
                faces: 0,
            });
        }
        Some(&first) if first != 0 => {
            return Err(SubdivisionError::BadFaceOffsets {
                index: 0,
                value: first,
                reason: "the first offset must be 0",
            });
        }
        _ => {}
    }
    for (i, w) in offsets.windows(2).enumerate() {
        if w[1] < w[0] {
            return Err(SubdivisionError::BadFaceOffsets {
                index: i + 1,
                value: w[1],
                reason: "offsets must not decrease",
            });
        }
    }
    let last = offsets[offsets.len() - 1];
    if last as usize != len {
        return Err(SubdivisionError::BadFaceOffsets {
            index: offsets.len() - 1,
            value: last,
            reason: "the last offset must equal the number of face indices",
        });
    }
    Ok(())
}

/// In-place exclusive-to-inclusive prefix sum of counts stored at `i + 1`.
fn prefix_sum(v: &mut [u32]) {
    for i in 1..v.len() {
        v[i] += v[i - 1];
    }
}
