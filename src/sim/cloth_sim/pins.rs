//! What drives a cloth from outside: pins, animated targets and the moving reference frame.

use glam::Vec3;

use super::ClothSim;
use crate::error::{ClothError, at_most};
use crate::sim::contact::{Pose, Target};
use crate::sim::settings::Inertia;
#[cfg(doc)]
use crate::sim::settings::SolverSettings;
use crate::sim::state::PinState;

impl ClothSim {
    /// Indices of the pinned particles.
    pub fn pinned(&self) -> impl Iterator<Item = u32> + '_ {
        self.pins.iter().map(|p| p.particle)
    }

    /// Replaces the pin set. Each pin is `(particle, target)`; a particle pinned for the first time
    /// moves to its target over the next step. Particles no longer listed are released with their
    /// current velocity. At most one pin per particle of the cloth ([`ClothError::TooMany`]
    /// past that, counted as they come: an endless iterator is refused, not collected).
    pub fn set_pins(
        &mut self,
        pins: impl IntoIterator<Item = (u32, Vec3)>,
    ) -> Result<(), ClothError> {
        let count = self.particles.positions.len();
        let mut new = Vec::new();
        for (particle, target) in pins {
            at_most("pins", new.len() + 1, count, || {
                format!("one per particle of the cloth, which has {count}; counting stopped there")
            })?;
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
    /// its target. Bad input (more targets than particles, a particle out of range, a negative
    /// or non-finite weight, a non-finite position or normal) is an error and changes nothing.
    pub fn set_targets(&mut self, targets: &[Target]) -> Result<(), ClothError> {
        let count = self.particles.positions.len();
        at_most("targets", targets.len(), count, || {
            format!("one per particle of the cloth, which has {count}")
        })?;
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
    pub(super) fn frame_motion(&self) -> Option<(Pose, Pose, Inertia)> {
        let inertia = self.settings.inertia;
        self.frame
            .filter(|(from, to)| !inertia.is_world() && from != to)
            .map(|(from, to)| (from, to, inertia))
    }
}
