//! One step of a cloth: its plan, the broad phases, sleep, the wind, the integrator's substeps,
//! the catch-up of dropped contacts, and the checks after it.

use glam::Vec3;

use super::{ClothSim, Environment};
use crate::error::ClothError;
use crate::sim::contact::bounds;
use crate::sim::integrate::{Spread, Step, add_contact_work};
use crate::sim::settings::Integrator;
use crate::sim::state::{first_not_finite, max_length};

impl ClothSim {
    /// Advances the cloth by `dt` seconds with nothing around it (see [`Self::step_in`]).
    pub fn step(&mut self, dt: f32) -> Result<(), ClothError> {
        self.step_in(dt, &Environment::default())
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

    pub(super) fn step_spread(
        &mut self,
        dt: f32,
        env: &Environment,
        spread: Option<&dyn Spread>,
    ) -> Result<(), ClothError> {
        if !(dt.is_finite() && dt > 0.0) {
            return Ok(());
        }
        if self.is_coarse() {
            return self.step_coarse(dt, env, spread);
        }
        // XPBD takes the air at any stiffness: only the integrators with a stability bound, and
        // the choices of `Auto` and tolerance mode, need the air's frequency.
        let bounded = self.settings.integrator != Integrator::Xpbd || self.adaptive.is_some();
        if self.air.is_some() && bounded {
            self.refresh_air_frequency();
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
    pub(super) fn step_planned(
        &mut self,
        dt: f32,
        env: &Environment,
        spread: Option<&dyn Spread>,
        plan: Option<(Integrator, u32)>,
        watch: bool,
    ) -> Result<(), ClothError> {
        // Asleep with nothing around that could wake it: skipped before any other work.
        if self.sleep.asleep
            && self.sleep.colliders == 0
            && env.colliders.is_empty()
            && env.cloths.is_empty()
            && env.wind.is_none()
            && !self.driven()
        {
            self.steps += 1;
            self.sleep.skipped = true;
            return Ok(());
        }
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
            air: self.air.as_ref(),
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
        if let Some(contacts) = self.contacts.self_contacts_mut() {
            contacts.release_parted(&self.particles.positions);
        }
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

    /// A generous bound on how far any particle can move in a step of `dt` when none is faster
    /// than `speed`: twice its free flight, plus gravity, plus the farthest pin or target jump,
    /// plus how far the frame carries it.
    pub(super) fn reach_bound(&self, dt: f32, speed: f32) -> f32 {
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
