//! [`PolyMesh`], the validated polygon control mesh that subdivision starts from.
//!
//! This module holds the mesh container, its constructors and its accessors.
//! It must not hold subdivision rules, refinement or file formats; a
//! `PolyMesh` that exists is always valid (manifold, finite, in range).

use std::sync::OnceLock;

use glam::{DVec3, Vec2, Vec3};

use super::topology::{LevelTopology, corner_count};
use super::{MAX_CONTROL_VERTICES, SubdivisionError};

/// A validated, oriented, manifold polygon mesh with optional face-varying UVs.
///
/// Faces are stored in CSR form: face `f` has corners
/// `face_indices[face_offsets[f]..face_offsets[f + 1]]`, listed
/// counter-clockwise when seen from the side its normal points to. Faces may
/// have any number of corners from 3 up. UVs, when present, are stored per
/// face corner (parallel to `face_indices`), so UV seams are representable.
///
/// Every constructor validates its input and returns a [`SubdivisionError`]
/// naming the offending value: empty mesh, malformed offsets, faces with fewer
/// than 3 corners, out-of-range indices, a vertex repeated within a face,
/// non-finite positions or UVs, edges shared by more than two faces or by two
/// faces with the same orientation, and vertices where several boundary fans
/// meet. Vertices that no face uses are allowed; subdivision keeps them in place.
///
/// # Example
/// ```
/// use glam::DVec3;
/// use bevy_cloth::subdivision::PolyMesh;
///
/// let quad = PolyMesh::from_quads(
///     [DVec3::ZERO, DVec3::X, DVec3::new(1.0, 0.0, 1.0), DVec3::Z],
///     &[0, 3, 2, 1],
/// )?;
/// assert_eq!(quad.face_count(), 1);
/// # Ok::<(), bevy_cloth::subdivision::SubdivisionError>(())
/// ```
#[derive(Debug, Clone)]
pub struct PolyMesh {
    positions: Vec<DVec3>,
    face_offsets: Vec<u32>,
    face_indices: Vec<u32>,
    uvs: Option<Vec<Vec2>>,
    /// The connectivity that validation derived, kept for refinement (built on first use for
    /// meshes that come out of a refinement).
    topology: OnceLock<LevelTopology>,
}

impl PartialEq for PolyMesh {
    /// Same positions, faces and UVs (the cached connectivity follows from them).
    fn eq(&self, other: &Self) -> bool {
        self.positions == other.positions
            && self.face_offsets == other.face_offsets
            && self.face_indices == other.face_indices
            && self.uvs == other.uvs
    }
}

impl PolyMesh {
    /// A mesh produced by refinement, which is valid by construction (no checks).
    pub(crate) fn from_refined(
        positions: Vec<DVec3>,
        face_offsets: Vec<u32>,
        face_indices: Vec<u32>,
        uvs: Option<Vec<Vec2>>,
    ) -> Self {
        PolyMesh {
            positions,
            face_offsets,
            face_indices,
            uvs,
            topology: OnceLock::new(),
        }
    }

    /// Builds a mesh from positions, CSR face offsets (length `faces + 1`,
    /// starting at 0 and ending at `face_indices.len()`), the flat corner list,
    /// and optional per-corner UVs (length `face_indices.len()`).
    pub fn new<P: Into<DVec3>>(
        positions: impl IntoIterator<Item = P>,
        face_offsets: Vec<u32>,
        face_indices: Vec<u32>,
        uvs: Option<Vec<Vec2>>,
    ) -> Result<Self, SubdivisionError> {
        // Counted before more than the bound are collected.
        let positions: Vec<DVec3> = positions
            .into_iter()
            .take(MAX_CONTROL_VERTICES + 1)
            .map(Into::into)
            .collect();
        if positions.len() > MAX_CONTROL_VERTICES {
            return Err(SubdivisionError::TooLarge {
                what: "control vertex",
                count: positions.len() as u64,
                max: MAX_CONTROL_VERTICES as u64,
            });
        }
        validate_positions(&positions)?;
        if let Some(uvs) = &uvs {
            validate_uvs(uvs, face_indices.len())?;
        }
        let topo = LevelTopology::build(positions.len(), face_offsets, face_indices)?;
        Ok(PolyMesh {
            positions,
            face_offsets: topo.face_offsets.clone(),
            face_indices: topo.face_indices.clone(),
            uvs,
            topology: OnceLock::from(topo),
        })
    }

