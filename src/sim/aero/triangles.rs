//! The aerodynamic forces of a triangle list: each triangle's relative wind and edges gathered in
//! batches of lanes ([`TriangleLanes`]), its [`plate_force`] added a third to each vertex; and the
//! triangles' centroids, where the wind is sampled.

use super::plate::{AeroParams, force_scale, plate_force};
use glam::Vec3;

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

/// `share` times the aerodynamic force (N) on one triangle; see [`TriangleLanes::forces`].
#[cfg(test)]
pub(super) fn triangle_force(
    p: [Vec3; 3],
    v: [Vec3; 3],
    wind: Vec3,
    params: &AeroParams,
    share: f32,
) -> Vec3 {
    let lane = TriangleLanes::<1>::gather(&[[0, 1, 2]], &p, &v, |_| wind);
    let f = lane.forces(params, share);
    Vec3::new(f[0][0], f[1][0], f[2][0])
}
