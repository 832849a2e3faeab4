//! [`ClothSim`]: a simulated cloth, its model, settings, particle state, pins and steppers,
//! stepped among the colliders and air of an [`Environment`]; it chooses the integrator
//! ([`Integrator::Auto`]) and the substeps (or, in tolerance mode, `adaptive` does, from error
//! estimates on a copy of the cloth), puts a quiet cloth to sleep, and stops a runaway one.
//!
//! Plain data in, plain data out: no ECS types, no allocation inside [`ClothSim::step`]. Every
//! buffer a step touches is sized when the cloth is built (or when pins or settings change).

use glam::Vec3;

use super::contact::{
    Collider, Contacts, OtherCloth, Pose, Reaction, SelfContacts, Target, bounds,
};
use super::forces::{SpringSet, max_frequency_bound};
use super::integrate::{Spread, Step, Steppers, add_contact_work};
use super::model::{ClothModel, SpringKind};
use super::settings::{
    AUTO_MAX_STRETCH, Integrator, MAX_SUBSTEPS, NONLINEAR_STABILITY_FRACTION, STABILITY_FRACTION,
    SolverSettings,
};
use super::state::{Energy, Particles, PinState, first_not_finite, max_length};
use super::wind::{WindField, WindScratch};
use crate::error::ClothError;

mod adaptive;
#[cfg(test)]
mod tests;

pub use adaptive::AccuracyReport;

/// A simulated cloth: its model, particle state (structure of arrays) and pins.
///
/// Positions are in world space. Pinned particles have inverse mass 0 and move to their target,
/// linearly interpolated across the substeps of a step.
#[derive(Debug, Clone)]
pub struct ClothSim {
    model: ClothModel,
    settings: SolverSettings,
    /// Positions, velocities and masses.
    particles: Particles,
    /// Per-spring stiffness `k` (N/m).
    stiffness: Vec<f32>,
    pins: Vec<PinState>,
    /// Each integrator's stepper and scratch.
    pub(super) steppers: Steppers,
    /// Gershgorin bound on the highest angular frequency of the springs, rad/s.
    omega_max: f32,
    /// The longest spring's rest length, m: a pin moving farther in one step makes
    /// [`Integrator::Auto`] choose XPBD.
    longest_spring: f32,
    /// The integrator of the current (or last) step: the configured one, or
    /// [`Integrator::Auto`]'s choice.
    active: Integrator,
    /// Colliders that passed this step's broad phase, and substep scratch for contacts.
    contacts: Contacts,
    /// The wind at each triangle for this step.
    wind: WindScratch,
    steps: u64,
    sleep: Sleep,
    /// Energy the contact responses added, J, when tracked (see [`Self::track_contact_work`]).
    contact_work: Option<f64>,
    /// Positions at the start of the current step, for the sleep test and the broad phase's
    /// catch-up (empty when neither needs them).
    step_start: Vec<Vec3>,
    runaway: Runaway,
    /// The reference frame's pose at the start and end of the next step (see
    /// [`Self::move_frame`]).
    frame: Option<(Pose, Pose)>,
    /// Tolerance mode's copy and controller ([`SolverSettings::accuracy`]); `None` with fixed
    /// substeps.
    adaptive: Option<Box<adaptive::Adaptive>>,
}

/// Steps of consecutive energy growth after which an explicit integrator past its stability limit
/// is declared unstable.
const RUNAWAY_STEPS: u32 = 5;
/// Growth per step of the kinetic plus elastic energy that counts towards a runaway.
const RUNAWAY_GROWTH: f64 = 1.5;
/// Growth of the kinetic plus elastic energy within one step that is a runaway by itself.
const RUNAWAY_STEP_GROWTH: f64 = 1e6;
/// Growth of the kinetic plus elastic energy over a run of steps past the bound that is a runaway
/// however slowly it grew (a mode near the bound's edge, or growth interrupted now and then).
const RUNAWAY_PAST_GROWTH: f64 = 1e3;

