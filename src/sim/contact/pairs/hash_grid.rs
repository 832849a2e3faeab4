//! Grids of cells: the spatial hash of boxes that the broad phases search through, and the cell
//! arithmetic and box tests that self-contacts' cubes and patches share (their maps hash cells
//! with [`IntHasher`](crate::hash::IntHasher)).

use glam::{Vec3, Vec3A};

/// A spatial hash of boxes no larger than its cells: each box is listed in every cell it meets
/// (at most two per axis), bucketed by a hash of the cell (counting sort, no per-build
/// allocation once grown).
#[derive(Debug, Clone, Default)]
pub(in crate::sim::contact) struct SpatialHash {
    /// The boxes, filled by the caller before [`Self::build`].
    pub(in crate::sim::contact) boxes: Vec<(Vec3, Vec3)>,
    /// 1 / cell size.
    inv_cell: f32,
    /// Buckets − 1 (a power of two less one).
    mask: u32,
    /// Where each bucket's entries begin in `entries` (one more than the buckets).
    start: Vec<u32>,
    /// (box, cell) per listing, grouped by bucket.
    entries: Vec<(u32, [i32; 3])>,
    /// The cell of each box's low corner.
    low: Vec<[i32; 3]>,
}

impl SpatialHash {
    /// Lists the boxes `i` for which `include(i)` holds in their cells. Returns `false` (and lists
    /// nothing) if a box is not finite.
    pub(in crate::sim::contact) fn build(&mut self, include: impl Fn(u32) -> bool) -> bool {
        if !self.finite() {
            self.entries.clear();
            return false;
        }
        let mut extent = 0.0f32;
        for (i, (lo, hi)) in self.boxes.iter().enumerate() {
            if include(i as u32) {
                extent = extent.max((*hi - *lo).max_element());
            }
        }
        self.inv_cell = 1.0 / extent.max(1e-6);
        let inv = self.inv_cell;
        // Low corners' cells (only those of listed boxes are read), then twice as many buckets
        // as entries, so that few cells share a bucket.
        self.low.clear();
        self.low.resize(self.boxes.len(), [0; 3]);
        let mut count = 0usize;
        for (i, (lo, hi)) in self.boxes.iter().enumerate() {
            if include(i as u32) {
                let (a, b) = (cell_of(*lo, inv), cell_of(*hi, inv));
                self.low[i] = a;
                count += (0..3)
                    .map(|k| (b[k] - a[k] + 1) as usize)
                    .product::<usize>();
            }
        }
        let buckets = (2 * count).next_power_of_two().max(16);
        self.mask = (buckets - 1) as u32;
        self.start.clear();
        self.start.resize(buckets + 1, 0);
        for (i, (_, hi)) in self.boxes.iter().enumerate() {
            if include(i as u32) {
                for_cells(self.low[i], self.cell(*hi), |c| {
                    self.start[bucket_of(c, self.mask) + 1] += 1;
                });
            }
        }
        for b in 0..buckets {
            self.start[b + 1] += self.start[b];
        }
        self.entries.clear();
        self.entries.resize(count, (0, [0; 3]));
        // `start[b]` serves as bucket b's cursor while filling, then is restored.
        for (i, (_, hi)) in self.boxes.iter().enumerate() {
            if include(i as u32) {
                for_cells(self.low[i], self.cell(*hi), |c| {
                    let b = bucket_of(c, self.mask);
                    self.entries[self.start[b] as usize] = (i as u32, c);
                    self.start[b] += 1;
                });
            }
        }
        for b in (1..=buckets).rev() {
            self.start[b] = self.start[b - 1];
        }
        self.start[0] = 0;
        true
    }

    /// Whether every box is finite (a search on non-finite positions pairs nothing).
    pub(in crate::sim::contact) fn finite(&self) -> bool {
        self.boxes
            .iter()
            .all(|(lo, hi)| lo.is_finite() && hi.is_finite())
    }

    /// Sets the boxes to those of triangles `tris` over positions `x`, grown by `grow`.
    pub(in crate::sim::contact) fn triangle_boxes(
        &mut self,
        tris: &[[u32; 3]],
        x: &[Vec3],
        grow: Vec3,
    ) {
        self.boxes.clear();
        self.boxes.extend(tris.iter().map(|t| {
            let [a, b, c] = t.map(|i| x[i as usize]);
            (a.min(b).min(c) - grow, a.max(b).max(c) + grow)
        }));
    }

    /// The cell of point `p`.
    fn cell(&self, p: Vec3) -> [i32; 3] {
        cell_of(p, self.inv_cell)
    }

