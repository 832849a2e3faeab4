//! Vertex normals of the canonical grid ([`ClothModel::grid`]) as a vector [`Kernel`]: the same
//! area-weighted sums of triangle cross products as [`compute_normals`], computed row by row over
//! one array per coordinate instead of triangle by triangle (whose scattered three-float reads
//! and writes no vector unit helps with). The sums are added in another order, so the two differ
//! by rounding.
//!
//! [`compute_normals`]: super::compute_normals

use glam::Vec3;

use super::ClothModel;
use crate::sim::simd::{self, Build, Kernel};
use crate::sim::soa::Soa;

/// Vertex normals of a canonical grid cloth, computed as a vector kernel instead of
/// [`compute_normals`](super::compute_normals)' triangle-by-triangle sums: the plugin uses it for
/// every unsubdivided grid cloth. Holds its scratch, so a computation allocates nothing.
///
/// ```
/// # use bevy_cloth::sim::{ClothModel, GridNormals, GridSpec};
/// # use bevy::math::Vec3;
/// let model = ClothModel::grid(&GridSpec::new(8, 8, 0.1)).unwrap();
/// let mut kernel = GridNormals::new(&model).expect("a canonical grid");
/// let mut normals = vec![Vec3::ZERO; model.particle_count()];
/// assert!(kernel.compute(&model.rest_positions, &mut normals));
/// assert!(normals.iter().all(|n| n.abs_diff_eq(Vec3::Y, 1e-6)));
/// ```
#[derive(Debug, Clone)]
pub struct GridNormals {
    nx: usize,
    ny: usize,
    /// The positions, one array per coordinate.
    positions: Soa,
    /// The cross products of each quad's two triangles, `(a, c, b)` and `(b, c, d)`, on a grid of
    /// `(nx + 1) × (ny + 1)` slots: quad `(i, j)` at slot `(i + 1, j + 1)`, the first and last row
    /// and column zero, so that every vertex adds the same six slots whether or not it is on an
    /// edge.
    first: Soa,
    second: Soa,
    /// The normals, one array per coordinate.
    normals: Soa,
}

impl GridNormals {
    /// The kernel for `model` if it is a grid whose triangles are those [`ClothModel::grid`]
    /// builds (a model edited since may not be).
    pub fn new(model: &ClothModel) -> Option<Self> {
        let (nx, ny) = model.canonical_grid()?;
        let slots = (nx + 1) * (ny + 1);
        Some(Self {
            nx,
            ny,
            positions: Soa::new(nx * ny),
            first: Soa::new(slots),
            second: Soa::new(slots),
            normals: Soa::new(nx * ny),
        })
    }

    /// Writes the unit vertex normals of the grid at `positions` into `normals` (a vertex with
    /// no area around it gets +Y, as in [`compute_normals`](super::compute_normals)); returns
    /// `false`, writing nothing, unless both have one entry per particle of the grid.
    pub fn compute(&mut self, positions: &[Vec3], normals: &mut [Vec3]) -> bool {
        let n = self.nx * self.ny;
        if positions.len() != n || normals.len() != n {
            return false;
        }
        self.positions.load(positions);
        simd::run(Normals {
            nx: self.nx,
            ny: self.ny,
            x: &self.positions,
            first: &mut self.first,
            second: &mut self.second,
            out: &mut self.normals,
        });
        self.normals.write_to(normals);
        true
    }
}

/// [`GridNormals::compute`]'s arguments, as a [`Kernel`].
struct Normals<'a> {
    nx: usize,
    ny: usize,
    x: &'a Soa,
    first: &'a mut Soa,
    second: &'a mut Soa,
    out: &'a mut Soa,
}

