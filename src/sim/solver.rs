//! The time stepper: particle state in structure-of-arrays form, pins, and the XPBD solver with
//! substeps (Macklin et al. 2016, "XPBD"; Macklin et al. 2019, "Small Steps in Physics Simulation").
//!
//! Plain data in, plain data out: no ECS types, no allocation inside [`ClothSim::step`]. Every buffer a
//! step touches is sized when the cloth is built (or when pins change).

use bevy::reflect::Reflect;
use glam::Vec3;
use serde::{Deserialize, Serialize};

use super::model::{ClothModel, SpringKind, Springs};
use crate::error::{ClothError, count_in, non_negative, positive};

/// Largest number of substeps per frame accepted by [`SolverSettings::validate`].
pub const MAX_SUBSTEPS: u32 = 1024;
/// Largest number of constraint iterations per substep accepted by [`SolverSettings::validate`].
pub const MAX_ITERATIONS: u32 = 256;

/// The time integration method. Every integrator solves the same canonical model (DESIGN.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, Reflect)]
pub enum Integrator {
    /// Extended position-based dynamics with substeps: springs as compliant distance constraints
    /// (compliance `α = 1/k`), solved by coloured Gauss-Seidel. Unconditionally stable.
    #[default]
    Xpbd,
}

/// Spring stiffness per family, in N/m.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Reflect)]
#[serde(deny_unknown_fields)]
pub struct Stiffness {
    /// Structural springs (rows, columns, mesh edges).
    pub structural: f32,
    /// Shear springs (cell diagonals).
    pub shear: f32,
    /// Bend springs (skip-one neighbours, across mesh edges).
    pub bend: f32,
}

impl Default for Stiffness {
    /// Stiff enough that a hanging cloth of a few hundred 1-gram particles stretches well under 2%.
    fn default() -> Self {
        Self {
            structural: 5_000.0,
            shear: 5_000.0,
            bend: 50.0,
        }
    }
}

impl Stiffness {
    /// Stiffness of one spring family.
    pub fn of(&self, kind: SpringKind) -> f32 {
        match kind {
            SpringKind::Structural => self.structural,
            SpringKind::Shear => self.shear,
            SpringKind::Bend => self.bend,
        }
    }

    /// Checks all three values are finite and non-negative (0 disables a family).
    pub fn validate(&self) -> Result<(), ClothError> {
        non_negative("stiffness.structural", self.structural)?;
        non_negative("stiffness.shear", self.shear)?;
        non_negative("stiffness.bend", self.bend)
    }
}

/// Everything that controls one step of a cloth, apart from its topology.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Reflect)]
#[serde(default, deny_unknown_fields)]
pub struct SolverSettings {
    /// Integration method.
    pub integrator: Integrator,
    /// Substeps per step (the step is the fixed time step of the schedule).
    pub substeps: u32,
    /// Constraint iterations per substep.
    pub iterations: u32,
    /// Spring stiffness per family, N/m.
    pub stiffness: Stiffness,
    /// Mass of each particle, kg.
    pub particle_mass: f32,
    /// Linear velocity damping rate, 1/s: velocities decay as `exp(-damping t)` (0 = undamped).
    pub damping: f32,
    /// Gravitational acceleration, m/s².
    pub gravity: Vec3,
}

impl Default for SolverSettings {
    fn default() -> Self {
        Self {
            integrator: Integrator::Xpbd,
            substeps: 20,
            iterations: 1,
            stiffness: Stiffness::default(),
            particle_mass: 0.001,
            damping: 0.5,
            gravity: Vec3::new(0.0, -9.81, 0.0),
        }
    }
}

impl SolverSettings {
    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), ClothError> {
        count_in("substeps", self.substeps, 1, MAX_SUBSTEPS)?;
        count_in("iterations", self.iterations, 1, MAX_ITERATIONS)?;
        self.stiffness.validate()?;
        positive("particle_mass", self.particle_mass)?;
        non_negative("damping", self.damping)?;
        for (field, v) in [
            ("gravity.x", self.gravity.x),
            ("gravity.y", self.gravity.y),
            ("gravity.z", self.gravity.z),
        ] {
            if !v.is_finite() {
                return Err(ClothError::InvalidValue {
                    field,
                    expected: "finite",
                    value: v as f64,
                });
            }
        }
        Ok(())
    }
}

