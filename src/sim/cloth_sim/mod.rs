//! [`ClothSim`]: a simulated cloth, its model, settings, particle state, pins and steppers,
//! stepped among the colliders and air of an [`Environment`]; it chooses the integrator
//! ([`Integrator::Auto`]) and the substeps (or, in tolerance mode, `adaptive` does, from error
//! estimates on a copy of the cloth), puts a quiet cloth to sleep, and stops a runaway one.
//!
//! Plain data in, plain data out: no ECS types, no allocation inside [`ClothSim::step`]. Every
//! buffer a step touches is sized when the cloth is built (or when pins or settings change).
//!
//! The `impl` is split by concern: `build` (construction, settings), `plan` (integrator and
//! substeps), `pins` (pins, targets, frame), `step`, `watchdog` (runaways), `sleep`, `readout`
//! (what a cloth reports) and `tear` (cuts and tears).

use glam::Vec3;

use super::contact::{Collider, Contacts, OtherCloth, Pose};
use super::integrate::Steppers;
use super::model::ClothModel;
use super::pressure::{Air, BoundScratch};
use super::settings::{Integrator, SolverSettings};
use super::state::{Particles, PinState};
use super::wind::{WindField, WindScratch};

mod adaptive;
mod build;
mod coarse;
mod pins;
mod plan;
mod readout;
mod sleep;
mod step;
mod tear;
#[cfg(test)]
mod tests;
mod watchdog;

pub use adaptive::AccuracyReport;
pub use coarse::COARSE_FADE_STEPS;
pub use readout::SelfContactStats;
use sleep::Sleep;
pub use tear::{Cut, Split};
use watchdog::Runaway;

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
    /// Bound on the highest angular frequency of the springs and the air, rad/s: the springs'
    /// (Gershgorin) and the air's (at the start of the step) combined.
    omega_max: f32,
    /// Gershgorin bound on the highest angular frequency of the springs, rad/s.
    spring_frequency: f32,
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
    /// The volume a closed cloth enclosed when it was built (world space), m³; `None` for a cloth
    /// that is not a closed surface wound outward.
    built_volume: Option<f32>,
    /// The air inside, while [`SolverSettings::pressure`] is on.
    air: Option<Air>,
    /// The highest angular frequency the air adds at the start of the step, rad/s (0 without
    /// air; see `Air::frequency`); part of `omega_max`, and the bound of implicit Euler's
    /// substeps, which take the air explicitly.
    air_frequency: f32,
    /// Scratch for the air's frequency bound.
    air_bound: BoundScratch,
    steps: u64,
    /// Particles split by tears since the cloth was built.
    tears: u64,
    /// The springs that tear under strain, each with the square of the length it tears past
    /// (empty while tearing is off).
    tear_limits: Vec<(u32, u32, f32)>,
    /// Per particle, the factor of the stretch at which its springs tear (see
    /// [`Self::set_tear_weights`]); `None`: 1.
    tear_weights: Option<Vec<f32>>,
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
    /// The fraction of its configured substeps a step takes (see [`Self::set_detail`]).
    detail: f32,
    /// Moves on whenever settings, masses, pins or topology are applied again: what was derived
    /// from them before is out of date.
    revision: u64,
    /// The coarse level of detail, once built ([`Self::set_coarse`]).
    coarse: Option<Box<coarse::Coarse>>,
    /// Why the coarse level could not be built, at which revision.
    no_coarse: Option<(u64, crate::error::ClothError)>,
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
