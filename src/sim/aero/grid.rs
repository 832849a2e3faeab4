//! [`add_aero_forces`] for the canonical grid, row by row over one array per coordinate
//! ([`GridAero`]), with the same bits as the triangle-by-triangle path. The force of each triangle
//! is `plate`'s; nothing here samples the wind.

use super::plate::{AeroParams, force_scale, plate_force};
#[cfg(doc)]
use super::triangles::add_aero_forces;
use crate::sim::model::two_rows;
use crate::sim::simd::{self, Build, Kernel};
use crate::sim::soa::{Coordinate, Soa};
use glam::Vec3;

/// The wind at each triangle, for [`GridAero::add_forces`].
#[derive(Debug, Clone, Copy)]
pub(crate) enum TriangleWind<'a> {
    /// The same air velocity (m/s) at every triangle.
    Uniform(Vec3),
    /// The air velocity at each particle (m/s); a triangle's is the mean of its corners'.
    Corners(&'a [Vec3]),
}

impl TriangleWind<'_> {
    /// The air velocity at the triangle with the corners `tri` (particles), their winds summed in
    /// its corners' order.
    #[inline(always)]
    pub fn at(&self, tri: [u32; 3]) -> Vec3 {
        match self {
            Self::Uniform(w) => *w,
            Self::Corners(w) => {
                (w[tri[0] as usize] + w[tri[1] as usize] + w[tri[2] as usize]) / 3.0
            }
        }
    }
}

/// [`add_aero_forces`] for the canonical grid ([`ClothModel::grid`]), row by row over one array
/// per coordinate instead of triangle by triangle, whose scattered three-float reads and writes
/// no vector unit helps with. Every triangle's force is [`plate_force`] of the same inputs, and
/// every vertex adds its triangles' forces in triangle order, so the result is the same, bit for
/// bit. Holds its scratch, so a call allocates nothing.
///
/// [`ClothModel::grid`]: crate::sim::ClothModel::grid
#[derive(Debug, Clone)]
pub(crate) struct GridAero {
    nx: usize,
    ny: usize,
    /// The positions and velocities, one array per coordinate, with [`Self::lanes`] zero vectors
    /// after the particles, so that a row's padded lanes read no further than that.
    x: Soa,
    v: Soa,
    /// The quads of a row, `nx − 1`, rounded up to whole vectors: every row is computed in
    /// vectors, without a scalar tail. The padded lanes compute from the next row's values (or the
    /// zeros after the last), and their results are never used.
    lanes: usize,
    /// The inputs and forces of one row of quads' first and second triangles.
    plates: [RowPlates; 2],
    /// The winds at the particles, one array per coordinate, padded as `x` (when they differ).
    winds: Soa,
    /// The forces (times a third) of each quad's two triangles, `(a, c, b)` and `(b, c, d)`, on a
    /// grid of `(nx + 1) × (ny + 1)` slots: quad `(i, j)` at slot `(i + 1, j + 1)`, the first
    /// and last row and column zero, so that every vertex adds the same six slots whether or not
    /// it is on an edge (adding a zero to a sum begun at +0 leaves its bits as they are).
    first: Soa,
    second: Soa,
    /// Each vertex's sum, one array per coordinate.
    sums: Soa,
}

/// The inputs of a row of triangles, one array per coordinate: their edges `e₁ = p₁ − p₀`,
/// `e₂ = p₂ − p₀` and relative winds `u` (see [`plate_force`]); and their forces `f`.
#[derive(Debug, Clone)]
struct RowPlates {
    e1: Soa,
    e2: Soa,
    u: Soa,
    f: Soa,
}

impl GridAero {
    /// The kernel for `model` if it is still the grid [`ClothModel::grid`] built.
    ///
    /// [`ClothModel::grid`]: crate::sim::ClothModel::grid
    pub fn new(model: &crate::sim::ClothModel) -> Option<Self> {
        let (nx, ny) = model.canonical_grid()?;
        let slots = (nx + 1) * (ny + 1);
        let lanes = (nx - 1).next_multiple_of(ROW_LANES);
        let plates = || RowPlates {
            e1: Soa::new(lanes),
            e2: Soa::new(lanes),
            u: Soa::new(lanes),
            f: Soa::new(lanes),
        };
        Some(Self {
            nx,
            ny,
            x: Soa::new(nx * ny + lanes),
            v: Soa::new(nx * ny + lanes),
            lanes,
            plates: [plates(), plates()],
            winds: Soa::new(nx * ny + lanes),
            first: Soa::new(slots),
            second: Soa::new(slots),
            sums: Soa::new(nx * ny),
        })
    }

