//! Everything that controls a cloth's step apart from its topology: the [`Integrator`] choice,
//! per-family [`Stiffness`] and the [`SolverSettings`] that hold them, with their validation.

use bevy::reflect::Reflect;
use glam::Vec3;
use serde::{Deserialize, Serialize};

use super::model::SpringKind;
use crate::error::{ClothError, count_in, non_negative, positive, unit_interval};

/// Largest number of substeps per frame accepted by [`SolverSettings::validate`].
pub const MAX_SUBSTEPS: u32 = 1024;
/// Largest number of constraint iterations per substep accepted by [`SolverSettings::validate`].
pub const MAX_ITERATIONS: u32 = 256;

/// The most [`SelfCollision::thickness`] may be, as a multiple of the cloth's mean rest edge
/// length (the mean over its triangles' edges): the pairs of its elements within the thickness at
/// rest, which are exempt and stored, grow with the square of the thickness over the edge length
/// (none below 0.7 of it on a grid, about 50 per particle at it), and so do the pairs each search
/// meets. [`ClothSim::new`](super::ClothSim::new) and
/// [`ClothSim::set_settings`](super::ClothSim::set_settings) check it while self-collision is on;
/// the distance a cloth keeps from other cloths is clamped to it (a step never fails on it).
pub const MAX_THICKNESS_PER_EDGE: f32 = 1.0;

/// Fraction of the explicit stability limit `h < 2/ω_max` that [`SolverSettings::auto_substeps`]
/// stays within, applied to the Gershgorin bound on `ω_max` (which itself over-estimates it).
pub const STABILITY_FRACTION: f32 = 0.9;

/// The fraction of the explicit stability limit that [`SolverSettings::auto_substeps`] stays
/// within while a spring is stretched by more than [`AUTO_MAX_STRETCH`]. Far from rest the
/// springs are nonlinear, and the explicit integrators meet resonances below the linear limit
/// (for Verlet at `h ω = √2` and `√3`, Schlick, Mandziuk, Skeel and Srinivas 1998), where the
/// stress suite found the energy running away.
pub const NONLINEAR_STABILITY_FRACTION: f32 = 0.5;

/// [`Integrator::Auto`] runs XPBD while any spring is stretched by more than this fraction of its
/// rest length (a hanging cloth of the default stiffness stretches by under 2%).
pub const AUTO_MAX_STRETCH: f32 = 0.1;

