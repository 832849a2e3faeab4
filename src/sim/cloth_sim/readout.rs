//! What a cloth reports: its particles, settings and step count, energies and strains, and its
//! contacts' statistics (and, for tests and the harness, the contact work). Reads only, but for
//! [`ClothSim::set_velocities`].

use glam::Vec3;

use super::ClothSim;
#[cfg(doc)]
use super::Environment;
use crate::error::ClothError;
use crate::sim::contact::Reaction;
use crate::sim::model::{ClothModel, SpringKind, enclosed_volume};
use crate::sim::pressure::air_energy;
use crate::sim::settings::SolverSettings;
use crate::sim::state::Energy;

/// Diagnostics of a cloth's self-contacts ([`ClothSim::self_contact_stats`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SelfContactStats {
    /// Vertex–triangle pairs the last broad phase found close enough to meet before the next.
    pub vertex_triangle: usize,
    /// Edge–edge pairs the last broad phase found.
    pub edge_edge: usize,
    /// Broad phases run since self-collision was turned on (or its thickness or friction
    /// changed): none while the particles stay within the last one's reach (a cloth at rest),
    /// several within a step while the cloth's parts move fast relative to each other.
    pub searches: u64,
    /// Substeps whose pairs were resolved since self-collision was turned on: every substep
    /// while the cloth's parts move relative to each other, a few a step while it rests folded
    /// or piled (its layers approach too slowly to need more).
    pub resolutions: u64,
}

impl ClothSim {
    /// The topology this cloth was built from.
    pub fn model(&self) -> &ClothModel {
        &self.model
    }

    /// Current particle positions (world space).
    pub fn positions(&self) -> &[Vec3] {
        &self.particles.positions
    }

    /// Current particle velocities.
    pub fn velocities(&self) -> &[Vec3] {
        &self.particles.velocities
    }

    /// Sets every particle's velocity (for tests and initial conditions). A velocity that is not
    /// finite is [`ClothError::InvalidValue`] and changes nothing.
    pub fn set_velocities(&mut self, velocity: Vec3) -> Result<(), ClothError> {
        if let Some(&bad) = velocity.to_array().iter().find(|c| !c.is_finite()) {
            return Err(ClothError::InvalidValue {
                field: "velocity",
                expected: "finite",
                value: bad as f64,
            });
        }
        self.particles.velocities.fill(velocity);
        self.coarse_stale();
        self.wake();
        Ok(())
    }

    /// Moves every particle to `positions` with `velocities` (one each per particle, finite),
    /// as a teleport: nothing in between is collided with, and the cloth wakes. Pins, targets and
    /// the reference frame start the next step where they were last moved to (a pinned particle
    /// goes to its pin within it). A wrong length or a value that is not finite is an error and
    /// changes nothing.
    pub fn place(&mut self, positions: &[Vec3], velocities: &[Vec3]) -> Result<(), ClothError> {
        let n = self.particles.positions.len();
        for (field, list) in [("positions", positions), ("velocities", velocities)] {
            if list.len() != n {
                return Err(ClothError::InvalidValue {
                    field,
                    expected: "one per particle",
                    value: list.len() as f64,
                });
            }
            if let Some(v) = list.iter().find(|v| !v.is_finite()) {
                return Err(ClothError::InvalidValue {
                    field,
                    expected: "finite",
                    value: v.max_element().max(-v.min_element()) as f64,
                });
            }
        }
        self.particles.positions.copy_from_slice(positions);
        self.particles.velocities.copy_from_slice(velocities);
        self.coarse_stale();
        self.runaway = Default::default();
        for pin in &mut self.pins {
            pin.from = pin.to;
        }
        self.contacts.limits_mut().end_step();
        if let Some((from, to)) = &mut self.frame {
            *from = *to;
        }
        self.wake();
        Ok(())
    }

    /// Current settings.
    pub fn settings(&self) -> &SolverSettings {
        &self.settings
    }

    /// Number of steps taken so far.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Conjugate-gradient iterations taken in the last substep of implicit Euler (0 before the first
    /// implicit step, and for the other integrators).
    pub fn cg_iterations(&self) -> u32 {
        self.steppers.cg_iterations()
    }

    /// Mass of each particle, kg (pinned ones included).
    pub fn masses(&self) -> &[f32] {
        &self.particles.mass
    }

    /// Starts adding up the energy that contact responses put into the cloth: across each
    /// response, the larger of the rise of its total energy (kinetic, gravitational and elastic)
    /// and the rise of its potential energy plus the colliders' work on the particles' motion
    /// (impulse times surface velocity), when positive. A collider sweeping through a cloth
    /// stretches its springs and hands it its speed; the stress suite allows the cloth that
    /// energy. Costs an energy evaluation (one pass over the springs) before and after each
    /// substep's contact response.
    #[cfg(any(test, feature = "harness"))]
    pub(crate) fn track_contact_work(&mut self) {
        self.contact_work.get_or_insert(0.0);
    }

