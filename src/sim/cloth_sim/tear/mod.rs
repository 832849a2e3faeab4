//! Tearing: springs stretched past [`Tearing::max_stretch`](crate::sim::settings::Tearing) and
//! cuts from the API split particles, and the cloth goes on with the torn topology.

use bevy::reflect::Reflect;
use glam::Vec3;
use serde::{Deserialize, Serialize};

use super::ClothSim;
use crate::error::{ClothError, finite_vec3, positive};
use crate::sim::model::{ClothModel, Splitter, pull_apart};
use crate::sim::settings::Pressure;

/// A cut through a cloth, in world space ([`ClothSim::tear`]). Cuts follow the cloth's edges: a
/// particle whose faces lie on both sides of the cut is split, one particle per side.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Reflect)]
pub enum Cut {
    /// The whole cloth cut by a plane: faces whose centres lie on the side `normal` points to are
    /// separated from the others.
    Plane {
        /// A point of the plane.
        point: Vec3,
        /// The plane's normal (any length but zero).
        normal: Vec3,
    },
    /// A blade drawn from `start` to `end` across the cloth (a sword's slash, a knife's cut): the
    /// plane through the segment, across the cloth (containing the cloth's mean normal near the
    /// segment), cuts the cloth where it is within `radius` of the segment.
    Segment {
        /// Where the blade starts.
        start: Vec3,
        /// Where it ends.
        end: Vec3,
        /// How far from the segment the cloth is cut, m (positive): at least the cloth's distance
        /// from the blade and about its edge length.
        radius: f32,
    },
    /// A hole punched by a ray (a cannonball through a sail): the faces whose centres lie within
    /// `radius` of the ray, ahead of its origin, are cut out as a piece of their own. Every layer
    /// the ray crosses is holed.
    Ray {
        /// Where the ray starts.
        origin: Vec3,
        /// Its direction (any length but zero).
        direction: Vec3,
        /// The hole's radius, m (positive).
        radius: f32,
    },
}

impl Cut {
    /// Checks every value is finite, directions are not zero and radii are positive.
    pub fn validate(&self) -> Result<(), ClothError> {
        let nonzero = |field: &'static str, v: Vec3| {
            if v.length_squared() > 0.0 && v.length_squared().is_finite() {
                Ok(())
            } else {
                Err(ClothError::InvalidValue {
                    field,
                    expected: "a direction: finite, not zero",
                    value: f64::from(v.length()),
                })
            }
        };
        match *self {
            Cut::Plane { point, normal } => {
                finite_vec3(["cut point.x", "cut point.y", "cut point.z"], point)?;
                nonzero("cut normal", normal)
            }
            Cut::Segment { start, end, radius } => {
                finite_vec3(["cut start.x", "cut start.y", "cut start.z"], start)?;
                finite_vec3(["cut end.x", "cut end.y", "cut end.z"], end)?;
                nonzero("cut end - start", end - start)?;
                positive("cut radius", radius)
            }
            Cut::Ray {
                origin,
                direction,
                radius,
            } => {
                finite_vec3(["cut origin.x", "cut origin.y", "cut origin.z"], origin)?;
                nonzero("cut direction", direction)?;
                positive("cut radius", radius)
            }
        }
    }
}

/// One particle split by a tear: `copy` is the new particle that took some of `particle`'s faces,
/// at `position` (world space) when it split.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Split {
    /// The particle that split (it keeps the faces on one side).
    pub particle: u32,
    /// The particle made for the faces on the other side.
    pub copy: u32,
    /// Where the split happened, world space.
    pub position: Vec3,
}

