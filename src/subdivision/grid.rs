//! Regular quad grids, refined as tensor products of curves.
//!
//! On a grid of `rows × cols` vertices every interior vertex has valence 4, and a Catmull-Clark
//! level is the tensor product of uniform cubic B-spline subdivision along the rows and along the
//! columns: face point `(1, 1) ⊗ (1, 1) / 4`, edge point `(1, 1) ⊗ (1, 6, 1) / 16`, vertex point
//! `(1, 6, 1) ⊗ (1, 6, 1) / 64`. The boundary rows and columns are crease curves, refined by the
//! same curve rule with their ends kept. So level `L` is two passes of curve stencils of at most
//! four taps each: along every row of the control grid, then down the columns over whole refined
//! rows, as contiguous loops (instead of one gathered stencil per refined vertex and level).
//!
//! Where the mesh's own rules are not that product (the corners in edge-only mode, whose crease
//! rule mixes the two directions), [`GridEvaluator`] finds the refined vertices that differ, once,
//! and evaluates them from their composed stencils instead.
//!
//! This module holds no topology traversal beyond recognising a grid, and its per-frame
//! [`GridEvaluator::apply`] does not allocate.

use std::ops::{Add, Mul};

use glam::{DVec3, Vec3};

use super::sparse_rows::SparseRows;
use super::stencil::StencilTable;
use super::topology::LevelTopology;
use crate::hash::splitmix;

/// A control mesh that is a grid: control vertex `(r, c)` is vertex `r * cols + c`, and the faces
/// are its `(rows − 1)(cols − 1)` cells, in any order, orientation and starting corner.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct GridShape {
    rows: usize,
    cols: usize,
}

impl GridShape {
    /// The grid `topo` is, if it is one (at least 2 × 2 vertices).
    pub fn detect(topo: &LevelTopology) -> Option<Self> {
        // In such a numbering the cell of vertex 0 is {0, 1, cols, cols + 1}.
        let &first = topo.faces_of(0).first()?;
        let cols = (*topo.face(first as usize).iter().max()? as usize).checked_sub(1)?;
        if cols < 2 || !topo.num_vertices.is_multiple_of(cols) {
            return None;
        }
        let rows = topo.num_vertices / cols;
        let cells = (rows - 1) * (cols - 1);
        if rows < 2 || topo.face_count() != cells {
            return None;
        }
        let mut seen = vec![false; cells];
        for f in 0..cells {
            let face = topo.face(f);
            let &[a, b, c, d] = face else {
                return None;
            };
            let k = a.min(b).min(c).min(d) as usize;
            let (r, c0) = (k / cols, k % cols);
            if r + 1 >= rows || c0 + 1 >= cols {
                return None;
            }
            let mut sorted = [a, b, c, d];
            sorted.sort_unstable();
            let cell = [k, k + 1, k + cols, k + cols + 1].map(|v| v as u32);
            // The four corners of the cell, each joined to the next by a side (not a diagonal).
            let sides = (0..4).all(|i| {
                let d = face[i].abs_diff(face[(i + 1) % 4]) as usize;
                d == 1 || d == cols
            });
            if sorted != cell || !sides || std::mem::replace(&mut seen[r * (cols - 1) + c0], true) {
                return None;
            }
        }
        Some(Self { rows, cols })
    }

    /// The `(row, column)` of each control vertex.
    pub fn coordinates(self) -> Vec<[u32; 2]> {
        (0..self.rows * self.cols)
            .map(|v| [(v / self.cols) as u32, (v % self.cols) as u32])
            .collect()
    }
}

/// The numbers the grid passes run in, and their weights.
trait Real: Copy + Default + Add<Output = Self> + Mul<Output = Self> {
    fn weights(taps: &CurveTaps) -> &[Self];
}

impl Real for f32 {
    fn weights(taps: &CurveTaps) -> &[f32] {
        &taps.weights_f32
    }
}

impl Real for f64 {
    fn weights(taps: &CurveTaps) -> &[f64] {
        &taps.weights
    }
}

/// Uniform cubic B-spline subdivision of an open curve of `n` points to level `L` (ends kept):
/// refined point `i` is `Σ_k weights[offsets[i] + k] · p[start[i] + k]`, over at most four
/// consecutive points.
#[derive(Debug, Clone)]
struct CurveTaps {
    start: Vec<u32>,
    offsets: Vec<u32>,
    weights: Vec<f64>,
    weights_f32: Vec<f32>,
}

