//! The stress suite: seeded random cloths at the edges of what the solver accepts, stepped while
//! their invariants are checked. Used by the `stress` tests and by `cloth_cli stress`.
//!
//! Each case draws, from its seed and index: the integrator, a time step of 1/240–1/15 s, 1–64
//! substeps, a structural stiffness of 1–10⁹ N/m (shear and bend below it), particle masses whose
//! neighbours differ up to 1000:1, a grid of 2×2 to 128×128 particles (shrunk to a work budget),
//! pins oscillating at up to 20 m/s, a collider (sphere, capsule, box or floor) sweeping through
//! the cloth at up to half its thickness per substep (the tunnelling limit of the swept test is a
//! whole thickness), wind of up to 50 m/s with gusts, and tethers to the pins (a quarter of the
//! cases, slack 0–0.2).
//!
//! A case fails if stepping panics, a position or velocity becomes non-finite without a typed
//! error, a free particle ends a step inside a collider by more than [`CLEARANCE_TOLERANCE`]
//! (measured with the suite's own distance functions, not the solver's), a free particle's
//! straight path over a step of one substep passes through a collider's core (tunnelling), a
//! pinned particle is off its target, the energy grows without an outside source, or
//! (with an outside source) the kinetic energy of the cloth, or of any one particle, exceeds the
//! whole cloth moving at [`RUNAWAY_SPEED_FACTOR`] times every driving speed added up plus the work
//! a moving collider's contacts did (none for a collider at rest), both times a symplectic
//! integrator's kinetic-energy inflation (a runaway check). Every check applies to
//! every step that returns `Ok`, past an explicit integrator's stability bound too. An explicit
//! integrator that reports [`ClothError::Unstable`] or [`ClothError::Diverged`] past its
//! stability bound `h ω_max ≥ 2`, or `Unstable` where its bound asks for more than
//! [`MAX_SUBSTEPS`] substeps, is not a failure: that is the detection working, and the case
//! records where the limit lies.

use std::f32::consts::TAU;
use std::panic::{AssertUnwindSafe, catch_unwind};

use bevy::math::primitives::{Capsule3d, Cuboid, InfinitePlane3d, Sphere};
use glam::{Quat, Vec3};

use crate::error::ClothError;
use crate::hash::{GOLDEN_GAMMA, mix64};
use crate::sim::contact::convex_minimum;
use crate::sim::{
    Accuracy, ClothModel, ClothSim, Collider, ColliderShape, Environment, Friction, GridSpec,
    Gusts, Integrator, MAX_SUBSTEPS, Pose, SelfCollision, SolverSettings, Stiffness, Tethers,
    WindField,
};

/// How deep (m) a free particle may end a step inside a collider before the case fails.
pub const CLEARANCE_TOLERANCE: f32 = 1e-3;

/// With something driving the cloth, its kinetic energy may not exceed the whole cloth moving at
/// this many times the sum of every driving speed (a runaway check). A runaway grows
/// exponentially and passes any such bound; the factor leaves room for motion the drivers feed
/// without running away, which this suite has found: single light particles whipping faster than
/// the rest, a box swept through a soft cloth of light particles stretching its springs, and a
/// stiff, undamped cloth shaken by its pins faster than XPBD's iterations carry the motion across
/// it, whose energy beats (BENCHMARKS.md, "Stress suite").
pub const RUNAWAY_SPEED_FACTOR: f64 = 10.0;

/// How big the cases may get.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StressLimits {
    /// Largest grid side, particles.
    pub max_side: u32,
    /// Most particle-substeps per case (particles × substeps × steps, the cap's substeps in
    /// tolerance mode); larger cases are shrunk.
    pub max_work: f64,
    /// Simulated time per case, s.
    pub duration: f32,
}

impl Default for StressLimits {
    /// Up to 128×128 particles and 10⁷ particle-substeps (tens of milliseconds in a release
    /// build for XPBD), half a second each.
    fn default() -> Self {
        Self {
            max_side: 128,
            max_work: 1e7,
            duration: 0.5,
        }
    }
}