impl Kernel for Normals<'_> {
    const WIDEST: Build = Build::Avx2;

    #[inline(always)]
    fn body<const WIDE: bool>(self) {
        let (nx, ny, w) = (self.nx, self.ny, self.nx + 1);
        let x = self.x;
        // The quads of row j, into slot row j + 1, columns 1..nx.
        for j in 0..ny - 1 {
            let start = j * nx;
            let ((x0, x1), (y0, y1), (z0, z1)) = (
                two_rows(&x.x, start, nx, nx),
                two_rows(&x.y, start, nx, nx),
                two_rows(&x.z, start, nx, nx),
            );
            let s = (j + 1) * w + 1..(j + 1) * w + nx;
            let (f, g) = (&mut *self.first, &mut *self.second);
            let (fx, fy, fz) = (
                &mut f.x[s.clone()],
                &mut f.y[s.clone()],
                &mut f.z[s.clone()],
            );
            let (gx, gy, gz) = (&mut g.x[s.clone()], &mut g.y[s.clone()], &mut g.z[s]);
            for i in 0..nx - 1 {
                // a = (i, j), b = (i + 1, j), c = (i, j + 1), d = (i + 1, j + 1).
                let (ca, ba) = (
                    [x1[i] - x0[i], y1[i] - y0[i], z1[i] - z0[i]],
                    [x0[i + 1] - x0[i], y0[i + 1] - y0[i], z0[i + 1] - z0[i]],
                );
                let (cb, db) = (
                    [x1[i] - x0[i + 1], y1[i] - y0[i + 1], z1[i] - z0[i + 1]],
                    [
                        x1[i + 1] - x0[i + 1],
                        y1[i + 1] - y0[i + 1],
                        z1[i + 1] - z0[i + 1],
                    ],
                );
                [fx[i], fy[i], fz[i]] = cross(ca, ba);
                [gx[i], gy[i], gz[i]] = cross(cb, db);
            }
        }
        // Vertex (i, j) touches quad (i, j) as its a (first triangle), (i − 1, j) as b (both),
        // (i, j − 1) as c (both) and (i − 1, j − 1) as d (second): slots (i + 1, j + 1),
        // (i, j + 1), (i + 1, j) and (i, j).
        for j in 0..ny {
            let (up, down) = ((j + 1) * w, j * w);
            let (f, g) = (&*self.first, &*self.second);
            let (xs, ys, zs) = (
                SlotRows::new(&f.x, &g.x, up, down, w),
                SlotRows::new(&f.y, &g.y, up, down, w),
                SlotRows::new(&f.z, &g.z, up, down, w),
            );
            let out = &mut *self.out;
            let row = j * nx..(j + 1) * nx;
            let (ox, oy, oz) = (
                &mut out.x[row.clone()],
                &mut out.y[row.clone()],
                &mut out.z[row],
            );
            for i in 0..nx {
                let (sx, sy, sz) = (xs.sum(i), ys.sum(i), zs.sum(i));
                // As `Vec3::try_normalize`, +Y where that fails.
                let r = 1.0 / (sx * sx + sy * sy + sz * sz).sqrt();
                let ok = r.is_finite() && r > 0.0;
                ox[i] = if ok { sx * r } else { 0.0 };
                oy[i] = if ok { sy * r } else { 1.0 };
                oz[i] = if ok { sz * r } else { 0.0 };
            }
        }
    }
}

/// `len` values from `start` in an array of rows `n` long, and the same in the next row.
#[inline(always)]
pub(crate) fn two_rows(v: &[f32], start: usize, n: usize, len: usize) -> (&[f32], &[f32]) {
    (&v[start..start + len], &v[start + n..start + n + len])
}

/// One coordinate of the two slot rows around a row of vertices, `w` long each: the first and
/// second triangles' cross products above (`up`) and below (`down`).
#[derive(Clone, Copy)]
struct SlotRows<'a> {
    first_up: &'a [f32],
    second_up: &'a [f32],
    first_down: &'a [f32],
    second_down: &'a [f32],
}

