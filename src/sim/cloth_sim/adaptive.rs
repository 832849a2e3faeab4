//! Tolerance mode ([`Accuracy::tolerance`]): an error estimate and a controller that choose the
//! integrator and the substeps of each step.
//!
//! **Estimate.** Now and then a step is also run on a copy of the cloth (the *shadow*, put in the
//! cloth's state, same surroundings) with about [`COARSENING`] times fewer substeps. For a method
//! of order `p` the error of the step taken is then about `|x − x_coarse| / (r^p − 1)`
//! (Richardson), where `r` is the exact ratio of the substep counts; the largest such distance
//! over the particles, divided by the step, is the estimated error per second. Within a few
//! rounding steps of the positions (`ε |x| √n`, scaled alike) the estimate says nothing about the
//! substeps: the controller does not raise them for it and reports the round-off floor.
//!
//! **Stability by monitoring, above a proven floor.** Verlet never runs below its proven
//! (Gershgorin) bound: a mode the cloth's motion has not excited (a cloth falling freely, its
//! springs at rest) can lie past an explicit method's limit unseen by any copy, and then grows
//! from a contact to overflow within one step. Above the bound, an explicit integrator past its
//! limit in the copy (contacts and stretch move it) runs away within the step (non-finite,
//! stopped by the runaway watch, or an estimate jumping tenfold as the count was lowered): that
//! counts as a runaway. Since the copy takes larger substeps than the cloth, the controller leaves
//! a count while the cloth itself is still stable, and Verlet never again runs at or below
//! [`UNSAFE_MARGIN`] times it.
//!
//! **Controller.** It aims at half the tolerance: a method of order `p` at `n` substeps with
//! estimate `e` needs about `n (e / (tol/2))^(1/p)`. It raises the count at once when the estimate
//! passes the tolerance (and takes the step again when it passed it twice over), lowers it by at
//! most a fifth per estimate and only below a quarter of the tolerance (hysteresis). It runs the
//! method that needs fewer substeps (XPBD, order 1, or Verlet, order 2), switching only for a
//! clear gain. It starts on Verlet at its proven bound where Verlet may run; XPBD's need is then
//! measured by *probes*: the copy runs XPBD and the difference to Verlet's far more accurate step
//! is XPBD's error. After a raise or a switch the next step is estimated; otherwise estimates
//! grow rarer (every 1, 2, 4 … up to [`MAX_INTERVAL`] steps), so a settled cloth pays little
//! for them. Where
//! [`Integrator::Auto`] would leave a step to XPBD (a pin jumping, a spring overstretched), XPBD
//! runs at the substeps it needs.

use glam::Vec3;

use super::{ClothSim, Environment, Runaway, Sleep};
use crate::error::ClothError;
use crate::sim::contact::{Limits, Pose, bounds};
use crate::sim::integrate::Spread;
use crate::sim::settings::{ErrorUnit, Integrator};
use crate::sim::state::PinState;

/// Ratio of the substeps of the cloth to those of its copy (rounded per count).
const COARSENING: f32 = 1.25;
/// The most steps between two estimates.
const MAX_INTERVAL: u32 = 16;
/// The controller aims at this fraction of the tolerance.
const AIM: f32 = 0.5;
/// Below this fraction of the tolerance the controller lowers the substeps.
const LOWER_BELOW: f32 = 0.25;
/// The most a count is lowered by at one estimate (a factor).
const LOWER_STEP: f32 = 0.8;
/// Another method is taken when it needs fewer substeps than this fraction of the current one's.
const SWITCH_GAIN: f32 = 0.8;
/// While Verlet runs, every this many estimates one measures XPBD's error instead.
const PROBE_EVERY: u32 = 8;
/// A step whose estimate exceeds the tolerance this many times is taken again at the new plan.
const REJECT_ABOVE: f32 = 2.0;
/// After Verlet's copy ran away at `n` substeps, Verlet keeps above `n` times this.
const UNSAFE_MARGIN: f32 = 1.15;
/// An estimate within this factor of the positions' round-off is not raised for (see
/// [`Adaptive::step`]).
const ROUNDING_FACTOR: f32 = 2.0;
/// Verlet's estimate growing this many times when its substeps were lowered is a runaway.
const RUNAWAY_JUMP: f32 = 10.0;