/// A collider of a case and how it moves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StressCollider {
    /// Its shape.
    pub shape: ColliderShape,
    /// Position at the start, m.
    pub start: Vec3,
    /// Constant velocity, m/s.
    pub velocity: Vec3,
    /// Rotation (fixed).
    pub rotation: Quat,
}

/// One drawn case (everything needed to rerun it).
#[derive(Debug, Clone, PartialEq)]
pub struct StressCase {
    /// Seed of the suite.
    pub seed: u64,
    /// Index of the case within the suite.
    pub index: u64,
    /// Solver settings (integrator, substeps, stiffness, mass, damping).
    pub settings: SolverSettings,
    /// Particles along each side of the square grid.
    pub side: u32,
    /// Side length of the cloth, m.
    pub size: f32,
    /// Fixed time step, s.
    pub dt: f32,
    /// Number of steps.
    pub steps: u32,
    /// Largest ratio of neighbouring particle masses.
    pub mass_ratio: f32,
    /// Pinned corners (0 to 4).
    pub pins: Vec<u32>,
    /// Peak speed of the pins' oscillation, m/s (0: fixed pins).
    pub pin_speed: f32,
    /// The collider, if any.
    pub collider: Option<StressCollider>,
    /// Mean wind, m/s (zero: no air at all).
    pub wind: Vec3,
    /// Whether the wind is gusty.
    pub gusts: bool,
}

/// How a case ended.
#[derive(Debug, Clone, PartialEq)]
pub enum StressOutcome {
    /// Every step ran and every invariant held.
    Stable,
    /// An explicit integrator past its stability bound stopped with a typed error, as it should.
    DetectedUnstable(ClothError),
    /// An invariant broke (the text says which, and where).
    Failure(String),
}

/// A case's outcome and the worst values seen while it ran.
#[derive(Debug, Clone, PartialEq)]
pub struct StressResult {
    /// The case.
    pub case: StressCase,
    /// How it ended.
    pub outcome: StressOutcome,
    /// Substeps the first step took (raised by `auto_substeps` for explicit integrators; a later
    /// step takes more while a spring is stretched far from rest).
    pub substeps: u32,
    /// `h ω_max`: the substep times the Gershgorin bound on the highest spring frequency.
    pub h_omega: f32,
    /// Deepest a free particle ended a step inside the collider, m (0 if never inside).
    pub max_penetration: f32,
    /// Largest distance of a pinned particle from its target, m.
    pub max_pin_error: f32,
    /// Largest particle speed, m/s.
    pub max_speed: f32,
    /// Largest growth of kinetic plus gravitational energy over the start, J (isolated cases).
    pub max_energy_gain: f64,
    /// Steps that ran.
    pub steps_run: u32,
    /// [`state_hash`] of the cloth where the case ended (0 if it was never built or panicked).
    pub state_hash: u64,
}

/// SplitMix64: a small, fast, well-mixed generator; enough for drawing cases reproducibly.
#[derive(Debug, Clone)]
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(GOLDEN_GAMMA);
        mix64(self.0)
    }

    /// Uniform in `[0, 1)`.
    fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }

    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit()
    }

    /// Log-uniform in `[lo, hi]`.
    fn log_range(&mut self, lo: f32, hi: f32) -> f32 {
        (lo.ln() + (hi.ln() - lo.ln()) * self.unit()).exp()
    }

    fn chance(&mut self, p: f32) -> bool {
        self.unit() < p
    }

    fn direction(&mut self) -> Vec3 {
        let z = self.range(-1.0, 1.0);
        let a = self.range(0.0, TAU);
        let r = (1.0 - z * z).sqrt();
        Vec3::new(r * a.cos(), z, r * a.sin())
    }

    fn pick<T: Copy>(&mut self, items: &[T]) -> T {
        items[(self.next() % items.len() as u64) as usize]
    }
}

/// The first `count` (at most 4) corners of a `side`×`side` grid, as pinned particles.
fn corner_pins(side: u32, count: usize) -> Vec<u32> {
    [0, side - 1, side * (side - 1), side * side - 1]
        .into_iter()
        .take(count)
        .collect()
}

