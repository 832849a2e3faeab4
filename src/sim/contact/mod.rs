//! Collisions between a cloth and colliders (spheres, capsules, cuboids and half-spaces, and any
//! other shape through the `Surface` queries; moving as given, or giving way as a body does),
//! and of a cloth with itself (`self_contact`, resolved right after the colliders in the same
//! substeps and on the same `ContactState`s; its pipeline is in that module's docs) and with
//! other cloths (`cloths`, right after the self-contacts, with the same pair response).
//! The limits on where a particle may go (`limits`: a maximum distance from an animated target,
//! a backstop behind it, tethers to the pins) are resolved in the same pass, just before the
//! colliders.
//!
//! # Pipeline, per step and per substep
//! 1. **Broad phase** (once per step, `Contacts::begin_step`): the cloth's bounding box, grown by
//!    the farthest any particle can travel in the step, against each collider's box swept from its
//!    start pose to its end pose and grown by its margin. Colliders that cannot be reached, or whose
//!    `layers` or `filters` do not meet the cloth's mask, are dropped for the whole step and cost
//!    nothing more.
//!    The reach assumes the particles' speeds at the step's start; a particle flung farther (by a
//!    spring stretched far from rest) is caught after the step (`Contacts::catch_up`): the
//!    dropped colliders its straight path comes near are resolved once over the whole step.
//! 2. **Narrow phase** (every substep, `Contacts::resolve_state`, on whatever layout the integrator
//!    keeps its particles in: `ContactState`): the collider's pose is interpolated to the end of the
//!    substep. A vector pass first skips every particle whose distance from the collider's bounding
//!    ball (or plane), less how far it moved, exceeds the ball's radius, the margin and the
//!    collider's travel. Each remaining free particle is taken into the collider's local frame and
//!    tested by the shape's signed distance `d`. A particle with `d < margin` is in contact. A
//!    particle that started the substep clear and whose path in the collider's frame (start to
//!    end of the substep) passes within the margin, whether it ends outside (it tunnelled) or
//!    inside, goes back to the first touching point of that path, found by a swept test (sphere
//!    tracing, exact because every signed distance here is exact): the nearest surface of where
//!    it ended may be the far side of a thin collider. A particle that started in contact is
//!    pushed out along the nearest surface, unless it went through: it ends inside where the
//!    nearest surface faces away from or across the one it started at, or ends outside after its
//!    path reached more than the margin below the surface (through a thin collider, or across a
//!    corner). Then it is pushed out to the tangent plane of where it started, plus the margin:
//!    a convex shape lies behind that plane, so the particle ends clear on its own side and keeps
//!    its motion along the surface.
//!    Spheres smaller than the cloth's longest edge are also tested against every triangle, so a
//!    small sphere cannot slip between particles.
//! 3. **Response**, per contact: the particle is projected to the surface plus margin, along the
//!    outward normal `n`. The relative velocity `v - v_c` (collider velocity at the contact point,
//!    linear and angular) is split into its normal part, whose inward component is removed (the
//!    push-out itself adds no velocity, so a contact never adds energy), and its tangential part,
//!    which Coulomb friction acts on: the particle's tangential displacement relative to the
//!    collider over the substep, `d_t`, is compared with the normal correction `δ`. If
//!    `|d_t| ≤ μ_s δ` the particle sticks (its relative tangential displacement and velocity are
//!    removed, so a moving collider drags it along); otherwise both are reduced by the fraction
//!    `μ_k δ / |d_t|` (kinetic friction: the tangential velocity drops by `μ_k` times the normal
//!    velocity removed). Friction only ever shrinks relative tangential motion.
//!
//! Because the narrow phase runs every substep on the interpolated pose, a collider moving up to
//! `margin × substeps / dt` cannot carry its surface past a particle between two tests; faster ones
//! are caught by the swept test.
//!
//! # Relation to the source paper
//! The source paper (named in the crate docs) detects cloth–sphere contact with a bounding volume and, in its Eq. 3 and Figure 4, moves
//! a penetrating particle back to radius + 0.05 along the line from the centre and splits its velocity
//! into a normal part (reflected and damped) and a tangential part (kept, scaled by a friction
//! factor). Here the bounding volume is the broad phase above; the push-out is the same projection
//! with `margin` in place of 0.05 and the exact signed distance in place of the centre line (they
//! agree for a sphere); the normal part is removed rather than reflected (a fully inelastic contact,
//! the paper's damping taken to its limit, so contacts never add energy); and the tangential factor
//! becomes Coulomb's law with static and kinetic coefficients, measured relative to the collider's
//! own velocity.
//!
//! # Layout
//! `shapes` (colliders and their queries), `narrow` (the narrow phase and response against
//! colliders, on any `ContactState`), `simd_passes` (the vector passes over a structure-of-arrays
//! state), `limits` (targets, backstops, tethers); `pairs` (what the contacts of a cloth with itself
//! and with other cloths share: the response to a vertex–triangle or edge–edge pair, the spatial
//! hash, the snapshots, the bands of distance), below `self_contact` (a cloth with itself: search,
//! cubes, patches) and `cloths` (a cloth with other cloths). Imports between these run one way.

