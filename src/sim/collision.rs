//! Collisions between a cloth and kinematic colliders: spheres, capsules, cuboids and half-spaces.
//!
//! # Pipeline, per step and per substep
//! 1. **Broad phase** (once per step, `Contacts::begin_step`): the cloth's bounding box, grown by
//!    the farthest any particle can travel in the step, against each collider's box swept from its
//!    start pose to its end pose and grown by its margin. Colliders that cannot be reached, or whose
//!    `layers` do not meet the cloth's mask, are dropped for the whole step and cost nothing more.
//! 2. **Narrow phase** (every substep, `Contacts::resolve_state`, on whatever layout the integrator
//!    keeps its particles in: `ContactState`): the collider's pose is interpolated to the end of the
//!    substep. A vector pass first skips every particle whose distance from the collider's bounding
//!    ball (or plane), less how far it moved, exceeds the ball's radius, the margin and the
//!    collider's travel. Each remaining free particle is taken into the collider's local frame and
//!    tested by the shape's signed distance `d`. A particle with `d < margin` is in contact. A
//!    particle that ends the substep outside, but whose path in the collider's frame (start to end
//!    of the substep) passes within the margin, tunnelled: a swept test (sphere tracing along that
//!    path, exact because every signed distance here is exact) finds the first touching point and
//!    puts it back there.
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
//! The paper detects cloth–sphere contact with a bounding volume and, in its Eq. 3 and Figure 4, moves
//! a penetrating particle back to radius + 0.05 along the line from the centre and splits its velocity
//! into a normal part (reflected and damped) and a tangential part (kept, scaled by a friction
//! factor). Here the bounding volume is the broad phase above; the push-out is the same projection
//! with `margin` in place of 0.05 and the exact signed distance in place of the centre line (they
//! agree for a sphere); the normal part is removed rather than reflected (a fully inelastic contact,
//! the paper's damping taken to its limit, so contacts never add energy); and the tangential factor
//! becomes Coulomb's law with static and kinetic coefficients, measured relative to the collider's
//! own velocity.

use bevy::math::primitives::{Capsule3d, Cuboid, InfinitePlane3d, Sphere};
use bevy::reflect::Reflect;
use glam::{Quat, Vec3};
use serde::{Deserialize, Serialize};

use crate::error::{ClothError, non_negative, positive};

/// Sphere tracing stops after this many steps along one path (a miss).
const MAX_SWEEP_STEPS: u32 = 64;

/// Passes of the particle–triangle test per substep: pushing one triangle moves vertices it shares
/// with its neighbours, so the pass repeats (Gauss-Seidel) until nothing moves, at most this often.
const TRIANGLE_PASSES: u32 = 4;

/// The shape of a collider, in its own frame.
#[derive(Debug, Clone, Copy, PartialEq, Reflect)]
pub enum ColliderShape {
    /// A ball centred on the origin.
    Sphere(Sphere),
    /// A capsule along the local Y axis, centred on the origin.
    Capsule(Capsule3d),
    /// A box centred on the origin.
    Cuboid(Cuboid),
    /// The solid half-space below a plane through the origin: everything with `p · normal < 0`.
    HalfSpace(InfinitePlane3d),
}

impl ColliderShape {
    /// Signed distance from local point `p` to the surface (negative inside) and the outward unit
    /// normal of the nearest surface point. Exact for every shape.
    pub fn signed_distance(&self, p: Vec3) -> (f32, Vec3) {
        match *self {
            ColliderShape::Sphere(s) => radial(p, s.radius),
            ColliderShape::Capsule(c) => {
                let axis = Vec3::new(0.0, p.y.clamp(-c.half_length, c.half_length), 0.0);
                radial(p - axis, c.radius)
            }
            ColliderShape::Cuboid(b) => box_distance(p, b.half_size),
            ColliderShape::HalfSpace(plane) => {
                let n = Vec3::from(plane.normal);
                (p.dot(n), n)
            }
        }
    }

    /// The shape with its dimensions scaled by a transform's `scale`: a cuboid per axis, a capsule's
    /// length by `|scale.y|` and its radius by the larger of `|scale.x|`, `|scale.z|`, a sphere by the
    /// largest `|scale|` component. A half-space is unchanged.
    pub fn scaled(&self, scale: Vec3) -> Self {
        let s = scale.abs();
        match *self {
            ColliderShape::Sphere(b) => {
                ColliderShape::Sphere(Sphere::new(b.radius * s.max_element()))
            }
            ColliderShape::Capsule(c) => ColliderShape::Capsule(Capsule3d {
                radius: c.radius * s.x.max(s.z),
                half_length: c.half_length * s.y,
            }),
            ColliderShape::Cuboid(b) => ColliderShape::Cuboid(Cuboid {
                half_size: b.half_size * s,
            }),
            ColliderShape::HalfSpace(p) => ColliderShape::HalfSpace(p),
        }
    }

    /// Checks the dimensions: radii and half sizes positive and finite, capsule half length
    /// non-negative.
    pub fn validate(&self) -> Result<(), ClothError> {
        match *self {
            ColliderShape::Sphere(s) => positive("collider.radius", s.radius),
            ColliderShape::Capsule(c) => {
                positive("collider.radius", c.radius)?;
                non_negative("collider.half_length", c.half_length)
            }
            ColliderShape::Cuboid(b) => {
                positive("collider.half_size.x", b.half_size.x)?;
                positive("collider.half_size.y", b.half_size.y)?;
                positive("collider.half_size.z", b.half_size.z)
            }
            ColliderShape::HalfSpace(p) => {
                if Vec3::from(p.normal).is_finite() {
                    Ok(())
                } else {
                    Err(ClothError::InvalidValue {
                        field: "collider.normal",
                        expected: "a finite unit vector",
                        value: f64::NAN,
                    })
                }
            }
        }
    }

