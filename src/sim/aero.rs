//! Aerodynamics for triangle-mesh cloth: per-triangle drag and lift in the style of NvCloth's wind
//! model, and a deterministic, smooth, seeded gust field to drive it.
//!
//! Each triangle is treated as a thin flat plate in a uniform relative air flow. With the relative
//! air velocity `u` (wind minus the triangle's mean vertex velocity), area `A`, unit normal `n` and
//! `cos θ = n·û`, the plate feels
//!
//! - drag `½ ρ C_d A |u|² |cos θ| û`: along the relative wind, proportional to the projected area;
//! - lift `½ ρ C_l A |u|² |cos θ| sin θ l̂`: perpendicular to the relative wind (see
//!   [`add_aero_forces`] for the direction `l̂`).
//!
//! Both vanish for an edge-on plate, lift also for a face-on one, and neither depends on the
//! triangle's winding. The wind itself is sampled per triangle (e.g. at [`triangle_centroids`]),
//! typically from [`Gusts::sample`].
//!
//! SI units throughout (m, s, kg, N). Plain slices in, plain slices out. Nothing here allocates
//! but `GridAero`'s scratch, once, when it is made; nothing holds state from one step to the next
//! (a [`GustSampler`] notes the noise cells it last used, a `GustTable` its knots, both for one
//! step).

use crate::hash::{GOLDEN_GAMMA, mix64, unit_interval};
use crate::sim::model::two_rows;
use crate::sim::simd::{self, Build, Kernel};
use crate::sim::soa::{Coordinate, Soa};
use bevy::reflect::Reflect;
use glam::Vec3;
use serde::{Deserialize, Serialize};
use std::f32::consts::TAU;

/// Squared relative speed (m²/s²) below which the air is treated as still: 1 µm/s.
const MIN_SPEED_SQ: f32 = 1e-12;

/// Area (m²) below which a triangle is treated as degenerate and skipped.
const MIN_AREA: f32 = 1e-12;

/// Sea-level air density, kg/m³.
pub const AIR_DENSITY: f32 = 1.225;

/// Aerodynamic coefficients of the cloth and the density of the air around it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Reflect)]
#[serde(default, deny_unknown_fields)]
pub struct AeroParams {
    /// Density of the air, kg/m³ (sea-level air: 1.225).
    pub air_density: f32,
    /// Drag coefficient `C_d`, dimensionless, scaling the force along the relative wind.
    pub drag: f32,
    /// Lift coefficient `C_l`, dimensionless, scaling the force across the relative wind.
    pub lift: f32,
}

impl Default for AeroParams {
    /// Sea-level air (1.225 kg/m³), `C_d = 1.0`, `C_l = 0.5`.
    fn default() -> Self {
        Self {
            air_density: AIR_DENSITY,
            drag: 1.0,
            lift: 0.5,
        }
    }
}

/// Adds the aerodynamic force on every triangle, in newtons, to its three vertices (a third each).
///
/// - `positions`, `velocities`: per-vertex positions (m) and velocities (m/s).
/// - `triangles`: vertex indices of each triangle; either winding works.
/// - `triangle_wind`: air velocity (m/s) at each triangle, e.g. sampled at its centroid.
/// - `forces`: per-vertex forces (N). Forces are **added**; the caller zeroes the buffer (or fills
///   it with other forces) beforehand.
///
/// For a triangle with relative air velocity `u = wind − mean(vertex velocities)`, area `A`, unit
/// normal `n` and `c = cos θ = n·û`, the force is `q (C_d |c| û + C_l c (n − c û))` with
/// `q = ½ ρ A |u|²`. The second term is the lift `q C_l |c| sin θ l̂`, derived as follows.
/// A flat plate is pushed towards its leeward side, along `n_l = sign(c) n`, which does not
/// depend on the winding. Lift is the part of that push perpendicular to the wind, so
/// `l̂ = sign(c) (n − c û) / sin θ` (note `|n − c û| = sin θ`), and
/// `|c| sin θ l̂ = |c| sign(c) (n − c û) = c (n − c û)`: no sign function and no division, zero
/// face-on and edge-on, and invariant under `n → −n` because both factors change sign.
///
/// Sign convention: `lift·n` has the sign of `n·û`; lift points to the plate's leeward side, away
/// from the face the air hits. A kite (plate tilted with its leading edge up into a horizontal
/// wind) deflects the air down and is lifted up; a ramp (leading edge down) is pushed down.
///
/// Triangles with area below 1e-12 m² and triangles in air slower than 1e-6 m/s relative to
/// them add nothing, so a cloth moving with the wind feels exactly zero force.
///
/// # Panics
///
/// If `velocities` or `forces` differ in length from `positions`, if `triangle_wind` differs in
/// length from `triangles`, or if a vertex index is out of range.
pub fn add_aero_forces(
    positions: &[Vec3],
    velocities: &[Vec3],
    triangles: &[[u32; 3]],
    triangle_wind: &[Vec3],
    params: &AeroParams,
    forces: &mut [Vec3],
) {
    assert_eq!(velocities.len(), positions.len(), "one velocity per vertex");
    assert_eq!(forces.len(), positions.len(), "one force per vertex");
    assert_eq!(
        triangle_wind.len(),
        triangles.len(),
        "one wind per triangle"
    );

    add_aero_forces_in(
        positions,
        velocities,
        triangles,
        |t| triangle_wind[t],
        params,
        forces,
    );
}

