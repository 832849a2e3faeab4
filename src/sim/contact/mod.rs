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

mod cloths;
mod limits;
mod narrow;
mod self_contact;
mod shapes;
#[cfg(test)]
mod tests;

use glam::{Vec3, Vec3A};

use crate::sim::simd::{self, Build, Kernel};
use crate::sim::soa::Soa;
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

/// The state as three arrays of vectors in the particles' own order.
struct Vectors<'a> {
    x: &'a mut [Vec3],
    v: &'a mut [Vec3],
    start: &'a [Vec3],
    inv_mass: &'a [f32],
    /// Where given, each touched particle's [`Touch`].
    touches: Option<&'a mut [Touch]>,
}

/// A collider's contact with one particle in a substep, as [`Contacts::resolve`] reports it: the
/// outward normal (zero: no contact) and the velocity of the collider's surface there.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Touch {
    /// Outward unit normal; zero for a particle no collider touched.
    pub normal: Vec3,
    /// Velocity of the collider's surface at the contact, m/s.
    pub surface: Vec3,
}

impl ContactState for Vectors<'_> {
    fn len(&self) -> usize {
        self.x.len()
    }
    #[inline(always)]
    fn inv_mass(&self, i: usize) -> f32 {
        self.inv_mass[i]
    }
    fn slot(&self, p: u32) -> usize {
        p as usize
    }
    #[inline(always)]
    fn start(&self, i: usize) -> Vec3 {
        self.start[i]
    }
    #[inline(always)]
    fn position(&self, i: usize) -> Vec3 {
        self.x[i]
    }
    #[inline(always)]
    fn velocity(&self, i: usize) -> Vec3 {
        self.v[i]
    }
    #[inline(always)]
    fn set(&mut self, i: usize, x: Vec3, v: Vec3) {
        (self.x[i], self.v[i]) = (x, v);
    }
    fn touched(&mut self, i: usize, normal: Vec3, surface: Vec3) {
        if let Some(touches) = self.touches.as_deref_mut() {
            touches[i] = Touch { normal, surface };
        }
    }
    fn clearances(&self, near: Near, within: f32, out: &mut [f32]) {
        for ((o, x), s) in out.iter_mut().zip(&*self.x).zip(self.start) {
            *o = near.distance(*x) - x.distance(*s) - within;
        }
    }
}

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
    /// Sized for a cloth of `particles` particles whose longest rest edge is `max_edge`.
    pub fn new(particles: usize, max_edge: f32) -> Self {
        Self {
            active: Vec::new(),
            start: vec![Vec3::ZERO; particles],
            clearance: vec![0.0; particles],
            max_edge,
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
        self.cloths
            .begin_step(others, spacing, (bounds, reach), self.max_edge, dt);
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

/// [`ContactState::clearances`] of particles displaced by `d` over the substep: ending at `x`, or
/// with `AHEAD` starting at `x` (and ending at `x + d`), against `within`. A vector [`Kernel`]
/// ([`simd`]).
pub(crate) fn soa_clearances<const AHEAD: bool>(
    x: &Soa,
    d: &Soa,
    (near, within): (Near, f32),
    out: &mut [f32],
) {
    let within = within.max(0.0);
    simd::run(Clearances::<AHEAD> {
        x,
        d,
        near,
        within,
        out,
    });
}

/// [`soa_clearances`]' arguments, as a [`Kernel`].
struct Clearances<'a, const AHEAD: bool> {
    x: &'a Soa,
    d: &'a Soa,
    near: Near,
    within: f32,
    out: &'a mut [f32],
}

impl<const AHEAD: bool> Kernel for Clearances<'_, AHEAD> {
    const WIDEST: Build = Build::Avx512;

    #[inline(always)]
    fn body<const WIDE: bool>(self) {
        clearances_body::<AHEAD>(self.x, self.d, (self.near, self.within), self.out);
    }
}

/// The sign of `|e| − |d| − w` (`w ≥ 0`) from `e2 = |e|²` and `d2 = |d|²`, without square
/// roots: `|e| ≤ w + |d|` holds where `q = |e|² − |d|² − w² ≤ 0`, and otherwise exactly where
/// `q² ≤ 4 w² |d|²`.
#[inline(always)]
fn point_gap_sign(e2: f32, d2: f32, w2: f32) -> f32 {
    let q = e2 - d2 - w2;
    if q <= 0.0 { q } else { q * q - 4.0 * w2 * d2 }
}

