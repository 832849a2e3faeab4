//! Running a case: building its cloth, stepping it among its pins, collider and wind, and
//! checking the invariants after every step (a panic caught as a failure).

use std::panic::{AssertUnwindSafe, catch_unwind};

use glam::Vec3;

use super::case::{StressCase, StressLimits};
use super::penetration::{CLEARANCE_TOLERANCE, signed_distance, tunnelled};
use super::result::{StressOutcome, StressResult, state_hash};
use crate::error::ClothError;
use crate::sim::{ClothSim, Environment, Gusts, Integrator, MAX_SUBSTEPS, WindField};

/// With something driving the cloth, its kinetic energy may not exceed the whole cloth moving at
/// this many times the sum of every driving speed (a runaway check). A runaway grows
/// exponentially and passes any such bound; the factor leaves room for motion the drivers feed
/// without running away, which this suite has found: single light particles whipping faster than
/// the rest, a box swept through a soft cloth of light particles stretching its springs, and a
/// stiff, undamped cloth shaken by its pins faster than XPBD's iterations carry the motion across
/// it, whose energy beats (CHANGELOG.md, 2026-12-02).
pub const RUNAWAY_SPEED_FACTOR: f64 = 10.0;

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
    result.splits = sim.tears();
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
    // The energy the cloth stores at the start may turn into motion: the springs are at rest,
    // but air kept at another volume or pressure than it has pushes the cloth there.
    let (mut e0, mut stored) = {
        let e = sim.energy();
        (e.kinetic + e.gravitational, e.elastic)
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
        start_positions.clear();
        start_positions.extend_from_slice(sim.positions());
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
        let energy_bound = (kinetic_bound + contact_work + stored) * inflation;
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
            let tolerance = energy_tolerance + elastic_slack * max_elastic + stored;
            if gain > tolerance {
                result.outcome = fail(format!(
                    "kinetic + gravitational energy grew by {gain:.3e} J with nothing driving it \
                     (tolerance {tolerance:.1e} J)"
                ));
                return;
            }
        }
        // Tears after the step's checks: splitting a particle keeps its momentum and weight,
        // but a stretched spring along a new edge is one on each side, so a tear may add
        // elastic energy, counted with what the cloth stored at the start. A copy of a pinned
        // particle is free, and brings its share of the pinned mass into the energy of the free
        // particles (a driver letting go of a body); with self-collision on, the tear moves its
        // sides apart (a jump of positions, not a force). The gravitational energy the tear
        // moves and the freed copies' kinetic energy join the start's.
        if case.settings.tearing.enabled || case.cut.is_some() {
            let cut = case.cut.filter(|(at, _)| *at == step).map(|(_, c)| c);
            match sim.tear(cut.as_slice()) {
                Ok(splits) if !splits.is_empty() => {
                    let torn = sim.energy();
                    stored += (torn.elastic - e.elastic).max(0.0);
                    e0 += torn.gravitational - e.gravitational;
                    let freed = splits.iter().filter(|s| pinned.contains(&s.particle));
                    for split in freed {
                        let i = split.copy as usize;
                        let m = f64::from(sim.masses()[i]);
                        e0 += 0.5 * m * sim.velocities()[i].as_dvec3().length_squared();
                    }
                }
                Ok(_) => {}
                Err(e) => {
                    result.outcome = fail(format!("tear: {e}"));
                    return;
                }
            }
        }
    }
}
