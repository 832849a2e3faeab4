//! A cloth's particle state: positions, velocities and masses ([`Particles`]), its pins
//! ([`PinState`]) and its [`Energy`].

use glam::Vec3;

use super::forces::{SpringSet, spring_energy};

/// Positions, velocities and masses of a cloth's particles, in the particles' own order.
#[derive(Debug, Clone)]
pub(crate) struct Particles {
    /// Positions (world space), m.
    pub positions: Vec<Vec3>,
    /// Velocities, m/s.
    pub velocities: Vec<Vec3>,
    /// Masses, kg (whether pinned or not).
    pub mass: Vec<f32>,
    /// Inverse masses, 1/kg (0 for pinned particles).
    pub inv_mass: Vec<f32>,
}

impl Particles {
    /// The energy of the free particles, with the springs `springs` and gravity `gravity`.
    pub fn energy(&self, springs: SpringSet<'_>, gravity: Vec3) -> Energy {
        energy_of(
            springs,
            (&self.mass, &self.inv_mass),
            gravity,
            &self.positions,
            &self.velocities,
        )
    }
}

/// A pinned particle and where it must be.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PinState {
    pub particle: u32,
    /// Target at the start of the current step.
    pub from: Vec3,
    /// Target at the end of the current step.
    pub to: Vec3,
}

/// Moves every pinned particle to its target at fraction `t1` of the step, with the velocity that
/// takes it there from its target at fraction `t0` in one substep (`inv_h = 1/h`). Pinned particles
/// have inverse mass 0, so no integrator moves them otherwise.
pub(crate) fn drive_pins(
    pins: &[PinState],
    t0: f32,
    t1: f32,
    inv_h: f32,
    x: &mut [Vec3],
    v: &mut [Vec3],
) {
    for pin in pins {
        let i = pin.particle as usize;
        (x[i], v[i]) = pin_motion(pin, t0, t1, inv_h);
    }
}

/// The largest length among `vectors` (0 for none).
pub(crate) fn max_length(vectors: &[Vec3]) -> f32 {
    // Eight independent running maxima, so the loop is not one long chain of dependent maxima.
    let (chunks, rest) = vectors.as_chunks::<8>();
    let mut max = [0.0f32; 8];
    for chunk in chunks {
        for (m, v) in max.iter_mut().zip(chunk) {
            *m = m.max(v.length_squared());
        }
    }
    rest.iter()
        .map(|v| v.length_squared())
        .chain(max)
        .fold(0.0, f32::max)
        .sqrt()
}

/// The largest distance from `from` to `to` among the particles whose `weight` (inverse mass)
/// is positive (0 for none).
pub(crate) fn max_distance(from: &[Vec3], to: &[Vec3], weight: &[f32]) -> f32 {
    let n = from.len().min(to.len()).min(weight.len());
    let (from, to, weight) = (&from[..n], &to[..n], &weight[..n]);
    // As in `max_length`: eight running maxima, and every particle's distance computed (a select,
    // not a branch), so that the loop runs in vectors.
    let squared = |k: usize| {
        let d = from[k].distance_squared(to[k]);
        if weight[k] > 0.0 { d } else { 0.0 }
    };
    let mut max = [0.0f32; 8];
    let blocks = n / 8 * 8;
    for k in (0..blocks).step_by(8) {
        for (l, m) in max.iter_mut().enumerate() {
            *m = m.max(squared(k + l));
        }
    }
    (blocks..n)
        .map(squared)
        .chain(max)
        .fold(0.0, f32::max)
        .sqrt()
}

/// A target that moves from `from` to `to` over the step, at fraction `t` of it: `Vec3::lerp`,
/// except that a coordinate that does not move is `from`'s exactly (the blend rounds it by an ulp
/// at some `t`, which would give a still pin or target a speed).
pub(crate) fn between(from: Vec3, to: Vec3, t: f32) -> Vec3 {
    Vec3::new(
        between_coordinate(from.x, to.x, t),
        between_coordinate(from.y, to.y, t),
        between_coordinate(from.z, to.z, t),
    )
}

/// One coordinate of [`between`], for vector kernels that keep coordinates in arrays.
#[inline(always)]
pub(crate) fn between_coordinate(from: f32, to: f32, t: f32) -> f32 {
    if from == to {
        from
    } else {
        from * (1.0 - t) + to * t
    }
}

