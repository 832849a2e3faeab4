//! The runaway watch: an explicit integrator run past its stability bound is stopped, with
//! [`ClothError::Unstable`], once its energy grows like an unstable mode's.

use super::ClothSim;
use crate::error::ClothError;
#[cfg(doc)]
use crate::sim::settings::MAX_SUBSTEPS;

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
pub(super) struct Runaway {
    /// Kinetic plus elastic energy after the last step, J.
    pub(super) energy: f64,
    /// Energy when the current streak of growth began, J.
    pub(super) streak_start: f64,
    /// Consecutive steps in which the energy grew by at least [`RUNAWAY_GROWTH`].
    pub(super) streak: u32,
    /// Kinetic plus elastic energy at the start of the current step, J (past the bound only).
    pub(super) before: f64,
    /// Kinetic plus elastic energy when the current run of steps past the bound began, J, and
    /// that step's number; `None` within the bound.
    pub(super) entered: Option<(f64, u64)>,
}

impl ClothSim {
    /// For an explicit integrator run past its stability bound (`h ω_max ≥ 2`, possible with
    /// `auto_substeps` off or at [`MAX_SUBSTEPS`], or fewer substeps than its bound asks for,
    /// held back by the cap): an error once the kinetic plus elastic energy
    /// has grown by [`RUNAWAY_GROWTH`]× in each of [`RUNAWAY_STEPS`] consecutive steps, the
    /// signature of an unstable mode (gravity, pins or wind add energy far more slowly), or by
    /// [`RUNAWAY_STEP_GROWTH`]× in one step over its start plus the whole cloth's weight lifted a
    /// metre (a mode unstable enough to do that within a step's substeps), or by
    /// [`RUNAWAY_PAST_GROWTH`]× over the same since the run of steps past the bound began. Within
    /// the bound this costs nothing.
    pub(super) fn check_runaway(
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
}