/// A pinned particle and where it must be.
#[derive(Debug, Clone, Copy, PartialEq)]
struct PinState {
    particle: u32,
    /// Target at the start of the current step.
    from: Vec3,
    /// Target at the end of the current step.
    to: Vec3,
}

/// A simulated cloth: its model, particle state (structure of arrays) and pins.
///
/// Positions are in world space. Pinned particles have inverse mass 0 and move to their target,
/// linearly interpolated across the substeps of a step.
#[derive(Debug, Clone)]
pub struct ClothSim {
    model: ClothModel,
    /// Particle positions, m.
    positions: Vec<Vec3>,
    /// Positions after the unconstrained move of the current substep (scratch).
    predicted: Vec<Vec3>,
    /// Particle velocities, m/s.
    velocities: Vec<Vec3>,
    /// Inverse masses, 1/kg (0 for pinned particles).
    inv_mass: Vec<f32>,
    /// Per-spring compliance `1/k` (m/N).
    compliance: Vec<f32>,
    /// Per-spring Lagrange multipliers of the current substep.
    lambda: Vec<f32>,
    pins: Vec<PinState>,
    settings: SolverSettings,
    steps: u64,
}

impl ClothSim {
    /// Creates a cloth at rest, its particles at `model.rest_positions` mapped by `to_world`.
    pub fn new(
        model: ClothModel,
        settings: SolverSettings,
        to_world: impl Fn(Vec3) -> Vec3,
    ) -> Result<Self, ClothError> {
        settings.validate()?;
        let n = model.particle_count();
        let positions: Vec<Vec3> = model.rest_positions.iter().map(|p| to_world(*p)).collect();
        if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
            return Err(ClothError::InvalidMesh {
                what: format!("vertex {i} has a non-finite world position"),
            });
        }
        let springs = model.springs.len();
        let mut sim = Self {
            predicted: positions.clone(),
            positions,
            velocities: vec![Vec3::ZERO; n],
            inv_mass: vec![0.0; n],
            compliance: vec![0.0; springs],
            lambda: vec![0.0; springs],
            pins: Vec::new(),
            model,
            settings,
            steps: 0,
        };
        sim.apply_settings();
        Ok(sim)
    }

    /// The topology this cloth was built from.
    pub fn model(&self) -> &ClothModel {
        &self.model
    }

    /// Current particle positions (world space).
    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    /// Current particle velocities.
    pub fn velocities(&self) -> &[Vec3] {
        &self.velocities
    }

    /// Sets every particle's velocity (for tests and initial conditions).
    pub fn set_velocities(&mut self, velocity: Vec3) {
        self.velocities.fill(velocity);
    }

    /// Current settings.
    pub fn settings(&self) -> &SolverSettings {
        &self.settings
    }

    /// Number of steps taken so far.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Replaces the settings, after validating them. Cheap (one pass over springs and particles);
    /// intended for runtime edits, not for calling every step.
    pub fn set_settings(&mut self, settings: SolverSettings) -> Result<(), ClothError> {
        settings.validate()?;
        self.settings = settings;
        self.apply_settings();
        Ok(())
    }

    fn apply_settings(&mut self) {
        let s = &self.model.springs;
        for (c, kind) in self.compliance.iter_mut().zip(&s.kind) {
            // A zero stiffness becomes a huge (finite) compliance: the spring does nothing.
            *c = 1.0 / self.settings.stiffness.of(*kind).max(1e-6);
        }
        self.inv_mass.fill(1.0 / self.settings.particle_mass);
        for pin in &self.pins {
            self.inv_mass[pin.particle as usize] = 0.0;
        }
    }

    /// Indices of the pinned particles.
    pub fn pinned(&self) -> impl Iterator<Item = u32> + '_ {
        self.pins.iter().map(|p| p.particle)
    }

    /// Replaces the pin set. Each pin is `(particle, target)`; a particle pinned for the first time
    /// moves to its target over the next step. Particles no longer listed are released with their
    /// current velocity.
    pub fn set_pins(
        &mut self,
        pins: impl IntoIterator<Item = (u32, Vec3)>,
    ) -> Result<(), ClothError> {
        let count = self.positions.len();
        let mut new = Vec::new();
        for (particle, target) in pins {
            if particle as usize >= count {
                return Err(ClothError::PinOutOfRange {
                    index: particle,
                    count,
                });
            }
            if !target.is_finite() {
                return Err(ClothError::InvalidValue {
                    field: "pin target",
                    expected: "finite",
                    value: f64::NAN,
                });
            }
            let from = self.positions[particle as usize];
            new.push(PinState {
                particle,
                from,
                to: target,
            });
        }
        self.pins = new;
        self.apply_settings();
        Ok(())
    }

    /// Moves the targets of existing pins, in the order given to [`Self::set_pins`]. The pinned
    /// particles travel from their current target to the new one across the next step.
    pub fn move_pins(&mut self, targets: impl IntoIterator<Item = Vec3>) {
        for (pin, target) in self.pins.iter_mut().zip(targets) {
            if target.is_finite() {
                pin.to = target;
            }
        }
    }

    /// Kinetic energy, J.
    pub fn kinetic_energy(&self) -> f32 {
        let m = self.settings.particle_mass;
        self.velocities
            .iter()
            .zip(&self.inv_mass)
            .filter(|(_, w)| **w > 0.0)
            .map(|(v, _)| 0.5 * m * v.length_squared())
            .sum()
    }

    /// Largest relative stretch `(|d| - L) / L` over the springs of `kind`.
    pub fn max_strain(&self, kind: SpringKind) -> f32 {
        let s = &self.model.springs;
        (0..s.len())
            .filter(|&k| s.kind[k] == kind)
            .map(|k| {
                let d = self.positions[s.a[k] as usize].distance(self.positions[s.b[k] as usize]);
                (d - s.rest[k]) / s.rest[k]
            })
            .fold(0.0, f32::max)
    }

    /// Advances the cloth by `dt` seconds. Returns an error (and leaves the state as it was at the
    /// failure) if a position became non-finite; the caller should stop stepping this cloth.
    pub fn step(&mut self, dt: f32) -> Result<(), ClothError> {
        if !(dt.is_finite() && dt > 0.0) {
            return Ok(());
        }
        match self.settings.integrator {
            Integrator::Xpbd => self.step_xpbd(dt),
        }
        self.steps += 1;
        for pin in &mut self.pins {
            pin.from = pin.to;
        }
        if let Some(particle) = self.positions.iter().position(|p| !p.is_finite()) {
            return Err(ClothError::Diverged {
                step: self.steps,
                particle,
                dt,
                substeps: self.settings.substeps,
            });
        }
        Ok(())
    }

    fn step_xpbd(&mut self, dt: f32) {
        let n = self.settings.substeps;
        let h = dt / n as f32;
        let inv_h = 1.0 / h;
        let inv_h2 = inv_h * inv_h;
        let gravity_dv = self.settings.gravity * h;
        let keep = (-self.settings.damping * h).exp();
        for sub in 0..n {
            // Integrate free particles (symplectic Euler) and remember where they would go without
            // constraints.
            for ((x, predicted), (v, w)) in self
                .positions
                .iter_mut()
                .zip(self.predicted.iter_mut())
                .zip(self.velocities.iter_mut().zip(&self.inv_mass))
            {
                if *w > 0.0 {
                    *v = (*v + gravity_dv) * keep;
                    *x += *v * h;
                }
                *predicted = *x;
            }
            // Pinned particles move to their interpolated target, at the velocity that takes them there.
            let t = (sub + 1) as f32 / n as f32;
            for pin in &self.pins {
                let i = pin.particle as usize;
                let target = pin.from.lerp(pin.to, t);
                self.velocities[i] = (target - self.positions[i]) * inv_h;
                self.positions[i] = target;
                self.predicted[i] = target;
            }
            let springs = &self.model.springs;
            if self.settings.iterations == 1 {
                // λ starts at 0 each substep, so one iteration needs no multiplier storage.
                solve_springs::<false>(
                    springs,
                    &self.compliance,
                    &mut self.lambda,
                    &self.inv_mass,
                    &mut self.positions,
                    inv_h2,
                );
            } else {
                self.lambda.fill(0.0);
                for _ in 0..self.settings.iterations {
                    solve_springs::<true>(
                        springs,
                        &self.compliance,
                        &mut self.lambda,
                        &self.inv_mass,
                        &mut self.positions,
                        inv_h2,
                    );
                }
            }
            // v = (x - x_start) / h, computed as v + (constraint correction) / h: the free-flight
            // part stays exact even far from the origin, where x - x_start would cancel in f32.
            for ((v, x), predicted) in self
                .velocities
                .iter_mut()
                .zip(&self.positions)
                .zip(&self.predicted)
            {
                *v += (*x - *predicted) * inv_h;
            }
        }
    }
}

