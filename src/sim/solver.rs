//! The time stepper: particle state in structure-of-arrays form, pins, the [`Integrator`] choice and
//! its dispatch, and the XPBD solver with substeps (Macklin et al. 2016, "XPBD"; Macklin et al. 2019,
//! "Small Steps in Physics Simulation"). The force-based integrators live in `explicit.rs`
//! (symplectic Euler, Verlet) and `implicit.rs` (Baraff & Witkin implicit Euler), on the shared
//! spring-force kernel of `forces.rs`.
//!
//! Plain data in, plain data out: no ECS types, no allocation inside [`ClothSim::step`]. Every buffer a
//! step touches is sized when the cloth is built (or when pins or settings change).

use bevy::reflect::Reflect;
use glam::Vec3;
use serde::{Deserialize, Serialize};

use super::collision::{Collider, Contacts};
use super::forces::{SpringSet, max_frequency_bound, spring_energy};
use super::implicit::ImplicitScratch;
use super::model::{ClothModel, SpringKind, Springs};
use super::wind::{WindField, WindScratch};
use super::{explicit, implicit};
use crate::error::{ClothError, count_in, non_negative, positive};

/// Largest number of substeps per frame accepted by [`SolverSettings::validate`].
pub const MAX_SUBSTEPS: u32 = 1024;
/// Largest number of constraint iterations per substep accepted by [`SolverSettings::validate`].
pub const MAX_ITERATIONS: u32 = 256;

/// Fraction of the explicit stability limit `h < 2/ω_max` that [`SolverSettings::auto_substeps`]
/// stays within, applied to the Gershgorin bound on `ω_max` (which itself over-estimates it).
pub const STABILITY_FRACTION: f32 = 0.9;

/// The time integration method. Every integrator solves the same canonical model (DESIGN.md): the
/// same springs, masses, gravity, pins (pinned particles follow their targets, interpolated across
/// substeps) and damping (velocities decay as `exp(-damping t)`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, Reflect)]
pub enum Integrator {
    /// Extended position-based dynamics with substeps: springs as compliant distance constraints
    /// (compliance `α = 1/k`), solved by coloured Gauss-Seidel, `iterations` sweeps per substep.
    /// Unconditionally stable, first order, with numerical damping that shrinks with the substep.
    ///
    /// The default, for robustness rather than accuracy: on the work-precision benchmark Verlet is
    /// far more accurate wherever it is stable (docs/accuracy.md), but a force-based integrator
    /// turns a teleported pin into the large elastic energy of the stretched springs and flings
    /// the cloth, where XPBD's projection absorbs it.
    #[default]
    Xpbd,
    /// Symplectic (semi-implicit) Euler with explicit spring forces: `v += h a(x)`, then `x += h v`.
    /// First order, symplectic (no energy drift), stable only for `h ω_max < 2`; see
    /// [`SolverSettings::auto_substeps`].
    SymplecticEuler,
    /// Position (Störmer–)Verlet, drift-kick-drift: `x += h/2 v`, `v += h a(x)`, `x += h/2 v`. The
    /// half-step positions follow the classic cloth recurrence `x⁺ = 2x - x⁻ + h² a(x)`. Second order,
    /// symplectic, one force evaluation per substep, stable only for `h ω_max < 2`. With
    /// [`SolverSettings::auto_substeps`] the most accurate integrator at every run time where it is
    /// stable, on every scene of the work-precision benchmark (docs/accuracy.md).
    Verlet,
    /// Implicit (backward) Euler after Baraff & Witkin 1998: per substep one Newton step on the
    /// linearised springs, `(M + h² K) Δv = h (f - h K v)`, solved by Jacobi-preconditioned conjugate
    /// gradients (at most `iterations` iterations, stopping at a relative residual of
    /// [`CG_TOLERANCE`](super::CG_TOLERANCE)); pins by filtering the CG. Unconditionally stable for
    /// the clamped (positive semi-definite) `K`, first order, strongly damped at large steps.
    ImplicitEuler,
}

