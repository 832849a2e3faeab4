//! [`SparseRows`]: rows of `(index, weight)` pairs in CSR form, the shape of refinement masks
//! and stencils alike, and the entry-count check every table that grows them applies.
//!
//! This module holds the storage only: no topology, rules or evaluation.

use super::{MAX_STENCIL_ENTRIES, SubdivisionError};

/// Sparse rows in CSR form: row `r` is `(index, weight)` pairs
/// `entries[offsets[r]..offsets[r + 1]]`.
#[derive(Debug, Clone, Default)]
pub(crate) struct SparseRows {
    pub offsets: Vec<u32>,
    pub indices: Vec<u32>,
    pub weights: Vec<f64>,
}

impl SparseRows {
    pub(crate) fn identity(n: usize) -> Self {
        SparseRows {
            offsets: (0..=n as u32).collect(),
            indices: (0..n as u32).collect(),
            weights: vec![1.0; n],
        }
    }

    pub(super) fn row(&self, r: usize) -> (&[u32], &[f64]) {
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
    pub(super) fn push_merged(
        &mut self,
        scratch: &mut [(u32, f64)],
    ) -> Result<(), SubdivisionError> {
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
pub(super) fn check_entries(len: usize) -> Result<u32, SubdivisionError> {
    if len > MAX_STENCIL_ENTRIES {
        return Err(SubdivisionError::TooLarge {
            what: "stencil entry",
            count: len as u64,
            max: MAX_STENCIL_ENTRIES as u64,
        });
    }
    Ok(len as u32)
}