/// Draws case `index` of the suite `seed`, with an integrator from `integrators`.
pub fn draw_case(
    seed: u64,
    index: u64,
    integrators: &[Integrator],
    limits: &StressLimits,
) -> StressCase {
    let mut rng = Rng(seed ^ index.wrapping_mul(0xD1B5_4A32_D192_ED03));
    rng.next();
    let integrator = rng.pick(if integrators.is_empty() {
        &Integrator::CHOICES
    } else {
        integrators
    });
    let dt = rng.log_range(1.0 / 240.0, 1.0 / 15.0);
    let substeps = rng.log_range(1.0, 64.99).floor() as u32;
    let structural = rng.log_range(1.0, 1e9);
    let stiffness = Stiffness {
        structural,
        shear: structural * rng.range(0.1, 1.0),
        bend: structural * rng.log_range(1e-3, 1.0),
    };
    let mut settings = SolverSettings {
        integrator,
        substeps,
        iterations: if integrator == Integrator::ImplicitEuler {
            50
        } else {
            rng.log_range(1.0, 4.99).floor() as u32
        },
        stiffness,
        particle_mass: rng.log_range(1e-4, 0.1),
        damping: if rng.chance(0.3) {
            0.0
        } else {
            rng.range(0.0, 2.0)
        },
        // Sleeping would hide steps from the checks.
        sleep_speed: 0.0,
        ..Default::default()
    };
    let steps = ((limits.duration / dt).ceil() as u32).clamp(4, 240);
    let side = rng.log_range(2.0, limits.max_side as f32 + 0.99).floor() as u32;
    let size = rng.log_range(0.2, 2.0);
    let mass_ratio = if rng.chance(0.5) {
        rng.log_range(1.0, 1000.0)
    } else {
        1.0
    };
    let pins = corner_pins(side, (rng.next() % 5) as usize);
    let pin_speed = if !pins.is_empty() && rng.chance(0.5) {
        rng.log_range(0.1, 20.0)
    } else {
        0.0
    };
    let collider = rng.chance(0.6).then(|| {
        let radius = rng.log_range(0.02, 0.5);
        let (shape, thickness) = match rng.next() % 4 {
            0 => (ColliderShape::Sphere(Sphere::new(radius)), 2.0 * radius),
            1 => (
                ColliderShape::Capsule(Capsule3d::new(radius, rng.range(0.0, 1.0))),
                2.0 * radius,
            ),
            2 => {
                let half = Vec3::new(
                    rng.log_range(0.02, 0.5),
                    rng.log_range(0.02, 0.5),
                    rng.log_range(0.02, 0.5),
                );
                (
                    ColliderShape::Cuboid(Cuboid::from_size(2.0 * half)),
                    2.0 * half.min_element(),
                )
            }
            _ => (ColliderShape::HalfSpace(InfinitePlane3d::new(Vec3::Y)), 1.0),
        };
        let half_space = matches!(shape, ColliderShape::HalfSpace(_));
        let h = dt / substeps as f32;
        // Up to half the thickness per substep (a floor rises at most 2 m/s).
        let limit = if half_space { 2.0 } else { 0.5 * thickness / h };
        let speed = if rng.chance(0.5) {
            0.0
        } else {
            rng.range(0.0, limit)
        };
        // Radius of a ball around the collider's centre that holds it.
        let extent = match shape {
            ColliderShape::Sphere(s) => s.radius,
            ColliderShape::Capsule(c) => c.radius + c.half_length,
            ColliderShape::Cuboid(b) => b.half_size.length(),
            ColliderShape::HalfSpace(_) => 0.0,
        };
        let (start, direction) = if half_space {
            (Vec3::new(0.0, rng.range(-1.0, 0.9), 0.0), Vec3::Y)
        } else if speed == 0.0 {
            // Below the cloth, which falls onto it.
            (
                Vec3::new(0.0, 0.95 - extent - rng.range(0.0, 0.5), 0.0),
                Vec3::Y,
            )
        } else {
            // Clear of the cloth at the start, heading through its middle.
            let d = rng.direction();
            let travel = speed * dt * steps as f32;
            let back = 0.5 * travel.min(3.0) + extent + 0.05;
            (Vec3::new(0.0, 1.0, 0.0) - d * back, d)
        };
        StressCollider {
            shape,
            start,
            velocity: direction * speed,
            rotation: if half_space {
                Quat::IDENTITY
            } else {
                Quat::from_axis_angle(rng.direction(), rng.range(0.0, TAU))
            },
        }
    });
    let (wind, gusts) = if rng.chance(0.5) {
        (rng.direction() * rng.log_range(0.5, 50.0), rng.chance(0.5))
    } else {
        (Vec3::ZERO, false)
    };
    // Tethers in a quarter of the cases, a third of those without slack (drawn last, so that
    // every other draw stays what it was).
    if rng.chance(0.25) {
        settings.tethers = Tethers {
            enabled: true,
            slack: if rng.chance(1.0 / 3.0) {
                0.0
            } else {
                rng.log_range(1e-3, 0.2)
            },
        };
    }
    StressCase {
        seed,
        index,
        settings,
        side,
        size,
        dt,
        steps,
        mass_ratio,
        pins,
        pin_speed,
        collider,
        wind,
        gusts,
    }
}