    /// Calls `f(box)` once for every box that meets box `lo..hi`, which must be no larger
    /// than a cell (in the one cell that holds the low corner of the two boxes' overlap).
    pub(in crate::sim::contact) fn visit(&self, lo: Vec3, hi: Vec3, mut f: impl FnMut(u32)) {
        if self.entries.is_empty() {
            return;
        }
        let from = self.cell(lo);
        for_cells(from, self.cell(hi), |c| {
            let b = bucket_of(c, self.mask);
            for &(i, cell) in &self.entries[self.start[b] as usize..self.start[b + 1] as usize] {
                if cell != c {
                    continue;
                }
                let (blo, bhi) = self.boxes[i as usize];
                // The overlap's low corner is the larger of the two low corners, and the cell
                // of a point is monotonic in it.
                let low = self.low[i as usize];
                let first = [0, 1, 2].map(|k| low[k].max(from[k]));
                if boxes_meet((blo, bhi), (lo, hi)) && first == c {
                    f(i);
                }
            }
        });
    }
}

/// Calls `f` for every cell from `lo` to `hi` (inclusive).
pub(in crate::sim::contact) fn for_cells(lo: [i32; 3], hi: [i32; 3], mut f: impl FnMut([i32; 3])) {
    for x in lo[0]..=hi[0] {
        for y in lo[1]..=hi[1] {
            for z in lo[2]..=hi[2] {
                f([x, y, z]);
            }
        }
    }
}

/// Whether boxes `a` and `b` (low and high corners) meet; false if a corner is NaN.
pub(in crate::sim::contact) fn boxes_meet(
    (alo, ahi): (Vec3, Vec3),
    (blo, bhi): (Vec3, Vec3),
) -> bool {
    alo.cmple(bhi).all() && ahi.cmpge(blo).all()
}

/// [`boxes_meet`] in whole vector registers, without a branch per axis (the inner loops of the
/// patch pairs' search, where most boxes do not meet and which axis tells is hard to predict).
pub(in crate::sim::contact) fn boxes_meet_wide(
    (alo, ahi): (Vec3A, Vec3A),
    (blo, bhi): (Vec3A, Vec3A),
) -> bool {
    (alo.cmple(bhi) & ahi.cmpge(blo)).all()
}

/// The cell of point `p` in a grid of cells `1 / inv` wide.
pub(in crate::sim::contact) fn cell_of(p: Vec3, inv: f32) -> [i32; 3] {
    // `floor` without a library call where the target lacks a rounding instruction: truncate,
    // then step down where that rounded up (negative non-integers). Saturating as `floor` and
    // `as` would, and 0 for NaN.
    (p * inv).to_array().map(|x| {
        let t = x as i32;
        t.saturating_sub(i32::from((t as f32) > x))
    })
}

/// The bucket of cell `c`.
fn bucket_of(c: [i32; 3], mask: u32) -> usize {
    let h = (c[0] as u32).wrapping_mul(0x8da6_b343)
        ^ (c[1] as u32).wrapping_mul(0xd816_3841)
        ^ (c[2] as u32).wrapping_mul(0xcb1a_b31f);
    (h & mask) as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cell_is_the_floor_of_the_scaled_point() {
        let values = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            2.999,
            -2.999,
            3.0,
            -3.0,
            1e-30,
            -1e-30,
            1e6 + 0.5,
            -1e6 - 0.5,
            3e9,
            -3e9,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        for x in values {
            let expected = Vec3::splat(x).floor().as_ivec3().x;
            assert_eq!(cell_of(Vec3::new(x, 0.0, 0.0), 1.0)[0], expected, "{x}");
        }
    }

    #[test]
    fn the_hash_finds_every_overlapping_box_once() {
        // Boxes on a jittered lattice, queried by boxes of every size up to a cell: the hash's
        // answers equal a brute-force overlap test's, each once.
        let mut hash = SpatialHash::default();
        let jitter = |i: usize, k: usize| ((i * 7919 + k * 104_729) % 1000) as f32 / 1000.0;
        hash.boxes = (0..300)
            .map(|i| {
                let lo = Vec3::new(jitter(i, 0), jitter(i, 1), jitter(i, 2)) * 3.0 - 1.5;
                (
                    lo,
                    lo + Vec3::new(jitter(i, 3), jitter(i, 4), jitter(i, 5)) * 0.4,
                )
            })
            .collect();
        assert!(hash.build(|_| true));
        for q in 0..200 {
            let lo = Vec3::new(jitter(q, 6), jitter(q, 7), jitter(q, 8)) * 3.0 - 1.5;
            let hi = lo + Vec3::new(jitter(q, 9), jitter(q, 10), jitter(q, 11)) * 0.3;
            let mut found = Vec::new();
            hash.visit(lo, hi, |i| found.push(i));
            let mut expected: Vec<u32> = (0..hash.boxes.len() as u32)
                .filter(|&i| {
                    let (blo, bhi) = hash.boxes[i as usize];
                    blo.cmple(hi).all() && bhi.cmpge(lo).all()
                })
                .collect();
            found.sort_unstable();
            expected.sort_unstable();
            assert_eq!(found, expected, "query {q}");
        }
    }
}