/// A pin's target at the end of the substep `[t0, t1]` (fractions of the step) of length
/// `1/inv_h`, and the velocity of its motion over the substep.
pub(crate) fn pin_motion(pin: &PinState, t0: f32, t1: f32, inv_h: f32) -> (Vec3, Vec3) {
    let target = between(pin.from, pin.to, t1);
    // `from` is where the particle was when the step began (pins start where their particle is).
    (target, (target - between(pin.from, pin.to, t0)) * inv_h)
}

/// The energy of the free particles (inverse mass > 0), with `(mass, inverse mass)` per
/// particle, at positions `x` and velocities `v` (see [`Energy`]).
pub(crate) fn energy_of(
    springs: SpringSet<'_>,
    (mass, inv_mass): (&[f32], &[f32]),
    gravity: Vec3,
    x: &[Vec3],
    v: &[Vec3],
) -> Energy {
    let g = gravity.as_dvec3();
    let mut e = Energy {
        elastic: spring_energy(springs, x),
        ..Default::default()
    };
    for i in 0..x.len() {
        if inv_mass[i] > 0.0 {
            let m = mass[i] as f64;
            e.kinetic += 0.5 * m * v[i].as_dvec3().length_squared();
            e.gravitational -= m * g.dot(x[i].as_dvec3());
        }
    }
    e
}

/// The energy of a cloth's free particles (pinned ones are driven, not part of the system), in
/// joules, accumulated in f64.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Energy {
    /// `Σ ½ m |v|²` over free particles.
    pub kinetic: f64,
    /// `-Σ m g·x` over free particles (zero at the world origin).
    pub gravitational: f64,
    /// `Σ ½ k (|d| - L)²` over all springs, plus the potential energy of the air inside a closed
    /// cloth with [`Pressure`](super::Pressure) (zero where the pressure inside equals the air
    /// outside).
    pub elastic: f64,
}

impl Energy {
    /// Kinetic plus gravitational plus elastic energy.
    pub fn total(&self) -> f64 {
        self.kinetic + self.gravitational + self.elastic
    }
}

/// The first of `v` with a coordinate that is not finite. Blocks of vectors are tested without
/// a branch per value (a vector loop), and only a failing block is searched.
pub(crate) fn first_not_finite(v: &[Vec3]) -> Option<usize> {
    const BLOCK: usize = 64;
    let flat: &[f32] = bytemuck::cast_slice(v);
    let block = flat
        .chunks(3 * BLOCK)
        .position(|c| !c.iter().fold(true, |ok, x| ok & x.is_finite()))?;
    let start = block * BLOCK;
    v[start..]
        .iter()
        .position(|x| !x.is_finite())
        .map(|i| start + i)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_largest_distance_counts_only_particles_with_weight() {
        for n in [0, 1, 7, 8, 9, 40] {
            let from: Vec<Vec3> = (0..n).map(|k| Vec3::splat(k as f32 * 0.1)).collect();
            let mut to: Vec<Vec3> = (0..n)
                .map(|k| from[k] + Vec3::new((k as f32).sin(), 0.5, -(k as f32 * 0.3).cos()))
                .collect();
            // Every third particle weightless, the farthest among them.
            let mut weight: Vec<f32> = (0..n).map(|k| (k % 3) as f32).collect();
            if n > 3 {
                to[n / 3 * 3 - 3] += Vec3::splat(100.0);
                weight[n / 3 * 3 - 3] = 0.0;
            }
            // The farthest with weight last (after the whole blocks of eight, for 9).
            if n > 0 && weight[n - 1] > 0.0 {
                to[n - 1] += Vec3::splat(50.0);
            }
            let expected = (0..n)
                .filter(|&k| weight[k] > 0.0)
                .map(|k| from[k].distance_squared(to[k]))
                .fold(0.0, f32::max)
                .sqrt();
            assert_eq!(max_distance(&from, &to, &weight), expected, "{n} particles");
        }
    }

    #[test]
    fn the_first_vector_not_finite_is_found_in_any_block_and_coordinate() {
        let n = 200;
        assert_eq!(first_not_finite(&vec![Vec3::ONE; n]), None);
        assert_eq!(first_not_finite(&[]), None);
        for bad in [0, 1, 63, 64, 65, 130, 199] {
            for (c, value) in [(0, f32::NAN), (1, f32::INFINITY), (2, f32::NEG_INFINITY)] {
                let mut v = vec![Vec3::splat(-2.5); n];
                v[bad][c] = value;
                // A later one does not hide it.
                v[n - 1].x = f32::NAN;
                assert_eq!(first_not_finite(&v), Some(bad), "{bad}, coordinate {c}");
            }
        }
    }
}