/// [`add_aero_forces`] with the wind at triangle `t` given by `wind(t)`. Triangles go in batches
/// of [`AERO_LANES`], whose forces are computed lane by lane (vector code) and then added to their
/// vertices in order; the rest one by one, with the same arithmetic.
pub(crate) fn add_aero_forces_in(
    positions: &[Vec3],
    velocities: &[Vec3],
    triangles: &[[u32; 3]],
    wind: impl Fn(usize) -> Vec3,
    params: &AeroParams,
    forces: &mut [Vec3],
) {
    let (batches, rest) = triangles.as_chunks::<AERO_LANES>();
    let mut add = |tris: &[[u32; 3]], f: &[[f32; AERO_LANES]; 3]| {
        for (l, tri) in tris.iter().enumerate() {
            let third = Vec3::new(f[0][l], f[1][l], f[2][l]);
            for &i in tri {
                forces[i as usize] += third;
            }
        }
    };
    for (b, batch) in batches.iter().enumerate() {
        let lanes =
            TriangleLanes::gather(batch, positions, velocities, |l| wind(b * AERO_LANES + l));
        add(batch, &lanes.forces(params, 1.0 / 3.0));
    }
    let first = batches.len() * AERO_LANES;
    for (t, tri) in rest.iter().enumerate() {
        let lane = TriangleLanes::<1>::gather(&[*tri], positions, velocities, |_| wind(first + t));
        let f = lane.forces(params, 1.0 / 3.0);
        let mut wide = [[0.0; AERO_LANES]; 3];
        for c in 0..3 {
            wide[c][0] = f[c][0];
        }
        add(&[*tri], &wide);
    }
}

/// The wind at each triangle, for [`GridAero::add_forces`].
#[derive(Debug, Clone, Copy)]
pub(crate) enum TriangleWind<'a> {
    /// The same air velocity (m/s) at every triangle.
    Uniform(Vec3),
    /// The air velocity at each triangle, in the model's triangle order.
    Each(&'a [Vec3]),
}

