//! Snapshots of a cloth's particles: the copies the narrow phase reads and writes, and where the
//! particles were at the last resolution, which lets a substep defer the next.

use glam::Vec3;

use crate::sim::contact::narrow::ContactState;
use crate::sim::contact::vectors::Vectors;
use crate::sim::soa::Soa;

/// How much closer than at their last resolution, as a share of the thickness, any two of the
/// cloth's particles may have come before its pairs are resolved again (see [`LastResolution`]): a
/// resting fold or pile, whose layers approach each other by micrometres a substep, is resolved
/// every few substeps instead of every one, and no layer sinks more than this into another
/// meanwhile. Far below what a crossing needs (a pair closing by its whole kept distance).
pub(in crate::sim::contact) const DEFER_CLOSING: f32 = 0.25;

/// Copies of some particles of a [`ContactState`] (each one's start, position, velocity and
/// inverse mass), for a narrow phase that visits each many times.
#[derive(Debug, Clone, Default)]
pub(in crate::sim::contact) struct GatheredParticles {
    pub(in crate::sim::contact) start: Vec<Vec3>,
    pub(in crate::sim::contact) x: Vec<Vec3>,
    pub(in crate::sim::contact) v: Vec<Vec3>,
    pub(in crate::sim::contact) inv_mass: Vec<f32>,
}

impl GatheredParticles {
    /// Copies the stored particles `which` out of `state`.
    pub(in crate::sim::contact) fn read<S: ContactState>(&mut self, state: &S, which: &[u32]) {
        let at = which.iter().map(|&s| s as usize);
        self.start.clear();
        self.start.extend(at.clone().map(|s| state.start(s)));
        self.x.clear();
        self.x.extend(at.clone().map(|s| state.position(s)));
        self.v.clear();
        self.v.extend(at.clone().map(|s| state.velocity(s)));
        self.inv_mass.clear();
        self.inv_mass.extend(at.map(|s| state.inv_mass(s)));
    }

    /// The copies as a state of their own (particle `k` is `which[k]` of [`Self::read`]).
    pub(in crate::sim::contact) fn state(&mut self) -> Vectors<'_> {
        Vectors {
            x: &mut self.x,
            v: &mut self.v,
            start: &self.start,
            inv_mass: &self.inv_mass,
            touches: None,
        }
    }

    /// Writes back into `state` the particles of `which` (as read) whose copies changed, and lists
    /// them in `moved`.
    pub(in crate::sim::contact) fn write<S: ContactState>(
        &self,
        state: &mut S,
        which: &[u32],
        moved: &mut Vec<u32>,
    ) {
        moved.clear();
        for ((&s, x), v) in which.iter().zip(&self.x).zip(&self.v) {
            let s = s as usize;
            // Bit for bit, so that a particle that is not a number is not written back.
            let same =
                |a: Vec3, b: Vec3| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits);
            if !same(*x, state.position(s)) || !same(*v, state.velocity(s)) {
                state.set(s, *x, *v);
                moved.push(s as u32);
            }
        }
    }
}

/// Whether `state` stores the particles in another order than `slot` (where each was stored).
pub(in crate::sim::contact) fn storage_order_changed<S: ContactState>(
    state: &S,
    slot: &[u32],
) -> bool {
    slot.len() != state.len()
        || (slot.iter().enumerate()).any(|(p, &s)| state.slot(p as u32) != s as usize)
}

/// Where a cloth's particles were when its pairs were last resolved (each then at least its kept
/// distance apart, or being pushed there), and the substeps deferred since: while no pair can have
/// crossed or come more than [`DEFER_CLOSING`] of its kept distance closer since, a substep's resolution
/// is deferred, for one vector pass over the particles. Every displacement since lies within a
/// distance `r` of a common vector `c`, so two of the cloth's particles have come at most `2 r`
/// closer, and one of them and a point that moved by `e` at most `r + |c| + e`.
#[derive(Debug, Clone, Default)]
pub(in crate::sim::contact) struct LastResolution {
    /// Each stored particle's position at the last resolution.
    at: Soa,
    /// The common displacement since then expected at the next substep.
    guess: Vec3,
    /// Whether `at` holds the last resolution's positions in the state's current order.
    valid: bool,
    /// Whether this step's storage order has been compared with the last one's.
    pub(in crate::sim::contact) order_checked: bool,
    /// Substeps deferred since the last resolution.
    pub deferred: u32,
    /// Whether this substep resolved the pairs and its end is to be taken.
    pub due: bool,
}

impl LastResolution {
    /// Keeps `state`'s positions after a resolution.
    pub fn take<S: ContactState>(&mut self, state: &S) {
        state.ends(&mut self.at);
        self.guess = Vec3::ZERO;
        self.valid = true;
        self.deferred = 0;
    }

    /// No resolution to defer from.
    pub fn forget(&mut self) {
        self.valid = false;
        self.deferred = 0;
    }

    /// Whether `within(r, c)` holds for the particles of `state` since the last resolution (see
    /// the type's docs); then the substep is counted as deferred. False without a snapshot, or
    /// if a displacement is not finite.
    pub fn holds<S: ContactState>(
        &mut self,
        state: &S,
        within: impl FnOnce(f32, Vec3) -> bool,
    ) -> bool {
        let n = state.len();
        if !self.valid || self.at.len() != n || n == 0 {
            return false;
        }
        let c = self.guess;
        let since = state.since(&self.at, c);
        // The next substep is expected to move like this one.
        self.guess = (since.moved + since.step) / n as f32;
        // `worst` is infinite for a displacement that is not finite.
        let holds = since.worst.is_finite() && within(since.worst.sqrt(), c);
        if holds {
            self.deferred += 1;
        }
        holds
    }
}