mod cloths;
mod limits;
mod narrow;
mod pairs;
mod self_contact;
mod shapes;
mod simd_passes;
#[cfg(test)]
mod tests;
mod vectors;

use glam::Vec3;

use crate::sim::state::max_distance;
pub(crate) use cloths::ClothContacts;
pub use cloths::OtherCloth;
pub(crate) use limits::Limits;
pub use limits::Target;
pub(crate) use narrow::ContactState;
pub use narrow::Reaction;
#[cfg(feature = "harness")]
pub(crate) use narrow::convex_minimum;
use narrow::{ActiveCollider, resolve, resolve_among};
pub(crate) use self_contact::SelfContacts;
pub(crate) use shapes::Near;
pub use shapes::{Collider, ColliderShape, Friction, Pose, Shape, Surface, bounds};
pub(crate) use simd_passes::{Since, soa_clearances, soa_displaced, soa_ends, soa_since};
pub(crate) use vectors::Touch;
use vectors::Vectors;

/// Per-cloth collision state: the colliders that survived this step's broad phase, the particle
/// positions at the start of the current substep (for states without their own, see
/// [`Contacts::resolve`]) and the particles' clearances. Buffers are reused from step to step;
/// they grow (allocate) only when a step has more active colliders than any step before.
#[derive(Debug, Clone, Default)]
pub(crate) struct Contacts {
    active: Vec<ActiveCollider>,
    /// Particle positions at the start of the current substep.
    start: Vec<Vec3>,
    /// Each particle's clearance from the collider being resolved (scratch).
    clearance: Vec<f32>,
    /// The longest edge of the cloth's triangles at rest, m: spheres smaller than this get the
    /// particle–triangle test.
    max_edge: f32,
    /// The mean length of the cloth's triangles' edges at rest, m (0 without triangles): the
    /// distance kept from other cloths is bounded by it.
    mean_edge: f32,
    /// The cloth's contacts with itself, when enabled.
    self_contacts: Option<SelfContacts>,
    /// Targets and tethers, resolved before the colliders.
    limits: Limits,
    /// The box the broad phase kept colliders in reach of this step, and whether it dropped one
    /// on the cloth's mask (see [`Self::catch_up`]).
    reach_box: (Vec3, Vec3),
    dropped: bool,
    /// Colliders [`Self::catch_up`] found (scratch).
    late: Vec<ActiveCollider>,
    /// The cloth's contacts with the other cloths of the step.
    cloths: ClothContacts,
}

impl Contacts {
    /// Sized for a cloth of `particles` particles whose longest and mean rest edges are
    /// `max_edge` and `mean_edge` long.
    pub fn new(particles: usize, (max_edge, mean_edge): (f32, f32)) -> Self {
        Self {
            active: Vec::new(),
            start: vec![Vec3::ZERO; particles],
            clearance: vec![0.0; particles],
            max_edge,
            mean_edge,
            self_contacts: None,
            limits: Limits::default(),
            reach_box: (Vec3::ZERO, Vec3::ZERO),
            dropped: false,
            late: Vec::new(),
            cloths: ClothContacts::default(),
        }
    }

    /// Turns self-contacts on (with their topology and exempt pairs) or off.
    pub fn set_self_contacts(&mut self, self_contacts: Option<SelfContacts>) {
        self.self_contacts = self_contacts;
    }