    /// The energy added up since [`track_contact_work`](Self::track_contact_work), J (`None` when
    /// not tracking).
    #[cfg(any(test, feature = "harness"))]
    pub(crate) fn contact_work(&self) -> Option<f64> {
        self.contact_work
    }

    /// Kinetic, gravitational and elastic energy of the free particles (see [`Energy`]).
    pub fn energy(&self) -> Energy {
        let mut e = self
            .particles
            .energy(self.spring_set(), self.settings.gravity);
        let triangles = &self.model.triangles;
        e.elastic += air_energy(self.air.as_ref(), triangles, &self.particles.positions);
        e
    }

    /// The volume a closed cloth encloses now, m³; `None` for a cloth that is not a closed
    /// surface wound outward (see [`ClothModel::check_closed`](crate::sim::ClothModel::check_closed)).
    pub fn volume(&self) -> Option<f32> {
        self.built_volume?;
        let x = &self.particles.positions;
        Some(enclosed_volume(&self.model.triangles, |i| x[i]) as f32)
    }

    /// The volume a closed cloth enclosed when it was built, m³ (see [`Self::volume`]).
    pub fn built_volume(&self) -> Option<f32> {
        self.built_volume
    }

    /// The pressure of the air inside above the air outside now, Pa; `None` while
    /// [`SolverSettings::pressure`](crate::sim::SolverSettings::pressure) is off. For
    /// [`Pressure::Volume`](crate::sim::Pressure::Volume) under XPBD, the pressure its
    /// compliance stands for (`K (V₀ − V) / V₀`).
    pub fn pressure(&self) -> Option<f32> {
        let air = self.air.as_ref()?;
        let x = &self.particles.positions;
        Some(air.gauge(enclosed_volume(&self.model.triangles, |i| x[i])) as f32)
    }

    /// Kinetic energy of the free particles, J.
    pub fn kinetic_energy(&self) -> f32 {
        self.particles
            .velocities
            .iter()
            .zip(self.particles.inv_mass.iter().zip(&self.particles.mass))
            .filter(|(_, (w, _))| **w > 0.0)
            .map(|(v, (_, m))| 0.5 * m * v.length_squared())
            .sum()
    }

    /// Relative stretch `(|d| - L) / L` of each spring of `kind`, in spring order.
    pub fn strains(&self, kind: SpringKind) -> impl Iterator<Item = f32> + '_ {
        let s = &self.model.springs;
        (0..s.len())
            .filter(move |&k| s.kind[k] == kind)
            .map(move |k| {
                let d = self.particles.positions[s.a[k] as usize]
                    .distance(self.particles.positions[s.b[k] as usize]);
                (d - s.rest[k]) / s.rest[k]
            })
    }

    /// Largest relative stretch `(|d| - L) / L` over the springs of `kind`.
    pub fn max_strain(&self, kind: SpringKind) -> f32 {
        self.strains(kind).fold(0.0, f32::max)
    }

    /// What the cloth's self-contacts did so far (all zero with self-collision off).
    pub fn self_contact_stats(&self) -> SelfContactStats {
        self.stepping()
            .contacts
            .self_contacts()
            .map_or(SelfContactStats::default(), |s| {
                let (vertex_triangle, edge_edge) = s.candidate_count();
                SelfContactStats {
                    vertex_triangle,
                    edge_edge,
                    searches: s.searches(),
                    resolutions: s.resolutions(),
                }
            })
    }

    /// Number of searches for contact candidates with other cloths run so far (see
    /// [`Environment::cloths`]): none while no other cloth comes within reach.
    pub fn cloth_contact_searches(&self) -> u64 {
        self.stepping().contacts.cloths().searches()
    }

    /// Number of substeps whose contacts with other cloths were resolved so far: every substep
    /// while the cloths approach each other, a few a step while one rests on another.
    pub fn cloth_contact_resolutions(&self) -> u64 {
        self.stepping().contacts.cloths().resolutions()
    }

    /// Number of colliders that passed the broad phase of the last step.
    pub fn active_colliders(&self) -> usize {
        self.stepping().contacts.active_count()
    }

    /// What the cloth took from each collider it touched during the last step: the sum of the
    /// contact impulses and their moment, per collider of the step's [`Environment::colliders`]
    /// (at most once each). The collider took the opposite: a game applies its negation to the
    /// body to make the coupling two-way.
    pub fn reactions(&self) -> impl Iterator<Item = &Reaction> {
        self.stepping().contacts.reactions()
    }
}
