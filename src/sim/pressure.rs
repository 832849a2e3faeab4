//! The air inside a closed cloth ([`Pressure`]): the pressure at an enclosed volume, the force it
//! puts on the particles (the force-based integrators), XPBD's volume constraint, its energy and
//! what it adds to the explicit integrators' frequency bound.
//!
//! The volume and its gradient come from the model's triangles, one cross product per triangle
//! (`AirScratch` in the steppers' numbering, each substep; `model::volume_gradient` for the
//! bound). Nothing here allocates once its scratch is sized.

use glam::{Vec3, Vec3A};

use super::model::{enclosed_volume, volume_gradient};
use super::settings::Pressure;
use super::soa::Soa;

/// How much higher than its linear bound the air's frequency is taken. The pressure changes as
/// the volume breathes, and an explicit integrator that takes a stiff air close to its linear
/// stability limit runs away (the stress suite's closed cloths show it); with the margin, the air
/// asks for `hω ≤ 1.2`.
pub(crate) const AIR_FREQUENCY_MARGIN: f32 = 1.5;

/// A closed cloth's air as its steppers see it: the model and the volumes it refers to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Air {
    /// The model (never [`Pressure::Off`]).
    pub pressure: Pressure,
    /// The volume the cloth enclosed when it was built, m³.
    pub built_volume: f32,
    /// The farthest the air alone moves a particle in one substep, m (see [`Air::project`] and
    /// [`Air::forces`]).
    pub max_move: f32,
}

impl Air {
    /// The air of a cloth that enclosed `built_volume` when built, its rest triangles' edges
    /// `mean_edge` long on average ([`ClothModel::mean_edge_length`]): its
    /// [`max_move`](Self::max_move) is half that.
    ///
    /// [`ClothModel::mean_edge_length`]: super::ClothModel::mean_edge_length
    pub fn new(pressure: Pressure, built_volume: f32, mean_edge: f32) -> Self {
        Self {
            pressure,
            built_volume,
            max_move: 0.5 * mean_edge,
        }
    }

    /// The factor that brings a move of `reach` (m, the farthest any particle would go) within
    /// [`max_move`](Self::max_move): 1 when it is already.
    fn within_reach(&self, reach: f32) -> f32 {
        if reach > self.max_move {
            self.max_move / reach
        } else {
            1.0
        }
    }

    /// The volume [`Pressure::Volume`] keeps, m³ (the built volume for a gas).
    pub fn kept_volume(&self) -> f32 {
        match self.pressure {
            Pressure::Volume { scale, .. } => scale * self.built_volume,
            _ => self.built_volume,
        }
    }

    /// The pressure inside above the air outside at volume `v`, Pa (positive pushes out).
    pub fn gauge(&self, v: f64) -> f64 {
        match self.pressure {
            Pressure::Off => 0.0,
            Pressure::Volume { bulk_modulus, .. } => {
                let kept = self.kept_volume() as f64;
                bulk_modulus as f64 * (kept - v) / kept
            }
            // A surface turned inside out encloses a negative volume: the gas's pressure is
            // held at its value at a thousandth of the built volume rather than changing sign.
            Pressure::Gas { nrt, ambient } => {
                nrt as f64 / v.max(1e-3 * self.built_volume as f64) - ambient as f64
            }
        }
    }

    /// The air's potential energy at volume `v`, J: the work the pressure does as the volume
    /// returns to where the pressure inside equals the air outside (the kept volume; for a gas
    /// `nRT / ambient`, or in a vacuum the built volume), so never negative but in a vacuum.
    pub fn energy(&self, v: f64) -> f64 {
        match self.pressure {
            Pressure::Off => 0.0,
            Pressure::Volume { bulk_modulus, .. } => {
                let kept = self.kept_volume() as f64;
                0.5 * bulk_modulus as f64 / kept * (v - kept).powi(2)
            }
            Pressure::Gas { nrt, ambient } => {
                let (nrt, ambient) = (nrt as f64, ambient as f64);
                let built = self.built_volume as f64;
                let rest = if ambient > 0.0 && nrt > 0.0 {
                    nrt / ambient
                } else {
                    built
                };
                let v = v.max(1e-3 * built);
                -nrt * (v / rest).ln() + ambient * (v - rest)
            }
        }
    }