impl Integrator {
    /// All integrators, in declaration order.
    pub const ALL: [Integrator; 4] = [
        Integrator::Xpbd,
        Integrator::SymplecticEuler,
        Integrator::Verlet,
        Integrator::ImplicitEuler,
    ];

    /// A short name for tables and logs.
    pub fn name(self) -> &'static str {
        match self {
            Integrator::Xpbd => "XPBD",
            Integrator::SymplecticEuler => "symplectic Euler",
            Integrator::Verlet => "Verlet",
            Integrator::ImplicitEuler => "implicit Euler",
        }
    }

    /// Whether the method is stable only below a step-size limit (`h ω_max < 2`).
    pub fn is_explicit(self) -> bool {
        matches!(self, Integrator::SymplecticEuler | Integrator::Verlet)
    }
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
    /// Substeps per step (the step is the fixed time step of the schedule). With
    /// [`auto_substeps`](Self::auto_substeps) and an explicit integrator this is the minimum, and
    /// the stability bound usually decides (84 for the default stiffness and mass at 60 Hz).
    pub substeps: u32,
    /// Inner iterations per substep: Gauss-Seidel sweeps for XPBD; the cap on conjugate-gradient
    /// iterations for implicit Euler (which usually stops earlier, at its tolerance; 20–100 is a
    /// sensible cap); unused by the explicit integrators.
    pub iterations: u32,
    /// For the explicit integrators (symplectic Euler, Verlet): raise the substep count, if needed,
    /// to what the stability bound asks for, `h ≤ STABILITY_FRACTION · 2/ω_max` with `ω_max` bounded
    /// from each particle's springs and mass. `substeps` stays the minimum. Ignored by XPBD and
    /// implicit Euler, which are stable at any step.
    pub auto_substeps: bool,
    /// Spring stiffness per family, N/m.
    pub stiffness: Stiffness,
    /// Mass of each particle, kg.
    pub particle_mass: f32,
    /// Linear velocity damping rate, 1/s: velocities decay as `exp(-damping t)` (0 = undamped).
    pub damping: f32,
    /// Gravitational acceleration, m/s².
    pub gravity: Vec3,
    /// Aerodynamic drag coefficient of the cloth's triangles (used only when there is wind).
    pub drag_coefficient: f32,
    /// Aerodynamic lift coefficient of the cloth's triangles (used only when there is wind).
    pub lift_coefficient: f32,
}

