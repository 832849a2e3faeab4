//! Sleep: a cloth whose free particles stay slower than [`SolverSettings::sleep_speed`] for
//! `sleep_steps` steps skips its steps until a pin, target, frame, wind or collider wakes it.

use glam::Vec3;

use super::{ClothSim, Environment};
use crate::sim::contact::bounds;
#[cfg(doc)]
use crate::sim::settings::SolverSettings;

/// The sleeping state of a cloth (see [`SolverSettings::sleep_speed`]).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Sleep {
    /// Consecutive steps with every free particle slower than the threshold.
    pub(super) quiet_steps: u32,
    /// Asleep: steps are skipped until something wakes the cloth.
    pub(super) asleep: bool,
    /// Colliders in reach when the cloth fell asleep (one arriving or leaving wakes it).
    pub(super) colliders: usize,
    /// Whether the last step was skipped.
    pub(super) skipped: bool,
    /// The cloth's bounding box while asleep.
    pub(super) bounds: (Vec3, Vec3),
}

impl ClothSim {
    /// Wakes a sleeping cloth (see [`SolverSettings::sleep_speed`]); it steps again from the
    /// next step and may fall asleep again after `sleep_steps` quiet steps.
    pub fn wake(&mut self) {
        self.sleep = Sleep::default();
        if let Some(coarse) = &mut self.coarse {
            coarse.wake();
        }
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

    /// Whether this step can be skipped: the cloth is asleep and nothing wakes it (no pin moves,
    /// no wind, no collider in reach moves, arrives or leaves). Runs after the broad phase.
    pub(super) fn sleeps_through(&mut self, env: &Environment) -> bool {
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
    pub(super) fn update_sleep(&mut self, env: &Environment, dt: f32) {
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
    pub(super) fn driven(&self) -> bool {
        self.pins.iter().any(|p| p.from != p.to)
            || self.contacts.limits().moving()
            || self.frame_motion().is_some()
    }
}