    /// How stiff the air is against a change of volume at volume `v`, Pa/m³: `−dp/dV` (for a gas
    /// compressed below a thousandth of its built volume, its value there).
    fn volume_stiffness(&self, v: f64) -> f64 {
        match self.pressure {
            Pressure::Off => 0.0,
            Pressure::Volume { bulk_modulus, .. } => {
                bulk_modulus as f64 / self.kept_volume() as f64
            }
            // Below the floor the pressure is held, but the stiffness is kept at the floor's, so
            // that XPBD's step and the explicit integrators' bound still see a stiff gas.
            Pressure::Gas { nrt, .. } => {
                let v = v.max(1e-3 * self.built_volume as f64);
                nrt as f64 / (v * v)
            }
        }
    }

    /// A bound on the highest angular frequency the air adds at `positions`, rad/s, over the
    /// particles of weight `inv_mass` (`triangles` numbered as they are), for the integrators
    /// that take the air as a force. The air's stiffness `∂F/∂x` has two parts: `−k ∇V ∇Vᵀ`
    /// (`k = −dp/dV`), of rank one, whose mass-weighted eigenvalue is `k Σ w |∇V|²`; and the
    /// pressure times the volume's second derivative, `p ∂²V/∂x²`, whose blocks are
    /// `[x_c − x_d]× / 6` for the corners `c`, `d` opposite an edge (none on the diagonal),
    /// bounded by rows (Gershgorin) with each row's own particle as the origin:
    /// `|p| max_a √w_a Σ (|x_c − x_a| √w_b + |x_b − x_a| √w_c) / 6` over its triangles
    /// `(a, b, c)`. The square of the bound is their sum (the eigenvalues of a sum are at most
    /// the sums of its terms' largest), and it is added to the springs' the same way. The result
    /// is that bound times [`AIR_FREQUENCY_MARGIN`].
    pub fn frequency(
        &self,
        scratch: &mut BoundScratch,
        triangles: &[u32],
        (positions, inv_mass): (&[Vec3], &[f32]),
    ) -> f32 {
        let BoundScratch { gradient, rows } = scratch;
        gradient.resize(positions.len(), Vec3::ZERO);
        let v = volume_gradient(triangles, |i| positions[i], gradient);
        let weighted: f64 = gradient
            .iter()
            .zip(inv_mass)
            .map(|(g, w)| (*w * g.length_squared()) as f64)
            .sum();
        rows.clear();
        rows.resize(positions.len(), 0.0);
        for t in triangles.chunks_exact(3) {
            for k in 0..3 {
                let (a, b, c) = (
                    t[k] as usize,
                    t[(k + 1) % 3] as usize,
                    t[(k + 2) % 3] as usize,
                );
                let (xa, xb, xc) = (positions[a], positions[b], positions[c]);
                rows[a] +=
                    xc.distance(xa) * inv_mass[b].sqrt() + xb.distance(xa) * inv_mass[c].sqrt();
            }
        }
        let geometric = rows
            .iter()
            .zip(inv_mass)
            .map(|(r, w)| r * w.sqrt() / 6.0)
            .fold(0.0f32, f32::max);
        let squared = self.volume_stiffness(v) * weighted + self.gauge(v).abs() * geometric as f64;
        AIR_FREQUENCY_MARGIN * squared.sqrt() as f32
    }