impl CurveTaps {
    fn new(n: usize, level: u32) -> Option<Self> {
        // Each refined point as (first control point, weights of the consecutive ones).
        let mut points: Vec<(usize, Vec<f64>)> = (0..n).map(|i| (i, vec![1.0])).collect();
        let mix = |parts: &[(&(usize, Vec<f64>), f64)]| {
            let first = parts.iter().map(|(p, _)| p.0).min().unwrap_or(0);
            let last = parts
                .iter()
                .map(|(p, _)| p.0 + p.1.len())
                .max()
                .unwrap_or(0);
            let mut w = vec![0.0; last - first];
            for ((s, pw), f) in parts {
                for (k, x) in pw.iter().enumerate() {
                    w[s - first + k] += f * x;
                }
            }
            (first, w)
        };
        for _ in 0..level {
            let m = points.len();
            let mut next = Vec::with_capacity(2 * m - 1);
            for i in 0..m {
                next.push(if i == 0 || i + 1 == m {
                    points[i].clone()
                } else {
                    let p = &points;
                    mix(&[(&p[i - 1], 0.125), (&p[i], 0.75), (&p[i + 1], 0.125)])
                });
                if i + 1 < m {
                    next.push(mix(&[(&points[i], 0.5), (&points[i + 1], 0.5)]));
                }
            }
            points = next;
        }
        let mut taps = Self {
            start: Vec::with_capacity(points.len()),
            offsets: vec![0],
            weights: Vec::new(),
            weights_f32: Vec::new(),
        };
        for (s, w) in points {
            if w.len() > 4 {
                return None;
            }
            taps.start.push(s as u32);
            taps.weights.extend_from_slice(&w);
            taps.weights_f32.extend(w.iter().map(|&x| x as f32));
            taps.offsets.push(taps.weights.len() as u32);
        }
        Some(taps)
    }

    fn len(&self) -> usize {
        self.start.len()
    }

    /// Refined point `i`'s first control point and weights.
    #[inline(always)]
    fn taps<T: Real>(&self, i: usize) -> (usize, &[T]) {
        let (a, b) = (self.offsets[i] as usize, self.offsets[i + 1] as usize);
        (self.start[i] as usize, &T::weights(self)[a..b])
    }
}

/// Evaluates a uniform refinement of a grid with the two curve passes, writing each refined
/// vertex where the [`Subdivider`](super::Subdivider)'s numbering puts it, then the vertices the
/// product gets wrong from their composed stencils.
#[derive(Debug, Clone)]
pub(crate) struct GridEvaluator {
    shape: GridShape,
    along_rows: CurveTaps,
    down_columns: CurveTaps,
    /// The refined vertex at each point of the refined grid (row-major).
    vertex_at: Vec<u32>,
    /// Refined vertices the product does not give, and their stencils over the control vertices
    /// (row `i` for vertex `fixed[i]`).
    fixed: Vec<u32>,
    fixed_rows: StencilTable,
    /// Control rows refined along their length: `shape.rows × along_rows.len()` points, x y z.
    rows_refined: Vec<f32>,
    /// One refined row, x y z.
    row: Vec<f32>,
}

impl GridEvaluator {
    /// The evaluator of `levels` (the level stencil tables of a grid of `shape`) whose refined
    /// vertices sit at `coords` on the refined grid, or `None` if they do not fill it.
    pub fn new(shape: GridShape, levels: &[StencilTable], coords: &[[u32; 2]]) -> Option<Self> {
        let level = u32::try_from(levels.len()).ok()?;
        let along_rows = CurveTaps::new(shape.cols, level)?;
        let down_columns = CurveTaps::new(shape.rows, level)?;
        let (rows, cols) = (down_columns.len(), along_rows.len());
        let mut vertex_at = vec![u32::MAX; rows * cols];
        for (v, &[r, c]) in coords.iter().enumerate() {
            if c as usize >= cols {
                return None;
            }
            let slot = vertex_at.get_mut(r as usize * cols + c as usize)?;
            if *slot != u32::MAX {
                return None;
            }
            *slot = v as u32;
        }
        if coords.len() != vertex_at.len() {
            return None;
        }
        let mut grid = Self {
            shape,
            along_rows,
            down_columns,
            vertex_at,
            fixed: Vec::new(),
            fixed_rows: StencilTable::from_rows(SparseRows::identity(0), 0),
            rows_refined: vec![0.0; 3 * shape.rows * cols],
            row: vec![0.0; 3 * cols],
        };
        grid.find_fixed(levels);
        Some(grid)
    }

    /// Lists the refined vertices where the product differs from the level stencils: both are
    /// evaluated on control points in general position (a fixed pseudo-random cloud), where
    /// stencils that differ give different points.
    fn find_fixed(&mut self, levels: &[StencilTable]) {
        let n = self.shape.rows * self.shape.cols;
        let unit = |h: u64| (h >> 11) as f64 / (1u64 << 53) as f64;
        let control: Vec<DVec3> = (0..n as u64)
            .map(|i| {
                let h = |k: u64| unit(splitmix(3 * i + k));
                DVec3::new(h(0), h(1), h(2))
            })
            .collect();
        let mut general = control.clone();
        for table in levels {
            let mut next = vec![DVec3::ZERO; table.len()];
            // The tables were built for these sizes; a mismatch leaves every vertex fixed up.
            let _ = table.apply_f64(&general, &mut next);
            general = next;
        }
        let mut product = vec![DVec3::ZERO; general.len()];
        self.evaluate::<f64>(bytemuck::cast_slice(&control), |v, p| {
            product[v] = DVec3::new(p[0], p[1], p[2]);
        });
        let mut rows = SparseRows::identity(0);
        for (v, (a, b)) in general.iter().zip(&product).enumerate() {
            if a.distance(*b) > 1e-9 {
                let row = composed_row(levels, v);
                self.fixed.push(v as u32);
                rows.indices.extend(row.iter().map(|&(k, _)| k));
                rows.weights.extend(row.iter().map(|&(_, w)| w));
                rows.offsets.push(rows.indices.len() as u32);
            }
        }
        self.fixed_rows = StencilTable::from_rows(rows, n);
    }