/// What tolerance mode chose and estimated ([`ClothSim::accuracy_report`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AccuracyReport {
    /// The integrator of the last step.
    pub integrator: Integrator,
    /// The substeps of the last step.
    pub substeps: u32,
    /// The last estimate of the error per second, m/s (infinite when the copy ran away).
    pub error_rate: f32,
    /// The tolerance in m/s (a relative tolerance times the cloth's size).
    pub tolerance: f32,
    /// The estimated error added up over the steps taken, m: each step adds the latest estimate
    /// times the step. Errors made early can grow or shrink later; this sum does not know.
    pub estimated_error: f64,
    /// Estimates made so far.
    pub estimates: u64,
    /// Whether the tolerance asked for more substeps than [`Accuracy::max_substeps`] allows at
    /// the last estimate.
    ///
    /// [`Accuracy::max_substeps`]: crate::sim::Accuracy::max_substeps
    pub at_cap: bool,
    /// Whether the estimate stopped falling as the substeps rose: the tolerance is below what
    /// the cloth's f32 positions resolve, and the controller no longer raises the substeps for it.
    pub at_floor: bool,
    /// Steps taken again because their estimate exceeded the tolerance more than twice.
    pub rejected: u64,
}

/// The state of tolerance mode: the shadow copy, the controller and its report.
#[derive(Debug, Clone)]
pub(super) struct Adaptive {
    /// The copy the estimates run on (fixed substeps, never asleep, nothing tracked).
    shadow: Box<ClothSim>,
    /// The allowed error per second, m/s.
    tolerance: f32,
    cap: u32,
    /// The method and substeps steps run at.
    method: Integrator,
    substeps: u32,
    /// Substeps XPBD needs by its last estimate (`u32::MAX` while unknown).
    need_xpbd: u32,
    /// The configured substeps: where XPBD starts, or its first probe.
    configured: u32,
    /// Substeps Verlet needs by its last estimate (before one: its proven stability bound).
    need_verlet: Option<u32>,
    /// Verlet's proven stability bound for the current step: it never runs below.
    verlet_bound: u32,
    /// The largest count at which Verlet's copy ran away: Verlet never runs at or below it.
    verlet_unsafe: u32,
    /// Whether the next estimate while Verlet runs measures XPBD instead (see [`Self::step`]),
    /// and the estimates since the last such probe.
    probe_due: bool,
    since_probe: u32,
    /// Steps between estimates, and steps left until the next.
    interval: u32,
    countdown: u32,
    /// The last estimate of each method (XPBD, Verlet) that did not run away, and its
    /// substeps.
    last: [Option<(u32, f32)>; 2],
    /// The last estimate that did not run away, m/s (what a step without one adds up).
    settled_rate: f32,
    /// The cloth's state at the start of an estimated step, to take it again if rejected.
    start: Snapshot,
    report: AccuracyReport,
}

/// What a step changes in a [`ClothSim`] outside its steppers' scratch.
#[derive(Debug, Clone, Default)]
struct Snapshot {
    positions: Vec<Vec3>,
    velocities: Vec<Vec3>,
    pins: Vec<PinState>,
    frame: Option<(Pose, Pose)>,
    targets: Limits,
    sleep: Sleep,
    steps: u64,
    contact_work: Option<f64>,
}

impl Snapshot {
    fn save(&mut self, sim: &ClothSim) {
        self.positions.clone_from(&sim.particles.positions);
        self.velocities.clone_from(&sim.particles.velocities);
        self.pins.clone_from(&sim.pins);
        self.frame = sim.frame;
        self.targets.sync_targets(sim.contacts.limits());
        self.sleep = sim.sleep;
        self.steps = sim.steps;
        self.contact_work = sim.contact_work;
    }

    fn restore(&self, sim: &mut ClothSim) {
        sim.particles.positions.copy_from_slice(&self.positions);
        sim.particles.velocities.copy_from_slice(&self.velocities);
        sim.pins.clone_from(&self.pins);
        sim.frame = self.frame;
        sim.contacts.limits_mut().sync_targets(&self.targets);
        sim.sleep = self.sleep;
        sim.steps = self.steps;
        sim.contact_work = self.contact_work;
    }
}

impl Adaptive {
    /// Multiplies the tolerance by `factor`.
    pub fn scale_tolerance(&mut self, factor: f32) {
        self.tolerance *= factor;
    }