    /// Hands `add` the air's force `p ∂V/∂x` on each particle at positions `x(i)` (in
    /// `scratch`'s numbering, of weights `inv_mass`), for a substep of `h` seconds. As in
    /// [`Air::project`], a force that alone would move a particle more than
    /// [`max_move`](Self::max_move) in the substep (`h² w |F|`) is scaled down, all of them alike.
    pub fn forces(
        &self,
        scratch: &mut AirScratch,
        x: impl Fn(usize) -> Vec3,
        (inv_mass, h): (&[f32], f32),
        mut add: impl FnMut(usize, Vec3),
    ) {
        for (i, p) in scratch.positions.iter_mut().enumerate() {
            *p = x(i).into();
        }
        let v = scratch.volume_gradient();
        let p = self.gauge(v) as f32 / 6.0;
        let (_, farthest) = weight_and_farthest(&scratch.six_gradient, inv_mass);
        let p = p * self.within_reach(h * h * p.abs() * farthest.sqrt());
        for (i, g) in scratch.six_gradient.iter().enumerate() {
            add(i, Vec3::from(*g * p));
        }
    }

    /// XPBD's pass for one substep of length `h`, on the positions `x + d` of its storage
    /// (`scratch` numbered in it, `inv_mass` per slot), moving the displacements `d` by
    /// `h² w ∇V p'`, where `p'` is the gauge at the volume the move reaches, linearised:
    /// `p' = p / (1 + h² k Σ w |∇V|²)` with `k = −dp/dV`. It is one backward-Euler step of the
    /// air's rank-one stiffness, stable at any stiffness and step; for [`Pressure::Volume`] it is
    /// XPBD's projection of `C = V − V₀` with compliance `V₀ / K` (the multiplier starting at 0
    /// each substep).
    ///
    /// Where the surface is crushed or torn inside out, a high pressure over a volume gradient
    /// that has almost vanished asks for moves far larger than the cloth; the whole move is then
    /// scaled down so that no particle moves more than [`max_move`](Self::max_move) (still along
    /// `w ∇V`, so the momentum it adds stays zero for equal masses).
    pub fn project(
        &self,
        scratch: &mut AirScratch,
        inv_mass: &[f32],
        (x, d): (&Soa, &mut Soa),
        h: f32,
    ) {
        let gathered = scratch.positions.iter_mut().zip(x.iter().zip(d.iter()));
        for (p, (a, b)) in gathered {
            *p = (a + b).into();
        }
        let v = scratch.volume_gradient();
        let six_gradient = &scratch.six_gradient;
        let (weight, farthest) = weight_and_farthest(six_gradient, inv_mass);
        let weight = weight / 36.0;
        let h2 = (h * h) as f64;
        let stiffness = self.volume_stiffness(v) * weight as f64;
        let scale = (h2 * self.gauge(v) / (1.0 + h2 * stiffness)) as f32 / 6.0;
        let scale = scale * self.within_reach(scale.abs() * farthest.sqrt());
        // A particle of weight 0 (pinned) moves by 0.
        for ((dx, dy, dz), (g, w)) in d.iter_mut().zip(six_gradient.iter().zip(inv_mass)) {
            let s = *w * scale;
            (*dx, *dy, *dz) = (*dx + g.x * s, *dy + g.y * s, *dz + g.z * s);
        }
    }
}

/// `Σ w |g|²` and `max w² |g|²` over the particles, in eight independent lanes (so that the
/// loop is vectorised), the rest one by one.
fn weight_and_farthest(g: &[Vec3A], w: &[f32]) -> (f32, f32) {
    const L: usize = 8;
    let n = g.len().min(w.len());
    let (g, w) = (&g[..n], &w[..n]);
    let (mut sum, mut max) = ([0.0f32; L], [0.0f32; L]);
    let (gs, ws) = (g.chunks_exact(L), w.chunks_exact(L));
    let rest = gs.remainder().iter().zip(ws.remainder());
    for (g, w) in gs.zip(ws) {
        for l in 0..L {
            let wg2 = w[l] * g[l].length_squared();
            sum[l] += wg2;
            let m = w[l] * wg2;
            max[l] = if m > max[l] { m } else { max[l] };
        }
    }
    let (mut total, mut farthest) = (sum.iter().sum::<f32>(), 0.0f32);
    for m in max {
        farthest = farthest.max(m);
    }
    for (g, w) in rest {
        let wg2 = w * g.length_squared();
        total += wg2;
        farthest = farthest.max(w * wg2);
    }
    (total, farthest)
}