impl ClothSim {
    /// Tears the cloth: along each of `cuts`, then, with [`Tearing`](crate::sim::Tearing) on,
    /// where springs are stretched past its limit (the most stretched first, at most
    /// `max_per_step` splits). A spring tears at its end that is free (a pinned particle does not
    /// split under strain) and already on an edge of the cloth, if one is: the faces around it
    /// on the far side of the plane across the spring go to a copy of it, so the tear runs across
    /// the spring and grows from its tip.
    ///
    /// The cloth goes on from where it is with the torn topology: copies start where their
    /// particle is, moving as it moves, and keep its targets and tear weight; pins hold the
    /// particles that keep their indices (a copy of a pinned particle is free). A piece torn off
    /// every pin (and every target of weight 0) while another piece keeps one loses its targets
    /// and falls free. Springs are rebuilt from the faces as [`ClothModel::from_mesh`] builds
    /// them (hand-made springs of a model are replaced), masses are shared by the faces' areas on
    /// each side (so the model holds per-particle masses from then on), and a torn closed cloth
    /// loses its air. Returns the splits (none: nothing changed). A bad cut is an error and
    /// changes nothing.
    pub fn tear(&mut self, cuts: &[Cut]) -> Result<Vec<Split>, ClothError> {
        for cut in cuts {
            cut.validate()?;
        }
        let tearing = self.settings.tearing;
        if cuts.is_empty() && !tearing.enabled {
            return Ok(Vec::new());
        }
        let overstretched = if tearing.enabled {
            self.torn_springs()
        } else {
            Vec::new()
        };
        if cuts.is_empty() && overstretched.is_empty() {
            return Ok(Vec::new());
        }
        let positions = &self.particles.positions;
        let mut splitter = Splitter::new(&self.model, &self.particles.mass);
        for cut in cuts {
            cut_through(&mut splitter, &self.model, cut, positions);
        }
        let mut torn = vec![false; positions.len()];
        let mut strained = 0;
        for (a, b) in overstretched {
            if strained >= tearing.max_per_step as usize {
                break;
            }
            if torn[a as usize] || torn[b as usize] {
                continue;
            }
            let free = |p: u32| self.particles.inv_mass[p as usize] > 0.0;
            // The free end, preferring one on an edge of the cloth: the tear's tip.
            let mut ends = [(a, b), (b, a)];
            ends.sort_by_key(|&(p, _)| (!free(p), !splitter.on_boundary(p)));
            for (p, q) in ends.into_iter().filter(|&(p, _)| free(p)) {
                let from = positions[p as usize];
                let across = positions[q as usize] - from;
                let copies = splitter.split(p, positions, |c| (c - from).dot(across) > 0.0);
                if !copies.is_empty() {
                    torn[a as usize] = true;
                    torn[b as usize] = true;
                    strained += copies.len();
                    break;
                }
            }
        }
        let copies: Vec<(u32, u32)> = splitter.copies().collect();
        if copies.is_empty() {
            return Ok(Vec::new());
        }
        let splits = copies
            .iter()
            .map(|&(particle, copy)| Split {
                particle,
                copy,
                position: positions[particle as usize],
            })
            .collect();
        // A self-colliding cloth's sides are pulled apart by the thickness, so that they are
        // layers on either side of a gap rather than one.
        let c = self.settings.self_collision;
        let gap = if c.enabled { 0.6 * c.thickness } else { 0.0 };
        // Pinned particles stay where their pins hold them.
        let apart: Vec<u32> = copies
            .iter()
            .flat_map(|&(p, c)| [p, c])
            .filter(|&p| self.pins.iter().all(|pin| pin.particle != p))
            .collect();
        let model = splitter.finish((&apart, gap))?;
        self.continue_torn(model, &copies, (&apart, gap))?;
        Ok(splits)
    }

    /// The springs of a kind that tears stretched past the limit, the most stretched first.
    fn torn_springs(&self) -> Vec<(u32, u32)> {
        let x = &self.particles.positions;
        let stretched = |&(a, b, limit): &(u32, u32, f32)| {
            x[a as usize].distance_squared(x[b as usize]) > limit
        };
        // Nearly every step nothing tears: a pass with no branch to take first.
        if !self
            .tear_limits
            .iter()
            .fold(false, |any, s| any | stretched(s))
        {
            return Vec::new();
        }
        let mut over: Vec<(f32, u32, u32)> = Vec::new();
        for &(a, b, limit) in &self.tear_limits {
            let length = x[a as usize].distance_squared(x[b as usize]);
            if length > limit {
                over.push((length / limit, a, b));
            }
        }
        over.sort_by(|p, q| q.0.total_cmp(&p.0).then((p.1, p.2).cmp(&(q.1, q.2))));
        over.into_iter().map(|(_, a, b)| (a, b)).collect()
    }