    /// What the shape at `pose` stays clear of, with a radius: the shape lies within that radius
    /// of the returned centre (its ball), or, for a half-space, on and below the returned plane
    /// (radius 0). A point at distance `D` from it is at least `D − radius` from the shape.
    fn near(&self, pose: &Pose) -> (Near, f32) {
        let centre = pose.translation;
        match *self {
            ColliderShape::Sphere(s) => (Near::Point(centre), s.radius),
            ColliderShape::Capsule(c) => (Near::Point(centre), c.half_length + c.radius),
            ColliderShape::Cuboid(b) => (Near::Point(centre), b.half_size.length()),
            ColliderShape::HalfSpace(plane) => (
                Near::Plane(centre, pose.rotation * Vec3::from(plane.normal)),
                0.0,
            ),
        }
    }

    /// World-space bounding box at `pose`, or `None` for the unbounded half-space.
    fn bounds(&self, pose: &Pose) -> Option<(Vec3, Vec3)> {
        let half = match *self {
            ColliderShape::Sphere(s) => {
                return Some(around(pose.translation, Vec3::splat(s.radius)));
            }
            ColliderShape::Capsule(c) => {
                let axis = (pose.rotation * Vec3::Y * c.half_length).abs();
                return Some(around(pose.translation, axis + Vec3::splat(c.radius)));
            }
            ColliderShape::Cuboid(b) => b.half_size,
            ColliderShape::HalfSpace(_) => return None,
        };
        let r = glam::Mat3::from_quat(pose.rotation);
        let extent = r.x_axis.abs() * half.x + r.y_axis.abs() * half.y + r.z_axis.abs() * half.z;
        Some(around(pose.translation, extent))
    }
}

/// The axis-aligned bounding box `(min, max)` of `positions` (min > max when empty).
pub fn bounds(positions: &[Vec3]) -> (Vec3, Vec3) {
    // Eight independent running boxes, so the loop is not one long chain of dependent min/max.
    let (chunks, rest) = positions.as_chunks::<8>();
    let mut boxes = [(Vec3::INFINITY, Vec3::NEG_INFINITY); 8];
    for chunk in chunks {
        for ((lo, hi), p) in boxes.iter_mut().zip(chunk) {
            (*lo, *hi) = (lo.min(*p), hi.max(*p));
        }
    }
    boxes
        .into_iter()
        .chain(rest.iter().map(|p| (*p, *p)))
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), (a, b)| {
            (lo.min(a), hi.max(b))
        })
}

fn around(centre: Vec3, half: Vec3) -> (Vec3, Vec3) {
    (centre - half, centre + half)
}

/// Distance to a ball of radius `r` about the origin, with the radial normal (+Y at the centre).
fn radial(p: Vec3, r: f32) -> (f32, Vec3) {
    let len = p.length();
    let n = if len > 1e-12 { p / len } else { Vec3::Y };
    (len - r, n)
}

/// Exact signed distance to an axis-aligned box of half size `h`, with the outward normal of the
/// nearest face, edge or corner.
fn box_distance(p: Vec3, h: Vec3) -> (f32, Vec3) {
    let q = p.abs() - h;
    let outside = q.max(Vec3::ZERO);
    let out_len = outside.length();
    if out_len > 0.0 {
        return (out_len, (outside / out_len) * p.signum());
    }
    // Inside: the nearest face is the one with the largest (least negative) q.
    let (d, axis) = if q.x >= q.y && q.x >= q.z {
        (q.x, Vec3::X)
    } else if q.y >= q.z {
        (q.y, Vec3::Y)
    } else {
        (q.z, Vec3::Z)
    };
    (d, axis * p.signum())
}

/// Coulomb friction coefficients.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Reflect)]
#[serde(deny_unknown_fields)]
pub struct Friction {
    /// Static coefficient `μ_s`: a contact sticks while its tangential push is at most `μ_s` times
    /// its normal push.
    pub static_coefficient: f32,
    /// Kinetic coefficient `μ_k`: a sliding contact loses `μ_k` times its normal velocity change
    /// from its tangential velocity.
    pub kinetic_coefficient: f32,
}

impl Friction {
    /// Frictionless contact.
    pub const NONE: Friction = Friction {
        static_coefficient: 0.0,
        kinetic_coefficient: 0.0,
    };

    /// Static and kinetic coefficient both `mu`.
    pub fn new(mu: f32) -> Self {
        Self {
            static_coefficient: mu,
            kinetic_coefficient: mu,
        }
    }

    /// Checks both coefficients are finite and non-negative.
    pub fn validate(&self) -> Result<(), ClothError> {
        non_negative("friction.static_coefficient", self.static_coefficient)?;
        non_negative("friction.kinetic_coefficient", self.kinetic_coefficient)
    }
}

impl Default for Friction {
    /// `μ_s = 0.5`, `μ_k = 0.4`, about cotton on wood.
    fn default() -> Self {
        Self {
            static_coefficient: 0.5,
            kinetic_coefficient: 0.4,
        }
    }
}

/// A rigid placement: rotation, then translation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Orientation.
    pub rotation: Quat,
    /// Position, m.
    pub translation: Vec3,
}

impl Pose {
    /// The identity placement.
    pub const IDENTITY: Pose = Pose {
        rotation: Quat::IDENTITY,
        translation: Vec3::ZERO,
    };

    /// A placement at `translation` with no rotation.
    pub fn from_translation(translation: Vec3) -> Self {
        Self {
            rotation: Quat::IDENTITY,
            translation,
        }
    }

    /// Local point to world.
    pub fn transform_point(&self, p: Vec3) -> Vec3 {
        self.rotation * p + self.translation
    }

    /// World point to local.
    pub fn inverse_transform_point(&self, p: Vec3) -> Vec3 {
        self.rotation.inverse() * (p - self.translation)
    }