    /// Refined vertices evaluated from their composed stencils rather than the product.
    #[cfg(test)]
    pub fn fixed_count(&self) -> usize {
        self.fixed.len()
    }

    /// The two passes, calling `emit(v, [x, y, z])` for every refined vertex `v`. `control` is the
    /// control positions as x y z triples.
    fn evaluate<T: Real>(&self, control: &[T], mut emit: impl FnMut(usize, &[T])) {
        let width = 3 * self.along_rows.len();
        let mut rows_refined = vec![T::default(); self.shape.rows * width];
        let mut line = vec![T::default(); width];
        self.passes(control, &mut rows_refined, &mut line, &mut emit);
    }

    /// [`Self::evaluate`] with its buffers given: `rows_refined` for the control rows refined
    /// along their length, `line` for one refined row.
    fn passes<T: Real>(
        &self,
        control: &[T],
        rows_refined: &mut [T],
        line: &mut [T],
        emit: &mut impl FnMut(usize, &[T]),
    ) {
        let (width, cols) = (line.len(), self.shape.cols);
        // Along each control row.
        for (src, dst) in control
            .chunks_exact(3 * cols)
            .zip(rows_refined.chunks_exact_mut(width))
        {
            for (i, out) in dst.chunks_exact_mut(3).enumerate() {
                let (s, w) = self.along_rows.taps::<T>(i);
                let mut acc = [T::default(); 3];
                for (k, &wk) in w.iter().enumerate() {
                    let p = &src[3 * (s + k)..3 * (s + k) + 3];
                    for c in 0..3 {
                        acc[c] = acc[c] + wk * p[c];
                    }
                }
                out.copy_from_slice(&acc);
            }
        }
        // Down the columns, a whole refined row at a time.
        for r in 0..self.down_columns.len() {
            let (s, w) = self.down_columns.taps::<T>(r);
            line.fill(T::default());
            for (k, &wk) in w.iter().enumerate() {
                let src = &rows_refined[(s + k) * width..(s + k + 1) * width];
                for (o, &x) in line.iter_mut().zip(src) {
                    *o = *o + wk * x;
                }
            }
            let at = &self.vertex_at[r * width / 3..(r + 1) * width / 3];
            for (&v, p) in at.iter().zip(line.chunks_exact(3)) {
                emit(v as usize, p);
            }
        }
    }

    /// Writes the refined positions of `control` (the grid's vertices) into `out` (the refined
    /// vertices); both lengths are checked by the caller. Does not allocate.
    pub fn apply(&mut self, control: &[Vec3], out: &mut [Vec3]) {
        let (mut rows_refined, mut line) = (
            std::mem::take(&mut self.rows_refined),
            std::mem::take(&mut self.row),
        );
        self.passes::<f32>(
            bytemuck::cast_slice(control),
            &mut rows_refined,
            &mut line,
            &mut |v, p| out[v] = Vec3::new(p[0], p[1], p[2]),
        );
        (self.rows_refined, self.row) = (rows_refined, line);
        let rows = &self.fixed_rows;
        for (&v, ends) in self.fixed.iter().zip(rows.offsets().windows(2)) {
            let entries = ends[0] as usize..ends[1] as usize;
            out[v as usize] = rows.indices()[entries.clone()]
                .iter()
                .zip(&rows.weights_f32()[entries])
                .fold(Vec3::ZERO, |s, (&k, &w)| s + w * control[k as usize]);
        }
    }
}

/// Refined vertex `v`'s stencil over the control vertices: its row of the last level table,
/// expanded through the earlier ones.
fn composed_row(levels: &[StencilTable], v: usize) -> Vec<(u32, f64)> {
    let mut row = vec![(v as u32, 1.0)];
    for table in levels.iter().rev() {
        let mut next: Vec<(u32, f64)> = Vec::new();
        for &(k, w) in &row {
            if let Some((idx, ws)) = table.stencil(k as usize) {
                next.extend(idx.iter().zip(ws).map(|(&i, &x)| (i, w * x)));
            }
        }
        next.sort_unstable_by_key(|&(i, _)| i);
        next.dedup_by(|b, a| {
            let same = a.0 == b.0;
            if same {
                a.1 += b.1;
            }
            same
        });
        row = next;
    }
    row
}
