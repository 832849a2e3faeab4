//! The one error type of the subdivision module, [`SubdivisionError`].
//!
//! This module holds only the error enum and its messages; it must not hold
//! validation logic (that lives next to the data it validates). Every message
//! names the offending field and value so that a user can find the bad input.

use thiserror::Error;

/// Everything that can go wrong when building, parsing, refining or
/// evaluating a subdivision mesh.
///
/// Library code in `subdivision` never panics on user data; it returns one of
/// these variants instead.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum SubdivisionError {
    /// The mesh has no vertices or no faces.
    #[error("mesh is empty: {vertices} vertices and {faces} faces (need at least one of each)")]
    EmptyMesh {
        /// Number of vertices given.
        vertices: usize,
        /// Number of faces given.
        faces: usize,
    },
    /// More vertices, faces or corners than 32-bit indices can address.
    #[error("{what} count {count} exceeds the supported maximum {max}")]
    TooLarge {
        /// Which quantity overflowed ("vertex", "face corner", "refined face", ...).
        what: &'static str,
        /// The count that was requested.
        count: u64,
        /// The largest supported count.
        max: u64,
    },
    /// `face_offsets` is not a valid CSR offset array.
    #[error("face_offsets[{index}] = {value} is invalid: {reason}")]
    BadFaceOffsets {
        /// Position in `face_offsets`.
        index: usize,
        /// The value found there.
        value: u32,
        /// What is wrong with it.
        reason: &'static str,
    },
    /// A flat index buffer whose length is not a multiple of the face size.
    #[error("{arity}-gon index buffer has {len} indices, which is not a multiple of {arity}")]
    BadIndexBufferLength {
        /// Length of the index buffer.
        len: usize,
        /// Vertices per face (3 for triangles, 4 for quads).
        arity: usize,
    },
    /// A face with fewer than three corners.
    #[error("face {face} has {len} vertices; a face needs at least 3")]
    FaceTooSmall {
        /// Face index.
        face: usize,
        /// Number of corners it has.
        len: usize,
    },
    /// A face references a vertex that does not exist.
    #[error("face {face} references vertex {vertex} but the mesh has {vertex_count} vertices")]
    IndexOutOfRange {
        /// Face index.
        face: usize,
        /// The bad vertex index.
        vertex: u64,
        /// Number of vertices in the mesh.
        vertex_count: usize,
    },
    /// A face uses the same vertex twice (a degenerate face).
    #[error("face {face} uses vertex {vertex} more than once (degenerate face)")]
    RepeatedVertex {
        /// Face index.
        face: usize,
        /// The repeated vertex.
        vertex: u32,
    },
    /// A vertex position has a NaN or infinite coordinate.
    #[error("vertex {vertex} has non-finite position ({x}, {y}, {z})")]
    NonFinitePosition {
        /// Vertex index.
        vertex: usize,
        /// x coordinate.
        x: f64,
        /// y coordinate.
        y: f64,
        /// z coordinate.
        z: f64,
    },
    /// A texture coordinate has a NaN or infinite component.
    #[error("uv of face corner {corner} is non-finite ({u}, {v})")]
    NonFiniteUv {
        /// Index of the face corner (into the flat face index buffer).
        corner: usize,
        /// u component.
        u: f32,
        /// v component.
        v: f32,
    },
    /// The number of UVs does not match the number of face corners (or vertices).
    #[error("{what} has {actual} uvs but the mesh has {expected} {what}")]
    UvCountMismatch {
        /// "face corners" or "vertices".
        what: &'static str,
        /// Required count.
        expected: usize,
        /// Count given.
        actual: usize,
    },
    /// An edge shared by more than two faces.
    #[error("edge ({a}, {b}) is used by {faces} faces; a manifold mesh allows at most 2")]
    NonManifoldEdge {
        /// Smaller vertex index of the edge.
        a: u32,
        /// Larger vertex index of the edge.
        b: u32,
        /// Number of faces using the edge.
        faces: usize,
    },
    /// Two faces traverse a shared edge in the same direction.
    #[error(
        "faces {face_a} and {face_b} both traverse edge ({a}, {b}) in the same direction (inconsistent orientation)"
    )]
    InconsistentOrientation {
        /// Smaller vertex index of the edge.
        a: u32,
        /// Larger vertex index of the edge.
        b: u32,
        /// First face.
        face_a: usize,
        /// Second face.
        face_b: usize,
    },
    /// A vertex where several boundary fans meet (boundary edge count not 0 or 2).
    #[error("vertex {vertex} has {boundary_edges} boundary edges; a manifold vertex has 0 or 2")]
    NonManifoldVertex {
        /// Vertex index.
        vertex: u32,
        /// Number of boundary edges at the vertex.
        boundary_edges: usize,
    },
    /// The requested subdivision level is above [`MAX_LEVEL`](super::MAX_LEVEL).
    #[error("subdivision level {level} exceeds the maximum {max}")]
    LevelTooHigh {
        /// Requested level.
        level: u32,
        /// Maximum supported level.
        max: u32,
    },
    /// An analysis was asked for an unsupported valence.
    #[error("valence {valence} is outside the supported range {min}..={max}")]
    ValenceOutOfRange {
        /// Requested valence.
        valence: u32,
        /// Smallest supported valence.
        min: u32,
        /// Largest supported valence.
        max: u32,
    },
    /// A slice passed to an evaluation function has the wrong length.
    #[error("{what} has length {actual}, expected {expected}")]
    LengthMismatch {
        /// Which argument ("control", "out", "positions", "normals", ...).
        what: &'static str,
        /// Required length.
        expected: usize,
        /// Length given.
        actual: usize,
    },
    /// An OBJ line could not be parsed.
    #[error("OBJ line {line}: {detail}")]
    ObjSyntax {
        /// 1-based line number.
        line: usize,
        /// What was wrong with it.
        detail: String,
    },
    /// An OBJ face references a `v` or `vt` that does not exist.
    #[error("OBJ line {line}: {kind} index {index} is out of range ({count} defined so far)")]
    ObjIndexOutOfRange {
        /// 1-based line number.
        line: usize,
        /// "vertex" or "texture coordinate".
        kind: &'static str,
        /// The index as written in the file.
        index: i64,
        /// How many elements of that kind were defined before this line.
        count: usize,
    },
}