    /// The placement a fraction `t` of the way to `other` (linear in position, spherical in
    /// rotation).
    pub fn lerp(&self, other: &Pose, t: f32) -> Pose {
        Pose {
            rotation: self.rotation.slerp(other.rotation, t),
            translation: self.translation.lerp(other.translation, t),
        }
    }
}

/// A collider as the solver sees it for one step: its shape, where it is at the start and at the
/// end of the step (it moves between them linearly, rotating at constant rate), and its contact
/// properties.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Collider {
    /// Shape in the collider's frame (already scaled).
    pub shape: ColliderShape,
    /// Pose at the start of the step.
    pub start: Pose,
    /// Pose at the end of the step.
    pub end: Pose,
    /// Friction against the cloth.
    pub friction: Friction,
    /// Thickness kept between the surface and the cloth's particles, m.
    pub margin: f32,
    /// Collision layers: the collider touches a cloth whose mask shares a bit with these.
    pub layers: u32,
}

impl Collider {
    /// A collider that stays at `pose` during the step, on every layer.
    pub fn fixed(shape: ColliderShape, pose: Pose, friction: Friction, margin: f32) -> Self {
        Self {
            shape,
            start: pose,
            end: pose,
            friction,
            margin,
            layers: u32::MAX,
        }
    }

    /// Checks the shape, friction and margin.
    pub fn validate(&self) -> Result<(), ClothError> {
        self.shape.validate()?;
        self.friction.validate()?;
        non_negative("collider.margin", self.margin)?;
        let finite = |p: &Pose| p.translation.is_finite() && p.rotation.is_finite();
        if finite(&self.start) && finite(&self.end) {
            Ok(())
        } else {
            Err(ClothError::InvalidValue {
                field: "collider transform",
                expected: "finite",
                value: f64::NAN,
            })
        }
    }
}

/// A collider that passed the broad phase, with its velocity over the step.
#[derive(Debug, Clone, Copy)]
struct ActiveCollider {
    collider: Collider,
    /// Velocity of the collider's origin, m/s.
    linear: Vec3,
    /// Angular velocity, rad/s.
    angular: Vec3,
    /// Whether triangles are tested too (spheres smaller than the cloth's longest edge).
    triangles: bool,
}

impl ActiveCollider {
    /// Velocity of the collider's material at world point `p`, with its origin at `origin`.
    fn velocity_at(&self, p: Vec3, origin: Vec3) -> Vec3 {
        self.linear + self.angular.cross(p - origin)
    }
}

/// The particle state a contact response reads and writes, in whatever layout a step keeps it:
/// each particle's position and velocity at the end of the substep and its position at the start.
/// Particles are addressed by where they are stored; [`Self::slot`] maps a model particle there.
pub(crate) trait ContactState {
    /// Number of particles.
    fn len(&self) -> usize;
    /// Inverse mass of the particle stored at `i` (0: pinned, never moved by a contact).
    fn inv_mass(&self, i: usize) -> f32;
    /// Where model particle `p` is stored.
    fn slot(&self, p: u32) -> usize;
    /// Position at the start of the substep.
    fn start(&self, i: usize) -> Vec3;
    /// Position now.
    fn position(&self, i: usize) -> Vec3;
    /// Velocity now.
    fn velocity(&self, i: usize) -> Vec3;
    /// Moves particle `i` to `x` with velocity `v`; its start stays where it was.
    fn set(&mut self, i: usize, x: Vec3, v: Vec3);
    /// For every particle, `near.distance(x) − |x − start|` into `out`: a lower bound on its
    /// distance from `near`'s point or plane all along its path over the substep.
    fn clearances(&self, near: Near, out: &mut [f32]);
}

/// What a particle's clearance from a collider is measured to (see [`ContactState::clearances`]):
/// the centre of its bounding ball, or, for a half-space, its plane.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Near {
    /// Euclidean distance from the point.
    Point(Vec3),
    /// Signed distance from the plane through the point with the unit normal.
    Plane(Vec3, Vec3),
}

impl Near {
    /// Distance (signed for a plane) of `x`.
    #[inline(always)]
    pub fn distance(&self, x: Vec3) -> f32 {
        match *self {
            Near::Point(c) => (x - c).length(),
            Near::Plane(c, n) => (x - c).dot(n),
        }
    }
}

/// The state as three arrays of vectors in the particles' own order.
struct Vectors<'a> {
    x: &'a mut [Vec3],
    v: &'a mut [Vec3],
    start: &'a [Vec3],
    inv_mass: &'a [f32],
}