    /// Adds the aerodynamic force of every triangle, a third to each of its vertices, to `forces`
    /// (as [`add_aero_forces`] does, with the same bits when `forces` starts at zero). Returns
    /// `false`, adding nothing, unless `positions`, `velocities`, `forces` and the winds of
    /// [`TriangleWind::Corners`] have one entry per particle.
    pub fn add_forces(
        &mut self,
        positions: &[Vec3],
        velocities: &[Vec3],
        wind: TriangleWind,
        params: &AeroParams,
        forces: &mut [Vec3],
    ) -> bool {
        let n = self.nx * self.ny;
        if [positions.len(), velocities.len(), forces.len()] != [n; 3]
            || matches!(wind, TriangleWind::Corners(w) if w.len() != n)
        {
            return false;
        }
        simd::run(GridAeroKernel {
            grid: self,
            state: (positions, velocities),
            wind,
            params,
            forces,
        });
        true
    }
}

/// [`GridAero::add_forces`]' arguments, as a [`Kernel`].
struct GridAeroKernel<'a> {
    grid: &'a mut GridAero,
    state: (&'a [Vec3], &'a [Vec3]),
    wind: TriangleWind<'a>,
    params: &'a AeroParams,
    forces: &'a mut [Vec3],
}

impl Kernel for GridAeroKernel<'_> {
    const WIDEST: Build = Build::Avx2;

    #[inline(always)]
    fn body<const WIDE: bool>(self) {
        let GridAero {
            nx,
            ny,
            x,
            v,
            lanes,
            plates,
            winds,
            first,
            second,
            sums,
        } = self.grid;
        let (nx, ny, w, lanes) = (*nx, *ny, *nx + 1, *lanes);
        // The copies in and out too, so that they are built for the same vector units.
        x.load(self.state.0);
        v.load(self.state.1);
        if let TriangleWind::Corners(each) = self.wind {
            winds.load(each);
        }
        let scale = force_scale(self.params, 1.0 / 3.0);
        let m = nx - 1;
        let wind = match self.wind {
            TriangleWind::Uniform(wind) => RowWind::Uniform(wind),
            TriangleWind::Corners(_) => RowWind::Corners(winds),
        };
        for j in 0..ny - 1 {
            // Quad (i, j) has the corners a = (i, j), b = (i + 1, j), c = (i, j + 1) and
            // d = (i + 1, j + 1); its triangles take them in the order (a, c, b) and (b, c, d),
            // as `TriangleLanes::gather` does.
            row_inputs(x, v, (j * nx, nx, lanes), plates, wind);
            // The forces of row j's quads, into slot row j + 1, columns 1..nx.
            let s = (j + 1) * w + 1..(j + 1) * w + nx;
            for (p, out) in plates.iter_mut().zip([&mut *first, &mut *second]) {
                let RowPlates { e1, e2, u, f } = p;
                let (fx, fy, fz) = (&mut f.x[..lanes], &mut f.y[..lanes], &mut f.z[..lanes]);
                let (e1x, e1y, e1z) = (&e1.x[..lanes], &e1.y[..lanes], &e1.z[..lanes]);
                let (e2x, e2y, e2z) = (&e2.x[..lanes], &e2.y[..lanes], &e2.z[..lanes]);
                let (ux, uy, uz) = (&u.x[..lanes], &u.y[..lanes], &u.z[..lanes]);
                for i in 0..lanes {
                    [fx[i], fy[i], fz[i]] = plate_force(
                        [e1x[i], e1y[i], e1z[i]],
                        [e2x[i], e2y[i], e2z[i]],
                        [ux[i], uy[i], uz[i]],
                        scale,
                    );
                }
                out.x[s.clone()].copy_from_slice(&fx[..m]);
                out.y[s.clone()].copy_from_slice(&fy[..m]);
                out.z[s.clone()].copy_from_slice(&fz[..m]);
            }
        }
        // Vertex (i, j) is d of quad (i − 1, j − 1) (its second triangle), c of (i, j − 1)
        // (both), b of (i − 1, j) (both) and a of (i, j) (first): slots (i, j), (i + 1, j),
        // (i, j + 1) and (i + 1, j + 1), added in that order, which is the triangles'.
        for j in 0..ny {
            let (up, down) = ((j + 1) * w, j * w);
            let row = j * nx..(j + 1) * nx;
            for (first, second, out) in [
                (&first.x, &second.x, &mut sums.x[row.clone()]),
                (&first.y, &second.y, &mut sums.y[row.clone()]),
                (&first.z, &second.z, &mut sums.z[row]),
            ] {
                let (fd, gd) = (&first[down..down + w], &second[down..down + w]);
                let (fu, gu) = (&first[up..up + w], &second[up..up + w]);
                for (i, o) in out.iter_mut().enumerate() {
                    *o = 0.0 + gd[i] + fd[i + 1] + gd[i + 1] + fu[i] + gu[i] + fu[i + 1];
                }
            }
        }
        for (f, s) in self.forces.iter_mut().zip(sums.iter()) {
            *f += s;
        }
    }
}