    /// Tolerance mode for `sim` (whose settings have a tolerance), with a fresh copy of it.
    pub fn new(sim: &ClothSim) -> Option<Self> {
        let accuracy = sim.settings.accuracy;
        let tolerance = accuracy.tolerance?;
        let mut shadow = Box::new(sim.clone());
        shadow.adaptive = None;
        shadow.detail = 1.0;
        shadow.settings.accuracy.tolerance = None;
        shadow.settings.sleep_speed = 0.0;
        shadow.contact_work = None;
        let size = if sim.model.rest_positions.is_empty() {
            0.0
        } else {
            let (lo, hi) = bounds(&sim.model.rest_positions);
            lo.distance(hi)
        };
        let tolerance = match accuracy.unit {
            ErrorUnit::Relative => tolerance * size.max(f32::MIN_POSITIVE),
            ErrorUnit::Metres => tolerance,
        } / sim.detail;
        let cap = accuracy.max_substeps;
        let substeps = sim.settings.substeps.clamp(2, cap);
        Some(Self {
            shadow,
            tolerance,
            cap,
            method: Integrator::Xpbd,
            substeps,
            need_xpbd: substeps,
            configured: substeps,
            need_verlet: None,
            verlet_bound: 0,
            verlet_unsafe: 0,
            probe_due: false,
            since_probe: 0,
            interval: 1,
            countdown: 0,
            last: [None; 2],
            settled_rate: 0.0,
            // Sized now, so that no step allocates.
            start: {
                let mut start = Snapshot::default();
                start.save(sim);
                start
            },
            report: AccuracyReport {
                integrator: Integrator::Xpbd,
                substeps,
                error_rate: 0.0,
                tolerance,
                estimated_error: 0.0,
                estimates: 0,
                at_cap: false,
                at_floor: false,
                rejected: 0,
            },
        })
    }

    /// What was chosen and estimated so far.
    pub fn report(&self) -> AccuracyReport {
        self.report
    }

    /// The substeps the next step takes (unless Verlet may not run it, when XPBD takes the
    /// substeps it needs).
    pub fn substeps(&self) -> u32 {
        self.substeps
    }

