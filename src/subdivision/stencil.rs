//! [`StencilTable`]: refined vertices as fixed linear combinations of coarser
//! vertices, in CSR form, and its per-frame application.
//!
//! This module holds the table and the hot evaluation loops. It must not
//! hold topology traversal or subdivision rules, and its `apply` functions
//! must not allocate: they run every simulation tick.

use glam::{DVec3, Vec3, Vec3A};

use super::SubdivisionError;
use super::sparse_rows::SparseRows;

/// Stencils of refined vertices over coarser ("control") vertices: either one
/// level over the previous one ([`Subdivider::level_stencils`](super::Subdivider::level_stencils),
/// what [`Subdivider::apply`](super::Subdivider::apply) evaluates) or the finest
/// level over the original control mesh
/// ([`Subdivider::composed_stencils`](super::Subdivider::composed_stencils)).
///
/// Row `r` (refined vertex `r`) is the list of `(control index, weight)`
/// pairs `indices[offsets[r]..offsets[r + 1]]` / `weights[..]`, sorted by
/// control index. Weights are kept in `f64` (the subdivision masks, or their
/// exact composition; each row sums to 1 up to rounding) and in `f32` for fast
/// per-frame evaluation. Stencils are linear, so
/// `refined = stencils · control` holds for any control positions (or any
/// other per-vertex quantity such as velocity).
#[derive(Debug, Clone, PartialEq)]
pub struct StencilTable {
    control_count: usize,
    offsets: Vec<u32>,
    indices: Vec<u32>,
    weights: Vec<f64>,
    weights_f32: Vec<f32>,
}

impl StencilTable {
    pub(crate) fn from_rows(rows: SparseRows, control_count: usize) -> Self {
        let weights_f32 = rows.weights.iter().map(|&w| w as f32).collect();
        StencilTable {
            control_count,
            offsets: rows.offsets,
            indices: rows.indices,
            weights: rows.weights,
            weights_f32,
        }
    }

    /// The table as sparse rows (f64 weights), for composition.
    pub(crate) fn sparse_rows(&self) -> SparseRows {
        SparseRows {
            offsets: self.offsets.clone(),
            indices: self.indices.clone(),
            weights: self.weights.clone(),
        }
    }

    /// Number of control (input) vertices the stencils read.
    pub fn control_count(&self) -> usize {
        self.control_count
    }

    /// Number of refined (output) vertices, one stencil each.
    pub fn len(&self) -> usize {
        self.offsets.len() - 1
    }

    /// Whether the table has no stencils.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Total number of `(index, weight)` entries.
    pub fn entry_count(&self) -> usize {
        self.indices.len()
    }

    /// CSR row offsets, length `len() + 1`.
    pub fn offsets(&self) -> &[u32] {
        &self.offsets
    }

    /// Control vertex indices of all entries.
    pub fn indices(&self) -> &[u32] {
        &self.indices
    }

    /// Weights of all entries in double precision.
    pub fn weights(&self) -> &[f64] {
        &self.weights
    }

    /// Weights of all entries in single precision.
    pub fn weights_f32(&self) -> &[f32] {
        &self.weights_f32
    }

    /// The stencil of refined vertex `r` as `(indices, f64 weights)`, or
    /// `None` when `r` is out of range.
    pub fn stencil(&self, r: usize) -> Option<(&[u32], &[f64])> {
        let s = *self.offsets.get(r)? as usize;
        let e = *self.offsets.get(r + 1)? as usize;
        Some((self.indices.get(s..e)?, self.weights.get(s..e)?))
    }

    fn check(&self, control: usize, out: usize) -> Result<(), SubdivisionError> {
        if control != self.control_count {
            return Err(SubdivisionError::LengthMismatch {
                what: "control",
                expected: self.control_count,
                actual: control,
            });
        }
        if out != self.len() {
            return Err(SubdivisionError::LengthMismatch {
                what: "out",
                expected: self.len(),
                actual: out,
            });
        }
        Ok(())
    }