impl Default for SolverSettings {
    fn default() -> Self {
        Self {
            integrator: Integrator::Xpbd,
            substeps: 20,
            iterations: 1,
            auto_substeps: true,
            stiffness: Stiffness::default(),
            particle_mass: 0.001,
            damping: 0.5,
            gravity: Vec3::new(0.0, -9.81, 0.0),
            drag_coefficient: 1.0,
            lift_coefficient: 0.5,
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
        non_negative("drag_coefficient", self.drag_coefficient)?;
        non_negative("lift_coefficient", self.lift_coefficient)?;
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
pub(super) struct PinState {
    pub particle: u32,
    /// Target at the start of the current step.
    pub from: Vec3,
    /// Target at the end of the current step.
    pub to: Vec3,
}

/// Moves every pinned particle to its target at fraction `t1` of the step, with the velocity that
/// takes it there from its target at fraction `t0` in one substep (`inv_h = 1/h`). Pinned particles
/// have inverse mass 0, so no integrator moves them otherwise.
pub(super) fn drive_pins(
    pins: &[PinState],
    t0: f32,
    t1: f32,
    inv_h: f32,
    x: &mut [Vec3],
    v: &mut [Vec3],
) {
    for pin in pins {
        let i = pin.particle as usize;
        let target = pin.from.lerp(pin.to, t1);
        // `from` is where the particle was when the step began (pins start where their particle is).
        v[i] = (target - pin.from.lerp(pin.to, t0)) * inv_h;
        x[i] = target;
    }
}

/// The energy of a cloth's free particles (pinned ones are driven, not part of the system), in
/// joules, accumulated in f64.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Energy {
    /// `Σ ½ m |v|²` over free particles.
    pub kinetic: f64,
    /// `-Σ m g·x` over free particles (zero at the world origin).
    pub gravitational: f64,
    /// `Σ ½ k (|d| - L)²` over all springs.
    pub elastic: f64,
}

impl Energy {
    /// Kinetic plus gravitational plus elastic energy.
    pub fn total(&self) -> f64 {
        self.kinetic + self.gravitational + self.elastic
    }
}

/// A simulated cloth: its model, particle state (structure of arrays) and pins.
///
/// Positions are in world space. Pinned particles have inverse mass 0 and move to their target,
/// linearly interpolated across the substeps of a step.
#[derive(Debug, Clone)]
pub struct ClothSim {
    pub(super) model: ClothModel,
    /// Particle positions, m.
    pub(super) positions: Vec<Vec3>,
    /// Positions after the unconstrained move of the current substep (XPBD scratch).
    pub(super) predicted: Vec<Vec3>,
    /// Particle velocities, m/s.
    pub(super) velocities: Vec<Vec3>,
    /// Particle masses, kg (whether pinned or not).
    pub(super) mass: Vec<f32>,
    /// Inverse masses, 1/kg (0 for pinned particles).
    pub(super) inv_mass: Vec<f32>,
    /// Per-spring stiffness `k` (N/m).
    pub(super) stiffness: Vec<f32>,
    /// Per-spring compliance `1/k` (m/N).
    pub(super) compliance: Vec<f32>,
    /// Per-spring Lagrange multipliers of the current substep.
    pub(super) lambda: Vec<f32>,
    /// Force accumulator of the force-based integrators (scratch).
    pub(super) forces: Vec<Vec3>,
    /// Linearised springs and conjugate-gradient vectors of implicit Euler; empty for the others.
    pub(super) implicit: ImplicitScratch,
    /// Gershgorin bound on the highest angular frequency of the springs, rad/s.
    pub(super) omega_max: f32,
    /// Colliders that passed this step's broad phase, and substep scratch for contacts.
    pub(super) contacts: Contacts,
    /// The wind at each triangle for this step.
    pub(super) wind: WindScratch,
    pub(super) pins: Vec<PinState>,
    pub(super) settings: SolverSettings,
    steps: u64,
}

/// What surrounds a cloth during one step: colliders (their poses at the start and end of the step),
/// which of them this cloth collides with, and the air.
#[derive(Debug, Clone, Copy)]
pub struct Environment<'a> {
    /// Colliders near or far; the broad phase drops the ones the cloth cannot reach.
    pub colliders: &'a [Collider],
    /// The cloth collides with a collider when `collider.layers & collision_mask != 0`.
    pub collision_mask: u32,
    /// The air; `None` means no aerodynamic forces at all (not even drag in still air).
    pub wind: Option<&'a WindField>,
}

impl Default for Environment<'_> {
    /// Nothing around: no colliders, every layer, no air.
    fn default() -> Self {
        Self {
            colliders: &[],
            collision_mask: u32::MAX,
            wind: None,
        }
    }
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
        if let Some(masses) = &model.particle_masses {
            if masses.len() != n {
                return Err(ClothError::InvalidMesh {
                    what: format!("has {} particle masses for {n} particles", masses.len()),
                });
            }
            for m in masses {
                positive("particle_masses", *m)?;
            }
        }
        let springs = model.springs.len();
        let mut sim = Self {
            predicted: positions.clone(),
            positions,
            velocities: vec![Vec3::ZERO; n],
            mass: vec![0.0; n],
            inv_mass: vec![0.0; n],
            stiffness: vec![0.0; springs],
            compliance: vec![0.0; springs],
            lambda: vec![0.0; springs],
            forces: vec![Vec3::ZERO; n],
            implicit: ImplicitScratch::default(),
            omega_max: 0.0,
            contacts: Contacts::new(n, model.max_edge_length()),
            wind: WindScratch::new(model.triangles.len() / 3),
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

    /// Recomputes everything derived from settings, masses and pins: per-spring stiffness and
    /// compliance, inverse masses, the frequency bound, and (for implicit Euler) its scratch buffers.
    /// Runs at construction and on edits, never inside a step.
    fn apply_settings(&mut self) {
        let s = &self.model.springs;
        for ((c, k), kind) in self
            .compliance
            .iter_mut()
            .zip(self.stiffness.iter_mut())
            .zip(&s.kind)
        {
            *k = self.settings.stiffness.of(*kind);
            // A zero stiffness becomes a huge (finite) compliance: the spring does nothing.
            *c = 1.0 / k.max(1e-6);
        }
        for (i, (m, w)) in self.mass.iter_mut().zip(&mut self.inv_mass).enumerate() {
            *m = self.model.mass_of(i, self.settings.particle_mass);
            *w = 1.0 / *m;
        }
        for pin in &self.pins {
            self.inv_mass[pin.particle as usize] = 0.0;
        }
        let mut scratch = vec![0.0; self.positions.len()];
        self.omega_max = max_frequency_bound(self.spring_set(), &self.inv_mass, &mut scratch);
        if self.settings.integrator == Integrator::ImplicitEuler
            && !self.implicit.fits(self.positions.len(), s.len())
        {
            self.implicit = ImplicitScratch::new(self.positions.len(), s.len());
        }
    }

    /// The springs with their current stiffness, for the force kernel.
    pub(super) fn spring_set(&self) -> SpringSet<'_> {
        let s = &self.model.springs;
        SpringSet {
            a: &s.a,
            b: &s.b,
            rest: &s.rest,
            k: &self.stiffness,
        }
    }