/// The time integration method. Every integrator solves the same canonical model
/// (`docs/guide.md`, "The model"): the same springs, masses, gravity, pins (pinned particles
/// follow their targets, interpolated across substeps) and damping (velocities decay as
/// `exp(-damping t)`).
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
    /// [`SolverSettings::auto_substeps`] the most accurate integrator where it is stable, on every
    /// scene of the work-precision benchmark (docs/accuracy.md).
    Verlet,
    /// Implicit (backward) Euler after Baraff & Witkin 1998: per substep one Newton step on the
    /// linearised springs, `(M + h² K) Δv = h (f - h K v)`, solved by Jacobi-preconditioned conjugate
    /// gradients (at most `iterations` iterations, stopping at a relative residual of
    /// [`CG_TOLERANCE`](super::CG_TOLERANCE)); pins by filtering the CG. Unconditionally stable for
    /// the clamped (positive semi-definite) `K`, first order, strongly damped at large steps.
    ImplicitEuler,
    /// The default: chosen afresh each step between the two integrators that the work-precision
    /// benchmark (docs/accuracy.md) puts on the best front. [`Verlet`](Self::Verlet) errs orders of
    /// magnitude less than XPBD at equal run time wherever it is stable; XPBD is the one that runs
    /// below Verlet's stability bound, takes any stiffness and absorbs a teleported pin.
    ///
    /// Verlet runs when `substeps` are within its stability bound ([`ClothSim::stable_substeps`](super::ClothSim::stable_substeps)),
    /// no pin jumps farther than the cloth's longest spring in the step and no spring is stretched
    /// by more than [`AUTO_MAX_STRETCH`] (a force-based integrator would release that energy as
    /// motion); XPBD runs otherwise, at the same `substeps`. So `substeps` is the one cost knob:
    /// at the default 20 a cloth of the default stiffness and mass at 60 Hz runs XPBD (fast,
    /// numerically damped); from its stability bound on it runs Verlet.
    /// [`ClothSim::active_integrator`](super::ClothSim::active_integrator) tells which one a step used.
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
    /// from each particle's springs and mass (`NONLINEAR_STABILITY_FRACTION` in place of
    /// `STABILITY_FRACTION` while a spring is stretched far from rest). `substeps` stays the
    /// minimum. Ignored by XPBD and
    /// implicit Euler, which are stable at any step (but for the air inside a closed cloth,
    /// which implicit Euler takes explicitly: its substeps are raised to the air's bound), and by
    /// [`Integrator::Auto`], which runs Verlet only within the bound.
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
    /// collider arriving or leaving, wind, or an edit). 0 disables sleeping. Measuring over the
    /// step, not the last substep's velocity, keeps the rounding jitter of a cloth far from the
    /// origin (one f32 step of 15 µm at 200 m) below the default threshold.
    pub sleep_speed: f32,
    /// Consecutive quiet steps before a cloth falls asleep: at least 1 (0 would put every cloth
    /// to sleep before its first step; to keep a cloth awake, set
    /// [`sleep_speed`](Self::sleep_speed) to 0).
    pub sleep_steps: u32,
    /// Collisions of the cloth with itself (off by default).
    pub self_collision: SelfCollision,
    /// How far particles tied to an animated target may leave it ([`ClothSim::set_targets`](super::ClothSim::set_targets)).
    pub targets: TargetLimits,
    /// Long-range attachments to the nearest pinned particle (off by default).
    pub tethers: Tethers,
    /// How much of its reference frame's motion the cloth feels ([`ClothSim::move_frame`](super::ClothSim::move_frame)).
    pub inertia: Inertia,
    /// Fixed substeps (the default), or a tolerance the solver meets by choosing the integrator
    /// and the substeps itself, step by step.
    pub accuracy: Accuracy,
    /// The air inside a closed cloth (off by default).
    pub pressure: Pressure,
    /// Tearing under strain (off by default).
    pub tearing: Tearing,
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
            self_collision: SelfCollision::default(),
            targets: TargetLimits::default(),
            tethers: Tethers::default(),
            inertia: Inertia::default(),
            accuracy: Accuracy::default(),
            pressure: Pressure::Off,
            tearing: Tearing::default(),
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
        count_in("sleep_steps", self.sleep_steps, 1, u32::MAX)?;
        self.self_collision.validate()?;
        self.targets.validate()?;
        self.tethers.validate()?;
        self.inertia.validate()?;
        self.accuracy.validate()?;
        self.pressure.validate()?;
        self.tearing.validate()?;
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

/// Self-collision: the cloth keeps its layers at least `thickness` apart, so a fold or a pile never
/// passes through itself (see the `contact` module's self-contact section). Pairs of the cloth's
/// elements that are closer than the thickness at rest (neighbours along the mesh) are exempt.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Reflect)]
#[serde(default, deny_unknown_fields)]
pub struct SelfCollision {
    /// Whether the cloth collides with itself.
    pub enabled: bool,
    /// Distance the cloth keeps between its own layers, m (positive): between a vertex and a
    /// triangle; two edges are kept 0.9 of it apart, so that edges of layers resting on each
    /// other are left alone. Every step ends with its layers that far apart; within a step,
    /// layers that approach slowly (a resting fold) may come up to a quarter of it closer before
    /// they are pushed back, which saves resolving them at every substep. Keeping it below half
    /// the cloth's particle spacing leaves the mesh's own neighbours out of it; it may be at most
    /// [`MAX_THICKNESS_PER_EDGE`] times the cloth's mean rest edge length (checked when the cloth
    /// is built or its settings change, while self-collision is on).
    pub thickness: f32,
    /// Coulomb friction between layers (0 = frictionless).
    pub friction: f32,
}

impl Default for SelfCollision {
    /// Off, 5 mm thick, friction 0.3.
    fn default() -> Self {
        Self {
            enabled: false,
            thickness: 0.005,
            friction: 0.3,
        }
    }
}

impl SelfCollision {
    /// Checks the thickness is finite and positive and the friction finite and non-negative
    /// (whether or not self-collision is enabled). The bound that depends on the cloth is
    /// [`Self::validate_for`]'s.
    pub fn validate(&self) -> Result<(), ClothError> {
        positive("self_collision.thickness", self.thickness)?;
        non_negative("self_collision.friction", self.friction)
    }

    /// Checks the thickness against a cloth whose triangles' edges are `mean_edge` long on
    /// average at rest: at most [`MAX_THICKNESS_PER_EDGE`] times that, while self-collision is
    /// enabled (a cloth without triangles, `mean_edge` 0, has no self-contacts to bound).
    pub fn validate_for(&self, mean_edge: f32) -> Result<(), ClothError> {
        if !self.enabled || mean_edge <= 0.0 {
            return Ok(());
        }
        within_thickness_bound("self_collision.thickness", self.thickness, mean_edge)
    }
}