/// The sign of `a − |d| − w` (`w ≥ 0`) from `a` and `d2 = |d|²`, without a square root: it is
/// at most 0 where `a − w ≤ 0`, and otherwise exactly where `(a − w)² ≤ |d|²`.
#[inline(always)]
fn plane_gap_sign(a: f32, d2: f32, w: f32) -> f32 {
    let q = a - w;
    if q <= 0.0 { q } else { q * q - d2 }
}

#[inline(always)]
fn clearances_body<const AHEAD: bool>(
    x: &Soa,
    d: &Soa,
    (near, within): (Near, f32),
    out: &mut [f32],
) {
    let n = out.len().min(x.len()).min(d.len());
    let (x, y, z) = (&x.x[..n], &x.y[..n], &x.z[..n]);
    let (dx, dy, dz) = (&d.x[..n], &d.y[..n], &d.z[..n]);
    let moved2 = |i: usize| dx[i] * dx[i] + dy[i] * dy[i] + dz[i] * dz[i];
    let end = |x: &[f32], d: &[f32], i: usize| if AHEAD { x[i] + d[i] } else { x[i] };
    match near {
        Near::Point(c) => {
            let w2 = within * within;
            for (i, o) in out[..n].iter_mut().enumerate() {
                let (ex, ey, ez) = (
                    end(x, dx, i) - c.x,
                    end(y, dy, i) - c.y,
                    end(z, dz, i) - c.z,
                );
                *o = point_gap_sign(ex * ex + ey * ey + ez * ez, moved2(i), w2);
            }
        }
        Near::Plane(c, normal) => {
            for (i, o) in out[..n].iter_mut().enumerate() {
                let along = (end(x, dx, i) - c.x) * normal.x
                    + (end(y, dy, i) - c.y) * normal.y
                    + (end(z, dz, i) - c.z) * normal.z;
                *o = plane_gap_sign(along, moved2(i), within);
            }
        }
    }
}

/// What [`ContactState::since`] measures over the particles: sums of their displacements since a
/// snapshot and over the substep, and how far the farthest one is from a guess.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Since {
    /// Sum over the particles of `end − snapshot`.
    pub moved: Vec3,
    /// Sum over the particles of `end − start`.
    pub step: Vec3,
    /// Largest `|end − snapshot − guess|²`; infinite if a sum is not finite (a particle's
    /// position or the snapshot is NaN or infinite).
    pub worst: f32,
}

impl Since {
    /// Infinite `worst` where a displacement is not finite, which the sums always see (`max`
    /// alone would drop a NaN).
    fn checked(self) -> Self {
        if self.moved.is_finite() && self.step.is_finite() {
            self
        } else {
            Self {
                worst: f32::INFINITY,
                ..self
            }
        }
    }
}

/// [`ContactState::since`] of particles displaced by `d` over the substep: ending at `x`, or with
/// `AHEAD` starting at `x` (and ending at `x + d`). A vector [`Kernel`] ([`simd`]): sixteen
/// running sums and maxima per quantity, added up in a fixed order, so every build gives the same
/// bits.
pub(crate) fn soa_since<const AHEAD: bool>(x: &Soa, d: &Soa, at: &Soa, guess: Vec3) -> Since {
    let mut out = Since::default();
    simd::run(SinceKernel::<AHEAD> {
        x,
        d,
        at,
        guess,
        out: &mut out,
    });
    out.checked()
}

/// [`ContactState::displaced`] of particles displaced by `d` over the substep (see
/// [`soa_since`]): a plain loop over the arrays, whose running sums stay in registers.
pub(crate) fn soa_displaced<const AHEAD: bool>(
    x: &Soa,
    d: &Soa,
    found: &[Vec3],
    moved: &mut [Vec3A],
) -> (Vec3A, Vec3A) {
    let n = x.len().min(d.len()).min(found.len()).min(moved.len());
    let (mut m0, mut m1) = (Vec3A::ZERO, Vec3A::ZERO);
    for i in 0..n {
        let p = Vec3A::new(x.x[i], x.y[i], x.z[i]);
        let q = Vec3A::new(d.x[i], d.y[i], d.z[i]);
        let (start, end) = if AHEAD { (p, p + q) } else { (p - q, p) };
        let at = Vec3A::from(found[i]);
        let d = end - at;
        moved[i] = d;
        m0 += start - at;
        m1 += d;
    }
    (m0, m1)
}