    /// The springs that tear with the settings' [`Tearing`](crate::sim::Tearing), each with the
    /// square of the length it tears past (none while tearing is off).
    pub(super) fn prepare_tearing(&mut self) {
        let tearing = self.settings.tearing;
        self.tear_limits.clear();
        if !tearing.enabled {
            return;
        }
        let weights = self.tear_weights.as_deref();
        let weight = |p: u32| weights.map_or(1.0, |w| w[p as usize]);
        let s = &self.model.springs;
        let springs = s.a.iter().zip(&s.b).zip(&s.rest).zip(&s.kind);
        self.tear_limits
            .extend(springs.filter(|(_, kind)| tearing.tears(**kind)).map(
                |(((&a, &b), &rest), _)| {
                    let stretch = tearing.max_stretch * weight(a).min(weight(b));
                    (a, b, ((1.0 + stretch) * rest).powi(2))
                },
            ));
        // In particle order the check walks the positions once, rather than once per colour.
        self.tear_limits.sort_unstable_by_key(|&(a, b, _)| (a, b));
    }

    /// Scales [`Tearing::max_stretch`](crate::sim::Tearing) particle by particle, a weight per
    /// particle (`None`: 1 everywhere): a spring tears past `1 + max_stretch · w` times its rest
    /// length, `w` the smaller of its ends' weights. A weight of 0 tears at any stretch (a
    /// perforated line), 2 takes twice the stretch, a very large one never tears. Copies a tear
    /// makes take their particle's weight. A weight that is negative or not finite, or a list of
    /// another length than the particles, is an error and changes nothing.
    pub fn set_tear_weights(&mut self, weights: Option<Vec<f32>>) -> Result<(), ClothError> {
        if let Some(w) = &weights {
            let n = self.particles.positions.len();
            if w.len() != n {
                return Err(ClothError::InvalidValue {
                    field: "tear weights",
                    expected: "one per particle",
                    value: w.len() as f64,
                });
            }
            for &x in w {
                crate::error::non_negative("tear weight", x)?;
            }
        }
        self.tear_weights = weights;
        self.prepare_tearing();
        Ok(())
    }

    /// The tear weights ([`Self::set_tear_weights`]), if set.
    pub fn tear_weights(&self) -> Option<&[f32]> {
        self.tear_weights.as_deref()
    }

    /// Replaces the cloth by `model`, its torn self with the `copies` made (each `(particle,
    /// copy)`), going on from where it is: the copies where their particles are, the pins, the
    /// targets and tear weights (a copy takes its particle's), the frame and the step count as
    /// they were.
    fn continue_torn(
        &mut self,
        model: ClothModel,
        copies: &[(u32, u32)],
        (apart, gap): (&[u32], f32),
    ) -> Result<(), ClothError> {
        let mut settings = self.settings;
        // An open cloth holds no air; the setting stays, as it is for any cloth torn open.
        settings.pressure = Pressure::Off;
        let mut next = ClothSim::assemble(model, settings, |p| p)?;
        let n = self.particles.positions.len();
        let origins = (0..n as u32).chain(copies.iter().map(|&(p, _)| p));
        let p = &mut next.particles;
        for ((x, v), o) in p.positions.iter_mut().zip(&mut p.velocities).zip(origins) {
            *x = self.particles.positions[o as usize];
            *v = self.particles.velocities[o as usize];
        }
        let (faces, size) = (&next.model.faces, next.model.face_size);
        pull_apart(faces, size, &mut next.particles.positions, apart, gap);
        next.settings.pressure = self.settings.pressure;
        next.tears = self.tears + copies.len() as u64;
        next.pins = std::mem::take(&mut self.pins);
        next.tear_weights = self.tear_weights.take().map(|w| {
            let copied = copies.iter().map(|&(p, _)| w[p as usize]);
            w.iter().copied().chain(copied).collect()
        });
        next.contacts
            .limits_mut()
            .inherit_targets(self.contacts.limits(), copies);
        next.release_loose_pieces();
        next.frame = self.frame;
        next.steps = self.steps;
        // The runaway watch keeps its memory: a cloth that tears every step would otherwise
        // start it afresh each time and never be stopped.
        next.runaway = self.runaway;
        next.contact_work = self.contact_work;
        next.detail = self.detail;
        next.part_the_sides();
        next.apply_settings();
        *self = next;
        Ok(())
    }