/// Checks that a distance kept between layers, `thickness` (named `field`), is at most
/// [`MAX_THICKNESS_PER_EDGE`] times `mean_edge`, the mean rest edge length of the cloth whose
/// contacts it sets.
pub(crate) fn within_thickness_bound(
    field: &'static str,
    thickness: f32,
    mean_edge: f32,
) -> Result<(), ClothError> {
    let bound = MAX_THICKNESS_PER_EDGE * mean_edge;
    if thickness <= bound {
        return Ok(());
    }
    Err(ClothError::TooLong {
        field,
        value: thickness,
        bound,
        why: format!(
            "MAX_THICKNESS_PER_EDGE = {MAX_THICKNESS_PER_EDGE} × the cloth's mean rest edge \
             length {mean_edge} m"
        ),
    })
}

/// Limits on particles tied to an animated target (a skinned position, or the rest shape carried
/// by the cloth's transform): a particle of weight `w > 0` stays within `w × max_distance_scale`
/// of its target, and outside a backstop sphere behind it (weight 0 keeps it on its target; the
/// plugin pins such vertices instead).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Reflect)]
#[serde(default, deny_unknown_fields)]
pub struct TargetLimits {
    /// Maximum distance from the target per unit weight, m.
    pub max_distance_scale: f32,
    /// Radius of the backstop sphere, m (0: no backstop). Its centre lies behind the target
    /// along the target's normal, at `backstop_radius + backstop_offset`, so a particle may go at
    /// most `backstop_offset` behind its target (a negative offset keeps it in front).
    pub backstop_radius: f32,
    /// How far behind the target the backstop sphere begins, m (negative: in front of it).
    pub backstop_offset: f32,
}

impl Default for TargetLimits {
    /// 1 m per unit weight, no backstop.
    fn default() -> Self {
        Self {
            max_distance_scale: 1.0,
            backstop_radius: 0.0,
            backstop_offset: 0.0,
        }
    }
}

impl TargetLimits {
    /// Checks the scale and radius are finite and non-negative and the offset finite.
    pub fn validate(&self) -> Result<(), ClothError> {
        non_negative("targets.max_distance_scale", self.max_distance_scale)?;
        non_negative("targets.backstop_radius", self.backstop_radius)?;
        crate::error::finite("targets.backstop_offset", self.backstop_offset)
    }
}

/// Tethers (long-range attachments): each free particle stays within `1 + slack` times its
/// geodesic rest distance (along the cloth's rest shape) from the nearest pinned particle, so a
/// cloth hanging from its pins does not stretch however few iterations it runs. XPBD projects
/// them after the springs in every substep; the force-based integrators with the contacts at the
/// end of every substep.
/// A tether's length is measured at rest, so slack 0 keeps the cloth from stretching along it at
/// all, even where its springs alone would (they are stiff, not rigid).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Reflect)]
#[serde(default, deny_unknown_fields)]
pub struct Tethers {
    /// Whether tethers act.
    pub enabled: bool,
    /// Stretch allowed beyond the geodesic rest distance, as a fraction (0 = none).
    pub slack: f32,
}

impl Default for Tethers {
    /// Off, 2% slack.
    fn default() -> Self {
        Self {
            enabled: false,
            slack: 0.02,
        }
    }
}

impl Tethers {
    /// Checks the slack is finite and non-negative.
    pub fn validate(&self) -> Result<(), ClothError> {
        non_negative("tethers.slack", self.slack)
    }
}

/// Tearing under strain: a spring stretched past `1 + max_stretch` times its rest length tears
/// the cloth at one of its ends, across the spring, so the two sides separate there
/// ([`ClothSim::tear`](super::ClothSim::tear)). At most `max_per_step` particles split in a step,
/// so an overloaded cloth unravels over several steps rather than in one. Off by default; cuts
/// from the API tear a cloth whether it is on or not.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Reflect)]
#[serde(default, deny_unknown_fields)]
pub struct Tearing {
    /// Whether springs tear when stretched past the limit.
    pub enabled: bool,
    /// Stretch past which a spring tears, as a fraction of its rest length (positive).
    pub max_stretch: f32,
    /// The most particles that split in one step (at least 1).
    pub max_per_step: u32,
    /// Which springs tear: the structural ones only, or the bending and shear springs too.
    pub springs: TearSprings,
}

/// The springs that tear ([`Tearing::springs`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, Reflect)]
pub enum TearSprings {
    /// Springs along the cloth's edges: the material itself.
    #[default]
    Structural,
    /// Every spring, so a cloth also tears where it is folded or sheared hard.
    All,
}