    /// An upper bound on the highest angular frequency of the cloth's springs about rest, in rad/s
    /// (Gershgorin's bound from each free particle's springs and mass; pins count as infinite mass).
    /// Explicit integrators need a substep `h < 2/ω_max`.
    pub fn max_frequency(&self) -> f32 {
        self.omega_max
    }

    /// Number of substeps a step of `dt` seconds takes: `substeps`, raised to the stability bound
    /// for the explicit integrators when [`SolverSettings::auto_substeps`] is on, and at most
    /// [`MAX_SUBSTEPS`].
    pub fn substeps_for(&self, dt: f32) -> u32 {
        let n = self.settings.substeps;
        if !(self.settings.auto_substeps && self.settings.integrator.is_explicit()) {
            return n;
        }
        let needed = (dt * self.omega_max / (2.0 * STABILITY_FRACTION)).ceil();
        if needed.is_finite() {
            n.max(needed.min(MAX_SUBSTEPS as f32) as u32)
        } else {
            MAX_SUBSTEPS
        }
    }

    /// Conjugate-gradient iterations taken in the last substep of implicit Euler (0 before the first
    /// implicit step, and for the other integrators).
    pub fn cg_iterations(&self) -> u32 {
        self.implicit.last_iterations
    }

    /// Mass of each particle, kg (pinned ones included).
    pub fn masses(&self) -> &[f32] {
        &self.mass
    }