    /// The cloth's self-contacts, when enabled.
    pub fn self_contacts(&self) -> Option<&SelfContacts> {
        self.self_contacts.as_ref()
    }

    /// The self-contacts, to change.
    pub fn self_contacts_mut(&mut self) -> Option<&mut SelfContacts> {
        self.self_contacts.as_mut()
    }

    /// Starts a step for the self-contacts, in which no particle is expected to move farther than
    /// `reach`, m (see [`SelfContacts::begin_step`]).
    pub fn begin_self_step(&mut self, reach: f32) {
        if let Some(s) = &mut self.self_contacts {
            s.begin_step(reach);
        }
    }

    /// The broad phase against the other cloths of a step of `dt` seconds, for a cloth whose
    /// layers are `spacing` (thickness, friction) thick, whose box at the start of the step is
    /// `bounds` and whose particles move at most `reach` in it (see [`ClothContacts`]).
    pub fn begin_cloth_step(
        &mut self,
        others: &[OtherCloth],
        spacing: (f32, f32),
        (bounds, reach): ((Vec3, Vec3), f32),
        dt: f32,
    ) {
        self.cloths.begin_step(
            others,
            spacing,
            (bounds, reach),
            (self.max_edge, self.mean_edge),
            dt,
        )
    }

    /// The contacts with other cloths.
    pub fn cloths(&self) -> &ClothContacts {
        &self.cloths
    }

    /// The targets and tethers.
    pub fn limits(&self) -> &Limits {
        &self.limits
    }

    /// The targets and tethers, to edit.
    pub fn limits_mut(&mut self) -> &mut Limits {
        &mut self.limits
    }

    /// Brings the particles at `x` (which started the step at `start`, velocities `v`) back
    /// within their targets and tethers as they are at the end of a step of `dt`, as the step's
    /// last substep would.
    pub fn hold_to_limits(
        &self,
        (x, v, start): (&mut [Vec3], &mut [Vec3], &[Vec3]),
        inv_mass: &[f32],
        dt: f32,
    ) {
        let mut state = Vectors {
            x,
            v,
            start,
            inv_mass,
            touches: None,
        };
        self.limits.resolve((0.0, 1.0, dt), &mut state);
    }

    /// Whether anything is resolved this step: a collider or another cloth survived the broad
    /// phase, the cloth collides with itself, or it has targets or tethers.
    pub fn is_active(&self) -> bool {
        !self.active.is_empty()
            || self.self_contacts.is_some()
            || !self.limits.is_empty()
            || self.cloths.is_active()
    }

    /// Number of colliders that survived the broad phase of this step.
    pub fn active_count(&self) -> usize {
        self.active.len()
    }

    /// The broad phase: keeps the colliders on `mask` that the cloth can reach during a step of
    /// `dt` seconds. `bounds` is the cloth's bounding box at the start of the step (see
    /// [`bounds`]); `reach` bounds how far any particle can move in the step. With `two_way`,
    /// colliders with a body give way to the particles' pushes within the step (see
    /// [`Collider::inv_mass`]).
    pub fn begin_step(
        &mut self,
        colliders: &[Collider],
        (mask, two_way): (u32, bool),
        bounds: (Vec3, Vec3),
        reach: f32,
        dt: f32,
    ) {
        self.active.clear();
        self.late.clear();
        self.dropped = false;
        if colliders.is_empty() || !(bounds.0.cmple(bounds.1).all()) {
            return;
        }
        let reach_box = (bounds.0 - Vec3::splat(reach), bounds.1 + Vec3::splat(reach));
        self.reach_box = reach_box;
        for (index, c) in colliders.iter().enumerate() {
            if !c.touches(mask) || c.validate().is_err() {
                continue;
            }
            if reachable(c, reach_box) {
                self.active
                    .push(ActiveCollider::new(c, index, (dt, self.max_edge), two_way));
            } else {
                self.dropped = true;
            }
        }
    }

    /// Whether [`Self::begin_step`] dropped a collider the cloth may still reach if a particle
    /// outruns the step's `reach`: the step then needs its start positions for
    /// [`Self::catch_up`].
    pub fn dropped(&self) -> bool {
        self.dropped
    }