/// Lanes a [`GridAero`] row is rounded up to: a whole number of the widest vectors.
const ROW_LANES: usize = 16;

/// The winds at a row's triangles, for [`row_inputs`].
#[derive(Clone, Copy)]
enum RowWind<'a> {
    /// The same at every triangle.
    Uniform(Vec3),
    /// The winds at the particles (padded as the positions), a triangle taking its corners' mean.
    Corners(&'a Soa),
}

/// The inputs of the triangles of the row of quads whose corners `a` are particles
/// `start..start + lanes` (rows of `nx` particles; the quads past `nx − 1` are padding), into
/// `plates`. Quad `i` has the corners `a`, `b = a + 1`, `c = a + nx` and `d = c + 1`; its
/// triangles take them in the order `(a, c, b)` and `(b, c, d)`, as `TriangleLanes::gather` does.
#[inline(always)]
fn row_inputs(
    x: &Soa,
    v: &Soa,
    (start, nx, lanes): (usize, usize, usize),
    [p0, p1]: &mut [RowPlates; 2],
    wind: RowWind,
) {
    let coords = [
        (
            &x.x,
            &v.x,
            [&mut p0.e1.x, &mut p0.e2.x, &mut p0.u.x],
            [&mut p1.e1.x, &mut p1.e2.x, &mut p1.u.x],
        ),
        (
            &x.y,
            &v.y,
            [&mut p0.e1.y, &mut p0.e2.y, &mut p0.u.y],
            [&mut p1.e1.y, &mut p1.e2.y, &mut p1.u.y],
        ),
        (
            &x.z,
            &v.z,
            [&mut p0.e1.z, &mut p0.e2.z, &mut p0.u.z],
            [&mut p1.e1.z, &mut p1.e2.z, &mut p1.u.z],
        ),
    ];
    for (c, (x, v, first, second)) in coords.into_iter().enumerate() {
        // Rows `a` and `c`, each one particle longer than the lanes (for `b` and `d`).
        let rows = |v| two_rows(v, start, nx, lanes + 1);
        // The coordinate chosen outside the loop over the row, so that it is a vector loop.
        match wind {
            RowWind::Uniform(w) => {
                let w = w.to_array()[c];
                row_coordinate(rows(x), rows(v), [first, second], lanes, |_| (w, w));
            }
            RowWind::Corners(w) => {
                let (wa, wc) = rows(w.coordinate(c));
                // As `TriangleWind::at`, in the triangles' corner orders.
                let corners = |i: usize| {
                    let (a, b, c, d) = (wa[i], wa[i + 1], wc[i], wc[i + 1]);
                    ((a + c + b) / 3.0, (b + c + d) / 3.0)
                };
                row_coordinate(rows(x), rows(v), [first, second], lanes, corners);
            }
        }
    }
}