    /// Kinetic, gravitational and elastic energy of the free particles (see [`Energy`]).
    pub fn energy(&self) -> Energy {
        let g = self.settings.gravity.as_dvec3();
        let mut e = Energy {
            elastic: spring_energy(self.spring_set(), &self.positions),
            ..Default::default()
        };
        for i in 0..self.positions.len() {
            if self.inv_mass[i] > 0.0 {
                let m = self.mass[i] as f64;
                e.kinetic += 0.5 * m * self.velocities[i].as_dvec3().length_squared();
                e.gravitational -= m * g.dot(self.positions[i].as_dvec3());
            }
        }
        e
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

    /// Kinetic energy of the free particles, J.
    pub fn kinetic_energy(&self) -> f32 {
        self.velocities
            .iter()
            .zip(self.inv_mass.iter().zip(&self.mass))
            .filter(|(_, (w, _))| **w > 0.0)
            .map(|(v, (_, m))| 0.5 * m * v.length_squared())
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

    /// Advances the cloth by `dt` seconds with nothing around it (see [`Self::step_in`]).
    pub fn step(&mut self, dt: f32) -> Result<(), ClothError> {
        self.step_in(dt, &Environment::default())
    }

    /// Number of colliders that passed the broad phase of the last step.
    pub fn active_colliders(&self) -> usize {
        self.contacts.active_count()
    }

    /// Advances the cloth by `dt` seconds among the colliders of `env`. Returns an error (and
    /// leaves the state as it was at the failure) if a position became non-finite; the caller
    /// should stop stepping this cloth.
    pub fn step_in(&mut self, dt: f32, env: &Environment) -> Result<(), ClothError> {
        if !(dt.is_finite() && dt > 0.0) {
            return Ok(());
        }
        let substeps = self.substeps_for(dt);
        if env.colliders.is_empty() {
            self.contacts.begin_step(&[], 0, &[], 0.0, dt);
        } else {
            let reach = self.reach(dt);
            self.contacts.begin_step(
                env.colliders,
                env.collision_mask,
                &self.positions,
                reach,
                dt,
            );
        }
        self.wind.begin_step(
            env.wind,
            (
                self.settings.drag_coefficient,
                self.settings.lift_coefficient,
            ),
            &self.positions,
            &self.model.triangles,
        );
        match self.settings.integrator {
            Integrator::Xpbd => self.step_xpbd(dt, substeps),
            Integrator::SymplecticEuler => explicit::step_symplectic_euler(self, dt, substeps),
            Integrator::Verlet => explicit::step_verlet(self, dt, substeps),
            Integrator::ImplicitEuler => implicit::step_implicit_euler(self, dt, substeps),
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
                substeps,
            });
        }
        Ok(())
    }

    /// A generous bound on how far any particle can move in a step of `dt`: twice the free flight
    /// of the fastest particle, plus gravity, plus the farthest pin jump.
    fn reach(&self, dt: f32) -> f32 {
        let speed = self
            .velocities
            .iter()
            .map(|v| v.length_squared())
            .fold(0.0, f32::max)
            .sqrt();
        let pin_jump = self
            .pins
            .iter()
            .map(|p| p.from.distance(p.to))
            .fold(0.0, f32::max);
        2.0 * speed * dt + self.settings.gravity.length() * dt * dt + pin_jump
    }

    /// Contacts at the end of substep `sub` of `n` (length `h`): after the integrator has its final
    /// positions and velocities for the substep.
    pub(super) fn resolve_contacts(&mut self, sub: u32, n: u32, h: f32) {
        if self.contacts.is_active() {
            self.contacts.resolve(
                sub as f32 / n as f32,
                (sub + 1) as f32 / n as f32,
                h,
                &self.model.triangles,
                &self.inv_mass,
                &mut self.positions,
                &mut self.velocities,
            );
        }
    }