/// Energy watch for the explicit integrators when they run past their stability bound.
#[derive(Debug, Clone, Copy, Default)]
struct Runaway {
    /// Kinetic plus elastic energy after the last step, J.
    energy: f64,
    /// Energy when the current streak of growth began, J.
    streak_start: f64,
    /// Consecutive steps in which the energy grew by at least [`RUNAWAY_GROWTH`].
    streak: u32,
    /// Kinetic plus elastic energy at the start of the current step, J (past the bound only).
    before: f64,
    /// Kinetic plus elastic energy when the current run of steps past the bound began, J, and
    /// that step's number; `None` within the bound.
    entered: Option<(f64, u64)>,
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

/// Diagnostics of a cloth's self-contacts ([`ClothSim::self_contact_stats`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SelfContactStats {
    /// Vertex–triangle pairs the last broad phase found close enough to meet before the next.
    pub vertex_triangle: usize,
    /// Edge–edge pairs the last broad phase found.
    pub edge_edge: usize,
    /// Broad phases run since self-collision was turned on (or its thickness or friction
    /// changed): none while the particles stay within the last one's reach (a cloth at rest),
    /// several within a step while the cloth's parts move fast relative to each other.
    pub searches: u64,
    /// Substeps whose pairs were resolved since self-collision was turned on: every substep
    /// while the cloth's parts move relative to each other, a few a step while it rests folded
    /// or piled (its layers approach too slowly to need more).
    pub resolutions: u64,
}

/// What surrounds a cloth during one step: colliders (their poses at the start and end of the step),
/// which of them this cloth collides with, and the air.
#[derive(Debug, Clone, Copy)]
pub struct Environment<'a> {
    /// Colliders near or far; the broad phase drops the ones the cloth cannot reach.
    pub colliders: &'a [Collider],
    /// The cloth collides with a collider when [`Collider::touches`] this mask.
    pub collision_mask: u32,
    /// The air; `None` means no aerodynamic forces at all (not even drag in still air).
    pub wind: Option<&'a WindField>,
    /// Whether colliders with a body ([`Collider::inv_mass`] above 0) give way to the cloth
    /// within the step (two-way coupling); otherwise every collider moves as given.
    pub two_way: bool,
    /// Other cloths this cloth keeps its distance from (see [`OtherCloth`]); the broad phase
    /// drops the ones it cannot reach, and invalid ones are ignored.
    pub cloths: &'a [OtherCloth<'a>],
}

