//! Engine-free Catmull-Clark subdivision: validated polygon meshes
//! ([`PolyMesh`]), OBJ input/output, uniform topology refinement with
//! OpenSubdiv-compatible boundary rules, three interior vertex rules
//! ([`VertexRule`]), stencil tables for per-frame evaluation
//! ([`StencilTable`], [`Subdivider`]) and eigen/curvature analysis of the
//! rules ([`analysis`]).
//!
//! This module must not import ECS, asset or rendering-engine types: it takes
//! slices and small config values and returns plain data. Topology work
//! happens once in [`Subdivider::new`]; per-frame work ([`Subdivider::apply`],
//! [`Subdivider::compute_normals`], [`RenderMesh::expand`]) only touches
//! numbers and does not allocate. Nothing here panics on user input; errors
//! are [`SubdivisionError`] values.
//!
//! Refined vertices follow OpenSubdiv's order (face points, then edge points,
//! then vertex points), and with [`VertexRule::Original`] the refined
//! positions match OpenSubdiv 3.7 (Catmull-Clark, default crease and triangle
//! options) for both [`BoundaryMode`]s.
//!
//! The modules depend one way, bottom up: `error`; `topology` (integer
//! connectivity); `sparse_rows` (CSR rows); `rules` (the weights); `mesh` and
//! `obj` (the input mesh); `refine` (refinement masks); `stencil` (per-frame
//! evaluation); `grid` and `subdivider` (the front ends); `analysis`.

pub mod analysis;
mod error;
mod grid;
mod mesh;
mod obj;
mod refine;
mod rules;
mod sparse_rows;
mod stencil;
mod subdivider;
mod topology;

pub use error::SubdivisionError;
pub use mesh::PolyMesh;
pub use obj::{parse_obj, write_obj};
pub use rules::{
    BoundaryMode, FacePointWeights, OneRingWeights, VertexRule, frequency_eigenvalues,
    subdominant_eigenvalue, tuned_diagonal_weight,
};
pub use stencil::StencilTable;
pub use subdivider::{Followed, RefinedTopology, RenderMesh, Subdivider, refine_positions};

/// Highest supported subdivision level.
pub const MAX_LEVEL: u32 = 6;

/// Largest number of faces a refinement may produce (about 4.2 million).
pub const MAX_REFINED_FACES: usize = 1 << 22;

/// Largest number of vertices a refinement may produce (about 8.4 million), predicted from the
/// control mesh's counts before anything is refined. Twice [`MAX_REFINED_FACES`]: a refinement
/// within that many faces has about as many vertices, more only along open boundaries (a mesh of
/// loose quads) and with vertices no face uses.
pub const MAX_REFINED_VERTICES: usize = 1 << 23;

/// Largest number of vertices a [`PolyMesh`] may have (about 4.2 million), counted before they
/// are collected.
pub const MAX_CONTROL_VERTICES: usize = 1 << 22;

/// Largest number of `(index, weight)` entries a stencil table (or one
/// level's refinement masks) may hold (about 67 million).
pub const MAX_STENCIL_ENTRIES: usize = 1 << 26;

#[cfg(test)]
mod tests;