    /// One step of `sim` (whose `adaptive` this was, taken out for the step) in tolerance mode.
    pub fn step(
        &mut self,
        sim: &mut ClothSim,
        dt: f32,
        env: &Environment,
        spread: Option<&dyn Spread>,
    ) -> Result<(), ClothError> {
        // Where `Auto` would leave the step to XPBD, Verlet is out of the choice.
        let verlet_allowed = !sim.needs_xpbd();
        let bound = sim.stable_substeps(dt).max(2);
        self.verlet_bound = bound;
        if self.need_verlet.is_none() {
            // The first step: Verlet at its proven bound where it can, as the more accurate
            // method (an XPBD probe follows); XPBD at the configured count otherwise.
            self.need_verlet = Some(bound);
            if verlet_allowed && bound <= self.cap {
                self.method = Integrator::Verlet;
                self.substeps = bound;
                self.need_xpbd = u32::MAX;
            }
        }
        // The bound moves with the step's length: Verlet follows it, or leaves to XPBD past the
        // cap.
        let (method, n) = match self.method {
            Integrator::Verlet if !verlet_allowed || bound > self.cap => {
                (Integrator::Xpbd, self.xpbd_count())
            }
            Integrator::Verlet => (Integrator::Verlet, self.substeps.max(bound)),
            method => (method, self.substeps),
        };
        let n = n.clamp(2, self.cap);
        let estimate = self.countdown == 0 && !sim.sleep.asleep;
        // A probe: the copy runs XPBD, and the difference to Verlet's far more accurate step is
        // XPBD's error at that count.
        let probe = estimate && self.probe_due && method == Integrator::Verlet;
        let copy_plan = if probe {
            (Integrator::Xpbd, self.xpbd_count().clamp(2, n))
        } else {
            (method, coarse_substeps(n))
        };
        let copy = if estimate {
            self.start.save(sim);
            self.sync_shadow(sim);
            Some(
                self.shadow
                    .step_planned(dt, env, None, Some(copy_plan), true),
            )
        } else {
            None
        };
        sim.step_planned(dt, env, spread, Some((method, n)), false)?;
        self.report.integrator = method;
        self.report.substeps = n;
        if sim.sleep.skipped {
            return Ok(());
        }
        let Some(copy) = copy else {
            self.countdown = self.countdown.saturating_sub(1);
            self.add_error(self.settled_rate, dt);
            return Ok(());
        };
        let largest = || {
            sim.particles
                .positions
                .iter()
                .zip(&self.shadow.particles.positions)
                .map(|(a, b)| a.distance_squared(*b))
                .fold(0.0, f32::max)
                .sqrt()
        };
        if probe {
            let rate = match copy {
                Ok(()) => largest() / dt,
                Err(_) => f32::INFINITY,
            };
            let (_, n_x) = copy_plan;
            let need = n_x as f32 * (rate / (AIM * self.tolerance));
            self.need_xpbd = if need.is_finite() {
                (need.ceil() as u32).max(2)
            } else {
                u32::MAX
            };
            self.probe_due = false;
            self.since_probe = 0;
            self.report.estimates += 1;
            self.choose((method, n), verlet_allowed);
            self.add_error(self.settled_rate, dt);
            return Ok(());
        }
        let coarse = copy_plan.1;
        let ratio = n as f32 / coarse as f32;
        let divisor = if method == Integrator::Verlet {
            ratio * ratio - 1.0
        } else {
            ratio - 1.0
        };
        let rate = match copy {
            Ok(()) => {
                let rate = largest() / divisor / dt;
                if rate.is_finite() {
                    rate
                } else {
                    f32::INFINITY
                }
            }
            Err(_) => f32::INFINITY,
        };
        // Each substep rounds the positions by about half an ulp; over `n` substeps the two runs'
        // roundings differ by about sqrt(n) of them.
        let scale = sim
            .particles
            .positions
            .iter()
            .map(|x| x.abs().max_element())
            .fold(0.0, f32::max);
        let noise = f32::EPSILON * scale * (n as f32).sqrt() / divisor / dt;
        self.report.error_rate = rate;
        self.report.estimates += 1;
        let runaway = self.update((method, n), rate, noise, verlet_allowed);
        if !runaway {
            self.settled_rate = rate;
            self.since_probe += 1;
            if method == Integrator::Verlet
                && (self.report.estimates == 1 || self.since_probe >= PROBE_EVERY)
            {
                self.probe_due = true;
                self.countdown = 0;
            }
        }
        let redo = (self.method, self.substeps);
        // A copy that ran away says nothing of the step taken, which ran at a count a copy
        // (with fewer substeps) had run stably before.
        if !runaway && rate > REJECT_ABOVE * self.tolerance && redo != (method, n) {
            // Too far off: the step is taken again at the new plan, and estimated at the next.
            self.start.restore(sim);
            sim.step_planned(dt, env, spread, Some(redo), false)?;
            self.report.rejected += 1;
            self.report.integrator = redo.0;
            self.report.substeps = redo.1;
            self.countdown = 0;
            let order = if redo.0 == Integrator::Verlet { 2 } else { 1 };
            let predicted = if redo.0 == method {
                rate * (n as f32 / redo.1 as f32).powi(order)
            } else {
                AIM * self.tolerance
            };
            self.add_error(predicted, dt);
        } else {
            self.add_error(self.settled_rate, dt);
        }
        Ok(())
    }

    /// Adds a step's estimated error (`rate` per second over `dt`) to the report's sum.
    fn add_error(&mut self, rate: f32, dt: f32) {
        if rate.is_finite() {
            self.report.estimated_error += f64::from(rate) * f64::from(dt);
        }
    }

    /// The substeps XPBD needs, or the configured count while that is unknown.
    fn xpbd_count(&self) -> u32 {
        if self.need_xpbd == u32::MAX {
            self.configured
        } else {
            self.need_xpbd
        }
    }

    /// Puts the shadow in the cloth's state at the start of its step. Its self-contacts keep
    /// their candidates: whether those still hold is judged from where the particles are against
    /// where they were found, however they got there.
    fn sync_shadow(&mut self, sim: &ClothSim) {
        let s = &mut *self.shadow;
        s.particles
            .positions
            .copy_from_slice(&sim.particles.positions);
        s.particles
            .velocities
            .copy_from_slice(&sim.particles.velocities);
        s.pins.clone_from(&sim.pins);
        s.frame = sim.frame;
        s.steps = sim.steps;
        s.runaway = Runaway::default();
        s.sleep = Sleep::default();
        s.contacts.limits_mut().sync_targets(sim.contacts.limits());
    }