/// A stepper's scratch for the air: the model's triangles in the stepper's numbering of the
/// particles, and per particle its position (gathered once, read by every triangle it is a
/// corner of) and six times the volume's gradient. Empty for a cloth without air.
#[derive(Debug, Clone, Default)]
pub(crate) struct AirScratch {
    triangles: Vec<[u32; 3]>,
    positions: Vec<Vec3A>,
    six_gradient: Vec<Vec3A>,
}

impl AirScratch {
    /// Sizes the scratch for `triangles` over `n` particles, stored where `slot` puts them, when
    /// `on`; frees it otherwise.
    pub fn prepare(&mut self, on: bool, triangles: &[u32], n: usize, slot: impl Fn(u32) -> u32) {
        self.triangles.clear();
        if on {
            let corners = triangles.chunks_exact(3);
            self.triangles
                .extend(corners.map(|t| [slot(t[0]), slot(t[1]), slot(t[2])]));
            // What `volume_gradient`'s unchecked reads and writes rest on.
            assert!(
                self.triangles.iter().flatten().all(|&i| (i as usize) < n),
                "a triangle's corner past the stepper's {n} particles"
            );
            spread_out(&mut self.triangles, n);
            self.positions.resize(n, Vec3A::ZERO);
            self.six_gradient.resize(n, Vec3A::ZERO);
        } else {
            self.triangles.shrink_to_fit();
            self.positions = Vec::new();
            self.six_gradient = Vec::new();
        }
    }

    /// The volume enclosed at `positions`, m³, with six times its gradient left in
    /// `six_gradient`: each corner gets its triangle's doubled area vector, as
    /// [`volume_gradient`] does, with the sixth left to the caller's scale. The volume's terms are
    /// summed in f32 over blocks of triangles and the blocks in f64, about the first corner.
    fn volume_gradient(&mut self) -> f64 {
        let (x, g) = (&self.positions[..], &mut self.six_gradient[..]);
        g.fill(Vec3A::ZERO);
        let Some(&[first, ..]) = self.triangles.first() else {
            return 0.0;
        };
        let origin = x[first as usize];
        let mut six_v = 0.0f64;
        for block in self.triangles.chunks(64) {
            let mut sum = Vec3A::ZERO;
            for &[a, b, c] in block {
                let (a, b, c) = (a as usize, b as usize, c as usize);
                // SAFETY: `prepare` checked every corner against `n`, the length it gave
                // `positions` and `six_gradient`, which nothing else resizes.
                unsafe {
                    let (pa, pb, pc) = (
                        *x.get_unchecked(a),
                        *x.get_unchecked(b),
                        *x.get_unchecked(c),
                    );
                    let area2 = (pb - pa).cross(pc - pa);
                    sum += (pa - origin) * area2;
                    *g.get_unchecked_mut(a) += area2;
                    *g.get_unchecked_mut(b) += area2;
                    *g.get_unchecked_mut(c) += area2;
                }
            }
            six_v += sum.element_sum() as f64;
        }
        six_v / 6.0
    }
}

/// Reorders `triangles` (over `n` particles) so that triangles near each other in the list
/// share no corner: each colour of a greedy colouring (no two triangles of a colour share a
/// corner) in turn. The gradient's additions to one corner are then never a store and a load
/// apart, and the processor overlaps them.
fn spread_out(triangles: &mut Vec<[u32; 3]>, n: usize) {
    // Per particle, the colours its triangles took, as bits (a corner has few triangles; past
    // 64 colours, the rest go in the last one, in their order).
    let mut taken = vec![0u64; n];
    let mut colours: Vec<Vec<[u32; 3]>> = Vec::new();
    for &t in triangles.iter() {
        let used = t.iter().fold(0u64, |u, &i| u | taken[i as usize]);
        let c = (used.trailing_ones() as usize).min(63);
        for &i in &t {
            taken[i as usize] |= 1 << c;
        }
        if colours.len() <= c {
            colours.resize_with(c + 1, Vec::new);
        }
        colours[c].push(t);
    }
    triangles.clear();
    triangles.extend(colours.into_iter().flatten());
}