    /// Builds a mesh from a list of polygons, each a slice of vertex indices.
    pub fn from_polygons<P: Into<DVec3>, F: AsRef<[u32]>>(
        positions: impl IntoIterator<Item = P>,
        faces: &[F],
    ) -> Result<Self, SubdivisionError> {
        let mut offsets = Vec::with_capacity(faces.len() + 1);
        let mut indices = Vec::new();
        offsets.push(0u32);
        for face in faces {
            indices.extend_from_slice(face.as_ref());
            offsets.push(corner_count(indices.len())?);
        }
        Self::new(positions, offsets, indices, None)
    }

    /// Builds a mesh from a flat triangle index buffer (3 indices per face).
    pub fn from_triangles<P: Into<DVec3>>(
        positions: impl IntoIterator<Item = P>,
        indices: &[u32],
    ) -> Result<Self, SubdivisionError> {
        Self::from_uniform(positions, indices, 3)
    }

    /// Builds a mesh from a flat quad index buffer (4 indices per face).
    pub fn from_quads<P: Into<DVec3>>(
        positions: impl IntoIterator<Item = P>,
        indices: &[u32],
    ) -> Result<Self, SubdivisionError> {
        Self::from_uniform(positions, indices, 4)
    }

    fn from_uniform<P: Into<DVec3>>(
        positions: impl IntoIterator<Item = P>,
        indices: &[u32],
        arity: usize,
    ) -> Result<Self, SubdivisionError> {
        if !indices.len().is_multiple_of(arity) {
            return Err(SubdivisionError::BadIndexBufferLength {
                len: indices.len(),
                arity,
            });
        }
        corner_count(indices.len())?;
        let offsets = (0..=indices.len() / arity)
            .map(|f| (f * arity) as u32)
            .collect();
        Self::new(positions, offsets, indices.to_vec(), None)
    }

    /// Returns the mesh with per-face-corner UVs (parallel to [`face_indices`](Self::face_indices)).
    pub fn with_corner_uvs(mut self, uvs: Vec<Vec2>) -> Result<Self, SubdivisionError> {
        validate_uvs(&uvs, self.face_indices.len())?;
        self.uvs = Some(uvs);
        Ok(self)
    }

    /// Returns the mesh with per-vertex UVs, expanded to every face corner.
    pub fn with_vertex_uvs(self, uvs: &[Vec2]) -> Result<Self, SubdivisionError> {
        if uvs.len() != self.positions.len() {
            return Err(SubdivisionError::UvCountMismatch {
                what: "vertices",
                expected: self.positions.len(),
                actual: uvs.len(),
            });
        }
        let corner: Vec<Vec2> = self.face_indices.iter().map(|&v| uvs[v as usize]).collect();
        self.with_corner_uvs(corner)
    }

    /// Returns the mesh without UVs.
    pub fn without_uvs(mut self) -> Self {
        self.uvs = None;
        self
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Number of faces.
    pub fn face_count(&self) -> usize {
        self.face_offsets.len() - 1
    }

    /// Vertex positions in double precision.
    pub fn positions(&self) -> &[DVec3] {
        &self.positions
    }

    /// Vertex positions converted to single precision.
    pub fn positions_f32(&self) -> Vec<Vec3> {
        self.positions.iter().map(|p| p.as_vec3()).collect()
    }

    /// CSR face offsets, length `face_count() + 1`.
    pub fn face_offsets(&self) -> &[u32] {
        &self.face_offsets
    }

    /// All face corners, concatenated.
    pub fn face_indices(&self) -> &[u32] {
        &self.face_indices
    }

    /// Corner vertices of face `f`, or `None` when `f` is out of range.
    pub fn face(&self, f: usize) -> Option<&[u32]> {
        let s = *self.face_offsets.get(f)? as usize;
        let e = *self.face_offsets.get(f + 1)? as usize;
        self.face_indices.get(s..e)
    }

    /// Iterator over the faces as slices of vertex indices.
    pub fn faces(&self) -> impl Iterator<Item = &[u32]> + '_ {
        self.face_offsets
            .windows(2)
            .map(|w| &self.face_indices[w[0] as usize..w[1] as usize])
    }