    /// The controller: after an estimate `rate` (m/s) of a step of `method` at `n` substeps,
    /// chooses the method and substeps of the next steps and when to estimate again.
    fn update(
        &mut self,
        (method, n): (Integrator, u32),
        rate: f32,
        noise: f32,
        verlet_allowed: bool,
    ) -> bool {
        let before = (self.method, self.substeps);
        let tol = self.tolerance;
        let order = if method == Integrator::Verlet {
            2.0
        } else {
            1.0
        };
        let slot = usize::from(method == Integrator::Verlet);
        // An explicit method's copy near its stability limit may stay finite but grow far
        // beyond what fewer substeps could explain: a runaway as well.
        let runaway = !rate.is_finite()
            || (method == Integrator::Verlet
                && self.last[slot].is_some_and(|(m, e)| n < m && rate > RUNAWAY_JUMP * e));
        if !runaway {
            self.last[slot] = Some((n, rate));
        }
        // Within round-off of the positions the estimate says nothing about the substeps.
        let rounding = rate <= ROUNDING_FACTOR * noise;
        self.report.at_floor = !runaway && rounding && rate > tol;
        let need = if runaway {
            // The copy ran away: only an explicit method does at a stable state.
            if method == Integrator::Verlet {
                let unsafe_count = (n as f32 * UNSAFE_MARGIN).ceil() as u32;
                self.verlet_unsafe = self.verlet_unsafe.max(unsafe_count);
            }
            n.saturating_mul(3) / 2 + 1
        } else {
            let need = n as f32 * (rate / (AIM * tol)).powf(1.0 / order);
            if rate > tol && !rounding {
                need.ceil() as u32
            } else if rate < LOWER_BELOW * tol {
                (need.ceil() as u32).max((LOWER_STEP * n as f32).ceil() as u32)
            } else {
                n
            }
        };
        let need = need.clamp(2, u32::MAX);
        self.report.at_cap = need > self.cap;
        match method {
            Integrator::Verlet => self.need_verlet = Some(need.max(self.verlet_unsafe + 1)),
            _ => self.need_xpbd = need,
        }
        self.choose(before, verlet_allowed);
        runaway
    }

    /// Takes the method that needs fewer substeps (switching only for a clear gain) at the count
    /// it needs, and schedules the next estimate: at the next step after a raise or a switch,
    /// rarer and rarer otherwise.
    fn choose(&mut self, before: (Integrator, u32), verlet_allowed: bool) {
        let verlet = self.need_verlet.unwrap_or(u32::MAX).max(self.verlet_bound);
        let verlet_usable =
            verlet_allowed && self.verlet_unsafe < self.cap && self.verlet_bound <= self.cap;
        let xpbd = self.need_xpbd;
        let (current, other, other_need) = if self.method == Integrator::Verlet {
            (verlet, Integrator::Xpbd, xpbd)
        } else {
            (xpbd, Integrator::Verlet, verlet)
        };
        let other_usable = other == Integrator::Xpbd || verlet_usable;
        let current_usable = self.method == Integrator::Xpbd || verlet_usable;
        if !current_usable
            || (other_usable && (other_need as f32) < SWITCH_GAIN * current.min(self.cap) as f32)
        {
            self.method = other;
        }
        let need = match self.method {
            Integrator::Verlet => verlet,
            _ => self.xpbd_count(),
        };
        self.substeps = need.clamp(2, self.cap);
        // A raise or a switch is checked at the next step; lowering is never urgent, so estimates
        // grow rarer through it as while nothing changes.
        if self.method != before.0 || self.substeps > before.1 {
            self.interval = 1;
        } else {
            self.interval = (self.interval * 2).min(MAX_INTERVAL);
        }
        self.countdown = self.interval - 1;
    }
}