impl StressCase {
    /// Where a pin that started at `start` should be at time `t`: all pins oscillate together
    /// (a rigid motion the cloth can follow) with peak speed `pin_speed`, amplitude 0.2 m, along
    /// a diagonal.
    fn pin_target(&self, start: Vec3, t: f32) -> Vec3 {
        if self.pin_speed <= 0.0 {
            return start;
        }
        let amplitude = 0.2;
        let omega = self.pin_speed / amplitude;
        start + Vec3::new(1.0, 1.0, 0.5).normalize() * amplitude * (omega * t).sin()
    }

    fn collider_at(&self, t0: f32, t1: f32) -> Option<Collider> {
        self.collider.map(|c| Collider {
            start: Pose {
                rotation: c.rotation,
                translation: c.start + c.velocity * t0,
            },
            end: Pose {
                rotation: c.rotation,
                translation: c.start + c.velocity * t1,
            },
            ..Collider::fixed(
                c.shape,
                Pose::from_translation(Vec3::ZERO),
                Friction::default(),
                0.005,
            )
        })
    }

    /// The same case with self-collision on, its thickness a quarter of the drawn grid's
    /// spacing (a cloth shrunk to the work budget is coarser, so its thickness stays below that).
    pub fn with_self_collision(mut self) -> Self {
        let spacing = self.size / (self.side.max(2) - 1) as f32;
        self.settings.self_collision = SelfCollision {
            enabled: true,
            thickness: 0.25 * spacing,
            ..Default::default()
        };
        self
    }

    /// The same case in tolerance mode ([`Accuracy`]): `tolerance` relative to the cloth's size
    /// per second, at most the default cap of substeps; the drawn integrator and substeps are
    /// then only where the controller starts.
    pub fn with_tolerance(mut self, tolerance: f32) -> Self {
        self.settings.accuracy = Accuracy {
            tolerance: Some(tolerance),
            ..Default::default()
        };
        self
    }

    fn isolated(&self) -> bool {
        self.pin_speed == 0.0
            && self.wind == Vec3::ZERO
            && self.collider.is_none_or(|c| c.velocity == Vec3::ZERO)
    }

    /// The cloth, shrunk (fewer particles) until it fits the work budget.
    fn build(&self, limits: &StressLimits) -> Result<(ClothSim, StressCase), ClothError> {
        let mut case = self.clone();
        loop {
            let sim = self.build_side(case.side)?;
            // In tolerance mode the controller may take up to its cap of substeps per step.
            let substeps = match self.settings.accuracy.tolerance {
                Some(_) => self.settings.accuracy.max_substeps,
                None => sim.substeps_for(case.dt),
            };
            let work = (case.side * case.side) as f64 * substeps as f64 * case.steps as f64;
            if work <= limits.max_work || case.side <= 2 {
                return Ok((sim, case));
            }
            let shrink = (limits.max_work / work).sqrt();
            case.side = ((case.side as f64 * shrink).floor() as u32).clamp(2, case.side - 1);
            case.pins = corner_pins(case.side, self.pins.len());
        }
    }