/// One coordinate of [`row_inputs`]: from rows `a` and `c` of the positions and velocities
/// (`lanes + 1` long), the first and second triangles' `e₁`, `e₂` and `u`, with `wind(i)` the
/// winds at quad `i`'s two triangles.
#[inline(always)]
fn row_coordinate(
    (xa, xc): (&[f32], &[f32]),
    (va, vc): (&[f32], &[f32]),
    [[e1, e2, u0], [f1, f2, u1]]: [[&mut Coordinate; 3]; 2],
    lanes: usize,
    wind: impl Fn(usize) -> (f32, f32),
) {
    let (xa, xb, xc, xd) = (&xa[..lanes], &xa[1..], &xc[..lanes], &xc[1..]);
    let (va, vb, vc, vd) = (&va[..lanes], &va[1..], &vc[..lanes], &vc[1..]);
    let (e1, e2, u0) = (&mut e1[..lanes], &mut e2[..lanes], &mut u0[..lanes]);
    let (f1, f2, u1) = (&mut f1[..lanes], &mut f2[..lanes], &mut u1[..lanes]);
    for i in 0..lanes {
        e1[i] = xc[i] - xa[i];
        e2[i] = xb[i] - xa[i];
        f1[i] = xc[i] - xb[i];
        f2[i] = xd[i] - xb[i];
        let (w0, w1) = wind(i);
        u0[i] = ((w0 - va[i]) + (w0 - vc[i]) + (w0 - vb[i])) * (1.0 / 3.0);
        u1[i] = ((w1 - vb[i]) + (w1 - vc[i]) + (w1 - vd[i])) * (1.0 / 3.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::aero::triangles::add_aero_forces;
    use crate::sim::{ClothModel, GridPlane, GridSpec};

    /// A grid bent out of its plane, with every particle moving differently, in `wind`. Some
    /// triangles are left moving with the wind (no force) and one pair of particles collapsed
    /// (a degenerate triangle), so that the kernel's cut-offs are crossed too.
    fn moving_grid(
        nx: u32,
        ny: u32,
        plane: GridPlane,
        wind: Vec3,
    ) -> (ClothModel, Vec<Vec3>, Vec<Vec3>) {
        let spec = GridSpec {
            plane,
            ..GridSpec::new(nx, ny, 0.1)
        };
        let model = ClothModel::grid(&spec).unwrap();
        let mut positions: Vec<Vec3> = model
            .rest_positions
            .iter()
            .enumerate()
            .map(|(k, p)| *p + Vec3::new(0.01, 0.03, -0.02) * (k as f32 * 0.7).sin())
            .collect();
        let mut velocities: Vec<Vec3> = (0..positions.len())
            .map(|k| Vec3::new((k as f32 * 1.3).sin(), (k as f32 * 0.4).cos(), -0.5) * 3.0)
            .collect();
        if positions.len() > 4 {
            velocities[..nx as usize + 1].fill(wind);
            positions[3] = positions[2];
        }
        (model, positions, velocities)
    }

    #[test]
    fn grid_rows_give_the_triangle_sums_bit_for_bit() {
        let params = AeroParams::default();
        let wind = Vec3::new(5.0, -1.0, 2.0);
        for (nx, ny, plane) in [
            (2, 2, GridPlane::Horizontal),
            (3, 7, GridPlane::Vertical),
            (17, 9, GridPlane::Horizontal),
            (64, 64, GridPlane::Vertical),
        ] {
            let (model, x, v) = moving_grid(nx, ny, plane, wind);
            let triangles = model.triangles.as_chunks::<3>().0;
            let each: Vec<Vec3> = (0..x.len())
                .map(|k| wind + Vec3::new(0.0, (k as f32).sin(), 0.5 * (k as f32).cos()))
                .collect();
            let mut grid = GridAero::new(&model).expect("a canonical grid");
            for winds in [TriangleWind::Uniform(wind), TriangleWind::Corners(&each)] {
                let mut expected = vec![Vec3::ZERO; x.len()];
                let at: Vec<Vec3> = triangles.iter().map(|t| winds.at(*t)).collect();
                add_aero_forces(&x, &v, triangles, &at, &params, &mut expected);
                let mut got = vec![Vec3::ZERO; x.len()];
                assert!(grid.add_forces(&x, &v, winds, &params, &mut got));
                let bits = |f: &[Vec3]| -> Vec<[u32; 3]> {
                    f.iter().map(|f| f.to_array().map(f32::to_bits)).collect()
                };
                assert_eq!(bits(&got), bits(&expected), "{nx}×{ny} {winds:?}");
                assert!(
                    expected.iter().any(|f| f.length() > 1e-3),
                    "{nx}×{ny}: no force"
                );
            }
        }
    }

    #[test]
    fn grid_rows_refuse_an_edited_model_and_wrong_lengths() {
        let (mut model, x, v) = moving_grid(5, 4, GridPlane::Horizontal, Vec3::X);
        let mut grid = GridAero::new(&model).expect("a canonical grid");
        let (params, wind) = (AeroParams::default(), TriangleWind::Uniform(Vec3::X));
        let mut forces = vec![Vec3::ZERO; x.len()];
        assert!(!grid.add_forces(&x[1..], &v[1..], wind, &params, &mut forces[1..]));
        assert!(!grid.add_forces(
            &x,
            &v,
            TriangleWind::Corners(&[Vec3::X; 3]),
            &params,
            &mut forces
        ));
        assert!(forces.iter().all(|f| *f == Vec3::ZERO), "nothing added");
        model.triangles.swap(0, 1);
        assert!(GridAero::new(&model).is_none());
    }
}
