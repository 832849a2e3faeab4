//! Cloths whose particles are the rows of a lattice ([`Lattice`]): the canonical grid, and any
//! mesh laid out the same way (a skinned cape made as a grid of vertices), found from its
//! triangles. Their coarse level of detail keeps some rows and columns of the lattice.

use super::ClothModel;

/// A cloth's particles as `ny` rows of `nx`: particle `(i, j)` is `j · nx + i`, and each cell
/// `(i, j)…(i + 1, j + 1)` is two triangles that share one of its diagonals.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Lattice {
    pub nx: usize,
    pub ny: usize,
    /// Whether the triangles wind clockwise in `(i, j)` (as the canonical grid's do).
    pub clockwise: bool,
}

impl ClothModel {
    /// The lattice the particles form, if they form one: for a grid its spec's, for a mesh the
    /// one its triangles fit exactly (every triangle within one cell, two per cell, sharing its
    /// diagonal, all wound alike).
    pub(crate) fn lattice(&self) -> Option<Lattice> {
        let tris = &self.triangles;
        let nx = match self.grid {
            Some(g) => g.nx as usize,
            // The row length is the farthest index a triangle at particle 0 reaches, or one less
            // (a cell's triangles reach `nx` or `nx + 1`).
            None => {
                let far = tris
                    .chunks_exact(3)
                    .filter(|t| t.contains(&0))
                    .flat_map(|t| t.iter().copied())
                    .max()? as usize;
                return [far.saturating_sub(1), far]
                    .into_iter()
                    .filter(|&nx| nx >= 2)
                    .find_map(|nx| self.fits(nx));
            }
        };
        self.fits(nx)
    }

    /// The lattice of rows of `nx` particles, if the triangles fit it.
    fn fits(&self, nx: usize) -> Option<Lattice> {
        let n = self.particle_count();
        if nx < 2 || !n.is_multiple_of(nx) || n / nx < 2 {
            return None;
        }
        let ny = n / nx;
        let cells = (nx - 1) * (ny - 1);
        if self.triangles.len() != 6 * cells {
            return None;
        }
        // Per cell, the corner its first triangle left out (4: none yet, 5: both triangles in).
        let mut left_out = vec![4u8; cells];
        let mut clockwise = None;
        for t in self.triangles.chunks_exact(3) {
            // The cell's first corner: the lowest column and row of the three.
            let i = t.iter().map(|&v| v as usize % nx).min()?;
            let j = t.iter().map(|&v| v as usize / nx).min()?;
            let a = j * nx + i;
            if i + 1 >= nx || j + 1 >= ny {
                return None;
            }
            // Each corner's place in the cell: bit 0 along i, bit 1 along j.
            let mut corners = [0u8; 3];
            for (c, &v) in corners.iter_mut().zip(t) {
                let d = (v as usize).checked_sub(a)?;
                *c = match d {
                    0 => 0,
                    1 => 1,
                    _ if d == nx => 2,
                    _ if d == nx + 1 => 3,
                    _ => return None,
                };
            }
            let missing = 6u8.checked_sub(corners.iter().sum())?;
            let cell = &mut left_out[j * (nx - 1) + i];
            match *cell {
                4 => *cell = missing,
                // The second triangle leaves out the other corner off the same diagonal (corners
                // 0 and 3, or 1 and 2, sum to 3).
                first if first < 4 && first + missing == 3 => *cell = 5,
                _ => return None,
            }
            let at = |c: u8| ((c & 1) as i32, (c >> 1) as i32);
            let (p, q, r) = (at(corners[0]), at(corners[1]), at(corners[2]));
            let area = (q.0 - p.0) * (r.1 - p.1) - (q.1 - p.1) * (r.0 - p.0);
            let cw = area < 0;
            if *clockwise.get_or_insert(cw) != cw || area == 0 {
                return None;
            }
        }
        left_out.iter().all(|&c| c == 5).then_some(Lattice {
            nx,
            ny,
            clockwise: clockwise?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::model::GridSpec;
    use glam::Vec3;

    fn mesh(nx: usize, ny: usize, flip: bool) -> ClothModel {
        let mut positions = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                positions.push(Vec3::new(i as f32, 0.0, j as f32));
            }
        }
        let mut indices = Vec::new();
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let a = (j * nx + i) as u32;
                let (b, c, d) = (a + 1, a + nx as u32, a + nx as u32 + 1);
                if flip {
                    indices.extend([a, b, d, a, d, c]);
                } else {
                    indices.extend([a, c, b, b, c, d]);
                }
            }
        }
        ClothModel::from_mesh(&positions, None, &indices, 3).unwrap()
    }

    #[test]
    fn grids_and_meshes_laid_out_in_rows_are_lattices() {
        let grid = ClothModel::grid(&GridSpec::new(5, 3, 0.1)).unwrap();
        let expect = |nx, ny, clockwise| Some(Lattice { nx, ny, clockwise });
        assert_eq!(grid.lattice(), expect(5, 3, true));
        assert_eq!(mesh(5, 3, false).lattice(), expect(5, 3, true));
        // The other diagonal and the other winding.
        assert_eq!(mesh(4, 6, true).lattice(), expect(4, 6, false));
        assert_eq!(mesh(2, 2, false).lattice(), expect(2, 2, true));
    }

    #[test]
    fn other_meshes_are_not_lattices() {
        // A cell's triangle replaced by one that folds over its neighbour.
        let mut folded = mesh(4, 4, false);
        folded.triangles[3..6].copy_from_slice(&[0, 4, 5]);
        assert_eq!(folded.lattice(), None);
        // One triangle wound the other way.
        let mut flipped = mesh(4, 4, false);
        flipped.triangles.swap(0, 1);
        assert_eq!(flipped.lattice(), None);
        // A cell missing.
        let mut holed = mesh(4, 4, false);
        holed.triangles.truncate(holed.triangles.len() - 6);
        assert_eq!(holed.lattice(), None);
        // A hand-made model whose triangle at particle 0 is all particle 0.
        let mut point = mesh(3, 3, false);
        point.triangles[..3].copy_from_slice(&[0, 0, 0]);
        assert_eq!(point.lattice(), None);
        let disc = ClothModel::disc(&crate::sim::model::DiscSpec::new(4, 8, 0.1)).unwrap();
        assert_eq!(disc.lattice(), None);
    }
}
