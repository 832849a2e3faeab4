//! The time stepper: particle state in structure-of-arrays form, pins, the [`Integrator`] choice and
//! its dispatch. The integrators live beside it: XPBD in `xpbd.rs`, symplectic Euler and Verlet in
//! `explicit.rs` and Baraff & Witkin implicit Euler in `implicit.rs`, the force-based ones on the
//! shared spring-force kernel of `forces.rs`.
//!
//! Plain data in, plain data out: no ECS types, no allocation inside [`ClothSim::step`]. Every buffer a
//! step touches is sized when the cloth is built (or when pins or settings change).

use bevy::reflect::Reflect;
use glam::Vec3;
use serde::{Deserialize, Serialize};

use super::collision::{Collider, ContactState, Contacts, Near, bounds};
use super::forces::{ForceRuns, Soa, SpringSet, max_frequency_bound, spring_energy};
use super::implicit::ImplicitScratch;
use super::model::{ClothModel, SpringKind};
use super::parallel::Spread;
use super::wind::{WindField, WindScratch};
use super::xpbd::Projections;
use super::{explicit, implicit, xpbd};
use crate::error::{ClothError, count_in, non_negative, positive};

/// Largest number of substeps per frame accepted by [`SolverSettings::validate`].
pub const MAX_SUBSTEPS: u32 = 1024;
/// Largest number of constraint iterations per substep accepted by [`SolverSettings::validate`].
pub const MAX_ITERATIONS: u32 = 256;

/// Fraction of the explicit stability limit `h < 2/ω_max` that [`SolverSettings::auto_substeps`]
/// stays within, applied to the Gershgorin bound on `ω_max` (which itself over-estimates it).
pub const STABILITY_FRACTION: f32 = 0.9;

/// [`Integrator::Auto`] runs XPBD while any spring is stretched by more than this fraction of its
/// rest length (a hanging cloth of the default stiffness stretches by under 2%).
pub const AUTO_MAX_STRETCH: f32 = 0.1;

/// The time integration method. Every integrator solves the same canonical model (DESIGN.md): the
/// same springs, masses, gravity, pins (pinned particles follow their targets, interpolated across
/// substeps) and damping (velocities decay as `exp(-damping t)`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, Reflect)]
pub enum Integrator {
    /// Extended position-based dynamics with substeps: springs as compliant distance constraints
    /// (compliance `α = 1/k`), solved by coloured Gauss-Seidel, `iterations` sweeps per substep.
    /// Unconditionally stable, first order, with numerical damping that shrinks with the substep.
    /// Robust where a force-based integrator is not: it absorbs a teleported pin (whose stretched
    /// springs would fling a force-based cloth) and any stiffness.
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
    /// The default: chosen afresh each step between the two integrators that the work-precision
    /// benchmark (docs/accuracy.md) puts on the best front. [`Verlet`](Self::Verlet) errs
    /// 600–5,000× less than XPBD at equal run time wherever it is stable; XPBD is the one that
    /// runs below Verlet's stability bound, takes any stiffness and absorbs a teleported pin.
    ///
    /// Verlet runs when `substeps` are within its stability bound ([`ClothSim::stable_substeps`]),
    /// no pin jumps farther than the cloth's longest spring in the step and no spring is stretched
    /// by more than [`AUTO_MAX_STRETCH`] (a force-based integrator would release that energy as
    /// motion); XPBD runs otherwise, at the same `substeps`. So `substeps` is the one cost knob:
    /// at the default 20 a cloth of the default stiffness and mass at 60 Hz runs XPBD (fast,
    /// numerically damped: its swing errs 2e-3 of the cloth's size after 0.2 s); from its bound of
    /// 84 on it runs Verlet (1e-6). [`ClothSim::active_integrator`] tells which one a step used.
    #[default]
    Auto,
}

impl Integrator {
    /// The four integration methods, in declaration order ([`Integrator::Auto`] chooses among
    /// them).
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
            Integrator::Auto => "auto",
        }
    }

    /// Every setting of the enum: [`Integrator::Auto`] first, then [`Integrator::ALL`].
    pub const CHOICES: [Integrator; 5] = [
        Integrator::Auto,
        Integrator::Xpbd,
        Integrator::SymplecticEuler,
        Integrator::Verlet,
        Integrator::ImplicitEuler,
    ];

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
    /// implicit Euler, which are stable at any step, and by [`Integrator::Auto`], which runs Verlet
    /// only within the bound.
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
    /// Sleeping: a cloth whose free particles all move slower than this (m/s, measured as the
    /// displacement over a whole step divided by the step) for [`sleep_steps`](Self::sleep_steps)
    /// consecutive steps stops stepping until something wakes it (a moving pin or collider, a
    /// collider arriving or leaving, wind, or an edit). 0 disables it. Measuring over the step, not
    /// the last substep's velocity, keeps the rounding jitter of a cloth far from the origin (one
    /// f32 step of 15 µm at 200 m) below the default threshold.
    pub sleep_speed: f32,
    /// Consecutive quiet steps before a cloth falls asleep.
    pub sleep_steps: u32,
}