    /// Evaluates all stencils in single precision: `out[r] = Σ w · control[i]`.
    ///
    /// `control` must have [`control_count`](Self::control_count) elements and
    /// `out` [`len`](Self::len); otherwise a
    /// [`SubdivisionError::LengthMismatch`] is returned and `out` is untouched.
    /// Does not allocate.
    pub fn apply(&self, control: &[Vec3], out: &mut [Vec3]) -> Result<(), SubdivisionError> {
        self.check(control.len(), out.len())?;
        self.apply_rows_unchecked_len(control, 0, out);
        Ok(())
    }

    /// Evaluates the stencils of refined vertices `first_row ..
    /// first_row + out.len()` into `out`, so that a caller can split the work
    /// into chunks and evaluate them in parallel on its own thread pool
    /// (`out` being a chunk of the full output). Errors when `control` does not
    /// have [`control_count`](Self::control_count) elements or the rows run
    /// past [`len`](Self::len). Does not allocate.
    pub fn apply_rows(
        &self,
        control: &[Vec3],
        first_row: usize,
        out: &mut [Vec3],
    ) -> Result<(), SubdivisionError> {
        if control.len() != self.control_count {
            return Err(SubdivisionError::LengthMismatch {
                what: "control",
                expected: self.control_count,
                actual: control.len(),
            });
        }
        if first_row > self.len() || out.len() > self.len() - first_row {
            return Err(SubdivisionError::LengthMismatch {
                what: "out (rows from first_row)",
                expected: self.len().saturating_sub(first_row),
                actual: out.len(),
            });
        }
        self.apply_rows_unchecked_len(control, first_row, out);
        Ok(())
    }

    /// [`apply`](Self::apply) for other vector layouts: the subdivider keeps its intermediate
    /// levels in 16-byte-aligned [`Vec3A`]s, read with one load per entry. Results are
    /// bit-identical to `apply` (same loop).
    pub(crate) fn apply_any<I: Copy + Into<Vec3A>, O: From<Vec3A>>(
        &self,
        control: &[I],
        out: &mut [O],
    ) -> Result<(), SubdivisionError> {
        self.check(control.len(), out.len())?;
        self.apply_rows_unchecked_len(control, 0, out);
        Ok(())
    }

    /// The hot loop; lengths are checked by the callers. Accumulates in [`Vec3A`]s (the same
    /// per-lane multiplies and adds as [`Vec3`]) whatever the layouts of `control` and `out`.
    fn apply_rows_unchecked_len<I: Copy + Into<Vec3A>, O: From<Vec3A>>(
        &self,
        control: &[I],
        first_row: usize,
        out: &mut [O],
    ) {
        let offsets = &self.offsets[first_row..first_row + out.len() + 1];
        let term = |i: u32, w: f32| control[i as usize].into() * w;
        for (o, w) in out.iter_mut().zip(offsets.windows(2)) {
            let (s, e) = (w[0] as usize, w[1] as usize);
            let (indices, weights) = (&self.indices[s..e], &self.weights_f32[s..e]);
            // Two partial sums (even and odd entries) halve the chain of dependent additions.
            let (mut even, mut odd) = (Vec3A::ZERO, Vec3A::ZERO);
            let pairs = indices.chunks_exact(2).zip(weights.chunks_exact(2));
            for (i, w) in pairs {
                even += term(i[0], w[0]);
                odd += term(i[1], w[1]);
            }
            if let (Some(&i), Some(&w)) = (
                indices.chunks_exact(2).remainder().first(),
                weights.chunks_exact(2).remainder().first(),
            ) {
                even += term(i, w);
            }
            *o = (even + odd).into();
        }
    }

    /// Evaluates all stencils in double precision (same contract as
    /// [`apply`](Self::apply)).
    pub fn apply_f64(&self, control: &[DVec3], out: &mut [DVec3]) -> Result<(), SubdivisionError> {
        self.check(control.len(), out.len())?;
        for (o, w) in out.iter_mut().zip(self.offsets.windows(2)) {
            let (s, e) = (w[0] as usize, w[1] as usize);
            let mut acc = DVec3::ZERO;
            for (&i, &wt) in self.indices[s..e].iter().zip(&self.weights[s..e]) {
                acc += control[i as usize] * wt;
            }
            *o = acc;
        }
        Ok(())
    }
}