/// Springs solved together in the batched XPBD kernel. Within one colour no two springs share a
/// particle, so a batch gives exactly the sequential Gauss-Seidel result.
const LANES: usize = 8;

/// One Gauss-Seidel sweep over all springs, colour by colour: the XPBD update
/// `Δλ = (-C - α̃ λ) / (w_a + w_b + α̃)`, `α̃ = α / h²`, `C = |x_a - x_b| - L`, then
/// `x_a += w_a Δλ n`, `x_b -= w_b Δλ n` with `n = (x_a - x_b) / |x_a - x_b|`.
///
/// Springs are processed in batches of [`LANES`] inside each colour: positions are gathered into
/// small arrays, the arithmetic (square root and division included) runs as SIMD, and corrections
/// are scattered back. With `ACCUMULATE = false` (one iteration per substep) λ is known to be 0
/// and is neither read nor stored.
#[inline(never)]
fn solve_springs<const ACCUMULATE: bool>(
    springs: &Springs,
    compliance: &[f32],
    lambda: &mut [f32],
    inv_mass: &[f32],
    x: &mut [Vec3],
    inv_h2: f32,
) {
    for color in springs.color_offsets.windows(2) {
        let (start, end) = (color[0] as usize, color[1] as usize);
        let mut k = start;
        while k + LANES <= end {
            solve_batch::<ACCUMULATE>(springs, compliance, lambda, inv_mass, x, inv_h2, k);
            k += LANES;
        }
        for k in k..end {
            solve_one::<ACCUMULATE>(springs, compliance, lambda, inv_mass, x, inv_h2, k);
        }
    }
}