impl Default for SolverSettings {
    fn default() -> Self {
        Self {
            integrator: Integrator::Auto,
            substeps: 20,
            iterations: 1,
            auto_substeps: true,
            stiffness: Stiffness::default(),
            particle_mass: 0.001,
            damping: 0.5,
            gravity: Vec3::new(0.0, -9.81, 0.0),
            drag_coefficient: 1.0,
            lift_coefficient: 0.5,
            sleep_speed: 0.005,
            sleep_steps: 30,
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
        non_negative("sleep_speed", self.sleep_speed)?;
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
        (x[i], v[i]) = pin_motion(pin, t0, t1, inv_h);
    }
}

/// Adds to tracked contact work (see [`ClothSim::track_contact_work`]) what a contact response
/// raised the total energy by, from `before` to `after`, J.
pub(super) fn count_contact_work(work: &mut Option<f64>, before: f64, after: f64) {
    if let Some(work) = work {
        *work += (after - before).max(0.0);
    }
}

/// The largest length among `vectors` (0 for none).
fn max_length(vectors: &[Vec3]) -> f32 {
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

/// The storage order of a step's coordinate arrays (`soa`, `velocity_soa`): `order[s]` is the
/// particle stored at `s`, empty for the particles' own order. XPBD's layout chooses it; the other
/// integrators keep the particles' order.
fn storage_order(integrator: Integrator, projections: &Projections) -> &[u32] {
    if integrator == Integrator::Xpbd {
        projections.order()
    } else {
        &[]
    }
}

/// A pin's target at the end of the substep `[t0, t1]` (fractions of the step) of length
/// `1/inv_h`, and the velocity of its motion over the substep.
pub(super) fn pin_motion(pin: &PinState, t0: f32, t1: f32, inv_h: f32) -> (Vec3, Vec3) {
    let target = pin.from.lerp(pin.to, t1);
    // `from` is where the particle was when the step began (pins start where their particle is).
    (target, (target - pin.from.lerp(pin.to, t0)) * inv_h)
}

/// The energy of the free particles (inverse mass > 0), with `(mass, inverse mass)` per
/// particle, at positions `x` and velocities `v` (see [`Energy`]).
pub(super) fn energy_of(
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
    /// Positions during a step, one array per coordinate (scratch; see
    /// [`Self::load_soa_state`]).
    pub(super) soa: Soa,
    /// Particle velocities, m/s.
    pub(super) velocities: Vec<Vec3>,
    /// Particle masses, kg (whether pinned or not).
    pub(super) mass: Vec<f32>,
    /// Inverse masses, 1/kg (0 for pinned particles).
    pub(super) inv_mass: Vec<f32>,
    /// Per-spring stiffness `k` (N/m).
    pub(super) stiffness: Vec<f32>,
    /// Force accumulator of implicit Euler (scratch).
    pub(super) forces: Vec<Vec3>,
    /// All forces of the explicit integrators, one array per coordinate (scratch; empty for the
    /// other integrators).
    pub(super) force_sums: Soa,
    /// Velocities during a step, one array per coordinate (scratch; see
    /// [`Self::load_soa_state`]).
    pub(super) velocity_soa: Soa,
    /// XPBD's displacements of the current substep (scratch, see `xpbd::Split`).
    pub(super) displacement: Soa,
    /// The velocities contacts set in the current substep, by storage slot (scratch, at most one
    /// per particle; see `xpbd::AheadOfEnd`), and where each slot's is in that list (1 + its place;
    /// 0 for none).
    pub(super) contact_velocities: (Vec<(u32, Vec3)>, Vec<u32>),
    /// Test builds only: XPBD resolves contacts after a separate end pass, on the end state, as
    /// the reference for the contacts it resolves ahead of its fused pass.
    #[cfg(test)]
    pub(super) contacts_after_end: bool,
    /// The springs laid out for XPBD's vector kernel (empty until XPBD is the integrator). While
    /// it is, `soa` and `velocity_soa` are in the layout's storage order (see [`storage_order`]).
    pub(super) projections: Projections,
    /// The springs grouped for the explicit integrators' vector force kernel (empty for the others).
    pub(super) force_runs: ForceRuns,
    /// Linearised springs and conjugate-gradient vectors of implicit Euler; empty for the others.
    pub(super) implicit: ImplicitScratch,
    /// Gershgorin bound on the highest angular frequency of the springs, rad/s.
    pub(super) omega_max: f32,
    /// The longest spring's rest length, m: a pin moving farther in one step makes
    /// [`Integrator::Auto`] choose XPBD.
    longest_spring: f32,
    /// The integrator of the current (or last) step: the configured one, or
    /// [`Integrator::Auto`]'s choice.
    pub(super) active: Integrator,
    /// Colliders that passed this step's broad phase, and substep scratch for contacts.
    pub(super) contacts: Contacts,
    /// The wind at each triangle for this step.
    pub(super) wind: WindScratch,
    pub(super) pins: Vec<PinState>,
    pub(super) settings: SolverSettings,
    steps: u64,
    sleep: Sleep,
    /// Energy the contact responses added, J, when tracked (see [`Self::track_contact_work`]).
    pub(super) contact_work: Option<f64>,
    /// Positions at the start of the current step, for the sleep test (empty when sleeping is off).
    step_start: Vec<Vec3>,
    runaway: Runaway,
}

/// Steps of consecutive energy growth after which an explicit integrator past its stability limit
/// is declared unstable.
const RUNAWAY_STEPS: u32 = 5;
/// Growth per step of the kinetic plus elastic energy that counts towards a runaway.
const RUNAWAY_GROWTH: f64 = 1.5;

/// Energy watch for the explicit integrators when they run past `h ω_max < 2`.
#[derive(Debug, Clone, Copy, Default)]
struct Runaway {
    /// Kinetic plus elastic energy after the last step, J.
    energy: f64,
    /// Energy when the current streak of growth began, J.
    streak_start: f64,
    /// Consecutive steps in which the energy grew by at least [`RUNAWAY_GROWTH`].
    streak: u32,
}

/// The sleeping state of a cloth (see [`SolverSettings::sleep_speed`]).
#[derive(Debug, Clone, Copy, Default)]
struct Sleep {
    /// Consecutive steps with every free particle slower than the threshold.
    quiet_steps: u32,
    /// Asleep: steps are skipped until something wakes the cloth.
    asleep: bool,
    /// Colliders in reach when the cloth fell asleep (one arriving or leaving wakes it).
    colliders: usize,
    /// Whether the last step was skipped.
    skipped: bool,
    /// The cloth's bounding box while asleep.
    bounds: (Vec3, Vec3),
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
            soa: Soa::new(n),
            positions,
            velocities: vec![Vec3::ZERO; n],
            mass: vec![0.0; n],
            inv_mass: vec![0.0; n],
            stiffness: vec![0.0; springs],
            forces: vec![Vec3::ZERO; n],
            force_sums: Soa::default(),
            velocity_soa: Soa::new(n),
            displacement: Soa::new(n),
            contact_velocities: (Vec::with_capacity(n), vec![0; n]),
            #[cfg(test)]
            contacts_after_end: false,
            projections: Projections::default(),
            force_runs: ForceRuns::default(),
            implicit: ImplicitScratch::default(),
            omega_max: 0.0,
            longest_spring: model.springs.rest.iter().copied().fold(0.0, f32::max),
            active: settings.integrator,
            contacts: Contacts::new(n, model.max_edge_length()),
            wind: WindScratch::new(n, model.triangles.len() / 3),
            pins: Vec::new(),
            model,
            settings,
            steps: 0,
            sleep: Sleep::default(),
            contact_work: None,
            step_start: Vec::with_capacity(n),
            runaway: Runaway::default(),
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
        self.wake();
    }

    /// Wakes a sleeping cloth (see [`SolverSettings::sleep_speed`]); it steps again from the
    /// next step and may fall asleep again after `sleep_steps` quiet steps.
    pub fn wake(&mut self) {
        self.sleep = Sleep::default();
    }

    /// Whether the cloth is asleep: its steps are skipped until something wakes it.
    pub fn is_sleeping(&self) -> bool {
        self.sleep.asleep
    }

    /// Whether the last step was skipped because the cloth was asleep (its positions did not
    /// change).
    pub fn slept_last_step(&self) -> bool {
        self.sleep.skipped
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
        self.wake();
        Ok(())
    }

    /// Recomputes everything derived from settings, masses and pins: per-spring stiffness and
    /// compliance, inverse masses, the frequency bound, and (for implicit Euler) its scratch buffers.
    /// Runs at construction and on edits, never inside a step.
    fn apply_settings(&mut self) {
        let s = &self.model.springs;
        for (k, kind) in self.stiffness.iter_mut().zip(&s.kind) {
            *k = self.settings.stiffness.of(*kind);
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
        let chosen = self.settings.integrator;
        let auto = chosen == Integrator::Auto;
        if chosen == Integrator::ImplicitEuler && !self.implicit.fits(self.positions.len(), s.len())
        {
            self.implicit = ImplicitScratch::new(self.positions.len(), s.len());
        }
        if chosen.is_explicit() || auto {
            if !self.force_runs.fits(s.len()) || self.force_sums.len() != self.positions.len() {
                self.force_runs = ForceRuns::new(&s.a, &s.b);
                self.force_sums = Soa::new(self.positions.len());
            }
            self.force_runs.set_stiffness(&s.rest, &self.stiffness);
        }
        if chosen == Integrator::Xpbd || auto {
            if !self.projections.fits(s.len()) {
                self.projections = Projections::new(&self.model);
            }
            self.projections
                .set_constants(&s.rest, &self.stiffness, &self.inv_mass);
        }
        self.active = self.choose_integrator(1.0 / 60.0);
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
        n.max(self.stable_substeps(dt).min(MAX_SUBSTEPS))
    }

    /// The fewest substeps per step of `dt` seconds at which the explicit integrators are within
    /// their stability bound, `h ≤ STABILITY_FRACTION · 2/ω_max` (see
    /// [`max_frequency`](Self::max_frequency)); `u32::MAX` if no count is.
    pub fn stable_substeps(&self, dt: f32) -> u32 {
        let needed = (dt * self.omega_max / (2.0 * STABILITY_FRACTION)).ceil();
        if needed.is_finite() && needed < u32::MAX as f32 {
            (needed as u32).max(1)
        } else {
            u32::MAX
        }
    }

    /// The integrator the current (or last) step used: the configured one, or the one
    /// [`Integrator::Auto`] chose for it (before the first step, its choice for a step of 1/60 s).
    pub fn active_integrator(&self) -> Integrator {
        self.active
    }

    /// The method for a step of `dt`: the configured one, or [`Integrator::Auto`]'s choice.
    fn choose_integrator(&self, dt: f32) -> Integrator {
        let s = &self.settings;
        if s.integrator != Integrator::Auto {
            return s.integrator;
        }
        let jump = self
            .pins
            .iter()
            .any(|p| p.from.distance(p.to) > self.longest_spring);
        if self.stable_substeps(dt) <= s.substeps && !jump && !self.overstretched() {
            Integrator::Verlet
        } else {
            Integrator::Xpbd
        }
    }

    /// Whether a spring is stretched by more than [`AUTO_MAX_STRETCH`] of its rest length. A
    /// force-based integrator would release that elastic energy as motion (a teleported pin flings
    /// the cloth), so [`Integrator::Auto`] leaves such a state to XPBD until it has relaxed.
    fn overstretched(&self) -> bool {
        let s = &self.model.springs;
        let x = &self.positions;
        s.a.iter().zip(&s.b).zip(&s.rest).any(|((&a, &b), &rest)| {
            x[a as usize].distance_squared(x[b as usize])
                > (rest * (1.0 + AUTO_MAX_STRETCH)).powi(2)
        })
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

    /// Starts adding up the energy that contact responses put into the cloth: the increase of its
    /// total energy (kinetic, gravitational and elastic) across each response that raises it. A
    /// collider sweeping through a cloth stretches its springs and hands it its speed; the stress
    /// suite allows the cloth that energy. Costs an energy evaluation (one pass over the springs)
    /// before and after each substep's contact response.
    pub(crate) fn track_contact_work(&mut self) {
        self.contact_work.get_or_insert(0.0);
    }

    /// The energy added up since [`track_contact_work`](Self::track_contact_work), J (`None` when
    /// not tracking).
    pub(crate) fn contact_work(&self) -> Option<f64> {
        self.contact_work
    }

    /// Kinetic, gravitational and elastic energy of the free particles (see [`Energy`]).
    pub fn energy(&self) -> Energy {
        energy_of(
            self.spring_set(),
            (&self.mass, &self.inv_mass),
            self.settings.gravity,
            &self.positions,
            &self.velocities,
        )
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
        self.wake();
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
        self.step_spread(dt, env, None)
    }

    /// [`Self::step_in`] with another thread from `spread`: XPBD projects each colour of a large
    /// cloth (about 20,000 springs or more) in two shares at once. The result is bit-identical to
    /// [`Self::step_in`]'s; other integrators and smaller cloths ignore `spread`.
    pub fn step_in_parallel(
        &mut self,
        dt: f32,
        env: &Environment,
        spread: &dyn Spread,
    ) -> Result<(), ClothError> {
        self.step_spread(dt, env, Some(spread))
    }

    fn step_spread(
        &mut self,
        dt: f32,
        env: &Environment,
        spread: Option<&dyn Spread>,
    ) -> Result<(), ClothError> {
        if !(dt.is_finite() && dt > 0.0) {
            return Ok(());
        }
        self.active = self.choose_integrator(dt);
        let substeps = self.substeps_for(dt);
        if env.colliders.is_empty() {
            self.contacts
                .begin_step(&[], 0, (Vec3::ONE, Vec3::ZERO), 0.0, dt);
        } else {
            // Asleep, the cloth has not moved since it fell asleep: its box is kept, and every
            // particle is slower than the sleep threshold.
            let (bounds, reach) = if self.sleep.asleep {
                (
                    self.sleep.bounds,
                    self.reach_bound(dt, self.settings.sleep_speed),
                )
            } else {
                let speed = max_length(&self.velocities);
                // Never below the sleep threshold, so that falling asleep does not change which
                // colliders are in reach.
                let speed = speed.max(self.settings.sleep_speed);
                (bounds(&self.positions), self.reach_bound(dt, speed))
            };
            self.contacts
                .begin_step(env.colliders, env.collision_mask, bounds, reach, dt);
        }
        if self.sleeps_through(env) {
            self.steps += 1;
            self.sleep.skipped = true;
            return Ok(());
        }
        self.sleep.skipped = false;
        if self.settings.sleep_speed > 0.0 {
            self.step_start.clear();
            self.step_start.extend_from_slice(&self.positions);
        }
        self.wind.begin_step(
            env.wind,
            (
                self.settings.drag_coefficient,
                self.settings.lift_coefficient,
            ),
            &self.positions,
            &self.velocities,
            (&self.inv_mass, dt),
            &self.model.triangles,
        );
        match self.active {
            // `choose_integrator` never leaves `Auto` active.
            Integrator::Xpbd | Integrator::Auto => xpbd::step_xpbd(self, dt, substeps, spread),
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
        self.check_runaway(dt, substeps)?;
        self.update_sleep(env, dt);
        Ok(())
    }

    /// For an explicit integrator run past its stability bound (`h ω_max ≥ 2`, possible with
    /// `auto_substeps` off or at [`MAX_SUBSTEPS`]): an error once the kinetic plus elastic energy
    /// has grown by [`RUNAWAY_GROWTH`]× in each of [`RUNAWAY_STEPS`] consecutive steps, the
    /// signature of an unstable mode (gravity, pins or wind add energy far more slowly). Within
    /// the bound this costs nothing.
    fn check_runaway(&mut self, dt: f32, substeps: u32) -> Result<(), ClothError> {
        let h = dt / substeps as f32;
        let h_omega = h * self.omega_max;
        if !(self.active.is_explicit() && h_omega >= 2.0) {
            self.runaway = Runaway::default();
            return Ok(());
        }
        let e = self.energy();
        let energy = e.kinetic + e.elastic;
        let r = &mut self.runaway;
        if energy > RUNAWAY_GROWTH * r.energy && energy > 1e-12 {
            if r.streak == 0 {
                r.streak_start = r.energy.max(f64::MIN_POSITIVE);
            }
            r.streak += 1;
        } else {
            r.streak = 0;
        }
        r.energy = energy;
        if r.streak >= RUNAWAY_STEPS {
            return Err(ClothError::Unstable {
                integrator: self.active.name(),
                step: self.steps,
                h,
                omega_max: self.omega_max,
                h_omega,
                substeps_needed: (dt * self.omega_max / (2.0 * STABILITY_FRACTION)).ceil() as u32,
                growth: energy / r.streak_start,
                steps: r.streak,
            });
        }
        Ok(())
    }

    /// Whether this step can be skipped: the cloth is asleep and nothing wakes it (no pin moves,
    /// no wind, no collider in reach moves, arrives or leaves). Runs after the broad phase.
    fn sleeps_through(&mut self, env: &Environment) -> bool {
        if !self.sleep.asleep {
            return false;
        }
        let disturbed = env.wind.is_some()
            || self.pins.iter().any(|p| p.from != p.to)
            || self.contacts.any_moving()
            || self.contacts.active_count() != self.sleep.colliders;
        if disturbed {
            self.wake();
            return false;
        }
        true
    }

    /// Counts quiet steps after a step that ran, and puts the cloth to sleep after enough of them.
    fn update_sleep(&mut self, env: &Environment, dt: f32) {
        let threshold = self.settings.sleep_speed;
        if threshold <= 0.0 || env.wind.is_some() || self.pins.iter().any(|p| p.from != p.to) {
            self.sleep.quiet_steps = 0;
            return;
        }
        let limit = threshold * dt;
        // Far from the origin f32 cannot hold a cloth's springs at their rest lengths, and a
        // cloth at rest there jitters by a few of its positions' representable steps: that much
        // movement counts as quiet too.
        let quiet = self
            .positions
            .iter()
            .zip(&self.step_start)
            .zip(&self.inv_mass)
            .all(|((x, x0), w)| {
                let jitter = 4.0 * f32::EPSILON * x0.abs().max_element();
                *w == 0.0 || x.distance_squared(*x0) < (limit + jitter).powi(2)
            });
        self.sleep.quiet_steps = if quiet { self.sleep.quiet_steps + 1 } else { 0 };
        if self.sleep.quiet_steps >= self.settings.sleep_steps {
            self.sleep.asleep = true;
            self.sleep.colliders = self.contacts.active_count();
            self.sleep.bounds = bounds(&self.positions);
        }
    }

    /// A generous bound on how far any particle can move in a step of `dt` when none is faster
    /// than `speed`: twice its free flight, plus gravity, plus the farthest pin jump.
    fn reach_bound(&self, dt: f32, speed: f32) -> f32 {
        let pin_jump = self
            .pins
            .iter()
            .map(|p| p.from.distance(p.to))
            .fold(0.0, f32::max);
        2.0 * speed * dt + self.settings.gravity.length() * dt * dt + pin_jump
    }

    /// Copies the state into one array per coordinate for a step: positions into `soa`,
    /// velocities into `velocity_soa`, where the integrators' particle loops are vector code. The
    /// step works there and copies it back with [`Self::store_soa_state`] at its end and around
    /// the contact response (which works on the vectors).
    pub(super) fn load_soa_state(&mut self) {
        let order = storage_order(self.active, &self.projections);
        self.soa.load_ordered(&self.positions, order);
        self.velocity_soa.load_ordered(&self.velocities, order);
    }

    /// Copies the state back from `soa` and `velocity_soa` (see [`Self::load_soa_state`]).
    pub(super) fn store_soa_state(&mut self) {
        let order = storage_order(self.active, &self.projections);
        self.soa.write_ordered(&mut self.positions, order);
        self.velocity_soa.write_ordered(&mut self.velocities, order);
    }

    /// Whether XPBD resolves contacts after its end pass (a test-only reference path; see
    /// `contacts_after_end`).
    pub(super) fn contacts_after_end(&self) -> bool {
        #[cfg(test)]
        return self.contacts_after_end;
        #[cfg(not(test))]
        false
    }

    /// Where particle `p` is stored in `soa` and `velocity_soa` (see [`storage_order`]).
    pub(super) fn soa_index(&self, p: u32) -> usize {
        if self.active == Integrator::Xpbd {
            self.projections.stored(p) as usize
        } else {
            p as usize
        }
    }

    /// Where a substep begins, for the contact response's swept tests: recorded in `displacement`
    /// by the explicit integrators (XPBD's displacement is already the record, see
    /// [`Self::resolve_soa_contacts`]).
    pub(super) fn begin_soa_substep(&mut self) {
        if self.contacts.is_active() {
            self.displacement.copy_from(&self.soa);
        }
    }

    /// Contacts at the end of substep `sub` of `n` (length `h`), after the integrator has its
    /// final positions and velocities for the substep, in `soa` and `velocity_soa`. The response
    /// works on them in place ([`SoaContacts`]), with `displacement` holding each particle's
    /// displacement over the substep: XPBD's own, or for the other integrators the difference from
    /// the start [`Self::begin_soa_substep`] recorded.
    pub(super) fn resolve_soa_contacts(&mut self, sub: u32, n: u32, h: f32) {
        if !self.contacts.is_active() {
            return;
        }
        let xpbd = self.active == Integrator::Xpbd;
        if !xpbd {
            let (x, d) = (&self.soa, &mut self.displacement);
            for (x, d) in [(&x.x, &mut d.x), (&x.y, &mut d.y), (&x.z, &mut d.z)] {
                for (x, d) in x.iter().zip(d.iter_mut()) {
                    *d = *x - *d;
                }
            }
        }
        let energy = |sim: &mut Self| {
            sim.contact_work.map(|_| {
                sim.store_soa_state();
                sim.energy().total()
            })
        };
        let before = energy(self);
        let mut state = SoaContacts {
            x: &mut self.soa,
            v: &mut self.velocity_soa,
            d: &mut self.displacement,
            inv_mass: if xpbd {
                self.projections.inv_mass()
            } else {
                &self.inv_mass
            },
            layout: xpbd.then_some(&self.projections),
        };
        let (t0, t1) = (sub as f32 / n as f32, (sub + 1) as f32 / n as f32);
        self.contacts
            .resolve_state((t0, t1, h), &self.model.triangles, &mut state);
        if let (Some(before), Some(after)) = (before, energy(self)) {
            count_contact_work(&mut self.contact_work, before, after);
        }
    }

    /// Moves the pinned particles to their targets at the end of substep `[t0, t1]` (fractions of
    /// the step) of length `1/inv_h`, with the velocity of that motion (state in `soa` and
    /// `velocity_soa`).
    pub(super) fn drive_soa_pins(&mut self, t0: f32, t1: f32, inv_h: f32) {
        for pin in &self.pins {
            let (target, velocity) = pin_motion(pin, t0, t1, inv_h);
            let i = self.soa_index(pin.particle);
            self.soa.set(i, target);
            self.velocity_soa.set(i, velocity);
        }
    }
}

/// A step's coordinate arrays as the contact response's state (see
/// [`ClothSim::resolve_soa_contacts`]): positions `x`, velocities `v` and displacements `d` over
/// the substep, so a particle started at `x − d`. Moving a particle moves its displacement with it,
/// so its start stays put.
struct SoaContacts<'a> {
    x: &'a mut Soa,
    v: &'a mut Soa,
    d: &'a mut Soa,
    /// Inverse masses in storage order.
    inv_mass: &'a [f32],
    /// XPBD's layout, whose storage order the arrays are in; `None`: the particles' own order.
    layout: Option<&'a Projections>,
}

impl ContactState for SoaContacts<'_> {
    fn len(&self) -> usize {
        self.x.len()
    }
    fn inv_mass(&self, i: usize) -> f32 {
        self.inv_mass[i]
    }
    fn slot(&self, p: u32) -> usize {
        self.layout.map_or(p, |l| l.stored(p)) as usize
    }
    fn start(&self, i: usize) -> Vec3 {
        self.x.get(i) - self.d.get(i)
    }
    fn position(&self, i: usize) -> Vec3 {
        self.x.get(i)
    }
    fn velocity(&self, i: usize) -> Vec3 {
        self.v.get(i)
    }
    fn set(&mut self, i: usize, x: Vec3, v: Vec3) {
        self.d.set(i, self.d.get(i) + (x - self.x.get(i)));
        self.x.set(i, x);
        self.v.set(i, v);
    }
    fn clearances(&self, near: Near, out: &mut [f32]) {
        soa_clearances::<false>(self.x, self.d, near, out);
    }
}

/// [`ContactState::clearances`] of particles displaced by `d` over the substep: ending at `x`, or
/// with `AHEAD` starting at `x` (and ending at `x + d`). On x86-64 CPUs with AVX2 the loop runs as
/// 8-wide vectors; the results are the same.
pub(super) fn soa_clearances<const AHEAD: bool>(x: &Soa, d: &Soa, near: Near, out: &mut [f32]) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports the feature the function is compiled for (checked above).
        unsafe { clearances_avx2::<AHEAD>(x, d, near, out) };
        return;
    }
    clearances_body::<AHEAD>(x, d, near, out);
}