    fn build_side(&self, side: u32) -> Result<ClothSim, ClothError> {
        let mut model =
            ClothModel::grid(&GridSpec::new(side, side, self.size / (side - 1) as f32))?;
        if self.mass_ratio > 1.0 {
            // Alternating heavy and light particles in a checkerboard, with smooth variation on
            // top: neighbours differ by up to `mass_ratio`.
            let m = self.settings.particle_mass;
            let masses = (0..side * side)
                .map(|i| {
                    let (x, y) = (i % side, i / side);
                    if (x + y) % 2 == 0 {
                        m * self.mass_ratio
                    } else {
                        m
                    }
                })
                .collect();
            model = model.with_particle_masses(masses)?;
        }
        ClothSim::new(model, self.settings, |p| p + Vec3::new(0.0, 1.0, 0.0))
    }
}

/// A fingerprint of a cloth's state: the bits of every position and velocity, in particle order.
/// Two runs agree bit for bit exactly when their hashes agree (up to a 2⁻⁶⁴ chance).
pub fn state_hash(sim: &ClothSim) -> u64 {
    let mut h = 0;
    for v in sim.positions().iter().chain(sim.velocities()) {
        for c in v.to_array() {
            h = mix64(h ^ u64::from(c.to_bits())).wrapping_add(GOLDEN_GAMMA);
        }
    }
    h
}

/// Runs one case, catching panics (a panic is a failure).
pub fn run_case(case: &StressCase, limits: &StressLimits) -> StressResult {
    trace_case(case, limits, |_, _| {})
}

/// [`run_case`], calling `observe` with the step's index and the cloth after every step that ran.
pub fn trace_case(
    case: &StressCase,
    limits: &StressLimits,
    mut observe: impl FnMut(u32, &ClothSim),
) -> StressResult {
    match catch_unwind(AssertUnwindSafe(|| {
        run_unguarded(case, limits, &mut observe)
    })) {
        Ok(result) => result,
        Err(panic) => {
            let message = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            StressResult::new(case, StressOutcome::Failure(format!("panicked: {message}")))
        }
    }
}

impl StressResult {
    /// A result with nothing measured yet.
    fn new(case: &StressCase, outcome: StressOutcome) -> Self {
        Self {
            case: case.clone(),
            outcome,
            substeps: 0,
            h_omega: 0.0,
            max_penetration: 0.0,
            max_pin_error: 0.0,
            max_speed: 0.0,
            max_energy_gain: 0.0,
            steps_run: 0,
            state_hash: 0,
        }
    }
}

fn run_unguarded(
    case: &StressCase,
    limits: &StressLimits,
    observe: &mut dyn FnMut(u32, &ClothSim),
) -> StressResult {
    let mut result = StressResult::new(case, StressOutcome::Stable);
    let (mut sim, case) = match case.build(limits) {
        Ok(built) => built,
        Err(e) => {
            result.outcome = StressOutcome::Failure(format!("could not build: {e}"));
            return result;
        }
    };
    result.case = case.clone();
    run_steps(&mut sim, &case, &mut result, observe);
    result.state_hash = state_hash(&sim);
    result
}