    /// The broad phase's safety net, after a step that started at `start` and ended at `x`: when
    /// a particle moved farther than the reach [`Self::begin_step`] was given (its bound assumes
    /// the particles' speeds at the step's start, and stretched springs can fling them faster),
    /// every collider it dropped that the particles' straight paths over the step come near is
    /// resolved once over the whole step, along those paths (contact, swept test and response,
    /// with `dt` as the substep). Without it a particle could pass through such a collider, or
    /// end inside it. Returns the colliders' work, as [`Self::resolve_state`] does.
    #[allow(clippy::too_many_arguments)]
    pub fn catch_up(
        &mut self,
        colliders: &[Collider],
        mask: u32,
        dt: f32,
        triangles: &[u32],
        inv_mass: &[f32],
        start: &[Vec3],
        (x, v): (&mut [Vec3], &mut [Vec3]),
    ) -> f64 {
        if !self.dropped {
            return 0.0;
        }
        let moved = max_distance(start, x, inv_mass);
        let (lo, hi) = bounds(start);
        let paths = (lo - Vec3::splat(moved), hi + Vec3::splat(moved));
        let (a, b) = self.reach_box;
        if a.cmple(paths.0).all() && b.cmpge(paths.1).all() {
            return 0.0;
        }
        self.late.clear();
        for (index, c) in colliders.iter().enumerate() {
            if !c.touches(mask) || c.validate().is_err() || reachable(c, self.reach_box) {
                continue;
            }
            if reachable(c, paths) {
                // Resolved once over the whole step: there is no later substep to slow it for.
                self.late
                    .push(ActiveCollider::new(c, index, (dt, self.max_edge), false));
            }
        }
        if self.late.is_empty() {
            return 0.0;
        }
        let mut state = Vectors {
            x,
            v,
            start,
            inv_mass,
            touches: None,
        };
        resolve(
            &mut self.late,
            &mut self.clearance,
            (0.0, 1.0, dt),
            triangles,
            &mut state,
        )
    }

    /// What the particles took from each collider they touched during the last step, in the
    /// substeps or in [`Self::catch_up`] (never both: it takes only colliders the broad phase
    /// dropped).
    pub fn reactions(&self) -> impl Iterator<Item = &Reaction> {
        self.active
            .iter()
            .chain(&self.late)
            .map(|c| &c.reaction)
            .filter(|r| r.impulse != Vec3::ZERO || r.moment != Vec3::ZERO)
    }

    /// Whether any collider or other cloth that passed this step's broad phase moves during the
    /// step.
    pub fn any_moving(&self) -> bool {
        self.active
            .iter()
            .any(|c| c.collider.start != c.collider.end)
            || self.cloths.any_moving()
    }

    /// Records the particle positions at the start of a substep (only when a collider is active),
    /// for [`Self::resolve`].
    pub fn begin_substep(&mut self, positions: &[Vec3]) {
        if self.is_active() {
            self.start.copy_from_slice(positions);
        }
    }

    /// Moves the free particles' (`inv_mass > 0`) recorded starts ([`Self::begin_substep`]) by
    /// `motion`, as a stepper carries the particles along by their frame's unfelt motion: the
    /// swept tests and friction then leave that motion out, as the cloth does not feel it.
    pub fn carry_starts(&mut self, inv_mass: &[f32], motion: impl Fn(Vec3) -> Vec3) {
        if self.is_active() {
            for (start, w) in self.start.iter_mut().zip(inv_mass) {
                if *w > 0.0 {
                    *start = motion(*start);
                }
            }
        }
    }

    /// [`Self::resolve_state`] for positions `x` and velocities `v` in the particles' own order,
    /// which started the substep where [`Self::begin_substep`] recorded. With `touches`, each
    /// particle a collider pushed gets its [`Touch`] there (the others are left as they were).
    /// Returns the colliders' work, as [`Self::resolve_state`] does.
    #[allow(clippy::too_many_arguments)]
    pub fn resolve(
        &mut self,
        t0: f32,
        t1: f32,
        h: f32,
        triangles: &[u32],
        inv_mass: &[f32],
        (x, v): (&mut [Vec3], &mut [Vec3]),
        touches: Option<&mut [Touch]>,
    ) -> f64 {
        let Self {
            active,
            start,
            clearance,
            self_contacts,
            limits,
            cloths,
            ..
        } = self;
        let mut state = Vectors {
            x,
            v,
            start,
            inv_mass,
            touches,
        };
        resolve_all(
            (active, clearance, self_contacts.as_mut(), limits),
            cloths,
            (t0, t1, h),
            triangles,
            &mut state,
        )
    }