/// [`clearances_body`] compiled for AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn clearances_avx2<const AHEAD: bool>(x: &Soa, d: &Soa, near: Near, out: &mut [f32]) {
    clearances_body::<AHEAD>(x, d, near, out);
}

#[inline(always)]
fn clearances_body<const AHEAD: bool>(x: &Soa, d: &Soa, near: Near, out: &mut [f32]) {
    let n = out.len().min(x.len()).min(d.len());
    let (x, y, z) = (&x.x[..n], &x.y[..n], &x.z[..n]);
    let (dx, dy, dz) = (&d.x[..n], &d.y[..n], &d.z[..n]);
    let moved = |i: usize| (dx[i] * dx[i] + dy[i] * dy[i] + dz[i] * dz[i]).sqrt();
    let end = |x: &[f32], d: &[f32], i: usize| if AHEAD { x[i] + d[i] } else { x[i] };
    match near {
        Near::Point(c) => {
            for (i, o) in out[..n].iter_mut().enumerate() {
                let (ex, ey, ez) = (
                    end(x, dx, i) - c.x,
                    end(y, dy, i) - c.y,
                    end(z, dz, i) - c.z,
                );
                *o = (ex * ex + ey * ey + ez * ez).sqrt() - moved(i);
            }
        }
        Near::Plane(c, normal) => {
            for (i, o) in out[..n].iter_mut().enumerate() {
                let along = (end(x, dx, i) - c.x) * normal.x
                    + (end(y, dy, i) - c.y) * normal.y
                    + (end(z, dz, i) - c.z) * normal.z;
                *o = along - moved(i);
            }
        }
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
    fn contacts_on_the_coordinate_arrays_match_contacts_on_vectors() {
        use crate::sim::collision::{ColliderShape, Friction, Pose};
        use bevy::math::primitives::Sphere;
        // A 40×12 grid (stored in XPBD's grid order), jostled, against a sphere smaller than its
        // edges (so triangles are tested too) and a large one, with every tenth particle pinned.
        let model = ClothModel::grid(&GridSpec::new(40, 12, 0.05)).unwrap();
        let layout = Projections::new(&model);
        assert!(!layout.order().is_empty(), "the grid order is in use");
        let n = model.particle_count();
        let wobble = |i: usize, k: usize| ((i * 7 + k * 13) % 17) as f32 / 17.0 - 0.5;
        let start: Vec<Vec3> = model.rest_positions.clone();
        let end: Vec<Vec3> = (0..n)
            .map(|i| start[i] + 0.02 * Vec3::new(wobble(i, 0), wobble(i, 1) - 0.6, wobble(i, 2)))
            .collect();
        let velocity: Vec<Vec3> = (0..n).map(|i| Vec3::new(wobble(i, 3), -1.0, 0.0)).collect();
        let inv_mass: Vec<f32> = (0..n)
            .map(|i| if i % 10 == 0 { 0.0 } else { 2.0 })
            .collect();
        let (lo, hi) = bounds(&start);
        let centre = 0.5 * (lo + hi);
        let sphere = |r: f32, at: Vec3| {
            Collider::fixed(
                ColliderShape::Sphere(Sphere::new(r)),
                Pose::from_translation(at),
                Friction::new(0.3),
                0.005,
            )
        };
        let colliders = [
            sphere(0.02, centre - 0.012 * Vec3::Y),
            sphere(0.3, centre + Vec3::new(0.6, -0.27, 0.0)),
        ];
        let mut contacts = Contacts::new(n, model.max_edge_length());
        contacts.begin_step(&colliders, u32::MAX, (lo, hi), 0.1, 1.0 / 60.0);
        assert_eq!(contacts.active_count(), 2);
        let t = (0.0, 0.05, 1.0 / 1200.0);

        let (mut x, mut v) = (end.clone(), velocity.clone());
        contacts.begin_substep(&start);
        contacts.resolve(t.0, t.1, t.2, &model.triangles, &inv_mass, &mut x, &mut v);

        let order = layout.order();
        let mut soa = [Soa::new(n), Soa::new(n), Soa::new(n)];
        soa[0].load_ordered(&end, order);
        soa[1].load_ordered(&velocity, order);
        let moved: Vec<Vec3> = (0..n).map(|i| end[i] - start[i]).collect();
        soa[2].load_ordered(&moved, order);
        let stored_mass: Vec<f32> = order.iter().map(|&i| inv_mass[i as usize]).collect();
        let [xs, vs, ds] = &mut soa;
        let mut state = SoaContacts {
            x: xs,
            v: vs,
            d: ds,
            inv_mass: &stored_mass,
            layout: Some(&layout),
        };
        contacts.resolve_state(t, &model.triangles, &mut state);

        let mut touched = 0;
        for p in 0..n {
            let s = layout.stored(p as u32) as usize;
            let close = |a: Vec3, b: Vec3| (a - b).length() <= 1e-5 * b.length().max(1.0);
            assert!(close(soa[0].get(s), x[p]), "position of {p}");
            assert!(close(soa[1].get(s), v[p]), "velocity of {p}");
            assert!(
                close(soa[0].get(s) - soa[2].get(s), start[p]),
                "start of {p}"
            );
            touched += usize::from(x[p] != end[p]);
        }
        assert!(touched > 20, "{touched} particles in contact");
    }

    #[test]
    fn auto_runs_verlet_within_its_stability_bound_and_xpbd_otherwise() {
        let dt = 1.0 / 60.0;
        let build = |integrator, substeps, structural| {
            let settings = SolverSettings {
                integrator,
                substeps,
                auto_substeps: false,
                stiffness: Stiffness {
                    structural,
                    ..Stiffness::default()
                },
                ..Default::default()
            };
            let mut s = sim(16, settings);
            s.set_pins([(0, s.positions()[0]), (15, s.positions()[15])])
                .unwrap();
            s
        };
        let bound = build(Integrator::Auto, 20, 5_000.0).stable_substeps(dt);
        assert!(bound > 20 && bound < 1_000, "bound {bound}");
        // Below the bound Auto is XPBD, from it on Verlet: the same steps, bit for bit.
        for (substeps, method) in [(bound - 1, Integrator::Xpbd), (bound, Integrator::Verlet)] {
            let mut auto = build(Integrator::Auto, substeps, 5_000.0);
            let mut plain = build(method, substeps, 5_000.0);
            for _ in 0..20 {
                auto.step(dt).unwrap();
                plain.step(dt).unwrap();
                assert_eq!(auto.active_integrator(), method);
            }
            assert_eq!(auto.positions(), plain.positions(), "{substeps} substeps");
            assert_eq!(auto.velocities(), plain.velocities());
        }
        // A pin jumping farther than the longest spring: XPBD for that step, and on while a
        // spring is stretched by more than `AUTO_MAX_STRETCH`; then Verlet again.
        let mut auto = build(Integrator::Auto, bound, 5_000.0);
        auto.step(dt).unwrap();
        assert_eq!(auto.active_integrator(), Integrator::Verlet);
        let (a, b) = (auto.positions()[0], auto.positions()[15]);
        auto.move_pins([a + Vec3::X, b + Vec3::X]);
        auto.step(dt).unwrap();
        assert_eq!(auto.active_integrator(), Integrator::Xpbd);
        assert!(auto.overstretched(), "the jump leaves springs stretched");
        let mut steps = 0;
        while auto.active_integrator() == Integrator::Xpbd && steps < 600 {
            auto.step(dt).unwrap();
            steps += 1;
        }
        assert_eq!(
            auto.active_integrator(),
            Integrator::Verlet,
            "{steps} steps"
        );
        // Too stiff for any affordable substep count: XPBD.
        let mut stiff = build(Integrator::Auto, bound, 1e9);
        stiff.step(dt).unwrap();
        assert_eq!(stiff.active_integrator(), Integrator::Xpbd);
        assert!(stiff.stable_substeps(dt) > MAX_SUBSTEPS);
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
    fn explicit_integrators_past_their_limit_are_stopped_with_the_limit_named() {
        for integrator in [Integrator::SymplecticEuler, Integrator::Verlet] {
            let mut s = sim(
                8,
                SolverSettings {
                    integrator,
                    substeps: 1,
                    auto_substeps: false,
                    ..Default::default()
                },
            );
            let pins = [(0, s.positions()[0]), (7, s.positions()[7])];
            s.set_pins(pins).unwrap();
            let err = (0..200)
                .find_map(|_| s.step(1.0 / 60.0).err())
                .expect("the runaway is detected");
            assert!(matches!(err, ClothError::Unstable { .. }), "{err}");
            assert!(err.to_string().contains("past the limit 2"), "{err}");
            assert!(s.positions().iter().all(|p| p.is_finite()));
            // Within the bound the same cloth runs on.
            let mut s = sim(
                8,
                SolverSettings {
                    integrator,
                    ..Default::default()
                },
            );
            s.set_pins(pins).unwrap();
            for _ in 0..200 {
                s.step(1.0 / 60.0).unwrap();
            }
        }
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