/// Steps a built case, checking its invariants after every step; stops at the first failure.
fn run_steps(
    sim: &mut ClothSim,
    case: &StressCase,
    result: &mut StressResult,
    observe: &mut dyn FnMut(u32, &ClothSim),
) {
    result.substeps = sim.substeps_for(case.dt);
    result.h_omega = case.dt / result.substeps as f32 * sim.max_frequency();
    let past_bound = case.settings.integrator.is_explicit() && result.h_omega >= 2.0;
    let starts: Vec<Vec3> = case
        .pins
        .iter()
        .map(|&p| sim.positions()[p as usize])
        .collect();
    if let Err(e) = sim.set_pins(case.pins.iter().copied().zip(starts.iter().copied())) {
        result.outcome = StressOutcome::Failure(format!("pins: {e}"));
        return;
    }
    let wind = (case.wind != Vec3::ZERO).then(|| WindField {
        velocity: case.wind,
        gusts: case.gusts.then(|| Gusts {
            seed: case.index,
            strength: 0.5,
            ..Default::default()
        }),
        ..Default::default()
    });
    let e0 = {
        let e = sim.energy();
        e.kinetic + e.gravitational
    };
    // A symplectic integrator conserves a modified energy, not the true one: for a harmonic
    // oscillator under position Verlet the kinetic energy it shows exceeds the true one by the
    // factor 1/(1 - (hω/2)²), so the true energy may exceed its start by up to
    // (hω)²/(4 - (hω)²) times the energy in the oscillation (bounded here by the largest elastic
    // energy seen). `auto_substeps` keeps hω ≤ 1.8 for the Gershgorin bound of ω: a factor ≤ 1.07.
    // `Auto` may run Verlet, and so may tolerance mode, never past its proven bound.
    let tolerance_mode = case.settings.accuracy.tolerance.is_some();
    let may_run_explicit = tolerance_mode
        || matches!(
            case.settings.integrator,
            Integrator::Auto | Integrator::Verlet | Integrator::SymplecticEuler
        );
    let elastic_slack = if may_run_explicit {
        let h_omega = if tolerance_mode {
            case.dt / sim.stable_substeps(case.dt) as f32 * sim.max_frequency()
        } else {
            result.h_omega
        };
        let x = (h_omega as f64).min(1.9).powi(2);
        x / (4.0 - x)
    } else {
        0.0
    };
    let total_mass: f64 = sim.masses().iter().map(|m| *m as f64).sum();
    // Gravity's work on the whole cloth over a metre, as the scale of an energy error.
    let energy_tolerance = 1e-3 * total_mass * 9.81 * (1.0 + case.size as f64) + 1e-9;
    // With something driving the cloth, a runaway check rather than a physical bound (a kinematic
    // collider or pin is an infinite-mass driver whose work has no bound): the kinetic energy may
    // not exceed the whole cloth moving at `RUNAWAY_SPEED_FACTOR` times the sum of every driving
    // speed (the fall, pins, collider, wind); see there.
    let fall = 9.81 * case.dt * case.steps as f32;
    let collider_speed = case.collider.map_or(0.0, |c| c.velocity.length());
    let drive = fall + case.pin_speed + collider_speed + 1.5 * case.wind.length() + 1.0;
    let kinetic_bound = 0.5 * total_mass * (RUNAWAY_SPEED_FACTOR * drive as f64).powi(2);
    // Plus the work a moving collider's contacts did (each push's impulse times the surface's
    // velocity, plus the potential energy its projections added; a collider pressing the cloth
    // against its springs does its work through the springs, which a response's own energy change
    // does not show, since it also takes away what the springs just gave): a collider
    // sweeping through a soft cloth of light particles stretches its springs by far more than
    // their length, and the springs whip the particles to many times the collider's speed. A
    // collider at rest does no work, so nothing is allowed for its contacts (their responses do
    // show small gains of elastic energy, pushing out a particle the springs pulled in, which
    // the integration loses again). The symplectic integrators show a kinetic energy inflated by
    // up to 1/(1 - (hω/2)²) (see above), which the bound allows them on both.
    let collider_moves = case.collider.is_some_and(|c| c.velocity != Vec3::ZERO);
    sim.track_contact_work();
    let mut max_elastic: f64 = 0.0;
    let mut start_positions = sim.positions().to_vec();
    for step in 0..case.steps {
        let (t0, t1) = (step as f32 * case.dt, (step + 1) as f32 * case.dt);
        let targets: Vec<Vec3> = starts.iter().map(|s| case.pin_target(*s, t1)).collect();
        sim.move_pins(targets.iter().copied());
        let collider = case.collider_at(t0, t1);
        let env = Environment {
            colliders: collider.as_slice(),
            wind: wind.as_ref(),
            ..Environment::default()
        };
        start_positions.copy_from_slice(sim.positions());
        // The substeps this step takes: the count depends on the state (an overstretched cloth
        // takes more), and tolerance mode reports what it ran (a rejected step runs again).
        let planned = sim.substeps_for(case.dt);
        if let Err(e) = sim.step_in(case.dt, &env) {
            result.outcome = match e {
                ClothError::Unstable { .. } | ClothError::Diverged { .. } if past_bound => {
                    StressOutcome::DetectedUnstable(e)
                }
                // Its bound asked for more substeps than the cap allows.
                ClothError::Unstable {
                    substeps_needed, ..
                } if substeps_needed > MAX_SUBSTEPS => StressOutcome::DetectedUnstable(e),
                e => StressOutcome::Failure(format!("step {step}: {e}")),
            };
            return;
        }
        result.steps_run += 1;
        observe(step, sim);
        let fail = |what: String| StressOutcome::Failure(format!("step {step}: {what}"));
        for (&p, target) in case.pins.iter().zip(&targets) {
            let error = sim.positions()[p as usize].distance(*target);
            result.max_pin_error = result.max_pin_error.max(error);
            if error > 1e-5 * (1.0 + target.length()) {
                result.outcome = fail(format!("pin {p} is {error} m off its target"));
                return;
            }
        }
        let arrays = [
            ("position", sim.positions()),
            ("velocity", sim.velocities()),
        ];
        for (name, values) in arrays {
            if let Some(i) = values.iter().position(|v| !v.is_finite()) {
                result.outcome = fail(format!("particle {i}'s {name} is not finite"));
                return;
            }
        }
        let pinned: Vec<u32> = sim.pinned().collect();
        // The suite's colliders are primitives, measured with its own distance functions.
        if let Some(c) = &collider
            && let Some(shape) = c.shape.primitive()
        {
            let ran = sim.accuracy_report().map_or(planned, |r| r.substeps);
            let one_substep = ran == 1;
            for (i, (x, x0)) in sim.positions().iter().zip(&start_positions).enumerate() {
                if pinned.contains(&(i as u32)) {
                    continue;
                }
                let d = signed_distance(shape, c.end.inverse_transform_point(*x));
                result.max_penetration = result.max_penetration.max(-d);
                if d < -CLEARANCE_TOLERANCE {
                    result.outcome = fail(format!("particle {i} is {} m inside the collider", -d));
                    return;
                }
                if one_substep {
                    let from = c.start.inverse_transform_point(*x0);
                    let to = c.end.inverse_transform_point(*x);
                    if let Some(depth) = tunnelled(shape, from, to) {
                        result.outcome = fail(format!(
                            "particle {i} went through the collider's core ({depth} m deep) \
                             from {from} to {to} in its frame"
                        ));
                        return;
                    }
                }
            }
        }
        let e = sim.energy();
        let contact_work = if collider_moves {
            sim.contact_work().unwrap_or(0.0)
        } else {
            0.0
        };
        let inflation = 1.0 + elastic_slack;
        // No particle can hold more kinetic energy than the whole cloth may have.
        let energy_bound = (kinetic_bound + contact_work) * inflation;
        for (i, (v, m)) in sim.velocities().iter().zip(sim.masses()).enumerate() {
            let speed = v.length();
            result.max_speed = result.max_speed.max(speed);
            let bound = (2.0 * energy_bound / *m as f64).sqrt();
            if speed as f64 > bound {
                result.outcome = fail(format!(
                    "particle {i} moves at {speed:.3e} m/s, faster than all the energy the cloth \
                     may have ({energy_bound:.3e} J) in its mass allows ({bound:.3e} m/s)"
                ));
                return;
            }
        }
        if e.kinetic > energy_bound {
            result.outcome = fail(format!(
                "kinetic energy {:.3e} J is beyond the whole cloth at {RUNAWAY_SPEED_FACTOR} times \
                 every driving speed ({kinetic_bound:.3e} J) plus the energy its contacts added \
                 ({contact_work:.3e} J), times a symplectic integrator's inflation \
                 ({inflation:.2})",
                e.kinetic
            ));
            return;
        }
        if case.isolated() {
            max_elastic = max_elastic.max(e.elastic);
            let gain = e.kinetic + e.gravitational - e0;
            result.max_energy_gain = result.max_energy_gain.max(gain);
            let tolerance = energy_tolerance + elastic_slack * max_elastic;
            if gain > tolerance {
                result.outcome = fail(format!(
                    "kinetic + gravitational energy grew by {gain:.3e} J with nothing driving it \
                     (tolerance {tolerance:.1e} J)"
                ));
                return;
            }
        }
    }
}