impl ContactState for Vectors<'_> {
    fn len(&self) -> usize {
        self.x.len()
    }
    fn inv_mass(&self, i: usize) -> f32 {
        self.inv_mass[i]
    }
    fn slot(&self, p: u32) -> usize {
        p as usize
    }
    fn start(&self, i: usize) -> Vec3 {
        self.start[i]
    }
    fn position(&self, i: usize) -> Vec3 {
        self.x[i]
    }
    fn velocity(&self, i: usize) -> Vec3 {
        self.v[i]
    }
    fn set(&mut self, i: usize, x: Vec3, v: Vec3) {
        (self.x[i], self.v[i]) = (x, v);
    }
    fn clearances(&self, near: Near, out: &mut [f32]) {
        for ((o, x), s) in out.iter_mut().zip(&*self.x).zip(self.start) {
            *o = near.distance(*x) - x.distance(*s);
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
}

impl Contacts {
    /// Sized for a cloth of `particles` particles whose longest rest edge is `max_edge`.
    pub fn new(particles: usize, max_edge: f32) -> Self {
        Self {
            active: Vec::new(),
            start: vec![Vec3::ZERO; particles],
            clearance: vec![0.0; particles],
            max_edge,
        }
    }

    /// Whether any collider survived the broad phase of this step.
    pub fn is_active(&self) -> bool {
        !self.active.is_empty()
    }

    /// Number of colliders that survived the broad phase of this step.
    pub fn active_count(&self) -> usize {
        self.active.len()
    }

    /// The broad phase: keeps the colliders on `mask` that the cloth can reach during a step of
    /// `dt` seconds. `bounds` is the cloth's bounding box at the start of the step (see
    /// [`bounds`]); `reach` bounds how far any particle can move in the step.
    pub fn begin_step(
        &mut self,
        colliders: &[Collider],
        mask: u32,
        bounds: (Vec3, Vec3),
        reach: f32,
        dt: f32,
    ) {
        self.active.clear();
        if colliders.is_empty() || !(bounds.0.cmple(bounds.1).all()) {
            return;
        }
        let lo = bounds.0 - Vec3::splat(reach);
        let hi = bounds.1 + Vec3::splat(reach);
        let inv_dt = 1.0 / dt;
        for c in colliders {
            if c.layers & mask == 0 || c.validate().is_err() {
                continue;
            }
            let m = Vec3::splat(c.margin);
            let reachable = match (c.shape.bounds(&c.start), c.shape.bounds(&c.end)) {
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
            };
            if !reachable {
                continue;
            }
            let spin = c.end.rotation * c.start.rotation.inverse();
            let (axis, angle) = spin.to_axis_angle();
            let angle = if angle > std::f32::consts::PI {
                angle - std::f32::consts::TAU
            } else {
                angle
            };
            self.active.push(ActiveCollider {
                collider: *c,
                linear: (c.end.translation - c.start.translation) * inv_dt,
                angular: axis * (angle * inv_dt),
                triangles: matches!(c.shape, ColliderShape::Sphere(s) if s.radius < self.max_edge),
            });
        }
    }

    /// Whether any collider that passed this step's broad phase moves during the step.
    pub fn any_moving(&self) -> bool {
        self.active
            .iter()
            .any(|c| c.collider.start != c.collider.end)
    }

    /// Records the particle positions at the start of a substep (only when a collider is active),
    /// for [`Self::resolve`].
    pub fn begin_substep(&mut self, positions: &[Vec3]) {
        if self.is_active() {
            self.start.copy_from_slice(positions);
        }
    }

    /// [`Self::resolve_state`] for positions `x` and velocities `v` in the particles' own order,
    /// which started the substep where [`Self::begin_substep`] recorded.
    #[allow(clippy::too_many_arguments)]
    pub fn resolve(
        &mut self,
        t0: f32,
        t1: f32,
        h: f32,
        triangles: &[u32],
        inv_mass: &[f32],
        x: &mut [Vec3],
        v: &mut [Vec3],
    ) {
        let Self {
            active,
            start,
            clearance,
            ..
        } = self;
        let mut state = Vectors {
            x,
            v,
            start,
            inv_mass,
        };
        resolve(active, clearance, (t0, t1, h), triangles, &mut state);
    }

    /// The narrow phase and response for the substep `[t0, t1]` (fractions of the step) of length
    /// `h`: every free particle (inverse mass > 0) is moved out of every active collider and its
    /// velocity corrected; then, for small spheres, every triangle.
    pub fn resolve_state<S: ContactState>(
        &mut self,
        (t0, t1, h): (f32, f32, f32),
        triangles: &[u32],
        state: &mut S,
    ) {
        resolve(
            &self.active,
            &mut self.clearance,
            (t0, t1, h),
            triangles,
            state,
        );
    }
}

/// See [`Contacts::resolve_state`]. Before the exact test, a particle whose clearance (see
/// [`ContactState::clearances`]) from the collider's bounding ball or plane exceeds the ball's
/// radius, the margin and the collider's travel over the substep is skipped: no point of its path
/// comes within the margin, so the exact test would leave it alone. This bound holds for colliders
/// that do not rotate during the substep; rotating ones get the exact test everywhere.
fn resolve<S: ContactState>(
    active: &[ActiveCollider],
    clearance: &mut Vec<f32>,
    (t0, t1, h): (f32, f32, f32),
    triangles: &[u32],
    state: &mut S,
) {
    // Sized with the cloth (`Contacts::new`), so this allocates only for a state of another size.
    clearance.resize(state.len(), 0.0);
    for c in active {
        let pose0 = c.collider.start.lerp(&c.collider.end, t0);
        let pose1 = c.collider.start.lerp(&c.collider.end, t1);
        let still = pose0 == pose1;
        let bound = (pose0.rotation == pose1.rotation).then(|| c.collider.shape.near(&pose1));
        if let Some((near, radius)) = bound {
            let travel = pose0.translation.distance(pose1.translation);
            // Rounding in the exact test is far below this slack (relative to the coordinates).
            let slack = 1e-5 * (pose1.translation.abs().max_element() + radius + travel + 1.0);
            let skip = radius + c.collider.margin + travel + slack;
            state.clearances(near, clearance);
            // Sixteen clearances compared at a time (vector code), then the few close ones visited.
            for (k, chunk) in clearance.chunks(16).enumerate() {
                let mut close = chunk
                    .iter()
                    .enumerate()
                    .fold(0u32, |m, (l, &gap)| m | (u32::from(gap <= skip) << l));
                while close != 0 {
                    let i = 16 * k + close.trailing_zeros() as usize;
                    close &= close - 1;
                    if state.inv_mass(i) > 0.0 {
                        collide_particle(c, (&pose0, &pose1, still), h, state, i);
                    }
                }
            }
        } else {
            for i in 0..state.len() {
                if state.inv_mass(i) > 0.0 {
                    collide_particle(c, (&pose0, &pose1, still), h, state, i);
                }
            }
        }
        if c.triangles {
            for _ in 0..TRIANGLE_PASSES {
                if !collide_triangles(c, (&pose0, &pose1, h), triangles, state) {
                    break;
                }
            }
        }
    }
}

/// Contact of particle `i` with one collider over a substep: projection, then the velocity split
/// and Coulomb friction described in the module docs.
fn collide_particle<S: ContactState>(
    c: &ActiveCollider,
    (pose0, pose1, still): (&Pose, &Pose, bool),
    h: f32,
    state: &mut S,
    i: usize,
) {
    let shape = &c.collider.shape;
    let margin = c.collider.margin;
    let (x, start) = (state.position(i), state.start(i));
    let mut local = pose1.inverse_transform_point(x);
    let (mut d, mut normal) = shape.signed_distance(local);
    // The signed distance changes no faster than the point moves: a particle that ends the
    // substep farther from a collider at rest than it travelled cannot have passed through it.
    if d >= margin && still && d - margin > x.distance(start) {
        return;
    }
    if d >= margin {
        let local0 = pose0.inverse_transform_point(start);
        match sweep(shape, local0, local, margin) {
            Some((hit, hit_d, hit_n)) => (local, d, normal) = (hit, hit_d, hit_n),
            None => return,
        }
    }
    let mut x = pose1.transform_point(local + normal * (margin - d));
    let push = (x - state.position(i)).length();
    let mut v = state.velocity(i);
    let vc = c.velocity_at(x, pose1.translation);
    respond(
        &c.collider.friction,
        pose1.rotation * normal,
        push,
        vc,
        (h, start),
        &mut x,
        &mut v,
    );
    state.set(i, x, v);
}

/// The response of a contact just pushed out by `push` along the outward normal `n`, against a
/// surface moving at `vc`: Coulomb friction on the tangential displacement relative to the surface
/// over the substep (`h` long, the particle starting at `start`), and removal of the inward
/// relative normal velocity. See the module docs.
fn respond(
    friction: &Friction,
    n: Vec3,
    push: f32,
    vc: Vec3,
    (h, start): (f32, Vec3),
    x: &mut Vec3,
    v: &mut Vec3,
) {
    let moved = (*x - start) - vc * h;
    let tangential = moved - n * moved.dot(n);
    let slide = tangential.length();
    let stop = if slide <= friction.static_coefficient * push {
        1.0
    } else {
        (friction.kinetic_coefficient * push / slide).min(1.0)
    };
    *x -= tangential * stop;
    let relative = *v - vc;
    let vn = relative.dot(n);
    let vt = relative - n * vn;
    *v = vc + n * vn.max(0.0) + vt * (1.0 - stop);
}

/// Sphere tracing from `from` to `to` (collider frame): the first point of the path within
/// `margin` of the surface, with its distance and normal; `None` if the path stays clear or starts
/// in contact (a particle leaving the surface).
fn sweep(shape: &ColliderShape, from: Vec3, to: Vec3, margin: f32) -> Option<(Vec3, f32, Vec3)> {
    let delta = to - from;
    let len = delta.length();
    if len <= margin || shape.signed_distance(from).0 < margin {
        return None;
    }
    let dir = delta / len;
    let min_step = 0.25 * margin.max(1e-4 * len);
    let mut t = 0.0;
    for _ in 0..MAX_SWEEP_STEPS {
        let p = from + dir * t;
        let (d, n) = shape.signed_distance(p);
        if d < margin {
            return Some((p, d, n));
        }
        t += (d - margin).max(min_step);
        if t >= len {
            return None;
        }
    }
    None
}

/// Particle–triangle contact with a small sphere: each triangle closer to the centre than radius +
/// margin is pushed away, its three vertices moved in proportion to barycentric weight and inverse
/// mass so that the touching point moves exactly out of contact (Bridson et al. 2002's impulse
/// distribution). The side the sphere must stay on is the one its centre was on at the start of
/// the substep (the direction from the triangle's closest point to the centre then), so neither a
/// fast sphere nor a triangle folding over it lets it pop through. The moved vertices get the same response as
/// particle contacts (friction, inward velocity removed). Returns whether any triangle was moved.
fn collide_triangles<S: ContactState>(
    c: &ActiveCollider,
    (pose0, pose1, h): (&Pose, &Pose, f32),
    triangles: &[u32],
    state: &mut S,
) -> bool {
    let ColliderShape::Sphere(sphere) = c.collider.shape else {
        return false;
    };
    let mut moved = false;
    let reach = sphere.radius + c.collider.margin;
    let (centre0, centre) = (pose0.translation, pose1.translation);
    for tri in triangles.chunks_exact(3) {
        let ids = [tri[0], tri[1], tri[2]].map(|p| state.slot(p));
        let [a, b, p] = ids.map(|i| state.position(i));
        let [a0, b0, p0] = ids.map(|i| state.start(i));
        // Swept boxes: the triangle from its start to its current place against the centre's
        // path, so a triangle that swept past the sphere within the substep is still tested.
        let lo = a.min(b).min(p).min(a0.min(b0).min(p0)) - Vec3::splat(reach);
        let hi = a.max(b).max(p).max(a0.max(b0).max(p0)) + Vec3::splat(reach);
        if centre.min(centre0).cmpgt(hi).any() || centre.max(centre0).cmplt(lo).any() {
            continue;
        }
        let (closest, bary) = closest_point_on_triangle(centre, a, b, p);
        // Direction from the triangle to the centre now, and at the start of the substep; the
        // centre must stay on the side it started on, so if the two disagree it has crossed (or
        // the triangle has folded over it) and the triangle is pushed back past it.
        let (closest0, _) = closest_point_on_triangle(centre0, a0, b0, p0);
        let side_of = |to_centre: Vec3, normal: Vec3| {
            if to_centre.length_squared() > 1e-20 {
                to_centre.normalize()
            } else {
                normal.normalize_or_zero()
            }
        };
        let was = side_of(centre0 - closest0, (b0 - a0).cross(p0 - a0));
        let to_centre = centre - closest;
        let now = side_of(to_centre, (b - a).cross(p - a));
        let (dir, dist) = if now.dot(was) >= 0.0 {
            (now, to_centre.length())
        } else {
            (-now, -to_centre.length())
        };
        let depth = reach - dist;
        if depth <= 0.0 || dir == Vec3::ZERO {
            continue;
        }
        let inv_mass = ids.map(|i| state.inv_mass(i));
        let weights = [0, 1, 2].map(|k| bary[k] * inv_mass[k]);
        let denom: f32 = (0..3).map(|k| bary[k] * weights[k]).sum();
        if denom <= 1e-12 {
            continue;
        }
        moved = true;
        for k in 0..3 {
            let i = ids[k];
            if inv_mass[k] <= 0.0 {
                continue;
            }
            // With all corners free no corner moves more than 3× the depth (Σ b² ≥ 1/3). With
            // pinned corners a free one far from the contact point would have to move depth / b,
            // without bound as b → 0 (the sphere presses next to a pinned corner): the push is
            // capped there, and the pinned triangle lets the sphere sink in instead of flinging
            // the corner.
            let push = (depth * weights[k] / denom).min(3.0 * depth);
            let (mut x, mut v) = (state.position(i) - dir * push, state.velocity(i));
            let vc = c.velocity_at(x, centre);
            respond(
                &c.collider.friction,
                -dir,
                push,
                vc,
                (h, state.start(i)),
                &mut x,
                &mut v,
            );
            state.set(i, x, v);
        }
    }
    moved
}

/// The point of triangle `abc` closest to `p`, with its barycentric coordinates (Ericson,
/// "Real-Time Collision Detection", §5.1.5: Voronoi regions of vertices, then edges, then the face).
fn closest_point_on_triangle(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> (Vec3, Vec3) {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, Vec3::X);
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return (b, Vec3::Y);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let t = d1 / (d1 - d3);
        return (a + ab * t, Vec3::new(1.0 - t, t, 0.0));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return (c, Vec3::Z);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let t = d2 / (d2 - d6);
        return (a + ac * t, Vec3::new(1.0 - t, 0.0, t));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        let t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + (c - b) * t, Vec3::new(0.0, 1.0 - t, t));
    }
    let denom = 1.0 / (va + vb + vc);
    let (s, t) = (vb * denom, vc * denom);
    (a + ab * s + ac * t, Vec3::new(1.0 - s - t, s, t))
}