/// Scratch for [`Air::frequency`], kept between steps: the volume's gradient and the pressure
/// term's row sums, per particle.
#[derive(Debug, Clone, Default)]
pub(crate) struct BoundScratch {
    gradient: Vec<Vec3>,
    rows: Vec<f32>,
}

/// The potential energy of `air` (none: 0) at `positions`, J (see [`Air::energy`]).
pub(crate) fn air_energy(air: Option<&Air>, triangles: &[u32], positions: &[Vec3]) -> f64 {
    air.map_or(0.0, |air| {
        air.energy(enclosed_volume(triangles, |i| positions[i]))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tetrahedron with outward (counter-clockwise from outside) triangles.
    fn tetrahedron() -> (Vec<Vec3>, Vec<u32>) {
        let x = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
        (x, vec![0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3])
    }

    #[test]
    fn triangles_next_to_each_other_share_no_corner() {
        let model = crate::sim::ClothModel::icosphere(0.3, 3).unwrap();
        let n = model.particle_count();
        let mut t: Vec<[u32; 3]> = model
            .triangles
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect();
        let touching = |t: &[[u32; 3]]| {
            t.windows(2)
                .filter(|w| w[0].iter().any(|i| w[1].contains(i)))
                .count()
        };
        let before = touching(&t);
        let mut sorted = t.clone();
        spread_out(&mut t, n);
        // The same triangles, corners in the same order.
        let mut after = t.clone();
        sorted.sort();
        after.sort();
        assert_eq!(sorted, after);
        // Only where one colour ends and the next begins (a corner has at most 6 triangles, so
        // the greedy colouring needs at most 16 colours).
        assert!(
            touching(&t) < 16,
            "{} of {} (before: {before})",
            touching(&t),
            t.len()
        );
        assert!(before > 100, "{before}");
    }

    #[test]
    fn a_unit_corner_tetrahedron_encloses_a_sixth() {
        let (x, t) = tetrahedron();
        let mut g = vec![Vec3::ZERO; 4];
        let v = volume_gradient(&t, |i| x[i] + Vec3::splat(100.0), &mut g);
        assert!((v - 1.0 / 6.0).abs() < 1e-6, "{v}");
        // Moving the far corner along +z by δ adds δ/6 (its base has area ½).
        assert!(
            (g[3] - Vec3::new(0.0, 0.0, 1.0 / 6.0)).length() < 1e-6,
            "{:?}",
            g[3]
        );
    }

    #[test]
    fn the_gradient_is_the_volumes_derivative() {
        let (mut x, t) = tetrahedron();
        x[1] = Vec3::new(1.2, 0.1, -0.2);
        let mut g = vec![Vec3::ZERO; 4];
        volume_gradient(&t, |i| x[i], &mut g);
        let eps = 1e-3;
        for (i, gi) in g.iter().enumerate() {
            for axis in 0..3 {
                let mut e = Vec3::ZERO;
                e[axis] = eps;
                let mut scratch = vec![Vec3::ZERO; 4];
                let plus = volume_gradient(
                    &t,
                    |j| x[j] + if j == i { e } else { Vec3::ZERO },
                    &mut scratch,
                );
                let minus = volume_gradient(
                    &t,
                    |j| x[j] - if j == i { e } else { Vec3::ZERO },
                    &mut scratch,
                );
                let numeric = (plus - minus) / (2.0 * eps as f64);
                assert!(
                    (numeric - gi[axis] as f64).abs() < 1e-4,
                    "{i} {axis}: {numeric} vs {}",
                    gi[axis]
                );
            }
        }
    }

    #[test]
    fn the_force_is_minus_the_energys_derivative() {
        let built = 1.0 / 6.0;
        for pressure in [
            Pressure::Volume {
                scale: 1.3,
                bulk_modulus: 2.0e3,
            },
            Pressure::gas(built, 500.0),
        ] {
            let air = Air {
                pressure,
                built_volume: built,
                max_move: f32::INFINITY,
            };
            let v = built as f64 * 0.9;
            let dv = 1e-6;
            let derivative = (air.energy(v + dv) - air.energy(v - dv)) / (2.0 * dv);
            // F = p ∇V, and the energy falls by p dV as the volume grows.
            assert!(
                (derivative + air.gauge(v)).abs() < 1e-3 * air.gauge(v).abs().max(1.0),
                "{pressure:?}: {derivative} vs {}",
                air.gauge(v)
            );
        }
    }

    #[test]
    fn one_stiff_volume_projection_restores_the_kept_volume() {
        let (x, t) = tetrahedron();
        let built = 1.0 / 6.0;
        let air = Air {
            pressure: Pressure::Volume {
                scale: 1.0,
                bulk_modulus: 1e12,
            },
            built_volume: built,
            max_move: f32::INFINITY,
        };
        let mut start = Soa::new(4);
        start.load(&x);
        let mut d = Soa::new(4);
        d.set(3, Vec3::new(0.0, 0.0, -0.3));
        let mut scratch = AirScratch::default();
        scratch.prepare(true, &t, 4, |i| i);
        let error =
            |d: &Soa| (enclosed_volume(&t, |i| start.get(i) + d.get(i)) / built as f64 - 1.0).abs();
        let mut errors = vec![error(&d)];
        for _ in 0..3 {
            air.project(&mut scratch, &[1.0; 4], (&start, &mut d), 1e-3);
            errors.push(error(&d));
        }
        // Each projection is a Gauss-Newton step on the linearised constraint: the error left
        // is of second order in the one before.
        assert!(errors[0] > 0.25, "{errors:?}");
        for pair in errors.windows(2) {
            assert!(pair[1] < 2.0 * pair[0] * pair[0] + 1e-6, "{errors:?}");
        }
        assert!(errors[3] < 1e-5, "{errors:?}");
    }

    #[test]
    fn a_crushed_ball_is_not_thrown_farther_than_max_move_by_the_step_or_the_force() {
        let model = ClothModel::icosphere(0.3, 2).unwrap();
        let built = model.check_closed().unwrap();
        let air = Air::new(Pressure::gas(built, 5.0e4), built, model.mean_edge_length());
        assert!(
            air.max_move > 0.01 && air.max_move < 0.1,
            "{}",
            air.max_move
        );
        // Crushed to a hundredth of its size, below the volume the gas's pressure is held at, so
        // that its gradient has almost vanished; one particle is a thousand times lighter than the
        // rest (a stress case's mass ratio).
        let n = model.particle_count();
        let crushed: Vec<Vec3> = model.rest_positions.iter().map(|p| 0.01 * *p).collect();
        let inv_mass: Vec<f32> = (0..n).map(|i| if i == 0 { 1.0e6 } else { 1.0e3 }).collect();
        let h = 1.0 / 600.0;
        // The farthest move XPBD's step makes, and the farthest one the force makes in a substep
        // (`h² w |F|`), with the air's `max_move` at `max_move`.
        let farthest = |max_move: f32| {
            let air = Air { max_move, ..air };
            let mut scratch = AirScratch::default();
            scratch.prepare(true, &model.triangles, n, |i| i);
            let mut start = Soa::new(n);
            start.load(&crushed);
            let mut d = Soa::new(n);
            air.project(&mut scratch, &inv_mass, (&start, &mut d), h);
            let projected = d.iter().map(|v| v.length()).fold(0.0, f32::max);
            let mut pushed = 0.0f32;
            air.forces(
                &mut scratch,
                |i| crushed[i],
                (&inv_mass, h),
                |i, f| {
                    pushed = pushed.max(h * h * inv_mass[i] * f.length());
                },
            );
            [projected, pushed]
        };
        let (free, held) = (farthest(f32::INFINITY), farthest(air.max_move));
        for k in 0..2 {
            let (free, held) = (free[k], held[k]);
            assert!(free > 2.0 * air.max_move, "{k}: {free} vs {}", air.max_move);
            assert!(
                held <= air.max_move * 1.0001,
                "{k}: {held} vs {}",
                air.max_move
            );
            assert!(
                held >= air.max_move * 0.999,
                "{k}: {held} vs {}",
                air.max_move
            );
        }
    }

    use crate::sim::ClothModel;

    /// The largest eigenvalue of `M^{-1/2} (−∂F/∂x) M^{-1/2}` for the air's force on `x`, by
    /// finite differences and power iteration (the matrix is symmetric).
    fn largest_eigenvalue(air: &Air, triangles: &[u32], x: &[Vec3], inv_mass: &[f32]) -> f64 {
        let n = x.len();
        let force = |x: &[Vec3]| -> Vec<f64> {
            let mut g = vec![Vec3::ZERO; n];
            let p = air.gauge(volume_gradient(triangles, |i| x[i], &mut g));
            g.iter()
                .flat_map(|g| [g.x as f64 * p, g.y as f64 * p, g.z as f64 * p])
                .collect()
        };
        let eps = 1e-4 * x.iter().map(|p| p.length()).fold(0.0, f32::max);
        let mut jacobian = vec![vec![0.0f64; 3 * n]; 3 * n];
        for j in 0..3 * n {
            let (mut plus, mut minus) = (x.to_vec(), x.to_vec());
            plus[j / 3][j % 3] += eps;
            minus[j / 3][j % 3] -= eps;
            let (fp, fm) = (force(&plus), force(&minus));
            for i in 0..3 * n {
                let scale = (inv_mass[i / 3] as f64 * inv_mass[j / 3] as f64).sqrt();
                jacobian[i][j] = -(fp[i] - fm[i]) / (2.0 * eps as f64) * scale;
            }
        }
        // Power iteration on A + cI (c shifts the spectrum positive).
        let c = jacobian
            .iter()
            .map(|r| r.iter().map(|v| v.abs()).sum::<f64>())
            .fold(0.0, f64::max);
        let mut v: Vec<f64> = (0..3 * n).map(|i| 1.0 + (i as f64 * 0.37).sin()).collect();
        let mut lambda = 0.0;
        for _ in 0..2000 {
            let w: Vec<f64> = (0..3 * n)
                .map(|i| jacobian[i].iter().zip(&v).map(|(a, b)| a * b).sum::<f64>() + c * v[i])
                .collect();
            let norm = w.iter().map(|a| a * a).sum::<f64>().sqrt();
            lambda = norm;
            v = w.iter().map(|a| a / norm).collect();
        }
        lambda - c
    }

    #[test]
    fn the_frequency_bound_holds_the_forces_largest_frequency() {
        for (subdivisions, pressure) in [
            (
                0,
                Pressure::Volume {
                    scale: 1.0120776,
                    bulk_modulus: 1.2e6,
                },
            ),
            (
                1,
                Pressure::Volume {
                    scale: 0.8,
                    bulk_modulus: 1e5,
                },
            ),
            (1, Pressure::gas(0.1, 5e4)),
            (0, Pressure::gas(0.1, -4e4)),
        ] {
            let model = ClothModel::icosphere(0.3, subdivisions).unwrap();
            let x = &model.rest_positions;
            let air = Air {
                pressure,
                built_volume: model.check_closed().unwrap(),
                max_move: f32::INFINITY,
            };
            let inv_mass: Vec<f32> = (0..x.len())
                .map(|i| {
                    if i == 0 {
                        0.0
                    } else {
                        1e3 * (1.0 + (i % 3) as f32)
                    }
                })
                .collect();
            let mut scratch = BoundScratch::default();
            let bound = air.frequency(&mut scratch, &model.triangles, (x, &inv_mass)) as f64;
            let exact = largest_eigenvalue(&air, &model.triangles, x, &inv_mass)
                .max(0.0)
                .sqrt();
            eprintln!("{subdivisions} {pressure:?}: bound {bound}, largest {exact}");
            assert!(
                exact <= bound / AIR_FREQUENCY_MARGIN as f64 * 1.001,
                "{pressure:?}: {exact} > {bound}"
            );
        }
    }
}