/// Whether the straight path `from` → `to` (a particle's motion over one substep, in a shape's
/// own frame) passes through the shape's core, deeper than half its thickness: a particle that
/// stood outside and ends outside went through rather than around. A particle sliding along the
/// surface cuts the surface by its path's sagitta, far less than that; one that started inside
/// (a collider placed across the cloth) is pushed out, not through. Returns the depth the path
/// reached. The signed distance of a convex shape is convex along a line, so a ternary search finds
/// the deepest point of the path.
fn tunnelled(shape: &ColliderShape, from: Vec3, to: Vec3) -> Option<f32> {
    let core = match shape {
        ColliderShape::Sphere(s) => 0.5 * s.radius,
        ColliderShape::Capsule(c) => 0.5 * c.radius,
        ColliderShape::Cuboid(b) => 0.5 * b.half_size.min_element(),
        // An infinite floor has no other side to reach.
        ColliderShape::HalfSpace(_) => return None,
    };
    if signed_distance(shape, from) < -CLEARANCE_TOLERANCE {
        return None;
    }
    let deepest = -convex_minimum(|t| signed_distance(shape, from.lerp(to, t)));
    (deepest > core).then_some(deepest)
}

/// Signed distance (m) from a point in a shape's own frame to its surface, negative inside: the
/// suite's own, so that an error in the solver's distance functions cannot hide a penetration.
fn signed_distance(shape: &ColliderShape, p: Vec3) -> f32 {
    match shape {
        ColliderShape::Sphere(s) => p.length() - s.radius,
        ColliderShape::Capsule(c) => {
            let y = p.y.clamp(-c.half_length, c.half_length);
            p.distance(Vec3::new(0.0, y, 0.0)) - c.radius
        }
        ColliderShape::Cuboid(b) => {
            let q = p.abs() - b.half_size;
            q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
        }
        ColliderShape::HalfSpace(h) => p.dot(*h.normal),
    }
}