/// [`ContactState::ends`] of particles displaced by `d` over the substep (see [`soa_since`]).
pub(crate) fn soa_ends<const AHEAD: bool>(x: &Soa, d: &Soa, out: &mut Soa) {
    let n = x.len().min(d.len());
    out.resize(n);
    for (o, (x, d)) in [&mut out.x, &mut out.y, &mut out.z].into_iter().zip([
        (&x.x, &d.x),
        (&x.y, &d.y),
        (&x.z, &d.z),
    ]) {
        if AHEAD {
            for ((o, x), d) in o.iter_mut().zip(&x[..n]).zip(&d[..n]) {
                *o = x + d;
            }
        } else {
            o.copy_from_slice(&x[..n]);
        }
    }
}

/// [`soa_since`]'s arguments, as a [`Kernel`].
struct SinceKernel<'a, const AHEAD: bool> {
    x: &'a Soa,
    d: &'a Soa,
    at: &'a Soa,
    guess: Vec3,
    out: &'a mut Since,
}

impl<const AHEAD: bool> Kernel for SinceKernel<'_, AHEAD> {
    // Sixteen lanes of seven running values fit AVX-512's registers (AVX2's spill).
    const WIDEST: Build = Build::Avx512;

    #[inline(always)]
    fn body<const WIDE: bool>(self) {
        *self.out = since_body::<AHEAD>(self.x, self.d, self.at, self.guess);
    }
}

#[inline(always)]
fn since_body<const AHEAD: bool>(x: &Soa, d: &Soa, at: &Soa, guess: Vec3) -> Since {
    let n = x.len().min(d.len()).min(at.len());
    let arrays = [&x.x, &x.y, &x.z, &d.x, &d.y, &d.z, &at.x, &at.y, &at.z].map(|a| &a[..n]);
    let mut acc = [[0.0; LANES]; 7];
    let whole = n - n % LANES;
    for base in (0..whole).step_by(LANES) {
        let block = |k: usize| -> &[f32; LANES] {
            arrays[k][base..base + LANES]
                .try_into()
                .expect("a whole block")
        };
        since_block::<AHEAD>(&mut acc, std::array::from_fn(block), guess);
    }
    for i in whole..n {
        since_lane::<AHEAD>(&mut acc, i - whole, arrays.map(|a| a[i]), guess);
    }
    let sum = |a: &[f32; LANES]| a.iter().sum::<f32>();
    Since {
        moved: Vec3::new(sum(&acc[0]), sum(&acc[1]), sum(&acc[2])),
        step: Vec3::new(sum(&acc[3]), sum(&acc[4]), sum(&acc[5])),
        worst: acc[6].iter().fold(0.0, |a, &w| a.max(w)),
    }
}

/// Lanes of [`since_body`]'s running sums and maxima.
const LANES: usize = 16;

/// One block of [`since_body`]: [`since_lane`] for [`LANES`] particles, whose x, y, z, d (x, y, z)
/// and snapshot (x, y, z) `block` holds.
#[inline(always)]
fn since_block<const AHEAD: bool>(
    acc: &mut [[f32; LANES]; 7],
    block: [&[f32; LANES]; 9],
    guess: Vec3,
) {
    for l in 0..LANES {
        since_lane::<AHEAD>(acc, l, block.map(|a| a[l]), guess);
    }
}

/// Adds one particle's move (x, y, z), substep displacement (x, y, z) and squared distance of the
/// move from `guess` (a maximum) to lane `l` of `acc`, from its x, y, z, d (x, y, z) and snapshot
/// (x, y, z).
#[inline(always)]
fn since_lane<const AHEAD: bool>(
    acc: &mut [[f32; LANES]; 7],
    l: usize,
    [x, y, z, dx, dy, dz, ax, ay, az]: [f32; 9],
    guess: Vec3,
) {
    let (ex, ey, ez) = if AHEAD {
        (x + dx, y + dy, z + dz)
    } else {
        (x, y, z)
    };
    let (mx, my, mz) = (ex - ax, ey - ay, ez - az);
    let (gx, gy, gz) = (mx - guess.x, my - guess.y, mz - guess.z);
    let w = gx * gx + gy * gy + gz * gz;
    acc[0][l] += mx;
    acc[1][l] += my;
    acc[2][l] += mz;
    acc[3][l] += dx;
    acc[4][l] += dy;
    acc[5][l] += dz;
    acc[6][l] = if w > acc[6][l] { w } else { acc[6][l] };
}