#[cfg(test)]
mod tests {
    use super::*;
    use bevy::math::Dir3;

    fn shapes() -> [ColliderShape; 4] {
        [
            ColliderShape::Sphere(Sphere::new(0.5)),
            ColliderShape::Capsule(Capsule3d::new(0.3, 1.0)),
            ColliderShape::Cuboid(Cuboid::new(1.0, 0.4, 0.6)),
            ColliderShape::HalfSpace(InfinitePlane3d::new(Vec3::new(0.0, 1.0, 1.0))),
        ]
    }

    #[test]
    fn signed_distances_are_exact_and_normals_are_gradients() {
        // Spot values.
        let sphere = ColliderShape::Sphere(Sphere::new(0.5));
        assert!((sphere.signed_distance(Vec3::new(0.0, 2.0, 0.0)).0 - 1.5).abs() < 1e-6);
        let capsule = ColliderShape::Capsule(Capsule3d::new(0.3, 1.0));
        assert!((capsule.signed_distance(Vec3::new(1.0, 0.2, 0.0)).0 - 0.7).abs() < 1e-6);
        assert!((capsule.signed_distance(Vec3::new(0.0, 1.5, 0.0)).0 - 0.7).abs() < 1e-6);
        let cuboid = ColliderShape::Cuboid(Cuboid::new(2.0, 2.0, 2.0));
        assert!((cuboid.signed_distance(Vec3::new(2.0, 2.0, 0.0)).0 - 2f32.sqrt()).abs() < 1e-6);
        assert!((cuboid.signed_distance(Vec3::new(0.0, 0.5, 0.0)).0 + 0.5).abs() < 1e-6);
        // The normal is the finite-difference gradient of the distance, away from creases.
        let mut seed = 7u32;
        let mut rand = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) as f32 / (1u32 << 24) as f32 * 4.0 - 2.0
        };
        for shape in shapes() {
            for _ in 0..200 {
                let p = Vec3::new(rand(), rand(), rand());
                let (d, n) = shape.signed_distance(p);
                let e = 1e-3;
                let grad = Vec3::new(
                    shape.signed_distance(p + Vec3::X * e).0
                        - shape.signed_distance(p - Vec3::X * e).0,
                    shape.signed_distance(p + Vec3::Y * e).0
                        - shape.signed_distance(p - Vec3::Y * e).0,
                    shape.signed_distance(p + Vec3::Z * e).0
                        - shape.signed_distance(p - Vec3::Z * e).0,
                ) / (2.0 * e);
                // Inside a box the distance has creases where two faces are equally near.
                if (grad.length() - 1.0).abs() < 1e-2 {
                    assert!(grad.distance(n) < 2e-2, "{shape:?} at {p}: {n} vs {grad}");
                }
                // Moving along the normal by the distance reaches the surface.
                let on = p - n * d;
                assert!(shape.signed_distance(on).0.abs() < 1e-4, "{shape:?} at {p}");
            }
        }
    }

    #[test]
    fn bounds_contain_the_shape() {
        let pose = Pose {
            rotation: Quat::from_euler(glam::EulerRot::XYZ, 0.3, 1.1, -0.4),
            translation: Vec3::new(1.0, -2.0, 0.5),
        };
        for shape in &shapes()[..3] {
            let (lo, hi) = shape.bounds(&pose).unwrap();
            for i in 0..2000 {
                let f = i as f32;
                let dir =
                    Vec3::new((f * 0.37).sin(), (f * 0.91).cos(), (f * 0.13).sin()).normalize();
                // March from the centre to the surface.
                let mut p = Vec3::ZERO;
                for _ in 0..50 {
                    let d = shape.signed_distance(p).0;
                    p += dir * (-d).max(0.0);
                    if d.abs() < 1e-5 {
                        break;
                    }
                }
                let w = pose.transform_point(p);
                assert!(w.cmpge(lo - 1e-4).all() && w.cmple(hi + 1e-4).all());
            }
        }
    }

    #[test]
    fn closest_point_on_triangle_matches_brute_force() {
        let (a, b, c) = (
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.2, 0.0),
            Vec3::new(0.3, 1.0, 0.4),
        );
        for i in 0..500 {
            let f = i as f32;
            let p = Vec3::new(
                (f * 0.7).sin() * 2.0,
                (f * 1.3).cos() * 2.0,
                (f * 0.29).sin(),
            );
            let (q, bary) = closest_point_on_triangle(p, a, b, c);
            assert!((a * bary.x + b * bary.y + c * bary.z).distance(q) < 1e-5);
            assert!((bary.element_sum() - 1.0).abs() < 1e-5 && bary.min_element() >= -1e-6);
            let mut best = f32::INFINITY;
            for s in 0..=100 {
                for t in 0..=(100 - s) {
                    let (s, t) = (s as f32 / 100.0, t as f32 / 100.0);
                    best = best.min(p.distance(a + (b - a) * s + (c - a) * t));
                }
            }
            assert!(p.distance(q) <= best + 1e-5, "{p}");
        }
    }

    fn active(collider: Collider, dt: f32, max_edge: f32) -> Contacts {
        let mut contacts = Contacts::new(1, max_edge);
        contacts.begin_step(&[collider], u32::MAX, (Vec3::ZERO, Vec3::ZERO), 10.0, dt);
        contacts
    }

    #[test]
    fn a_particle_is_pushed_out_and_loses_only_inward_velocity() {
        let collider = Collider::fixed(
            ColliderShape::Sphere(Sphere::new(1.0)),
            Pose::IDENTITY,
            Friction::NONE,
            0.05,
        );
        let contacts = active(collider, 0.01, 0.1);
        let (mut x, mut v) = ([Vec3::new(0.0, 0.99, 0.0)], [Vec3::new(2.0, -3.0, 0.0)]);
        let mut c = contacts;
        c.begin_substep(&[Vec3::new(-0.02, 1.02, 0.0)]);
        c.resolve(0.0, 1.0, 0.01, &[], &[1.0], &mut x, &mut v);
        assert!((x[0].length() - 1.05).abs() < 1e-6);
        // Frictionless: the tangential velocity survives, the inward normal part is gone.
        let n = x[0].normalize();
        assert!(v[0].dot(n).abs() < 1e-5);
        assert!((v[0] - n * v[0].dot(n)).length() > 1.9);
        // Outward velocity is left alone.
        let (mut x, mut v) = ([Vec3::new(0.0, 1.0, 0.0)], [Vec3::new(0.0, 4.0, 0.0)]);
        c.resolve(0.0, 1.0, 0.01, &[], &[1.0], &mut x, &mut v);
        assert_eq!(v[0], Vec3::new(0.0, 4.0, 0.0));
    }

    #[test]
    fn a_fast_particle_cannot_tunnel_through_a_thin_box() {
        // A 2 cm slab; the particle crosses it entirely within one substep.
        let collider = Collider::fixed(
            ColliderShape::Cuboid(Cuboid::new(2.0, 0.02, 2.0)),
            Pose::IDENTITY,
            Friction::NONE,
            0.01,
        );
        let mut c = active(collider, 0.01, 0.1);
        c.begin_substep(&[Vec3::new(0.1, 0.5, 0.0)]);
        let (mut x, mut v) = ([Vec3::new(0.1, -0.5, 0.0)], [Vec3::new(0.0, -100.0, 0.0)]);
        c.resolve(0.0, 1.0, 0.01, &[], &[1.0], &mut x, &mut v);
        assert!(x[0].y >= 0.01 + 0.01 - 1e-5, "{}", x[0]);
        assert!(v[0].y >= 0.0);
    }

    #[test]
    fn friction_sticks_below_the_cone_and_slides_above() {
        let plane = ColliderShape::HalfSpace(InfinitePlane3d::new(Dir3::Y));
        for (mu, sticks) in [(0.8, true), (0.3, false)] {
            let collider = Collider::fixed(plane, Pose::IDENTITY, Friction::new(mu), 0.0);
            let mut c = active(collider, 0.01, 0.1);
            // Moved 0.5 mm sideways while sinking 1 mm: the tangent/normal ratio is 0.5.
            c.begin_substep(&[Vec3::new(0.0, 0.0, 0.0)]);
            let (mut x, mut v) = (
                [Vec3::new(0.0005, -0.001, 0.0)],
                [Vec3::new(0.05, -0.1, 0.0)],
            );
            c.resolve(0.0, 1.0, 0.01, &[], &[1.0], &mut x, &mut v);
            assert!(x[0].y.abs() < 1e-7);
            if sticks {
                assert!(x[0].x.abs() < 1e-7 && v[0].x.abs() < 1e-6);
            } else {
                // Kinetic: the tangential velocity loses μ times the normal velocity removed.
                assert!((v[0].x - (0.05 - mu * 0.1)).abs() < 1e-4, "{}", v[0]);
            }
        }
    }

    #[test]
    fn a_moving_collider_drags_the_cloth_within_the_friction_cone() {
        let plane = ColliderShape::HalfSpace(InfinitePlane3d::new(Dir3::Y));
        // The particle sinks 1 mm in a 10 ms substep (normal velocity 0.1 m/s removed), μ = 1.
        for (slide, expected) in [(0.0005, 0.05), (0.01, 0.1)] {
            let collider = Collider {
                end: Pose::from_translation(Vec3::new(slide, 0.0, 0.0)),
                ..Collider::fixed(plane, Pose::IDENTITY, Friction::new(1.0), 0.0)
            };
            let mut c = active(collider, 0.01, 0.1);
            c.begin_substep(&[Vec3::ZERO]);
            let (mut x, mut v) = ([Vec3::new(0.0, -0.001, 0.0)], [Vec3::new(0.0, -0.1, 0.0)]);
            c.resolve(0.0, 1.0, 0.01, &[], &[1.0], &mut x, &mut v);
            // Slow collider: the particle sticks and moves with it. Fast: kinetic friction gives it
            // μ times the normal velocity removed.
            assert!(
                (v[0] - Vec3::new(expected, 0.0, 0.0)).length() < 1e-4,
                "{}",
                v[0]
            );
            assert!(v[0].x <= slide / 0.01 + 1e-6);
        }
    }

    /// [`Vectors`] without the clearance skip: every particle gets the exact test.
    struct Exact<'a>(Vectors<'a>);

    impl ContactState for Exact<'_> {
        fn len(&self) -> usize {
            self.0.len()
        }
        fn inv_mass(&self, i: usize) -> f32 {
            self.0.inv_mass(i)
        }
        fn slot(&self, p: u32) -> usize {
            self.0.slot(p)
        }
        fn start(&self, i: usize) -> Vec3 {
            self.0.start(i)
        }
        fn position(&self, i: usize) -> Vec3 {
            self.0.position(i)
        }
        fn velocity(&self, i: usize) -> Vec3 {
            self.0.velocity(i)
        }
        fn set(&mut self, i: usize, x: Vec3, v: Vec3) {
            self.0.set(i, x, v);
        }
        fn clearances(&self, _: Near, out: &mut [f32]) {
            out.fill(f32::NEG_INFINITY);
        }
    }

    #[test]
    fn the_clearance_skip_changes_no_contact() {
        // Particles scattered around each shape, some inside, some grazing it, some far, moving
        // up to 0.6 m in the substep; colliders at rest, translating and rotating.
        let mut seed = 0x2545_f491_4f6c_dd1d_u64;
        let mut uniform = |lo: f32, hi: f32| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            lo + (hi - lo) * (seed >> 40) as f32 / (1u64 << 24) as f32
        };
        let n = 3000;
        let start: Vec<Vec3> = (0..n)
            .map(|_| Vec3::new(uniform(-1.1, 1.1), uniform(-1.1, 1.1), uniform(-1.1, 1.1)))
            .collect();
        let end: Vec<Vec3> = start
            .iter()
            .map(|s| {
                *s + 0.2 * Vec3::new(uniform(-1.0, 1.0), uniform(-1.0, 1.0), uniform(-1.0, 1.0))
            })
            .collect();
        let v0: Vec<Vec3> = (0..n)
            .map(|_| Vec3::new(uniform(-3.0, 3.0), uniform(-3.0, 3.0), uniform(-3.0, 3.0)))
            .collect();
        let inv_mass: Vec<f32> = (0..n)
            .map(|i| if i % 50 == 0 { 0.0 } else { 1.0 })
            .collect();
        let pose = Pose {
            rotation: Quat::from_rotation_y(0.4) * Quat::from_rotation_x(0.3),
            translation: Vec3::new(0.1, -0.2, 0.05),
        };
        let motions = [
            pose,
            Pose {
                translation: pose.translation + Vec3::new(1.2, 0.4, -0.8),
                ..pose
            },
            Pose {
                rotation: Quat::from_rotation_z(0.5) * pose.rotation,
                ..pose
            },
        ];
        for shape in shapes() {
            for end_pose in motions {
                let collider = Collider {
                    end: end_pose,
                    ..Collider::fixed(shape, pose, Friction::new(0.5), 0.02)
                };
                let mut contacts = active(collider, 1.0 / 60.0, 0.1);
                let mut run = |exact: bool| {
                    let (mut x, mut v) = (end.clone(), v0.clone());
                    let state = Vectors {
                        x: &mut x,
                        v: &mut v,
                        start: &start,
                        inv_mass: &inv_mass,
                    };
                    let (active, clearance) = (&contacts.active, &mut contacts.clearance);
                    let t = (0.25, 0.5, 1.0 / 240.0);
                    if exact {
                        resolve(active, clearance, t, &[], &mut Exact(state));
                    } else {
                        resolve(active, clearance, t, &[], &mut { state });
                    }
                    (x, v)
                };
                let (skipped, exact) = (run(false), run(true));
                assert_eq!(skipped, exact, "{shape:?} moving to {end_pose:?}");
                let moved = (0..n).filter(|&i| exact.0[i] != end[i]).count();
                assert!(
                    moved > 50 && moved < n - 50,
                    "{shape:?}: {moved} of {n} in contact"
                );
            }
        }
    }

    #[test]
    fn the_broad_phase_skips_far_and_masked_colliders() {
        let near = Collider::fixed(
            ColliderShape::Sphere(Sphere::new(0.5)),
            Pose::from_translation(Vec3::new(0.0, -0.55, 0.0)),
            Friction::NONE,
            0.01,
        );
        let far = Collider {
            start: Pose::from_translation(Vec3::new(50.0, 0.0, 0.0)),
            end: Pose::from_translation(Vec3::new(50.0, 0.0, 0.0)),
            ..near
        };
        let masked = Collider { layers: 2, ..near };
        let below = Collider::fixed(
            ColliderShape::HalfSpace(InfinitePlane3d::new(Dir3::Y)),
            Pose::from_translation(Vec3::new(0.0, -10.0, 0.0)),
            Friction::NONE,
            0.01,
        );
        let touching = Collider {
            start: below.start,
            end: Pose::from_translation(Vec3::new(0.0, -0.055, 0.0)),
            ..below
        };
        let mut c = Contacts::new(2, 0.1);
        let cloth = [Vec3::ZERO, Vec3::new(1.0, 0.0, 1.0)];
        c.begin_step(
            &[near, far, masked, below, touching],
            1,
            bounds(&cloth),
            0.05,
            0.01,
        );
        assert_eq!(c.active_count(), 2);
        assert_eq!(c.active[0].collider, near);
        assert_eq!(c.active[1].collider, touching);
    }
}