    /// The narrow phase and response for the substep `[t0, t1]` (fractions of the step) of length
    /// `h`: every free particle (inverse mass > 0) is brought back within its targets' and
    /// tethers' limits, moved out of every active collider and its
    /// velocity corrected; then, for small spheres, every triangle; then the cloth's layers are
    /// kept apart (with self-contacts on). Returns the work the colliders did on the particles'
    /// motion, J: each push's impulse times the velocity of the collider's surface, which bounds
    /// the kinetic energy the responses can add (with the potential energy the projections
    /// add, what a contact gives the cloth).
    pub fn resolve_state<S: ContactState>(
        &mut self,
        (t0, t1, h): (f32, f32, f32),
        triangles: &[u32],
        state: &mut S,
    ) -> f64 {
        resolve_all(
            (
                &mut self.active,
                &mut self.clearance,
                self.self_contacts.as_mut(),
                &self.limits,
            ),
            &mut self.cloths,
            (t0, t1, h),
            triangles,
            state,
        )
    }
}

/// Whether collider `c`, over its sweep from its start pose to its end pose and grown by its
/// margin, meets the box `(lo, hi)`.
fn reachable(c: &Collider, (lo, hi): (Vec3, Vec3)) -> bool {
    let m = Vec3::splat(c.margin);
    match (c.shape.bounds(&c.start), c.shape.bounds(&c.end)) {
        (Some((a0, a1)), Some((b0, b1))) => {
            let (c0, c1) = (a0.min(b0) - m, a1.max(b1) + m);
            c0.cmple(hi).all() && c1.cmpge(lo).all()
        }
        // A half-space: is the box's lowest corner along the normal within the margin?
        _ => [c.start, c.end].iter().any(|pose| {
            let (_, n) = c.shape.signed_distance(Vec3::ZERO);
            let n = pose.rotation * n;
            let centre = 0.5 * (lo + hi);
            let half = 0.5 * (hi - lo);
            (centre - pose.translation).dot(n) - half.dot(n.abs()) < c.margin
        }),
    }
}

/// The limits (targets and tethers), the colliders' response, then the self-contacts' (if any)
/// and the contacts with other cloths (if near); the colliders once more if either moved
/// anything, since pushing layers apart may push one into a collider: for the particles the
/// self-contacts moved, or every particle if the cloth contacts moved any. Colliders come after
/// the limits so that they have the last word; the self-contacts then note where the substep
/// ended (see [`SelfContacts::end_substep`]).
/// Returns the colliders' work (see [`Contacts::resolve_state`]).
fn resolve_all<S: ContactState>(
    (active, clearance, mut self_contacts, limits): (
        &mut [ActiveCollider],
        &mut Vec<f32>,
        Option<&mut SelfContacts>,
        &Limits,
    ),
    cloths: &mut ClothContacts,
    t: (f32, f32, f32),
    triangles: &[u32],
    state: &mut S,
) -> f64 {
    if !limits.is_empty() {
        limits.resolve(t, state);
    }
    let mut work = resolve(active, clearance, t, triangles, state);
    // A step's last substep ends at t = 1 exactly (`sub + 1 == n` substeps of `n`).
    let last = t.1 >= 1.0;
    let layered = (self_contacts.as_deref_mut()).is_some_and(|s| s.resolve((t.2, last), state));
    let apart = cloths.resolve(t, triangles, state);
    if apart {
        work += resolve(active, clearance, t, triangles, state);
    } else if layered && let Some(s) = self_contacts.as_deref() {
        // Only the particles the layers moved can have been pushed into a collider.
        work += resolve_among(active, clearance, t, triangles, state, Some(s.moved()));
    }
    if let Some(s) = self_contacts {
        s.end_substep(state);
    }
    cloths.end_substep(state);
    work
}