/// One line describing a cloth's state for `cloth_cli stress --trace`: its energies, the work the
/// contacts added, and its fastest particle.
pub fn trace_line(sim: &ClothSim) -> String {
    let e = sim.energy();
    let (fastest, speed) = sim
        .velocities()
        .iter()
        .map(|v| v.length())
        .enumerate()
        .fold(
            (0, 0.0),
            |best, (i, s)| if s > best.1 { (i, s) } else { best },
        );
    let springs = &sim.model().springs;
    let x = sim.positions();
    let (shortest, longest) = springs.a.iter().zip(&springs.b).zip(&springs.rest).fold(
        (f32::INFINITY, 0.0f32),
        |(lo, hi), ((&a, &b), &rest)| {
            let ratio = x[a as usize].distance(x[b as usize]) / rest;
            (lo.min(ratio), hi.max(ratio))
        },
    );
    let mut line = format!(
        "kinetic {:.4e} J, gravitational {:.4e} J, elastic {:.4e} J, contact work {:.4e} J, \
         fastest particle {fastest} at {speed:.4e} m/s, springs at {shortest:.3}–{longest:.3} \
         of their rest length",
        e.kinetic,
        e.gravitational,
        e.elastic,
        sim.contact_work().unwrap_or(0.0),
    );
    if let Some(r) = sim.accuracy_report() {
        line += &format!(
            ", tolerance mode: {:?} × {}, estimate {:.3e} of {:.3e} m/s",
            r.integrator, r.substeps, r.error_rate, r.tolerance
        );
    }
    line
}
