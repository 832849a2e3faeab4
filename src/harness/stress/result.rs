//! What a case reports: how it ended ([`StressOutcome`]), the worst values seen ([`StressResult`]),
//! and the cloth's fingerprint ([`state_hash`]) and one-line description ([`trace_line`]).

use super::case::StressCase;
use crate::error::ClothError;
use crate::hash::{GOLDEN_GAMMA, mix64};
use crate::sim::ClothSim;

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
    /// Particles split by tears ([`StressCase::with_tearing`]).
    pub splits: u64,
}

impl StressResult {
    /// A result with nothing measured yet.
    pub(super) fn new(case: &StressCase, outcome: StressOutcome) -> Self {
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
            splits: 0,
        }
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