impl TriangleWind<'_> {
    /// The air velocity at triangle `t`.
    #[inline(always)]
    pub fn at(&self, t: usize) -> Vec3 {
        match self {
            Self::Uniform(w) => *w,
            Self::Each(each) => each[t],
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
    plates: [Plates; 2],
    /// The winds at one row's first and second triangles, when they differ between triangles.
    winds: [Soa; 2],
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
struct Plates {
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
        let plates = || Plates {
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
            winds: [Soa::new(lanes), Soa::new(lanes)],
            first: Soa::new(slots),
            second: Soa::new(slots),
            sums: Soa::new(nx * ny),
        })
    }

    /// Adds the aerodynamic force of every triangle, a third to each of its vertices, to `forces`
    /// (as [`add_aero_forces`] does, with the same bits when `forces` starts at zero). Returns
    /// `false`, adding nothing, unless `positions`, `velocities` and `forces` have one entry per
    /// particle and `wind` one per triangle.
    pub fn add_forces(
        &mut self,
        positions: &[Vec3],
        velocities: &[Vec3],
        wind: TriangleWind,
        params: &AeroParams,
        forces: &mut [Vec3],
    ) -> bool {
        let n = self.nx * self.ny;
        let triangles = 2 * (self.nx - 1) * (self.ny - 1);
        if [positions.len(), velocities.len(), forces.len()] != [n; 3]
            || matches!(wind, TriangleWind::Each(w) if w.len() != triangles)
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
        let scale = force_scale(self.params, 1.0 / 3.0);
        for j in 0..ny - 1 {
            // Quad (i, j) has the corners a = (i, j), b = (i + 1, j), c = (i, j + 1) and
            // d = (i + 1, j + 1); its triangles take them in the order (a, c, b) and (b, c, d),
            // as `TriangleLanes::gather` does.
            let (m, rows) = (nx - 1, j * (nx - 1));
            let wind = match self.wind {
                TriangleWind::Uniform(wind) => RowWind::Uniform(wind),
                TriangleWind::Each(each) => {
                    let each = &each[2 * rows..2 * (rows + m)];
                    for (t, wind) in winds.iter_mut().enumerate() {
                        for (i, (x, y, z)) in wind.iter_mut().take(m).enumerate() {
                            (*x, *y, *z) = each[2 * i + t].into();
                        }
                    }
                    RowWind::Each(winds)
                }
            };
            row_inputs(x, v, (j * nx, nx, lanes), plates, wind);
            // The forces of row j's quads, into slot row j + 1, columns 1..nx.
            let s = (j + 1) * w + 1..(j + 1) * w + nx;
            for (p, out) in plates.iter_mut().zip([&mut *first, &mut *second]) {
                let Plates { e1, e2, u, f } = p;
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
    /// At the first and the second triangle of each quad.
    Each(&'a [Soa; 2]),
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
    [p0, p1]: &mut [Plates; 2],
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
            RowWind::Each([w0, w1]) => {
                let (w0, w1) = (&w0.coordinate(c)[..lanes], &w1.coordinate(c)[..lanes]);
                row_coordinate(rows(x), rows(v), [first, second], lanes, |i| (w0[i], w1[i]));
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

/// Writes the centroid (mean of the three vertex positions, m) of each triangle into `out`, for
/// sampling the wind field per triangle.
///
/// # Panics
///
/// If `out` differs in length from `triangles`, or if a vertex index is out of range.
pub fn triangle_centroids(positions: &[Vec3], triangles: &[[u32; 3]], out: &mut [Vec3]) {
    assert_eq!(out.len(), triangles.len(), "one centroid per triangle");
    for (o, tri) in out.iter_mut().zip(triangles) {
        // Indexed one by one rather than through `tri.map(..)`, which the compiler may leave a
        // call in this loop.
        let (a, b, c) = (
            positions[tri[0] as usize],
            positions[tri[1] as usize],
            positions[tri[2] as usize],
        );
        *o = (a + b + c) / 3.0;
    }
}

/// Triangles per batch in [`add_aero_forces_in`].
const AERO_LANES: usize = 8;

/// `N` triangles' aerodynamic inputs, one array per coordinate: the edges `e₁ = p₁ − p₀`,
/// `e₂ = p₂ − p₀` and the relative wind `u`.
struct TriangleLanes<const N: usize> {
    e1: [[f32; N]; 3],
    e2: [[f32; N]; 3],
    u: [[f32; N]; 3],
}

impl<const N: usize> TriangleLanes<N> {
    /// The inputs of `triangles` (`N` of them), the wind at the `l`-th being `wind(l)`.
    #[inline(always)]
    fn gather(
        triangles: &[[u32; 3]],
        positions: &[Vec3],
        velocities: &[Vec3],
        wind: impl Fn(usize) -> Vec3,
    ) -> Self {
        let mut lanes = Self {
            e1: [[0.0; N]; 3],
            e2: [[0.0; N]; 3],
            u: [[0.0; N]; 3],
        };
        for (l, tri) in triangles.iter().enumerate().take(N) {
            let [a, b, c] = tri.map(|i| i as usize);
            let (p0, w) = (positions[a], wind(l));
            let e1 = positions[b] - p0;
            let e2 = positions[c] - p0;
            // Averaging the per-vertex differences makes `u` exactly zero when every vertex
            // moves with the wind (averaging the velocities first would leave rounding noise).
            let u = ((w - velocities[a]) + (w - velocities[b]) + (w - velocities[c])) * (1.0 / 3.0);
            for (k, (e1, e2, u)) in [(e1.x, e2.x, u.x), (e1.y, e2.y, u.y), (e1.z, e2.z, u.z)]
                .into_iter()
                .enumerate()
            {
                (lanes.e1[k][l], lanes.e2[k][l], lanes.u[k][l]) = (e1, e2, u);
            }
        }
        lanes
    }

    /// `share` times each triangle's aerodynamic force (N), lane by lane ([`plate_force`]); see
    /// [`add_aero_forces`].
    #[inline(always)]
    fn forces(&self, params: &AeroParams, share: f32) -> [[f32; N]; 3] {
        let scale = force_scale(params, share);
        let (e1, e2, u) = (&self.e1, &self.e2, &self.u);
        let mut f = [[0.0; N]; 3];
        for l in 0..N {
            let at = |v: &[[f32; N]; 3]| [v[0][l], v[1][l], v[2][l]];
            let g = plate_force(at(e1), at(e2), at(u), scale);
            for d in 0..3 {
                f[d][l] = g[d];
            }
        }
        f
    }
}

/// The factors of [`plate_force`]'s drag and lift, `ρ/4 · share · C_d` and `ρ/4 · share · C_l`.
#[inline(always)]
fn force_scale(params: &AeroParams, share: f32) -> (f32, f32) {
    let scale = 0.25 * params.air_density * share;
    (scale * params.drag, scale * params.lift)
}

/// The force of [`TriangleLanes::forces`] on one triangle with edges `e1`, `e2` and relative
/// wind `u`, `(drag, lift)` being [`force_scale`]: written once, so that every path computes the
/// same bits.
///
/// With the cross product `c = e₁ × e₂` (so `A = |c|/2`, `n = c/|c|`) and `k = c·u`, the
/// force `q (C_d |cos θ| û + C_l cos θ (n − cos θ û))` becomes
/// `ρ/4 (C_d |k| u + C_l k (|u|² c − k u) / (|c| |u|))`: one square root and one division,
/// and exactly zero when the plate is edge-on (`k = 0`).
#[inline(always)]
fn plate_force(e1: [f32; 3], e2: [f32; 3], u: [f32; 3], (drag, lift): (f32, f32)) -> [f32; 3] {
    let c = [
        e1[1] * e2[2] - e1[2] * e2[1],
        e1[2] * e2[0] - e1[0] * e2[2],
        e1[0] * e2[1] - e1[1] * e2[0],
    ];
    let speed_sq = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
    let cross_sq = c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
    let k = c[0] * u[0] + c[1] * u[1] + c[2] * u[2];
    let r = 1.0 / (cross_sq * speed_sq).sqrt();
    // Still air, or a degenerate triangle (|c| = 2A): no force.
    let on = speed_sq >= MIN_SPEED_SQ && cross_sq >= 4.0 * MIN_AREA * MIN_AREA;
    let (drag, lift) = if on {
        (drag * k.abs(), lift * k * r)
    } else {
        (0.0, 0.0)
    };
    let mut f = [0.0; 3];
    for d in 0..3 {
        f[d] = drag * u[d] + lift * (speed_sq * c[d] - k * u[d]);
    }
    f
}

/// `share` times the aerodynamic force (N) on one triangle; see [`TriangleLanes::forces`].
#[cfg(test)]
fn triangle_force(p: [Vec3; 3], v: [Vec3; 3], wind: Vec3, params: &AeroParams, share: f32) -> Vec3 {
    let lane = TriangleLanes::<1>::gather(&[[0, 1, 2]], &p, &v, |_| wind);
    let f = lane.forces(params, share);
    Vec3::new(f[0][0], f[1][0], f[2][0])
}

/// A gusty wind field: a base wind whose speed and direction fluctuate smoothly in time, with the
/// fluctuations carried downstream at the base wind speed ("frozen" gusts, Taylor's hypothesis).
///
/// A pure function of its fields and the inputs of [`Gusts::sample`]: no state, no allocation,
/// no global random number generator. Points at the same downstream distance see the same gust at
/// the same time; the field does not vary across the wind.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Reflect)]
#[serde(default, deny_unknown_fields)]
pub struct Gusts {
    /// Seed of the noise; different seeds give uncorrelated gusts.
    pub seed: u64,
    /// Relative amplitude of the speed fluctuation: the speed stays within
    /// `|base| (1 ± strength)` (0.3 = ±30%). Above 1 the wind reverses in lulls.
    pub strength: f32,
    /// Rate of the noise, Hz: roughly how many independent gust values per second.
    pub frequency: f32,
    /// Relative amplitude of the direction wobble: the direction is tilted by the angle
    /// `atan(turbulence · |w|)` with `|w| ≤ √2` (0.1 = up to about 8°).
    pub turbulence: f32,
}

impl Default for Gusts {
    /// Seed 0, ±30% speed gusts at 0.5 Hz, 10% direction wobble.
    fn default() -> Self {
        Self {
            seed: 0,
            strength: 0.3,
            frequency: 0.5,
            turbulence: 0.1,
        }
    }
}

/// Noise channels, to derive independent seeds from [`Gusts::seed`].
const CHANNEL_SPEED: u64 = 0;
const CHANNEL_WOBBLE_1: u64 = 1;
const CHANNEL_WOBBLE_2: u64 = 2;
const CHANNEL_SINE_PHASES: u64 = 3;

/// Frequencies of the two sine components relative to [`Gusts::frequency`]: `(√5 − 1)/4` and
/// `1/√2`, an irrational ratio, so the sum never repeats.
const SINE_FREQUENCIES: [f32; 2] = [0.309_017, std::f32::consts::FRAC_1_SQRT_2];

/// Weights of the fractal noise and the two sines in the speed fluctuation.
const SPEED_WEIGHTS: [f32; 3] = [1.0, 0.35, 0.2];

/// Frequency of the direction wobble relative to [`Gusts::frequency`].
const WOBBLE_FREQUENCY: f32 = 1.7;

impl Gusts {
    /// Checks that `strength`, `frequency` and `turbulence` are finite and not negative; the error
    /// names the first bad one.
    pub fn validate(&self) -> Result<(), crate::error::ClothError> {
        self.validate_as(["gusts.strength", "gusts.frequency", "gusts.turbulence"])
    }

    /// [`validate`](Self::validate), naming the fields `strength`, `frequency` and `turbulence`
    /// as given (e.g. with the path where they were read from).
    pub(crate) fn validate_as(
        &self,
        [strength, frequency, turbulence]: [&'static str; 3],
    ) -> Result<(), crate::error::ClothError> {
        use crate::error::non_negative;
        non_negative(strength, self.strength)?;
        non_negative(frequency, self.frequency)?;
        non_negative(turbulence, self.turbulence)
    }

    /// The gusty wind velocity (m/s) at `position` (m) and `time` (s), around the mean wind
    /// `base` (m/s).
    ///
    /// The noise is evaluated at the phase `time − position·b̂ / |base|`, so a point a distance `d`
    /// downstream sees the same gust `d / |base|` later. The speed is `|base| (1 + strength·g)`
    /// with `g ∈ [−1, 1]` a normalised sum of three octaves of [`value_noise`] and two sines of
    /// incommensurate frequency. The direction is `b̂ + turbulence·w`, renormalised, where `w` is
    /// perpendicular to `base` with components from two further noise channels; the speed is not
    /// affected by the wobble.
    ///
    /// Returns exactly `base` when `strength` and `turbulence` are zero, and `base` unchanged for
    /// calm air (`|base| < 1e-6` m/s, including exactly zero). Many points at one time are
    /// sampled faster, to the same values, through [`GustSampler`].
    pub fn sample(&self, base: Vec3, time: f32, position: Vec3) -> Vec3 {
        GustSampler::new(self, base, time).sample(position)
    }
}

/// [`Gusts::sample`] at many points for one mean wind and time: what does not depend on the point
/// (the channels' seeds, the sines' phases, the directions across the wind) is worked out once,
/// and each noise octave keeps the lattice cell it last blended, which neighbouring points mostly
/// share. The values are those of [`Gusts::sample`], bit for bit.
#[derive(Debug, Clone)]
pub struct GustSampler {
    gusts: Gusts,
    base: Vec3,
    speed: f32,
    speed_sq: f32,
    time: f32,
    /// Two unit vectors across the mean wind.
    across: (Vec3, Vec3),
    /// Phases of the two sines of the speed fluctuation.
    sine_phases: [f32; 2],
    /// The noise of the speed and of the two wobble components.
    channels: [Fractal; 3],
}

impl GustSampler {
    /// Prepares `gusts` around the mean wind `base` (m/s) at `time` (s).
    pub fn new(gusts: &Gusts, base: Vec3, time: f32) -> Self {
        let speed_sq = base.length_squared();
        let speed = speed_sq.sqrt();
        // Calm air has no direction (and is returned as it is).
        let across = if speed_sq < MIN_SPEED_SQ {
            (Vec3::X, Vec3::Y)
        } else {
            (base / speed).any_orthonormal_pair()
        };
        let phases = channel_seed(gusts.seed, CHANNEL_SINE_PHASES);
        let channel = |c| Fractal::new(channel_seed(gusts.seed, c));
        Self {
            gusts: *gusts,
            base,
            speed,
            speed_sq,
            time,
            across,
            sine_phases: [
                TAU * unit_interval(phases),
                TAU * unit_interval(mix64(phases)),
            ],
            channels: [
                channel(CHANNEL_SPEED),
                channel(CHANNEL_WOBBLE_1),
                channel(CHANNEL_WOBBLE_2),
            ],
        }
    }

    /// The gusty wind velocity (m/s) at `position` (m): [`Gusts::sample`].
    pub fn sample(&mut self, position: Vec3) -> Vec3 {
        if self.is_calm() {
            return self.base;
        }
        let phase = self.phase(position);
        self.at_phase(phase)
    }

    /// Whether the mean wind is too slow to have a direction (it is then returned as it is).
    fn is_calm(&self) -> bool {
        self.speed_sq < MIN_SPEED_SQ
    }

    /// The noise phase of the gust at `position`. Frozen gusts: the air now at `position`
    /// crossed the plane through the origin `position·b̂ / |base|` seconds ago, carrying the gust
    /// it had then.
    fn phase(&self, position: Vec3) -> f32 {
        (self.time - position.dot(self.base) / self.speed_sq) * self.gusts.frequency
    }

    /// The gusty wind velocity (m/s) at noise phase `phase` (not calm air).
    fn at_phase(&mut self, phase: f32) -> Vec3 {
        let (base, speed) = (self.base, self.speed);
        let gain = 1.0 + self.gusts.strength * self.speed_fluctuation(phase);

        let (e1, e2) = self.across;
        let wobble_phase = WOBBLE_FREQUENCY * phase;
        let [_, wobble_1, wobble_2] = &mut self.channels;
        let w = wobble_1.at(wobble_phase) * e1 + wobble_2.at(wobble_phase) * e2;
        // Tilting `base` by the perpendicular `turbulence |base| w` and restoring its length: a
        // rotation by `atan(turbulence |w|)`. With zero turbulence this is `base` bit for bit.
        let turbulence = self.gusts.turbulence;
        let tilted = (base + turbulence * speed * w)
            / (1.0 + turbulence * turbulence * w.length_squared()).sqrt();
        gain * tilted
    }

    /// The speed fluctuation `g ∈ [−1, 1]` at a noise phase (time × frequency).
    fn speed_fluctuation(&mut self, phase: f32) -> f32 {
        let [phase_1, phase_2] = self.sine_phases;
        let [w_noise, w_sine_1, w_sine_2] = SPEED_WEIGHTS;
        let sum = w_noise * self.channels[0].at(phase)
            + w_sine_1 * (TAU * SINE_FREQUENCIES[0] * phase + phase_1).sin()
            + w_sine_2 * (TAU * SINE_FREQUENCIES[1] * phase + phase_2).sin();
        (sum / (w_noise + w_sine_1 + w_sine_2)).clamp(-1.0, 1.0)
    }
}

/// Spacing of a [`GustTable`]'s knots, in noise phase (time × [`Gusts::frequency`]). The wind
/// is a smooth function of the phase (quintic fades, sines), so linear interpolation errs by a
/// part of the gusts' amplitude `|base| (strength + turbulence)` that falls with the square of
/// the spacing; at this spacing a unit test of `WindField::sample_many` holds it under
/// 2.5·10⁻⁵ for gusts up to 6 Hz.
const GUST_KNOT_SPACING: f32 = 1.0 / 512.0;

/// Most knots a [`GustTable`] holds (on the stack): points spread over more phase than this
/// covers are sampled one by one.
const MAX_GUST_KNOTS: usize = 512;

/// [`GustSampler::sample`] for many points of one step. The wind depends on a point only through
/// its phase along the wind, so where the points' phases span few knots
/// ([`GUST_KNOT_SPACING`]) next to their number, the sampler is evaluated at the knots and each
/// point gets the linear interpolation between its two, so a cloth's triangles share a few
/// samples. Otherwise each point is sampled, with exactly [`GustSampler::sample`]'s value.
#[derive(Debug, Clone)]
pub(crate) struct GustTable {
    sampler: GustSampler,
    knots: Option<Knots>,
}

/// The wind at `len` knots `GUST_KNOT_SPACING` apart in phase; a point `p` lies
/// `p·scale + offset` knots past the first.
#[derive(Debug, Clone)]
struct Knots {
    scale: Vec3,
    offset: f32,
    len: usize,
    wind: [Vec3; MAX_GUST_KNOTS],
}

impl GustTable {
    /// `sampler` for `points`: with knots where they are fewer than a quarter of the points.
    pub fn new(mut sampler: GustSampler, points: &[Vec3]) -> Self {
        if sampler.is_calm() {
            return Self {
                sampler,
                knots: None,
            };
        }
        // The phase as a linear function of the point, `p·along + at_origin`: `phase`'s value to
        // rounding, which the interpolation does not resolve anyway.
        let frequency = sampler.gusts.frequency;
        let along = sampler.base * (-frequency / sampler.speed_sq);
        let at_origin = sampler.time * frequency;
        let (lo, hi) = points
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |r, p| {
                let phase = p.dot(along) + at_origin;
                (r.0.min(phase), r.1.max(phase))
            });
        // At least two knots; a span that is not finite (or too long for `usize`) fails the
        // count below.
        let len = (((hi - lo) / GUST_KNOT_SPACING).ceil() as usize)
            .saturating_add(1)
            .max(2);
        let knots = (len <= MAX_GUST_KNOTS && 4 * len <= points.len()).then(|| {
            let mut wind = [Vec3::ZERO; MAX_GUST_KNOTS];
            for (k, w) in wind[..len].iter_mut().enumerate() {
                *w = sampler.at_phase(lo + k as f32 * GUST_KNOT_SPACING);
            }
            Knots {
                scale: along / GUST_KNOT_SPACING,
                offset: (at_origin - lo) / GUST_KNOT_SPACING,
                len,
                wind,
            }
        });
        Self { sampler, knots }
    }

    /// The gusty wind velocity (m/s) at `position`, one of the points the table was made for.
    #[inline]
    pub fn sample(&mut self, position: Vec3) -> Vec3 {
        let Some(knots) = &self.knots else {
            return self.sampler.sample(position);
        };
        let x = position.dot(knots.scale) + knots.offset;
        // `as` saturates (and takes NaN to 0); the last interval extends past its knot.
        let k = (x as usize).min(knots.len - 2);
        let (a, b) = (knots.wind[k], knots.wind[k + 1]);
        a + (b - a) * (x - k as f32)
    }

    /// Whether the points are interpolated between knots (else sampled one by one).
    #[cfg(test)]
    pub fn interpolates(&self) -> bool {
        self.knots.is_some()
    }
}

/// Smooth 1-D value noise in `[−1, 1]`, deterministic in `(seed, t)`.
///
/// Each integer `i` gets a pseudo-random value in `[−1, 1]` hashed from `(seed, i)`; between two
/// lattice points the values are blended with the quintic fade `6f⁵ − 15f⁴ + 10f³`, so the noise
/// is C² and its slope is at most 3.75 per unit `t`. Independent of the lattice values, so
/// uncorrelated beyond one unit. `t` should be finite and well below 2²³ in magnitude, where `f32`
/// still resolves fractions of a unit.
pub fn value_noise(seed: u64, t: f32) -> f32 {
    Octave::new(seed).at(t)
}

/// `t.floor()`, and as an integer (saturating; 0 for NaN), without the library call that `floor`
/// is on x86-64 below SSE4.1.
#[inline]
fn floor(t: f32) -> (f32, i64) {
    // From 2²³ up every `f32` is whole (and NaN and the infinities go the library's way).
    if t.is_nan() || t.abs() >= 8_388_608.0 {
        return (t.floor(), t as i64);
    }
    let i = t as i64;
    // `as` truncates toward zero; below zero that is one above the floor unless `t` is whole.
    let i = if (i as f32) > t { i - 1 } else { i };
    // The sign, for -0.
    ((i as f32).copysign(t), i)
}

/// Relative rates and amplitudes of [`Fractal`]'s octaves.
const OCTAVES: [(f32, f32); 3] = [(1.0, 1.0), (2.03, 0.5), (4.11, 0.25)];

/// Three octaves of [`value_noise`] of one seed (relative rates 1, 2.03, 4.11; amplitudes 1, ½,
/// ¼), normalised to `[−1, 1]`; the non-integer rates keep the octaves' lattices from lining up.
/// Each octave keeps the lattice cell it last blended.
#[derive(Debug, Clone)]
struct Fractal {
    octaves: [Octave; 3],
}

impl Fractal {
    fn new(seed: u64) -> Self {
        Self {
            octaves: [0, 1, 2].map(|k| Octave::new(channel_seed(seed, k))),
        }
    }

    /// The noise at `t`.
    fn at(&mut self, t: f32) -> f32 {
        let mut sum = 0.0;
        let mut total = 0.0;
        for (octave, &(rate, amplitude)) in self.octaves.iter_mut().zip(&OCTAVES) {
            sum += amplitude * octave.at(rate * t);
            total += amplitude;
        }
        (sum / total).clamp(-1.0, 1.0)
    }
}

/// [`value_noise`] of one seed, keeping the lattice cell it last blended.
#[derive(Debug, Clone, Copy)]
struct Octave {
    seed: u64,
    /// The cell last blended, with the lattice values at its two ends.
    last: Option<(i64, f32, f32)>,
}

impl Octave {
    fn new(seed: u64) -> Self {
        Self { seed, last: None }
    }

    /// The noise at `t`.
    fn at(&mut self, t: f32) -> f32 {
        let (cell, i) = floor(t);
        let (a, b) = match self.last {
            Some((j, a, b)) if j == i => (a, b),
            _ => {
                let (a, b) = (
                    lattice_value(self.seed, i),
                    lattice_value(self.seed, i.wrapping_add(1)),
                );
                self.last = Some((i, a, b));
                (a, b)
            }
        };
        let f = t - cell;
        let fade = (f * f * f * (f * (f * 6.0 - 15.0) + 10.0)).min(1.0);
        (a + (b - a) * fade).clamp(-1.0, 1.0)
    }
}

/// The value in `[−1, 1]` at lattice point `i`: entry `i` of a SplitMix64 stream keyed by `seed`.
#[inline]
fn lattice_value(seed: u64, i: i64) -> f32 {
    let key = mix64(seed.wrapping_add(GOLDEN_GAMMA));
    let h = mix64(key.wrapping_add((i as u64).wrapping_mul(GOLDEN_GAMMA)));
    2.0 * unit_interval(h) - 1.0
}

/// A seed for sub-channel `channel` of `seed`.
#[inline]
fn channel_seed(seed: u64, channel: u64) -> u64 {
    mix64(seed ^ mix64(channel.wrapping_add(1).wrapping_mul(GOLDEN_GAMMA)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::{ClothModel, GridPlane, GridSpec};
    use std::f32::consts::FRAC_1_SQRT_2;

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
            let each: Vec<Vec3> = (0..triangles.len())
                .map(|t| wind + Vec3::new(0.0, (t as f32).sin(), 0.5 * (t as f32).cos()))
                .collect();
            let mut grid = GridAero::new(&model).expect("a canonical grid");
            for winds in [TriangleWind::Uniform(wind), TriangleWind::Each(&each)] {
                let mut expected = vec![Vec3::ZERO; x.len()];
                match winds {
                    TriangleWind::Uniform(w) => {
                        add_aero_forces_in(&x, &v, triangles, |_| w, &params, &mut expected)
                    }
                    TriangleWind::Each(e) => {
                        add_aero_forces(&x, &v, triangles, e, &params, &mut expected)
                    }
                }
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
            TriangleWind::Each(&[Vec3::X; 3]),
            &params,
            &mut forces
        ));
        assert!(forces.iter().all(|f| *f == Vec3::ZERO), "nothing added");
        model.triangles.swap(0, 1);
        assert!(GridAero::new(&model).is_none());
    }

    /// `|a − b| ≤ tol · max(1, |b|)`.
    fn close(a: Vec3, b: Vec3, tol: f32) -> bool {
        (a - b).length() <= tol * b.length().max(1.0)
    }

    /// Forces on a mesh with still vertices in a uniform wind.
    fn forces_in_wind(
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        wind: Vec3,
        params: &AeroParams,
    ) -> Vec<Vec3> {
        let velocities = vec![Vec3::ZERO; positions.len()];
        let winds = vec![wind; triangles.len()];
        let mut forces = vec![Vec3::ZERO; positions.len()];
        add_aero_forces(
            positions,
            &velocities,
            triangles,
            &winds,
            params,
            &mut forces,
        );
        forces
    }

    fn total(forces: &[Vec3]) -> Vec3 {
        forces.iter().copied().sum()
    }

    /// A generic tilted triangle.
    const TILTED: [Vec3; 3] = [
        Vec3::new(0.1, -0.2, 0.3),
        Vec3::new(1.3, 0.4, -0.2),
        Vec3::new(-0.3, 0.9, 0.8),
    ];

    #[test]
    fn zero_relative_velocity_gives_exactly_zero_force() {
        let v = Vec3::new(1.3, -0.7, 2.1);
        let mut forces = vec![Vec3::ZERO; 3];
        add_aero_forces(
            &TILTED,
            &[v; 3],
            &[[0, 1, 2]],
            &[v],
            &AeroParams::default(),
            &mut forces,
        );
        assert!(forces.iter().all(|&f| f == Vec3::ZERO), "{forces:?}");
    }

    #[test]
    fn force_scales_with_relative_speed_squared() {
        let dir = Vec3::new(0.6, 0.48, -0.64);
        let params = AeroParams::default();
        let f10 = total(&forces_in_wind(&TILTED, &[[0, 1, 2]], 10.0 * dir, &params));
        let f5 = total(&forces_in_wind(&TILTED, &[[0, 1, 2]], 5.0 * dir, &params));
        assert!(f5.length() > 0.0);
        assert!((f10.length() / f5.length() - 4.0).abs() < 1e-4);
        assert!(close(f10, 4.0 * f5, 1e-5), "same direction");
    }

    #[test]
    fn plate_facing_wind_gets_pure_drag() {
        // Right triangle in the yz plane with legs 2 m and 3 m: area 3 m².
        let plate = [
            Vec3::ZERO,
            Vec3::new(0.0, 2.0, 0.0),
            Vec3::new(0.0, 0.0, 3.0),
        ];
        let params = AeroParams::default();
        let speed = 8.0;
        let f = total(&forces_in_wind(
            &plate,
            &[[0, 1, 2]],
            speed * Vec3::X,
            &params,
        ));
        let expected = 0.5 * params.air_density * params.drag * 3.0 * speed * speed;
        assert!(
            (f.x - expected).abs() < 1e-5 * expected,
            "{f} vs {expected}"
        );
        assert_eq!((f.y, f.z), (0.0, 0.0), "no lift");
    }

    #[test]
    fn edge_on_plate_gets_zero_force() {
        // Plate in the xy plane (normal z), wind along x.
        let plate = [
            Vec3::ZERO,
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.5, 1.0, 0.0),
        ];
        let forces = forces_in_wind(&plate, &[[0, 1, 2]], 12.0 * Vec3::X, &AeroParams::default());
        assert!(forces.iter().all(|&f| f == Vec3::ZERO), "{forces:?}");
    }

    #[test]
    fn flipping_triangle_winding_leaves_forces_unchanged() {
        let positions = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.1, 0.0),
            Vec3::new(0.0, 0.2, 1.0),
            Vec3::new(1.1, 0.5, 1.2),
        ];
        let velocities = [
            Vec3::new(0.1, 0.0, -0.2),
            Vec3::new(-0.3, 0.4, 0.0),
            Vec3::new(0.0, 0.2, 0.5),
            Vec3::new(0.2, -0.1, 0.1),
        ];
        let winds = [Vec3::new(4.0, 1.0, 2.0), Vec3::new(3.0, -2.0, 1.5)];
        let run = |triangles: &[[u32; 3]]| {
            let mut forces = [Vec3::ZERO; 4];
            let params = AeroParams::default();
            add_aero_forces(
                &positions,
                &velocities,
                triangles,
                &winds,
                &params,
                &mut forces,
            );
            forces
        };
        let original = run(&[[0, 1, 2], [1, 3, 2]]);
        let flipped = run(&[[0, 2, 1], [1, 2, 3]]);
        assert!(original.iter().any(|f| f.length() > 1.0));
        for (a, b) in original.iter().zip(&flipped) {
            assert!(close(*b, *a, 1e-6), "{a} vs {b}");
        }
    }

    #[test]
    fn plate_at_45_degrees_gets_lift_perpendicular_to_wind_upward_for_a_kite() {
        let params = AeroParams {
            drag: 0.0,
            ..AeroParams::default()
        };
        let speed = 10.0;
        let wind = speed * Vec3::X;
        // Kite: leading (upwind) edge up, plate running down-wind along (1, −1, 0); area √2/2 m².
        let kite = [Vec3::ZERO, Vec3::new(1.0, -1.0, 0.0), Vec3::Z];
        // Ramp: leading edge down, plate rising down-wind along (1, 1, 0).
        let ramp = [Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), Vec3::Z];
        let area = 0.5 * std::f32::consts::SQRT_2;
        let lift = 0.5 * params.air_density * params.lift * area * speed * speed * 0.5;

        let f = total(&forces_in_wind(&kite, &[[0, 1, 2]], wind, &params));
        assert!(
            f.dot(Vec3::X).abs() < 1e-5 * lift,
            "perpendicular to the wind: {f}"
        );
        assert!(
            close(f, lift * Vec3::Y, 1e-5),
            "kite lifted up: {f} vs {lift}"
        );

        let f = total(&forces_in_wind(&ramp, &[[0, 1, 2]], wind, &params));
        assert!(
            close(f, -lift * Vec3::Y, 1e-5),
            "ramp pushed down: {f} vs {lift}"
        );

        // With drag on, the along-wind part is the drag on the projected area.
        let params = AeroParams::default();
        let f = total(&forces_in_wind(&kite, &[[0, 1, 2]], wind, &params));
        let drag = 0.5 * params.air_density * params.drag * area * speed * speed * FRAC_1_SQRT_2;
        let lift = 0.5 * params.air_density * params.lift * area * speed * speed * 0.5;
        assert!(close(f, Vec3::new(drag, lift, 0.0), 1e-5), "{f}");
    }

    #[test]
    fn vertex_forces_sum_to_triangle_force() {
        let velocities = [
            Vec3::new(0.2, 0.0, 0.1),
            Vec3::ZERO,
            Vec3::new(-0.1, 0.3, 0.0),
        ];
        let wind = Vec3::new(5.0, 2.0, -3.0);
        let params = AeroParams::default();
        let expected = triangle_force(TILTED, velocities, wind, &params, 1.0);
        let mut forces = [Vec3::splat(1.0); 3];
        add_aero_forces(
            &TILTED,
            &velocities,
            &[[0, 1, 2]],
            &[wind],
            &params,
            &mut forces,
        );
        assert!(expected.length() > 1.0);
        for f in forces {
            assert!(
                close(f - Vec3::ONE, expected / 3.0, 1e-6),
                "a third each, added"
            );
        }
        assert!(close(total(&forces) - Vec3::splat(3.0), expected, 1e-6));
    }

    #[test]
    fn degenerate_triangle_gets_zero_force() {
        let line = [Vec3::ZERO, Vec3::X, 2.0 * Vec3::X];
        let forces = forces_in_wind(
            &line,
            &[[0, 1, 2]],
            Vec3::new(3.0, 4.0, 5.0),
            &AeroParams::default(),
        );
        assert!(forces.iter().all(|&f| f == Vec3::ZERO));
    }

    #[test]
    fn triangle_centroids_are_vertex_means() {
        let mut out = [Vec3::ZERO; 2];
        triangle_centroids(
            &[
                Vec3::ZERO,
                Vec3::new(3.0, 0.0, 0.0),
                Vec3::new(0.0, 3.0, 0.0),
                Vec3::new(0.0, 0.0, 6.0),
            ],
            &[[0, 1, 2], [1, 2, 3]],
            &mut out,
        );
        assert_eq!(out, [Vec3::new(1.0, 1.0, 0.0), Vec3::new(1.0, 1.0, 2.0)]);
    }

    /// `n` evenly spaced samples over `[from, to)`.
    fn samples(from: f32, to: f32, n: usize) -> impl Iterator<Item = f32> {
        (0..n).map(move |k| from + (to - from) * k as f32 / n as f32)
    }

    #[test]
    fn value_noise_is_deterministic_for_same_seed() {
        for t in samples(-50.0, 50.0, 1000) {
            assert_eq!(value_noise(42, t).to_bits(), value_noise(42, t).to_bits());
        }
    }

    #[test]
    fn value_noise_differs_across_seeds() {
        let differing = samples(-50.0, 50.0, 1000)
            .filter(|&t| (value_noise(1, t) - value_noise(2, t)).abs() > 1e-3)
            .count();
        assert!(differing > 900, "{differing} of 1000 differ");
    }

    #[test]
    fn value_noise_stays_within_unit_range() {
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for seed in [0, 7, u64::MAX] {
            for t in samples(-20_000.0, 20_000.0, 200_000) {
                let g = value_noise(seed, t);
                assert!((-1.0..=1.0).contains(&g), "g({t}) = {g}");
                (lo, hi) = (lo.min(g), hi.max(g));
            }
        }
        assert!(lo < -0.99 && hi > 0.99, "spans the range: [{lo}, {hi}]");
    }

    #[test]
    fn value_noise_is_continuous() {
        // Slope ≤ 3.75, so a step of 1e-4 moves it by at most 3.75e-4 (plus rounding). The
        // sampling crosses many lattice points, where a discontinuity would show.
        let dt = 1e-4;
        for t in samples(-100.0, 100.0, 20_011).chain((-100..100).map(|i| i as f32 - 0.5 * dt)) {
            let step = (value_noise(3, t + dt) - value_noise(3, t)).abs();
            assert!(step < 1e-3, "jump {step} at {t}");
        }
    }

    #[test]
    fn floor_is_the_library_floor() {
        let mut values = vec![0.0, -0.0, 0.5, -0.5, 1.0, -1.0, 2.999_999_8, -3.000_000_2];
        values.extend((-3000..3000).map(|k| k as f32 * 0.377));
        values.extend([8_388_607.5, -8_388_607.5, 8_388_608.0, -1e20, 1e20, 3e38]);
        values.extend([f32::NAN, f32::INFINITY, f32::NEG_INFINITY]);
        for t in values {
            let (cell, i) = floor(t);
            assert_eq!(cell.to_bits(), t.floor().to_bits(), "floor of {t}");
            assert_eq!(i, t.floor() as i64, "floor of {t} as an integer");
        }
    }

    #[test]
    fn a_sampler_kept_for_many_points_gives_each_what_a_fresh_one_gives() {
        let gusts = Gusts {
            seed: 11,
            strength: 0.6,
            frequency: 2.0,
            turbulence: 0.4,
        };
        let (base, time) = (Vec3::new(3.0, -1.0, 0.5), 4.0);
        let mut kept = GustSampler::new(&gusts, base, time);
        // Back and forth along the wind over several lattice cells of every octave, so that the
        // cells each octave keeps are both reused and replaced.
        let mut reused = 0;
        let mut last = None;
        for k in 0..1000 {
            let p = base * ((k as f32 * 0.05).sin() * 0.4 + (k % 4) as f32 * 0.01);
            let w = kept.sample(p);
            assert_eq!(w, GustSampler::new(&gusts, base, time).sample(p), "at {p}");
            let cell = kept.channels[0].octaves[0].last;
            reused += usize::from(last == Some(cell));
            last = Some(cell);
        }
        assert!(
            reused > 500 && reused < 1000,
            "the first octave kept its cell {reused} times"
        );
    }

    #[test]
    fn gusts_with_zero_strength_and_turbulence_return_base() {
        let gusts = Gusts {
            seed: 9,
            strength: 0.0,
            turbulence: 0.0,
            ..Gusts::default()
        };
        let base = Vec3::new(3.7, -0.3, 1.9);
        for t in samples(0.0, 100.0, 500) {
            let p = Vec3::new(t.sin(), 2.0, -t);
            assert_eq!(gusts.sample(base, t, p), base);
        }
    }

    #[test]
    fn gusts_with_zero_base_return_zero() {
        let gusts = Gusts::default();
        assert_eq!(gusts.sample(Vec3::ZERO, 1.5, Vec3::ONE), Vec3::ZERO);
    }

    #[test]
    fn gust_speed_stays_within_strength_band() {
        let gusts = Gusts {
            seed: 5,
            strength: 0.4,
            turbulence: 0.3,
            frequency: 2.0,
        };
        let base = Vec3::new(0.0, 0.0, -6.0);
        for t in samples(0.0, 200.0, 20_000) {
            let speed = gusts.sample(base, t, Vec3::ZERO).length();
            assert!(
                (3.6 * 0.99999..=8.4 * 1.00001).contains(&speed),
                "{speed} at {t}"
            );
        }
    }

    #[test]
    fn gust_mean_speed_is_close_to_base_speed() {
        let gusts = Gusts::default();
        let base = Vec3::new(8.0, 0.0, 6.0);
        let n = 100_000;
        let mean = samples(0.0, 5_000.0, n)
            .map(|t| f64::from(gusts.sample(base, t, Vec3::new(1.0, 2.0, 3.0)).length()))
            .sum::<f64>()
            / n as f64;
        assert!((mean / 10.0 - 1.0).abs() < 0.02, "mean speed {mean}");
    }

    #[test]
    fn downstream_point_sees_same_gust_delayed() {
        let gusts = Gusts {
            seed: 11,
            ..Gusts::default()
        };
        let base = Vec3::new(6.0, 0.0, 8.0);
        let upstream = Vec3::new(1.0, 2.0, -3.0);
        let distance = 25.0;
        let downstream = upstream + distance * base.normalize();
        let delay = distance / base.length();
        let mut varies = false;
        for t in samples(0.0, 60.0, 600) {
            let here = gusts.sample(base, t, upstream);
            let later = gusts.sample(base, t + delay, downstream);
            assert!(close(later, here, 1e-4), "{here} vs {later} at {t}");
            varies |= (gusts.sample(base, t, downstream) - here).length() > 0.1;
        }
        assert!(varies, "the gust is not the same everywhere at once");
    }
}