    /// Per-face-corner UVs, if the mesh has them.
    pub fn uvs(&self) -> Option<&[Vec2]> {
        self.uvs.as_deref()
    }

    /// UVs of the corners of face `f`, if the mesh has UVs and `f` is in range.
    pub fn face_uvs(&self, f: usize) -> Option<&[Vec2]> {
        let s = *self.face_offsets.get(f)? as usize;
        let e = *self.face_offsets.get(f + 1)? as usize;
        self.uvs.as_ref()?.get(s..e)
    }

    /// Whether every face has exactly four corners.
    pub fn is_all_quads(&self) -> bool {
        self.face_offsets.windows(2).all(|w| w[1] - w[0] == 4)
    }

    /// Axis-aligned bounding box `(min, max)` of the positions.
    pub fn bounding_box(&self) -> (DVec3, DVec3) {
        self.positions.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), &p| (lo.min(p), hi.max(p)),
        )
    }

    /// Number of vertices of the mesh refined uniformly `level` times, from its vertex, edge,
    /// face and corner counts alone (nothing is refined), saturating at `u64::MAX`.
    ///
    /// ```
    /// use glam::DVec3;
    /// use bevy_cloth::subdivision::PolyMesh;
    ///
    /// let quad = PolyMesh::from_quads(
    ///     [DVec3::ZERO, DVec3::X, DVec3::new(1.0, 0.0, 1.0), DVec3::Z],
    ///     &[0, 3, 2, 1],
    /// )?;
    /// // A 2×2, then a 4×4 grid of quads.
    /// assert_eq!(quad.refined_vertex_count(1)?, 9);
    /// assert_eq!(quad.refined_vertex_count(2)?, 25);
    /// # Ok::<(), bevy_cloth::subdivision::SubdivisionError>(())
    /// ```
    pub fn refined_vertex_count(&self, level: u32) -> Result<u64, SubdivisionError> {
        Ok(self.topology()?.refined_counts(level).0)
    }

    /// Derived connectivity; cannot fail because `self` is valid.
    pub(crate) fn topology(&self) -> Result<&LevelTopology, SubdivisionError> {
        if let Some(topo) = self.topology.get() {
            return Ok(topo);
        }
        let topo = LevelTopology::build(
            self.positions.len(),
            self.face_offsets.clone(),
            self.face_indices.clone(),
        )?;
        Ok(self.topology.get_or_init(|| topo))
    }
}

fn validate_positions(positions: &[DVec3]) -> Result<(), SubdivisionError> {
    if let Some((vertex, p)) = positions.iter().enumerate().find(|(_, p)| !p.is_finite()) {
        return Err(SubdivisionError::NonFinitePosition {
            vertex,
            x: p.x,
            y: p.y,
            z: p.z,
        });
    }
    Ok(())
}