/// The substeps of the copy for a step of `n`: about `n / COARSENING`, always fewer than `n`.
fn coarse_substeps(n: u32) -> u32 {
    ((n as f32 / COARSENING).round() as u32).clamp(1, n.saturating_sub(1).max(1))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::{Accuracy, ClothModel, GridSpec, SolverSettings};

    fn controller() -> Adaptive {
        let model = ClothModel::grid(&GridSpec::new(4, 4, 0.1)).unwrap();
        let settings = SolverSettings {
            accuracy: Accuracy::relative(1e-3, 256),
            ..Default::default()
        };
        let sim = ClothSim::new(model, settings, |p| p).unwrap();
        let mut a = Adaptive::new(&sim).unwrap();
        a.method = Integrator::Verlet;
        a.substeps = 100;
        a.need_verlet = Some(100);
        a.need_xpbd = 1000;
        a
    }

    #[test]
    fn a_copy_that_ran_away_raises_the_count_for_good() {
        let mut a = controller();
        let tol = a.tolerance;
        // Far below the tolerance: lowered by a fifth at most.
        assert!(!a.update((Integrator::Verlet, 100), 1e-3 * tol, 0.0, true));
        assert_eq!((a.method, a.substeps), (Integrator::Verlet, 80));
        assert!(a.update((Integrator::Verlet, 80), f32::INFINITY, 0.0, true));
        assert!(a.substeps > 80 * 5 / 4, "{}", a.substeps);
        let floor = a.verlet_unsafe;
        assert!(floor >= 92, "{floor}");
        // However small the estimates later, Verlet stays above the count that ran away.
        for _ in 0..20 {
            let n = a.substeps;
            a.update((Integrator::Verlet, n), 1e-3 * tol, 0.0, true);
            assert!(a.substeps > floor, "{} after a runaway at 80", a.substeps);
        }
        // An estimate that jumps a hundredfold as the count is lowered is a runaway too.
        let mut a = controller();
        a.update((Integrator::Verlet, 100), 0.01 * tol, 0.0, true);
        assert!(a.update((Integrator::Verlet, 80), 2.0 * tol, 0.0, true));
        assert!(a.verlet_unsafe >= 92);
    }

    #[test]
    fn verlet_stays_at_or_above_its_proven_bound() {
        let mut a = controller();
        a.verlet_bound = 100;
        let tol = a.tolerance;
        // However small the estimate, not lowered below the bound.
        for _ in 0..10 {
            a.update((Integrator::Verlet, a.substeps), 1e-3 * tol, 0.0, true);
            assert_eq!((a.method, a.substeps), (Integrator::Verlet, 100));
        }
        // A bound past the cap leaves the step to XPBD.
        a.verlet_bound = 300;
        a.update((Integrator::Verlet, 100), 1e-3 * tol, 0.0, true);
        assert_eq!((a.method, a.substeps), (Integrator::Xpbd, 256));
    }

    #[test]
    fn the_count_follows_the_order_of_the_method() {
        // Verlet is second order: four times the error asks for twice the substeps (aiming at
        // half the tolerance); XPBD, first order, for four times.
        let mut a = controller();
        let tol = a.tolerance;
        a.update((Integrator::Verlet, 100), 2.0 * tol, 0.0, true);
        assert_eq!((a.method, a.substeps), (Integrator::Verlet, 200));
        let mut a = controller();
        a.method = Integrator::Xpbd;
        a.substeps = 20;
        a.need_verlet = Some(1000);
        a.need_xpbd = 20;
        a.update((Integrator::Xpbd, 20), 2.0 * tol, 0.0, true);
        assert_eq!((a.method, a.substeps), (Integrator::Xpbd, 80));
        assert_eq!(a.interval, 1, "a raise is checked at the next step");
        // Within the band between a quarter of the tolerance and the tolerance: no change, and
        // the next estimate comes later.
        a.update((Integrator::Xpbd, 80), 0.5 * tol, 0.0, true);
        assert_eq!(a.substeps, 80);
        assert_eq!(a.interval, 2);
        // Lowered: not urgent, later still.
        a.update((Integrator::Xpbd, 80), 0.1 * tol, 0.0, true);
        assert_eq!((a.substeps, a.interval), (64, 4));
        // Within round-off: not raised however far above the tolerance.
        a.update((Integrator::Xpbd, 80), 3.0 * tol, 2.0 * tol, true);
        assert_eq!(a.substeps, 80);
        assert!(a.report.at_floor);
    }

    #[test]
    fn the_cheaper_method_is_chosen_and_verlet_only_where_allowed() {
        let mut a = controller();
        let tol = a.tolerance;
        // XPBD at 100 substeps meets the tolerance with room to spare, Verlet needs 100.
        a.method = Integrator::Xpbd;
        a.update((Integrator::Xpbd, 100), 0.5 * tol, 0.0, true);
        assert_eq!(a.method, Integrator::Xpbd);
        // XPBD needs 400: Verlet, at its 100.
        a.update((Integrator::Xpbd, 100), 2.0 * tol, 0.0, true);
        assert_eq!((a.method, a.substeps), (Integrator::Verlet, 100));
        // Where Verlet is not allowed (a pin jumping), XPBD at what it needs.
        a.update((Integrator::Xpbd, 100), 2.0 * tol, 0.0, false);
        assert_eq!((a.method, a.substeps), (Integrator::Xpbd, 256));
        assert!(a.report.at_cap);
    }

    #[test]
    fn the_copy_always_takes_fewer_substeps() {
        for n in 2..2000 {
            let c = coarse_substeps(n);
            assert!(c < n && c >= 1, "{n} {c}");
            assert!(n as f32 / c as f32 <= 2.0 + 1e-6);
        }
    }
}