impl Default for Tearing {
    /// Off; 50% stretch, 8 splits a step, structural springs.
    fn default() -> Self {
        Self {
            enabled: false,
            max_stretch: 0.5,
            max_per_step: 8,
            springs: TearSprings::Structural,
        }
    }
}

impl Tearing {
    /// Checks the stretch is finite and positive and the cap at least 1.
    pub fn validate(&self) -> Result<(), ClothError> {
        positive("tearing.max_stretch", self.max_stretch)?;
        count_in("tearing.max_per_step", self.max_per_step, 1, u32::MAX)
    }

    /// Whether a spring of `kind` tears.
    pub fn tears(&self, kind: SpringKind) -> bool {
        self.springs == TearSprings::All || kind == SpringKind::Structural
    }
}

/// How much of its reference frame's motion the cloth feels (its inertia in that frame): 1 is
/// plain world-space simulation, 0 makes the free particles move with the frame as if it were
/// still (a cape on a character that sprints off or rides a platform), values between damp the
/// frame's pull. Linear and angular motion are scaled separately.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Reflect)]
#[serde(default, deny_unknown_fields)]
pub struct Inertia {
    /// Fraction of the frame's translation the cloth feels, 0..=1.
    pub linear: f32,
    /// Fraction of the frame's rotation the cloth feels, 0..=1.
    pub angular: f32,
}

impl Default for Inertia {
    /// World space: the cloth feels all of its frame's motion.
    fn default() -> Self {
        Self {
            linear: 1.0,
            angular: 1.0,
        }
    }
}

impl Inertia {
    /// Checks both factors lie in 0..=1.
    pub fn validate(&self) -> Result<(), ClothError> {
        unit_interval("inertia.linear", self.linear)?;
        unit_interval("inertia.angular", self.angular)
    }

    /// Whether the cloth feels all of its frame's motion (nothing to do).
    pub fn is_world(&self) -> bool {
        self.linear == 1.0 && self.angular == 1.0
    }
}

/// How the substeps of a step are chosen: as configured ([`SolverSettings::integrator`] at
/// [`SolverSettings::substeps`]), or to meet a tolerance.
///
/// With a [`tolerance`](Self::tolerance) the solver estimates every step's error by running the
/// step again on a copy of the cloth with fewer substeps (Richardson's estimate), and a
/// controller picks the integrator (XPBD or Verlet) and the substep count that keep the estimated
/// error below the tolerance, never above [`max_substeps`](Self::max_substeps). A copy that runs
/// away (an explicit integrator past its stability limit) counts as a large error, so the
/// controller moves away from a substep count before the cloth itself is at risk.
/// [`ClothSim::accuracy_report`](super::ClothSim::accuracy_report) tells what it chose.
/// [`SolverSettings::integrator`] and [`SolverSettings::auto_substeps`] are then unused, and
/// [`SolverSettings::substeps`] is where XPBD starts (the controller starts on Verlet at its
/// proven stability bound where Verlet may run). Editing the settings or the pins starts the
/// controller afresh.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Reflect)]
#[serde(default, deny_unknown_fields)]
pub struct Accuracy {
    /// `None`: fixed substeps. `Some(tolerance)`: the largest error per second of simulated time
    /// the solver allows itself, in [`unit`](Self::unit)s (positive).
    pub tolerance: Option<f32>,
    /// What the tolerance is measured in.
    pub unit: ErrorUnit,
    /// The most substeps a step may take in tolerance mode (2 to [`MAX_SUBSTEPS`]): the bound on
    /// a step's cost. Where the tolerance needs more, the step runs at the cap and the report
    /// says so.
    pub max_substeps: u32,
}

impl Default for Accuracy {
    /// Fixed substeps; a tolerance, when set, relative to the cloth's size, capped at 256 substeps.
    fn default() -> Self {
        Self {
            tolerance: None,
            unit: ErrorUnit::Relative,
            max_substeps: 256,
        }
    }
}

impl Accuracy {
    /// Tolerance mode with `tolerance` relative to the cloth's size (per second), capped at
    /// `max_substeps`.
    pub fn relative(tolerance: f32, max_substeps: u32) -> Self {
        Self {
            tolerance: Some(tolerance),
            unit: ErrorUnit::Relative,
            max_substeps,
        }
    }

    /// Checks the tolerance (when set) is finite and positive and the cap within
    /// 2..=[`MAX_SUBSTEPS`] (whether or not a tolerance is set).
    pub fn validate(&self) -> Result<(), ClothError> {
        if let Some(t) = self.tolerance {
            positive("accuracy.tolerance", t)?;
        }
        count_in("accuracy.max_substeps", self.max_substeps, 2, MAX_SUBSTEPS)
    }
}