fn validate_uvs(uvs: &[Vec2], corners: usize) -> Result<(), SubdivisionError> {
    if uvs.len() != corners {
        return Err(SubdivisionError::UvCountMismatch {
            what: "face corners",
            expected: corners,
            actual: uvs.len(),
        });
    }
    if let Some((corner, uv)) = uvs.iter().enumerate().find(|(_, uv)| !uv.is_finite()) {
        return Err(SubdivisionError::NonFiniteUv {
            corner,
            u: uv.x,
            v: uv.y,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> Vec<DVec3> {
        vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 1.0),
            DVec3::new(0.0, 0.0, 1.0),
        ]
    }

    #[test]
    fn valid_quad_and_triangles() {
        let m = PolyMesh::from_quads(square(), &[0, 3, 2, 1]).unwrap();
        assert_eq!(m.face_count(), 1);
        assert!(m.is_all_quads());
        let t = PolyMesh::from_triangles(square(), &[0, 3, 2, 0, 2, 1]).unwrap();
        assert_eq!(t.face_count(), 2);
        assert_eq!(t.face(1), Some(&[0u32, 2, 1][..]));
        assert_eq!(t.face(2), None);
    }

    #[test]
    fn bad_inputs_give_the_right_errors() {
        use SubdivisionError as E;
        assert!(matches!(
            PolyMesh::from_quads(Vec::<DVec3>::new(), &[]),
            Err(E::EmptyMesh { .. })
        ));
        assert!(matches!(
            PolyMesh::from_quads(square(), &[]),
            Err(E::EmptyMesh {
                vertices: 4,
                faces: 0
            })
        ));
        assert!(matches!(
            PolyMesh::from_triangles(square(), &[0, 1]),
            Err(E::BadIndexBufferLength { len: 2, arity: 3 })
        ));
        let e = PolyMesh::from_quads(square(), &[0, 3, 2, 99]).unwrap_err();
        assert_eq!(
            e,
            E::IndexOutOfRange {
                face: 0,
                vertex: 99,
                vertex_count: 4
            }
        );
        assert_eq!(
            e.to_string(),
            "face 0 references vertex 99 but the mesh has 4 vertices"
        );
        assert!(matches!(
            PolyMesh::from_polygons(square(), &[vec![0u32, 1]]),
            Err(E::FaceTooSmall { face: 0, len: 2 })
        ));
        assert!(matches!(
            PolyMesh::from_quads(square(), &[0, 1, 1, 2]),
            Err(E::RepeatedVertex { face: 0, vertex: 1 })
        ));
        let mut p = square();
        p[2].y = f64::NAN;
        assert!(matches!(
            PolyMesh::from_quads(p, &[0, 3, 2, 1]),
            Err(E::NonFinitePosition { vertex: 2, .. })
        ));
        // Same orientation on the shared edge (0, 2).
        assert!(matches!(
            PolyMesh::from_triangles(square(), &[0, 2, 1, 0, 2, 3]),
            Err(E::InconsistentOrientation { a: 0, b: 2, .. })
        ));
        // Three triangles on edge (0, 1).
        let mut p5 = square();
        p5.push(DVec3::new(0.5, 1.0, 0.0));
        assert!(matches!(
            PolyMesh::from_triangles(p5, &[0, 1, 2, 1, 0, 3, 0, 1, 4]),
            Err(E::NonManifoldEdge {
                a: 0,
                b: 1,
                faces: 3
            })
        ));
        // Bow tie: two triangles touching at vertex 0 only.
        let bow = vec![
            DVec3::ZERO,
            DVec3::X,
            DVec3::new(1.0, 0.0, 1.0),
            DVec3::new(-1.0, 0.0, 0.0),
            DVec3::new(-1.0, 0.0, -1.0),
        ];
        assert!(matches!(
            PolyMesh::from_triangles(bow, &[0, 1, 2, 0, 3, 4]),
            Err(E::NonManifoldVertex {
                vertex: 0,
                boundary_edges: 4
            })
        ));
        assert!(matches!(
            PolyMesh::new(square(), vec![1, 4], vec![0, 3, 2, 1], None),
            Err(E::BadFaceOffsets { index: 0, .. })
        ));
        assert!(matches!(
            PolyMesh::new(square(), vec![0, 5], vec![0, 3, 2, 1], None),
            Err(E::BadFaceOffsets { index: 1, .. })
        ));
        assert!(matches!(
            PolyMesh::new(
                square(),
                vec![0, 4],
                vec![0, 3, 2, 1],
                Some(vec![Vec2::ZERO])
            ),
            Err(E::UvCountMismatch { .. })
        ));
        assert!(matches!(
            PolyMesh::from_quads(square(), &[0, 3, 2, 1])
                .unwrap()
                .with_corner_uvs(vec![Vec2::ZERO, Vec2::ONE, Vec2::NAN, Vec2::ONE]),
            Err(E::NonFiniteUv { corner: 2, .. })
        ));
    }

    #[test]
    fn vertex_uvs_expand_to_corners() {
        let uv = [Vec2::new(0.0, 0.0), Vec2::X, Vec2::ONE, Vec2::Y];
        let m = PolyMesh::from_quads(square(), &[0, 3, 2, 1])
            .unwrap()
            .with_vertex_uvs(&uv)
            .unwrap();
        assert_eq!(m.face_uvs(0).unwrap(), &[uv[0], uv[3], uv[2], uv[1]]);
    }
}