/// The XPBD step size `Δλ / |d|` for one spring, or 0 where the spring cannot act (both ends
/// pinned, or zero length).
#[inline(always)]
fn spring_scale(len2: f32, w: f32, rest: f32, alpha: f32, lambda: f32) -> (f32, f32) {
    let len = len2.sqrt();
    let dl = (-(len - rest) - alpha * lambda) / (w + alpha);
    if w > 0.0 && len2 > 1e-20 {
        (dl / len, dl)
    } else {
        (0.0, 0.0)
    }
}

#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn solve_batch<const ACCUMULATE: bool>(
    s: &Springs,
    compliance: &[f32],
    lambda: &mut [f32],
    inv_mass: &[f32],
    x: &mut [Vec3],
    inv_h2: f32,
    k: usize,
) {
    let (a, b) = (&s.a[k..k + LANES], &s.b[k..k + LANES]);
    let (rest, comp) = (&s.rest[k..k + LANES], &compliance[k..k + LANES]);
    let mut d = [Vec3::ZERO; LANES];
    let (mut wa, mut wb) = ([0.0f32; LANES], [0.0f32; LANES]);
    for l in 0..LANES {
        let (ia, ib) = (a[l] as usize, b[l] as usize);
        d[l] = x[ia] - x[ib];
        wa[l] = inv_mass[ia];
        wb[l] = inv_mass[ib];
    }
    let mut scale = [0.0f32; LANES];
    if ACCUMULATE {
        let lam = &mut lambda[k..k + LANES];
        for l in 0..LANES {
            let (sc, dl) = spring_scale(d[l].length_squared(), wa[l] + wb[l], rest[l], comp[l] * inv_h2, lam[l]);
            scale[l] = sc;
            lam[l] += dl;
        }
    } else {
        for l in 0..LANES {
            scale[l] = spring_scale(d[l].length_squared(), wa[l] + wb[l], rest[l], comp[l] * inv_h2, 0.0).0;
        }
    }
    for l in 0..LANES {
        let corr = d[l] * scale[l];
        x[a[l] as usize] += corr * wa[l];
        x[b[l] as usize] -= corr * wb[l];
    }
}