impl Default for Environment<'_> {
    /// Nothing around: no colliders, every layer, no air.
    fn default() -> Self {
        Self {
            colliders: &[],
            collision_mask: u32::MAX,
            wind: None,
            two_way: false,
            cloths: &[],
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
        // The steppers' vector kernels and threads rely on a consistent model (indices in range,
        // a proper colouring, a truthful grid): checked here, where every model enters.
        model.validate()?;
        let n = model.particle_count();
        let positions: Vec<Vec3> = model.rest_positions.iter().map(|p| to_world(*p)).collect();
        if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
            return Err(ClothError::InvalidMesh {
                what: format!("vertex {i} has a non-finite world position"),
            });
        }
        let springs = model.springs.len();
        let mut sim = Self {
            particles: Particles {
                positions,
                velocities: vec![Vec3::ZERO; n],
                mass: vec![0.0; n],
                inv_mass: vec![0.0; n],
            },
            stiffness: vec![0.0; springs],
            steppers: Steppers::default(),
            omega_max: 0.0,
            longest_spring: model.springs.rest.iter().copied().fold(0.0, f32::max),
            active: settings.integrator,
            contacts: Contacts::new(n, model.max_edge_length()),
            wind: WindScratch::new(&model),
            pins: Vec::new(),
            model,
            settings,
            steps: 0,
            sleep: Sleep::default(),
            contact_work: None,
            step_start: Vec::with_capacity(n),
            runaway: Runaway::default(),
            frame: None,
            adaptive: None,
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
        &self.particles.positions
    }

    /// Current particle velocities.
    pub fn velocities(&self) -> &[Vec3] {
        &self.particles.velocities
    }

    /// Sets every particle's velocity (for tests and initial conditions). A velocity that is not
    /// finite is [`ClothError::InvalidValue`] and changes nothing.
    pub fn set_velocities(&mut self, velocity: Vec3) -> Result<(), ClothError> {
        if let Some(&bad) = velocity.to_array().iter().find(|c| !c.is_finite()) {
            return Err(ClothError::InvalidValue {
                field: "velocity",
                expected: "finite",
                value: bad as f64,
            });
        }
        self.particles.velocities.fill(velocity);
        self.wake();
        Ok(())
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

    /// Recomputes everything derived from settings, masses and pins: per-spring stiffness,
    /// inverse masses, the frequency bound, and the steppers the integrator may run (their
    /// layouts, constants and scratch, [`Steppers::prepare`]). Runs at construction and on edits,
    /// never inside a step.
    fn apply_settings(&mut self) {
        let s = &self.model.springs;
        for (k, kind) in self.stiffness.iter_mut().zip(&s.kind) {
            *k = self.settings.stiffness.of(*kind);
        }
        let p = &mut self.particles;
        for (i, (m, w)) in p.mass.iter_mut().zip(&mut p.inv_mass).enumerate() {
            *m = self.model.mass_of(i, self.settings.particle_mass);
            *w = 1.0 / *m;
        }
        for pin in &self.pins {
            p.inv_mass[pin.particle as usize] = 0.0;
        }
        let pinned: Vec<bool> = p.inv_mass.iter().map(|w| *w == 0.0).collect();
        let limits = self.contacts.limits_mut();
        limits.set_settings(self.settings.targets);
        limits.set_tethers(
            self.settings.tethers,
            (&self.model.triangles, &self.model.rest_positions),
            &pinned,
        );
        let mut scratch = vec![0.0; self.particles.positions.len()];
        self.omega_max =
            max_frequency_bound(self.spring_set(), &self.particles.inv_mass, &mut scratch);
        self.prepare_self_contacts();
        // Tolerance mode chooses between XPBD and Verlet, as `Auto` does.
        let integrator = if self.settings.accuracy.tolerance.is_some() {
            Integrator::Auto
        } else {
            self.settings.integrator
        };
        self.steppers.prepare(
            integrator,
            &self.model,
            (&self.stiffness, &self.particles.inv_mass),
            self.contacts.limits(),
        );
        self.active = self.choose_integrator(1.0 / 60.0);
        // The copy tolerance mode estimates on is made of this cloth without its own copy.
        self.adaptive = None;
        self.adaptive = adaptive::Adaptive::new(self).map(Box::new);
        if let Some(a) = &self.adaptive {
            self.active = a.report().integrator;
        }
    }

    /// Builds the self-contacts' topology and exempt pairs when self-collision is turned on or its
    /// thickness changes, and drops them when it is turned off.
    fn prepare_self_contacts(&mut self) {
        let c = self.settings.self_collision;
        if !c.enabled {
            self.contacts.set_self_contacts(None);
            return;
        }
        if self.contacts.self_contacts().map(|s| s.settings()) == Some((c.thickness, c.friction)) {
            return;
        }
        self.contacts.set_self_contacts(Some(SelfContacts::new(
            &self.model.triangles,
            &self.model.rest_positions,
            c.thickness,
            c.friction,
        )));
    }

    /// The springs with their current stiffness, for the force kernel.
    fn spring_set(&self) -> SpringSet<'_> {
        SpringSet::new(&self.model.springs, &self.stiffness)
    }

    /// An upper bound on the highest angular frequency of the cloth's springs about rest, in rad/s
    /// (Gershgorin's bound from each free particle's springs and mass; pins count as infinite mass).
    /// Explicit integrators need a substep `h < 2/ω_max`.
    pub fn max_frequency(&self) -> f32 {
        self.omega_max
    }

    /// Number of substeps a step of `dt` seconds takes: `substeps`, raised to the stability bound
    /// for the explicit integrators when [`SolverSettings::auto_substeps`] is on, and at most
    /// [`MAX_SUBSTEPS`]. While a spring is stretched by more than [`AUTO_MAX_STRETCH`], the bound
    /// is taken at [`NONLINEAR_STABILITY_FRACTION`] instead.
    ///
    /// In tolerance mode ([`SolverSettings::accuracy`]), the count its controller chose for the
    /// next step.
    pub fn substeps_for(&self, dt: f32) -> u32 {
        match &self.adaptive {
            Some(a) => a.substeps(),
            None => self.substep_plan(dt).0,
        }
    }

    /// What tolerance mode ([`SolverSettings::accuracy`]) chose and estimated; `None` with fixed
    /// substeps.
    pub fn accuracy_report(&self) -> Option<AccuracyReport> {
        self.adaptive.as_ref().map(|a| a.report())
    }

    /// [`Self::substeps_for`], and the substeps the explicit integrators' bound asks for (the
    /// configured count for the others, or with `auto_substeps` off), which may exceed
    /// [`MAX_SUBSTEPS`].
    fn substep_plan(&self, dt: f32) -> (u32, u32) {
        let n = self.settings.substeps;
        if !(self.settings.auto_substeps && self.settings.integrator.is_explicit()) {
            return (n, n);
        }
        let fraction = if self.overstretched() {
            NONLINEAR_STABILITY_FRACTION
        } else {
            STABILITY_FRACTION
        };
        let wanted = n.max(self.substeps_within(dt, fraction));
        (wanted.min(MAX_SUBSTEPS), wanted)
    }

    /// The fewest substeps per step of `dt` seconds at which the explicit integrators are within
    /// their stability bound, `h ≤ STABILITY_FRACTION · 2/ω_max` (see
    /// [`max_frequency`](Self::max_frequency)); `u32::MAX` if no count is.
    pub fn stable_substeps(&self, dt: f32) -> u32 {
        self.substeps_within(dt, STABILITY_FRACTION)
    }

    /// The fewest substeps per step of `dt` seconds with `h ≤ fraction · 2/ω_max`; `u32::MAX` if
    /// no count is.
    fn substeps_within(&self, dt: f32, fraction: f32) -> u32 {
        let needed = (dt * self.omega_max / (2.0 * fraction)).ceil();
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
        if self.stable_substeps(dt) <= s.substeps && !self.needs_xpbd() {
            Integrator::Verlet
        } else {
            Integrator::Xpbd
        }
    }

    /// Whether the next step is one for XPBD whatever the substeps: a pin jumps farther than the
    /// cloth's longest spring, or a spring is overstretched.
    fn needs_xpbd(&self) -> bool {
        self.pins
            .iter()
            .any(|p| p.from.distance(p.to) > self.longest_spring)
            || self.overstretched()
    }

    /// Whether a spring is stretched by more than [`AUTO_MAX_STRETCH`] of its rest length. A
    /// force-based integrator would release that elastic energy as motion (a teleported pin flings
    /// the cloth), so [`Integrator::Auto`] leaves such a state to XPBD until it has relaxed.
    fn overstretched(&self) -> bool {
        let s = &self.model.springs;
        let x = &self.particles.positions;
        s.a.iter().zip(&s.b).zip(&s.rest).any(|((&a, &b), &rest)| {
            x[a as usize].distance_squared(x[b as usize])
                > (rest * (1.0 + AUTO_MAX_STRETCH)).powi(2)
        })
    }

    /// Conjugate-gradient iterations taken in the last substep of implicit Euler (0 before the first
    /// implicit step, and for the other integrators).
    pub fn cg_iterations(&self) -> u32 {
        self.steppers.cg_iterations()
    }

    /// Mass of each particle, kg (pinned ones included).
    pub fn masses(&self) -> &[f32] {
        &self.particles.mass
    }

    /// Starts adding up the energy that contact responses put into the cloth: across each
    /// response, the larger of the rise of its total energy (kinetic, gravitational and elastic)
    /// and the rise of its potential energy plus the colliders' work on the particles' motion
    /// (impulse times surface velocity), when positive. A collider sweeping through a cloth
    /// stretches its springs and hands it its speed; the stress suite allows the cloth that
    /// energy. Costs an energy evaluation (one pass over the springs) before and after each
    /// substep's contact response.
    #[cfg(any(test, feature = "harness"))]
    pub(crate) fn track_contact_work(&mut self) {
        self.contact_work.get_or_insert(0.0);
    }

    /// The energy added up since [`track_contact_work`](Self::track_contact_work), J (`None` when
    /// not tracking).
    #[cfg(any(test, feature = "harness"))]
    pub(crate) fn contact_work(&self) -> Option<f64> {
        self.contact_work
    }

    /// Kinetic, gravitational and elastic energy of the free particles (see [`Energy`]).
    pub fn energy(&self) -> Energy {
        self.particles
            .energy(self.spring_set(), self.settings.gravity)
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
        let count = self.particles.positions.len();
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
            let from = self.particles.positions[particle as usize];
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

    /// Ties particles to animated targets (replacing any earlier ones): each [`Target`]'s particle
    /// stays within `weight × max_distance_scale` of its target's position and, with a backstop
    /// ([`SolverSettings::targets`]), outside the backstop sphere behind it. Targets move with
    /// [`Self::move_targets`], interpolated across each step like pins. A pinned particle ignores
    /// its target. Bad input (a particle out of range, a negative or non-finite weight, a
    /// non-finite position or normal) is an error and changes nothing.
    pub fn set_targets(&mut self, targets: &[Target]) -> Result<(), ClothError> {
        let count = self.particles.positions.len();
        for t in targets {
            if t.particle as usize >= count {
                return Err(ClothError::InvalidTargets {
                    what: format!(
                        "target particle {} is out of range: the cloth has {count} particles",
                        t.particle
                    ),
                });
            }
            crate::error::non_negative("target weight", t.weight)?;
            crate::error::finite_vec3(
                [
                    "target position.x",
                    "target position.y",
                    "target position.z",
                ],
                t.position,
            )?;
            crate::error::finite_vec3(
                ["target normal.x", "target normal.y", "target normal.z"],
                t.normal,
            )?;
        }
        self.contacts
            .limits_mut()
            .set_targets(targets.iter().copied());
        self.wake();
        Ok(())
    }

    /// Moves the targets, in the order given to [`Self::set_targets`], to `(position, normal)`
    /// at the end of the next step; they travel there linearly across it. Non-finite values are
    /// ignored (the target keeps its last one).
    pub fn move_targets(&mut self, targets: impl IntoIterator<Item = (Vec3, Vec3)>) {
        self.contacts.limits_mut().move_targets(targets);
    }

    /// Number of targets ([`Self::set_targets`]) and of tethers ([`SolverSettings::tethers`]:
    /// one per free particle joined to a pinned one along the mesh).
    pub fn limit_counts(&self) -> (usize, usize) {
        self.contacts.limits().counts()
    }

    /// Sets where the cloth's reference frame will be at the end of the next step (its start is
    /// where the last call left it). With [`SolverSettings::inertia`] below 1, the free particles
    /// are carried along by that share of the frame's motion, substep by substep, without feeling
    /// it; at 1 (the default) the frame changes nothing. A non-finite pose is ignored.
    pub fn move_frame(&mut self, pose: Pose) {
        if !(pose.translation.is_finite() && pose.rotation.is_finite()) {
            return;
        }
        let from = self.frame.map_or(pose, |(_, to)| to);
        self.frame = Some((from, pose));
    }

    /// The frame's motion over the next step as the steppers take it: `None` when the cloth
    /// feels all of it or it stands still.
    fn frame_motion(&self) -> Option<(Pose, Pose, super::settings::Inertia)> {
        let inertia = self.settings.inertia;
        self.frame
            .filter(|(from, to)| !inertia.is_world() && from != to)
            .map(|(from, to)| (from, to, inertia))
    }

    /// Kinetic energy of the free particles, J.
    pub fn kinetic_energy(&self) -> f32 {
        self.particles
            .velocities
            .iter()
            .zip(self.particles.inv_mass.iter().zip(&self.particles.mass))
            .filter(|(_, (w, _))| **w > 0.0)
            .map(|(v, (_, m))| 0.5 * m * v.length_squared())
            .sum()
    }

    /// Relative stretch `(|d| - L) / L` of each spring of `kind`, in spring order.
    pub fn strains(&self, kind: SpringKind) -> impl Iterator<Item = f32> + '_ {
        let s = &self.model.springs;
        (0..s.len())
            .filter(move |&k| s.kind[k] == kind)
            .map(move |k| {
                let d = self.particles.positions[s.a[k] as usize]
                    .distance(self.particles.positions[s.b[k] as usize]);
                (d - s.rest[k]) / s.rest[k]
            })
    }

    /// Largest relative stretch `(|d| - L) / L` over the springs of `kind`.
    pub fn max_strain(&self, kind: SpringKind) -> f32 {
        self.strains(kind).fold(0.0, f32::max)
    }

    /// Advances the cloth by `dt` seconds with nothing around it (see [`Self::step_in`]).
    pub fn step(&mut self, dt: f32) -> Result<(), ClothError> {
        self.step_in(dt, &Environment::default())
    }

    /// What the cloth's self-contacts did so far (all zero with self-collision off).
    pub fn self_contact_stats(&self) -> SelfContactStats {
        self.contacts
            .self_contacts()
            .map_or(SelfContactStats::default(), |s| {
                let (vertex_triangle, edge_edge) = s.candidate_count();
                SelfContactStats {
                    vertex_triangle,
                    edge_edge,
                    searches: s.searches(),
                    resolutions: s.resolutions(),
                }
            })
    }

    /// Number of searches for contact candidates with other cloths run so far (see
    /// [`Environment::cloths`]): none while no other cloth comes within reach.
    pub fn cloth_contact_searches(&self) -> u64 {
        self.contacts.cloths().searches()
    }

    /// Number of substeps whose contacts with other cloths were resolved so far: every substep
    /// while the cloths approach each other, a few a step while one rests on another.
    pub fn cloth_contact_resolutions(&self) -> u64 {
        self.contacts.cloths().resolutions()
    }

    /// Number of colliders that passed the broad phase of the last step.
    pub fn active_colliders(&self) -> usize {
        self.contacts.active_count()
    }

    /// What the cloth took from each collider it touched during the last step: the sum of the
    /// contact impulses and their moment, per collider of the step's [`Environment::colliders`]
    /// (at most once each). The collider took the opposite: a game applies its negation to the
    /// body to make the coupling two-way.
    pub fn reactions(&self) -> impl Iterator<Item = &Reaction> {
        self.contacts.reactions()
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
        match self.adaptive.take() {
            Some(mut adaptive) => {
                let result = adaptive.step(self, dt, env, spread);
                self.adaptive = Some(adaptive);
                result
            }
            None => self.step_planned(dt, env, spread, None, true),
        }
    }

    /// One step of `dt` (finite and positive) at `plan`'s method and substeps, or the configured
    /// ones when `None`. With `watch`, an explicit integrator past its stability bound is watched
    /// for a runaway (tolerance mode watches its steps by its estimates instead).
    fn step_planned(
        &mut self,
        dt: f32,
        env: &Environment,
        spread: Option<&dyn Spread>,
        plan: Option<(Integrator, u32)>,
        watch: bool,
    ) -> Result<(), ClothError> {
        let (substeps, wanted) = match plan {
            Some((method, substeps)) => {
                self.active = method;
                (substeps, substeps)
            }
            None => {
                self.active = self.choose_integrator(dt);
                self.substep_plan(dt)
            }
        };
        // Past its bound: an explicit integrator beyond the linear limit, or held below what its
        // bound asks for by the substep cap.
        let past_bound = watch
            && self.active.is_explicit()
            && (dt / substeps as f32 * self.omega_max >= 2.0 || wanted > substeps);
        if past_bound {
            let e = self.energy();
            let r = &mut self.runaway;
            r.before = e.kinetic + e.elastic;
            r.entered.get_or_insert((r.before, self.steps));
        }
        if self.settings.self_collision.enabled {
            // Only motion relative to the cloth's mean brings its own elements together.
            let v = &self.particles.velocities;
            let mean = v.iter().sum::<Vec3>() / v.len().max(1) as f32;
            let speed = v.iter().map(|v| v.distance(mean)).fold(0.0, f32::max);
            self.contacts.begin_self_step(self.reach_bound(dt, speed));
        }
        // Asleep, the cloth has not moved since it fell asleep: its box is kept, and every
        // particle is slower than the sleep threshold.
        let reach_box = |sim: &Self| {
            if sim.sleep.asleep {
                (
                    sim.sleep.bounds,
                    sim.reach_bound(dt, sim.settings.sleep_speed),
                )
            } else {
                let speed = max_length(&sim.particles.velocities);
                // Never below the sleep threshold, so that falling asleep does not change which
                // colliders are in reach.
                let speed = speed.max(sim.settings.sleep_speed);
                (bounds(&sim.particles.positions), sim.reach_bound(dt, speed))
            }
        };
        let reach = (!env.colliders.is_empty() || !env.cloths.is_empty()).then(|| reach_box(self));
        match reach {
            Some((bounds, reach)) if !env.colliders.is_empty() => self.contacts.begin_step(
                env.colliders,
                (env.collision_mask, env.two_way),
                bounds,
                reach,
                dt,
            ),
            _ => self
                .contacts
                .begin_step(&[], (0, false), (Vec3::ONE, Vec3::ZERO), 0.0, dt),
        }
        let layers = &self.settings.self_collision;
        self.contacts.begin_cloth_step(
            env.cloths,
            (layers.thickness, layers.friction),
            reach.unwrap_or(((Vec3::ONE, Vec3::ZERO), 0.0)),
            dt,
        );
        if self.sleeps_through(env) {
            self.steps += 1;
            self.sleep.skipped = true;
            return Ok(());
        }
        self.sleep.skipped = false;
        let dropped = self.contacts.dropped();
        if self.settings.sleep_speed > 0.0 || dropped {
            self.step_start.clear();
            self.step_start.extend_from_slice(&self.particles.positions);
        }
        self.wind.begin_step(
            env.wind,
            (
                self.settings.drag_coefficient,
                self.settings.lift_coefficient,
            ),
            &self.particles.positions,
            &self.particles.velocities,
            (&self.particles.inv_mass, dt),
            &self.model.triangles,
        );
        let frame = self.frame_motion();
        let mut step = Step {
            model: &self.model,
            settings: &self.settings,
            stiffness: &self.stiffness,
            pins: &self.pins,
            wind: &self.wind,
            particles: &mut self.particles,
            contacts: &mut self.contacts,
            contact_work: &mut self.contact_work,
            frame,
        };
        // `choose_integrator` never leaves `Auto` active.
        self.steppers
            .step(self.active, &mut step, (dt, substeps), spread);
        if dropped {
            let before = self.contact_work.map(|_| self.energy());
            let p = &mut self.particles;
            let work = self.contacts.catch_up(
                env.colliders,
                env.collision_mask,
                dt,
                &self.model.triangles,
                &p.inv_mass,
                &self.step_start,
                (&mut p.positions, &mut p.velocities),
            );
            if let Some(before) = before {
                let after = self.energy();
                add_contact_work(&mut self.contact_work, (before, after), work);
            }
        }
        self.steps += 1;
        for pin in &mut self.pins {
            pin.from = pin.to;
        }
        self.contacts.limits_mut().end_step();
        if let Some((from, to)) = &mut self.frame {
            *from = *to;
        }
        let p = &self.particles;
        let not_finite = first_not_finite(&p.positions).or_else(|| first_not_finite(&p.velocities));
        if let Some(particle) = not_finite {
            return Err(ClothError::Diverged {
                step: self.steps,
                particle,
                dt,
                substeps,
            });
        }
        self.check_runaway(dt, (substeps, wanted), past_bound)?;
        self.update_sleep(env, dt);
        Ok(())
    }

    /// For an explicit integrator run past its stability bound (`h ω_max ≥ 2`, possible with
    /// `auto_substeps` off or at [`MAX_SUBSTEPS`], or fewer substeps than its bound asks for,
    /// held back by the cap): an error once the kinetic plus elastic energy
    /// has grown by [`RUNAWAY_GROWTH`]× in each of [`RUNAWAY_STEPS`] consecutive steps, the
    /// signature of an unstable mode (gravity, pins or wind add energy far more slowly), or by
    /// [`RUNAWAY_STEP_GROWTH`]× in one step over its start plus the whole cloth's weight lifted a
    /// metre (a mode unstable enough to do that within a step's substeps), or by
    /// [`RUNAWAY_PAST_GROWTH`]× over the same since the run of steps past the bound began. Within
    /// the bound this costs nothing.
    fn check_runaway(
        &mut self,
        dt: f32,
        (substeps, wanted): (u32, u32),
        past_bound: bool,
    ) -> Result<(), ClothError> {
        let h = dt / substeps as f32;
        let h_omega = h * self.omega_max;
        if !past_bound {
            self.runaway = Runaway::default();
            return Ok(());
        }
        let e = self.energy();
        let energy = e.kinetic + e.elastic;
        let weight: f64 = self
            .particles
            .mass
            .iter()
            .map(|m| f64::from(*m))
            .sum::<f64>()
            * f64::from(self.settings.gravity.length().max(1.0));
        let r = &mut self.runaway;
        let burst = energy > RUNAWAY_STEP_GROWTH * (r.before + weight);
        let sustained = r
            .entered
            .filter(|(entered, _)| energy > RUNAWAY_PAST_GROWTH * (entered + weight));
        if energy > RUNAWAY_GROWTH * r.energy && energy > 1e-12 {
            if r.streak == 0 {
                r.streak_start = r.energy.max(f64::MIN_POSITIVE);
            }
            r.streak += 1;
        } else {
            r.streak = 0;
        }
        r.energy = energy;
        if r.streak >= RUNAWAY_STEPS || burst || sustained.is_some() {
            let (growth, steps) = if burst {
                (energy / r.before.max(f64::MIN_POSITIVE), 1)
            } else if let Some((entered, since)) = sustained {
                let steps = u32::try_from(self.steps - since).unwrap_or(u32::MAX);
                (energy / entered.max(f64::MIN_POSITIVE), steps)
            } else {
                (energy / r.streak_start, r.streak)
            };
            return Err(ClothError::Unstable {
                integrator: self.active.name(),
                step: self.steps,
                h,
                omega_max: self.omega_max,
                h_omega,
                substeps_needed: wanted.max(self.stable_substeps(dt)),
                growth,
                steps,
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
            || self.driven()
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
        if threshold <= 0.0 || env.wind.is_some() || self.driven() {
            self.sleep.quiet_steps = 0;
            return;
        }
        let limit = threshold * dt;
        // Far from the origin f32 cannot hold a cloth's springs at their rest lengths, and a
        // cloth at rest there jitters by a few of its positions' representable steps: that much
        // movement counts as quiet too.
        let quiet = self
            .particles
            .positions
            .iter()
            .zip(&self.step_start)
            .zip(&self.particles.inv_mass)
            .all(|((x, x0), w)| {
                let jitter = 4.0 * f32::EPSILON * x0.abs().max_element();
                *w == 0.0 || x.distance_squared(*x0) < (limit + jitter).powi(2)
            });
        self.sleep.quiet_steps = if quiet { self.sleep.quiet_steps + 1 } else { 0 };
        if self.sleep.quiet_steps >= self.settings.sleep_steps {
            self.sleep.asleep = true;
            self.sleep.colliders = self.contacts.active_count();
            self.sleep.bounds = bounds(&self.particles.positions);
        }
    }

    /// Whether a pin, a target or the reference frame (felt at less than full inertia) moves
    /// during the next step.
    fn driven(&self) -> bool {
        self.pins.iter().any(|p| p.from != p.to)
            || self.contacts.limits().moving()
            || self.frame_motion().is_some()
    }

    /// A generous bound on how far any particle can move in a step of `dt` when none is faster
    /// than `speed`: twice its free flight, plus gravity, plus the farthest pin or target jump,
    /// plus how far the frame carries it.
    fn reach_bound(&self, dt: f32, speed: f32) -> f32 {
        let pin_jump = self
            .pins
            .iter()
            .map(|p| p.from.distance(p.to))
            .fold(self.contacts.limits().max_jump(), f32::max);
        let carried = self.frame_motion().map_or(0.0, |(from, to, inertia)| {
            // The frame's turn sweeps the particles by at most its angle times their distance
            // from its origin (bounded through the cloth's box).
            let (lo, hi) = bounds(&self.particles.positions);
            let far = (lo - from.translation)
                .abs()
                .max((hi - from.translation).abs())
                .length();
            let angle = from.rotation.angle_between(to.rotation);
            (1.0 - inertia.linear) * from.translation.distance(to.translation)
                + (1.0 - inertia.angular) * angle * far
        });
        2.0 * speed * dt + self.settings.gravity.length() * dt * dt + pin_jump + carried
    }
}