impl<'a> SlotRows<'a> {
    #[inline(always)]
    fn new(first: &'a [f32], second: &'a [f32], up: usize, down: usize, w: usize) -> Self {
        Self {
            first_up: &first[up..up + w],
            second_up: &second[up..up + w],
            first_down: &first[down..down + w],
            second_down: &second[down..down + w],
        }
    }

    /// The six cross products around vertex `i` of the row.
    #[inline(always)]
    fn sum(self, i: usize) -> f32 {
        self.first_up[i + 1]
            + (self.first_up[i] + self.second_up[i])
            + (self.first_down[i + 1] + self.second_down[i + 1])
            + self.second_down[i]
    }
}

#[inline(always)]
fn cross(u: [f32; 3], v: [f32; 3]) -> [f32; 3] {
    [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::{GridPlane, GridSpec, compute_normals};

    fn wavy(nx: u32, ny: u32, plane: GridPlane) -> (ClothModel, Vec<Vec3>) {
        let spec = GridSpec {
            plane,
            ..GridSpec::new(nx, ny, 0.1)
        };
        let model = ClothModel::grid(&spec).unwrap();
        let positions = model
            .rest_positions
            .iter()
            .enumerate()
            .map(|(k, p)| *p + Vec3::new(0.01, 0.03, -0.02) * (k as f32 * 0.7).sin())
            .collect();
        (model, positions)
    }

    #[test]
    fn the_grid_kernel_agrees_with_the_triangle_sums() {
        for (nx, ny, plane) in [
            (2, 2, GridPlane::Horizontal),
            (3, 7, GridPlane::Vertical),
            (17, 9, GridPlane::Horizontal),
            (64, 64, GridPlane::Horizontal),
        ] {
            let (model, positions) = wavy(nx, ny, plane);
            let mut expected = vec![Vec3::ZERO; positions.len()];
            compute_normals(&positions, &model.triangles, &mut expected);
            let mut got = vec![Vec3::ZERO; positions.len()];
            assert!(
                GridNormals::new(&model)
                    .expect("a grid")
                    .compute(&positions, &mut got)
            );
            for (k, (e, g)) in expected.iter().zip(&got).enumerate() {
                assert!(e.distance(*g) < 1e-5, "{nx}×{ny} vertex {k}: {e} vs {g}");
            }
        }
    }

    #[test]
    fn every_build_gives_the_same_normals() {
        let (model, positions) = wavy(37, 11, GridPlane::Horizontal);
        let mut g = GridNormals::new(&model).unwrap();
        g.positions.load(&positions);
        let mut results = Vec::new();
        for build in [Build::Plain, Build::Avx2] {
            let mut out = Soa::new(positions.len());
            let ran = simd::run_as(
                build,
                Normals {
                    nx: g.nx,
                    ny: g.ny,
                    x: &g.positions,
                    first: &mut g.first,
                    second: &mut g.second,
                    out: &mut out,
                },
            );
            if ran {
                results.push((out.x, out.y, out.z));
            }
        }
        assert!(results.windows(2).all(|w| w[0] == w[1]));
    }

    #[test]
    fn a_collapsed_vertex_gets_up_and_only_the_canonical_grid_is_taken() {
        let (model, _) = wavy(4, 4, GridPlane::Horizontal);
        // Every particle at one point: no area anywhere.
        let mut normals = vec![Vec3::ZERO; 16];
        let mut g = GridNormals::new(&model).unwrap();
        assert!(g.compute(&[Vec3::ONE; 16], &mut normals));
        assert!(normals.iter().all(|n| *n == Vec3::Y));
        // Not this grid's particles: nothing written.
        assert!(!g.compute(&[Vec3::ONE; 15], &mut normals[..15]));
        let mut edited = model.clone();
        edited.triangles.swap(0, 1);
        assert!(GridNormals::new(&edited).is_none());
        let mut mesh = model;
        mesh.grid = None;
        assert!(GridNormals::new(&mesh).is_none());
    }
}