#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn solve_one<const ACCUMULATE: bool>(
    s: &Springs,
    compliance: &[f32],
    lambda: &mut [f32],
    inv_mass: &[f32],
    x: &mut [Vec3],
    inv_h2: f32,
    k: usize,
) {
    let (ia, ib) = (s.a[k] as usize, s.b[k] as usize);
    let (wa, wb) = (inv_mass[ia], inv_mass[ib]);
    let d = x[ia] - x[ib];
    let lam = if ACCUMULATE { lambda[k] } else { 0.0 };
    let (scale, dl) = spring_scale(d.length_squared(), wa + wb, s.rest[k], compliance[k] * inv_h2, lam);
    if ACCUMULATE {
        lambda[k] += dl;
    }
    let corr = d * scale;
    x[ia] += corr * wa;
    x[ib] -= corr * wb;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::GridSpec;

    fn sim(nx: u32, settings: SolverSettings) -> ClothSim {
        ClothSim::new(
            ClothModel::grid(&GridSpec::new(nx, nx, 0.1)).unwrap(),
            settings,
            |p| p,
        )
        .unwrap()
    }

    #[test]
    fn free_fall_matches_the_parabola() {
        let settings = SolverSettings {
            damping: 0.0,
            ..Default::default()
        };
        let mut s = sim(3, settings);
        let v0 = Vec3::new(1.0, 2.0, 0.5);
        s.set_velocities(v0);
        let x0 = s.positions()[4];
        for _ in 0..60 {
            s.step(1.0 / 60.0).unwrap();
        }
        let exact = x0 + v0 + 0.5 * settings.gravity;
        let err = s.positions()[4].distance(exact);
        // Symplectic Euler in the substeps errs by g t h / 2.
        let h = 1.0 / 60.0 / 20.0;
        assert!(err <= 0.5 * 9.81 * h * 1.01 + 1e-4, "error {err}");
        assert!(err / (0.5 * 9.81) < 1e-3);
    }

    #[test]
    fn pins_hold_and_move() {
        let mut s = sim(4, SolverSettings::default());
        let p0 = s.positions()[0];
        s.set_pins([(0, p0), (3, s.positions()[3])]).unwrap();
        for _ in 0..30 {
            s.step(1.0 / 60.0).unwrap();
        }
        assert_eq!(s.positions()[0], p0);
        s.move_pins([p0 + Vec3::X, s.positions()[3] + Vec3::X]);
        s.step(1.0 / 60.0).unwrap();
        assert!(s.positions()[0].distance(p0 + Vec3::X) < 1e-6);
        assert!(s.set_pins([(16, Vec3::ZERO)]).is_err());
    }

    #[test]
    fn bad_settings_are_rejected() {
        for (bad, field) in [
            (
                SolverSettings {
                    substeps: 0,
                    ..Default::default()
                },
                "substeps",
            ),
            (
                SolverSettings {
                    particle_mass: -1.0,
                    ..Default::default()
                },
                "particle_mass",
            ),
            (
                SolverSettings {
                    stiffness: Stiffness {
                        bend: -3.0,
                        ..Default::default()
                    },
                    ..Default::default()
                },
                "stiffness.bend",
            ),
            (
                SolverSettings {
                    damping: f32::NAN,
                    ..Default::default()
                },
                "damping",
            ),
        ] {
            let e = bad.validate().unwrap_err().to_string();
            assert!(e.contains(field), "{e}");
        }
    }
}