    /// Marks the self-contacts' exempt pairs (within the thickness at rest) that no spring joins
    /// as parting: the two sides of a tear lay within the thickness at rest, and are kept apart by
    /// less until they have parted by it.
    pub(super) fn part_the_sides(&mut self) {
        let s = &self.model.springs;
        let mut linked: Vec<u64> =
            s.a.iter()
                .zip(&s.b)
                .map(|(&a, &b)| u64::from(a.min(b)) << 32 | u64::from(a.max(b)))
                .collect();
        linked.sort_unstable();
        if let Some(contacts) = self.contacts.self_contacts_mut() {
            contacts.mark_parting(|p, q| {
                let key = u64::from(p.min(q)) << 32 | u64::from(p.max(q));
                p == q || linked.binary_search(&key).is_ok()
            });
        }
    }

    /// Drops the targets of the pieces torn off everything that holds the cloth: where some
    /// piece has a pinned particle (or a target of weight 0), the pieces without one fall free.
    fn release_loose_pieces(&mut self) {
        let (count, pieces) = self.model.pieces();
        if count < 2 {
            return;
        }
        let mut held = vec![false; count];
        let limits = self.contacts.limits_mut();
        let weightless = limits.targeted().filter(|&(_, w)| w == 0.0).map(|(p, _)| p);
        for p in self.pins.iter().map(|pin| pin.particle).chain(weightless) {
            held[pieces[p as usize] as usize] = true;
        }
        if held.contains(&true) {
            limits.retain_targets(|p| held[pieces[p as usize] as usize]);
        }
    }

    /// The particles tied to targets ([`Self::set_targets`]), in the order they were given (a
    /// tear gives copies their particle's targets, after them, and drops those of pieces torn
    /// free).
    pub fn targeted(&self) -> impl Iterator<Item = u32> + '_ {
        self.contacts.limits().targeted().map(|(p, _)| p)
    }

    /// Particles split by tears since the cloth was built.
    pub fn tears(&self) -> u64 {
        self.tears
    }
}

/// Splits the particles `cut` passes through, the model's particles at `positions`.
fn cut_through(splitter: &mut Splitter, model: &ClothModel, cut: &Cut, positions: &[Vec3]) {
    // Copies made by earlier cuts are cut again where a later cut crosses them.
    let n = splitter.particle_count() as u32;
    let at = |splitter: &Splitter, p: u32| positions[splitter.origin(p) as usize];
    match *cut {
        Cut::Plane { point, normal } => {
            for p in 0..n {
                splitter.split(p, positions, |c| (c - point).dot(normal) > 0.0);
            }
        }
        Cut::Segment { start, end, radius } => {
            let along = end - start;
            let near = |x: Vec3| {
                let t = ((x - start).dot(along) / along.length_squared()).clamp(0.0, 1.0);
                x.distance_squared(start + t * along) <= radius * radius
            };
            // Across the cloth: the plane holds the segment and the mean normal of the
            // triangles at the particles it cuts.
            let normal: Vec3 = model
                .triangles
                .chunks_exact(3)
                .map(|t| [0, 1, 2].map(|k| positions[t[k] as usize]))
                .filter(|corners| corners.iter().any(|&x| near(x)))
                .map(|[a, b, c]| (b - a).cross(c - a))
                .sum();
            let across = along.cross(normal);
            if !(across.length_squared() > 0.0 && across.is_finite()) {
                return;
            }
            for p in 0..n {
                if near(at(splitter, p)) {
                    splitter.split(p, positions, |c| (c - start).dot(across) > 0.0);
                }
            }
        }
        Cut::Ray {
            origin,
            direction,
            radius,
        } => {
            let d = direction.normalize();
            let inside = |c: Vec3| {
                let t = (c - origin).dot(d);
                t >= 0.0 && (c - origin - t * d).length_squared() < radius * radius
            };
            for p in 0..n {
                splitter.split(p, positions, inside);
            }
        }
    }
}

#[cfg(test)]
mod tests;