/// The unit of [`Accuracy::tolerance`]: a position error per second of simulated time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, Reflect)]
pub enum ErrorUnit {
    /// A fraction of the cloth's size (the diagonal of its rest shape's bounding box) per second.
    #[default]
    Relative,
    /// Metres per second.
    Metres,
}

/// Standard atmospheric pressure, Pa: the default air outside a [`Pressure::Gas`] cloth.
pub const STANDARD_ATMOSPHERE: f32 = 101_325.0;

/// The air inside a closed cloth: a balloon, a ball, a cushion. Off by default. A cloth with
/// pressure must be a closed surface whose triangles wind counter-clockwise seen from outside
/// ([`ClothModel::check_closed`](super::ClothModel::check_closed));
/// [`ClothSim::new`](super::ClothSim::new) and
/// [`ClothSim::set_settings`](super::ClothSim::set_settings) refuse it on any other cloth. The
/// volume is measured from the triangles each substep; the pressure pushes on every triangle
/// along its normal, shared equally by its three corners (`p ∂V/∂x` per particle).
///
/// The force-based integrators apply the pressure as a force, and their stability bound counts
/// the air's stiffness (a stiff volume or a gas well above the air outside asks for more
/// substeps, as a stiff spring does; implicit Euler, which takes the air explicitly, too). XPBD
/// moves the particles once per substep, after its spring sweeps, by one backward-Euler step of
/// the air's stiffness (stable at any stiffness); like its springs, it then comes to rest a
/// little softer than set at few substeps, and at the set stiffness as substeps grow.
///
/// In every integrator, an air that alone would move a particle more than half the rest
/// triangles' mean edge in one substep (a ball crushed flat or torn inside out by a fast
/// collider, its gas held at a high pressure) is scaled down to that, all particles alike.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize, Reflect)]
pub enum Pressure {
    /// No air: a closed cloth collapses like a sack.
    #[default]
    Off,
    /// The cloth keeps a volume, `scale` times the volume it encloses when built, as stiff as a
    /// fluid of bulk modulus `bulk_modulus` (Pa): the pressure inside, above the air outside, is
    /// `K (V₀ − V) / V₀` at volume `V` (`V₀` the kept volume). For XPBD this is one compliant
    /// constraint `V − V₀` per substep, of compliance `V₀ / K` (m³/Pa).
    Volume {
        /// The kept volume over the built volume; 1 keeps the built shape's volume.
        scale: f32,
        /// How much the pressure rises as the volume shrinks, Pa (`K` above; air compressed
        /// slowly ≈ 1.0e5, water 2.2e9).
        bulk_modulus: f32,
    },
    /// An ideal gas (isothermal): the pressure inside is `p = nRT / V`, and each triangle is
    /// pushed by `p − ambient`.
    Gas {
        /// Amount of gas × gas constant × temperature, `nRT`, J (= Pa·m³): the pressure inside
        /// times the volume. [`Pressure::gas`] sets it from a pressure at a volume.
        nrt: f32,
        /// The pressure of the air outside, Pa ([`STANDARD_ATMOSPHERE`] at sea level; 0 in a
        /// vacuum).
        ambient: f32,
    },
}

impl Pressure {
    /// An ideal gas in air at [`STANDARD_ATMOSPHERE`] that is `gauge` Pa above it when the cloth
    /// encloses `volume` m³ (a beach ball: a few kPa at its built volume).
    pub fn gas(volume: f32, gauge: f32) -> Self {
        Pressure::Gas {
            nrt: (STANDARD_ATMOSPHERE + gauge) * volume,
            ambient: STANDARD_ATMOSPHERE,
        }
    }

    /// Whether there is air (anything but [`Pressure::Off`]).
    pub fn is_on(&self) -> bool {
        !matches!(self, Pressure::Off)
    }

    /// Checks the values: `scale` and `bulk_modulus` finite and > 0; `nrt` and `ambient` finite
    /// and ≥ 0.
    pub fn validate(&self) -> Result<(), ClothError> {
        match *self {
            Pressure::Off => Ok(()),
            Pressure::Volume {
                scale,
                bulk_modulus,
            } => {
                positive("pressure.scale", scale)?;
                positive("pressure.bulk_modulus", bulk_modulus)
            }
            Pressure::Gas { nrt, ambient } => {
                non_negative("pressure.nrt", nrt)?;
                non_negative("pressure.ambient", ambient)
            }
        }
    }
}