    fn step_xpbd(&mut self, dt: f32, n: u32) {
        let h = dt / n as f32;
        let inv_h = 1.0 / h;
        let inv_h2 = inv_h * inv_h;
        let gravity_dv = self.settings.gravity * h;
        let keep = (-self.settings.damping * h).exp();
        for sub in 0..n {
            self.contacts.begin_substep(&self.positions);
            // Integrate free particles (symplectic Euler) and remember where they would go without
            // constraints. Wind forces are evaluated at the start of the substep.
            if self.wind.active {
                self.forces.fill(Vec3::ZERO);
                self.wind.add_forces(
                    &self.positions,
                    &self.velocities,
                    &self.model.triangles,
                    &mut self.forces,
                );
            }
            let wind = self.wind.active;
            for (((x, predicted), (v, w)), f) in self
                .positions
                .iter_mut()
                .zip(self.predicted.iter_mut())
                .zip(self.velocities.iter_mut().zip(&self.inv_mass))
                .zip(&self.forces)
            {
                if *w > 0.0 {
                    let dv = if wind {
                        gravity_dv + *f * (*w * h)
                    } else {
                        gravity_dv
                    };
                    *v = (*v + dv) * keep;
                    *x += *v * h;
                }
                *predicted = *x;
            }
            // Pinned particles move to their interpolated target, at the velocity that takes them there.
            let (t0, t1) = (sub as f32 / n as f32, (sub + 1) as f32 / n as f32);
            drive_pins(
                &self.pins,
                t0,
                t1,
                inv_h,
                &mut self.positions,
                &mut self.velocities,
            );
            for pin in &self.pins {
                self.predicted[pin.particle as usize] = self.positions[pin.particle as usize];
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
            // Contacts last, so every substep ends outside the colliders; their push-out is not
            // turned into velocity (see `collision.rs`).
            self.resolve_contacts(sub, n, h);
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
            solve_batch::<ACCUMULATE, LANES>(springs, compliance, lambda, inv_mass, x, inv_h2, k);
            k += LANES;
        }
        // The colour's last few springs, one at a time.
        for k in k..end {
            solve_batch::<ACCUMULATE, 1>(springs, compliance, lambda, inv_mass, x, inv_h2, k);
        }
    }
}

/// The XPBD step of one spring: `(Δλ / |d|, Δλ)`, or zeros for a spring of (near) zero length,
/// which has no direction. Branch-free so that a batch of springs vectorises. A spring whose ends
/// are both pinned (`w = 0`) gets a finite step that its zero inverse masses then ignore: `α̃ > 0`
/// because every stiffness is finite.
#[inline(always)]
fn spring_scale(len2: f32, w: f32, rest: f32, alpha: f32, lambda: f32) -> (f32, f32) {
    let len = len2.sqrt();
    let scale = (rest - len - alpha * lambda) / ((w + alpha) * len);
    let scale = if len2 > 1e-20 { scale } else { 0.0 };
    (scale, scale * len)
}

/// Solves springs `k..k + N` of one colour: gather, vectorisable arithmetic, scatter.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn solve_batch<const ACCUMULATE: bool, const N: usize>(
    s: &Springs,
    compliance: &[f32],
    lambda: &mut [f32],
    inv_mass: &[f32],
    x: &mut [Vec3],
    inv_h2: f32,
    k: usize,
) {
    let (a, b) = (&s.a[k..k + N], &s.b[k..k + N]);
    let (rest, comp) = (&s.rest[k..k + N], &compliance[k..k + N]);
    // Gather into lanes (structure of arrays), so the arithmetic below vectorises.
    let (mut dx, mut dy, mut dz) = ([0.0f32; N], [0.0f32; N], [0.0f32; N]);
    let (mut wa, mut wb) = ([0.0f32; N], [0.0f32; N]);
    for l in 0..N {
        let (ia, ib) = (a[l] as usize, b[l] as usize);
        let d = x[ia] - x[ib];
        (dx[l], dy[l], dz[l]) = (d.x, d.y, d.z);
        wa[l] = inv_mass[ia];
        wb[l] = inv_mass[ib];
    }
    let mut scale = [0.0f32; N];
    let mut lam = [0.0f32; N];
    if ACCUMULATE {
        lam.copy_from_slice(&lambda[k..k + N]);
    }
    for l in 0..N {
        let len2 = dx[l] * dx[l] + dy[l] * dy[l] + dz[l] * dz[l];
        let (sc, dl) = spring_scale(len2, wa[l] + wb[l], rest[l], comp[l] * inv_h2, lam[l]);
        scale[l] = sc;
        lam[l] += dl;
    }
    if ACCUMULATE {
        lambda[k..k + N].copy_from_slice(&lam);
    }
    for l in 0..N {
        let corr = Vec3::new(dx[l], dy[l], dz[l]) * scale[l];
        x[a[l] as usize] += corr * wa[l];
        x[b[l] as usize] -= corr * wb[l];
    }
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
