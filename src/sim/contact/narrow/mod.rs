//! The narrow phase and the response (steps 2 and 3 of the pipeline in the module docs of
//! [`contact`](super)), on any particle layout a stepper keeps ([`ContactState`]).
//! `particles.rs` holds the contacts of particles with a collider, `triangles.rs` those of
//! triangles with a small sphere.

mod particles;
mod triangles;

use glam::{Quat, Vec3, Vec3A};

#[cfg(feature = "harness")]
pub(crate) use particles::convex_minimum;
use particles::{BATCH, collide_particles};
#[cfg(test)]
pub(super) use triangles::closest_point_on_triangle;
use triangles::collide_triangles;

use super::shapes::{Collider, ColliderShape, Near, Pose, Shape};
use super::simd_passes::Since;
use crate::sim::soa::Soa;

/// Sphere tracing stops after this many steps along one path (a miss).
const MAX_SWEEP_STEPS: u32 = 64;

/// Passes of the particle–triangle test per substep: pushing one triangle moves vertices it shares
/// with its neighbours, so the pass repeats (Gauss-Seidel) until nothing moves, at most this often.
const TRIANGLE_PASSES: u32 = 8;

/// The impulse the particles took from one collider over a step, and its moment.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Reaction {
    /// Where the collider is in the list the step was given.
    pub collider: usize,
    /// Sum of the impulses the collider gave the particles, N s.
    pub impulse: Vec3,
    /// Sum of their moments about the collider's origin at the end of the step, N m s.
    pub moment: Vec3,
}

/// A collider that passed the broad phase, with its velocity over the step.
#[derive(Debug, Clone)]
pub(super) struct ActiveCollider {
    pub collider: Collider,
    /// What the particles took from it during the step.
    pub reaction: Reaction,
    /// The point the reaction's moment is taken about: the collider's origin at the end of the
    /// step as given (see [`Reaction::moment`]).
    origin: Vec3,
    /// Length of the step, s.
    dt: f32,
    /// The fraction of the step up to which a collider that gives way has gained its
    /// acceleration (a substep may be resolved twice).
    accelerated: f32,
    /// Velocity of the collider's origin, m/s.
    pub linear: Vec3,
    /// Angular velocity, rad/s.
    pub angular: Vec3,
    /// Whether triangles are tested too (spheres smaller than the cloth's longest edge).
    pub triangles: bool,
}

impl ActiveCollider {
    /// `c`, the collider at `index` of the step's list, over a step of `dt` seconds, for a cloth
    /// whose longest rest edge is `max_edge`. It gives way to the particles (see
    /// [`Collider::inv_mass`]) only with `gives_way`; otherwise it moves as given.
    pub(super) fn new(
        c: &Collider,
        index: usize,
        (dt, max_edge): (f32, f32),
        gives_way: bool,
    ) -> Self {
        let mut c = c.clone();
        if !(gives_way && c.inv_mass > 0.0) {
            c.inv_mass = 0.0;
            c.end.translation += c.acceleration * (dt * dt);
            c.acceleration = Vec3::ZERO;
        }
        let inv_dt = 1.0 / dt;
        let spin = c.end.rotation * c.start.rotation.inverse();
        let (axis, angle) = spin.to_axis_angle();
        let angle = if angle > std::f32::consts::PI {
            angle - std::f32::consts::TAU
        } else {
            angle
        };
        let triangles =
            matches!(c.shape, Shape::Primitive(ColliderShape::Sphere(s)) if s.radius < max_edge);
        Self {
            reaction: Reaction {
                collider: index,
                ..Reaction::default()
            },
            origin: c.end.translation,
            dt,
            accelerated: 0.0,
            linear: (c.end.translation - c.start.translation) * inv_dt,
            angular: axis * (angle * inv_dt),
            triangles,
            collider: c,
        }
    }

    /// A collider with a body gives way to what the particles took from it in the substep
    /// `[t0, t1]` (fractions of the step), `before` being its [`Reaction`] at the substep's start:
    /// its velocity changes by its acceleration over the substep less the impulse over its mass,
    /// its angular velocity by its inverse inertia times minus the impulses' moment about its
    /// origin, and the rest of its path starts from its pose at `t1` with those velocities.
    fn give_way(&mut self, before: &Reaction, (t0, t1): (f32, f32)) {
        let c = &mut self.collider;
        if c.inv_mass <= 0.0 {
            return;
        }
        let impulse = self.reaction.impulse - before.impulse;
        let at = c.start.lerp(&c.end, t1);
        // The moments were taken about `origin`; about the origin's place at `t1`:
        let moment =
            self.reaction.moment - before.moment - (at.translation - self.origin).cross(impulse);
        let pulled = (t1 - t0.max(self.accelerated)).max(0.0) * self.dt;
        self.accelerated = self.accelerated.max(t1);
        let (dv, dw) = (
            c.acceleration * pulled - impulse * c.inv_mass,
            c.inv_inertia * -moment,
        );
        if !(dv.is_finite() && dw.is_finite()) {
            return;
        }
        self.linear += dv;
        self.angular += dw;
        let (before_t1, after_t1) = (t1 * self.dt, (1.0 - t1) * self.dt);
        c.start = Pose {
            rotation: Quat::from_scaled_axis(self.angular * -before_t1) * at.rotation,
            translation: at.translation - self.linear * before_t1,
        };
        c.end = Pose {
            rotation: Quat::from_scaled_axis(self.angular * after_t1) * at.rotation,
            translation: at.translation + self.linear * after_t1,
        };
    }

    /// Its reaction and the point the reaction's moment is taken about, for
    /// [`push_out`](particles::push_out).
    fn reacted(&mut self) -> (&mut Reaction, Vec3) {
        (&mut self.reaction, self.origin)
    }

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
    /// Whether the stepper projects the tethers itself, inside its solve (XPBD, every substep);
    /// otherwise the limits project them at the end of each step.
    fn projects_tethers(&self) -> bool {
        false
    }
    /// Position at the start of the substep.
    fn start(&self, i: usize) -> Vec3;
    /// Position now.
    fn position(&self, i: usize) -> Vec3;
    /// Velocity now.
    fn velocity(&self, i: usize) -> Vec3;
    /// Moves particle `i` to `x` with velocity `v`; its start stays where it was.
    fn set(&mut self, i: usize, x: Vec3, v: Vec3);
    /// Records that a collider pushed particle `i` out along the outward `normal` while its
    /// surface there moved at `surface`, for a stepper that holds contacts in its next solve
    /// (implicit Euler); others forget it.
    fn touched(&mut self, _i: usize, _normal: Vec3, _surface: Vec3) {}
    /// For every particle, a value into `out` that is at most 0 exactly where its clearance
    /// `near.distance(x) − |x − start|`, a lower bound on its distance from `near`'s point or
    /// plane all along its path over the substep, is at most `within` (≥ 0), up to rounding; NaN
    /// counts as near. Only the sign is meant, so a kernel may compare squares and take no
    /// square root.
    fn clearances(&self, near: Near, within: f32, out: &mut [f32]);
    /// Calls `f(i, start, position)` for every stored particle `i`, in storage order: one pass
    /// over the whole state (a stepper overrides it with a loop over its own arrays).
    fn paths(&self, mut f: impl FnMut(usize, Vec3, Vec3))
    where
        Self: Sized,
    {
        for i in 0..self.len() {
            f(i, self.start(i), self.position(i));
        }
    }
    /// Writes each particle's displacement since `found` (by stored particle, as many as the state
    /// holds) at the end of the substep into `moved`, and returns the sums of the displacements
    /// since `found` at the substep's start and at its end: one pass over the whole state (a
    /// stepper overrides it with a loop over its own arrays).
    fn displaced(&self, found: &[Vec3], moved: &mut [Vec3A]) -> (Vec3A, Vec3A)
    where
        Self: Sized,
    {
        let (mut m0, mut m1) = (Vec3A::ZERO, Vec3A::ZERO);
        self.paths(|i, start, end| {
            let (start, end, at) = (Vec3A::from(start), Vec3A::from(end), Vec3A::from(found[i]));
            let d = end - at;
            moved[i] = d;
            m0 += start - at;
            m1 += d;
        });
        (m0, m1)
    }
    /// The particles' displacements since they were at `at` (by stored particle, as many as the
    /// state holds) and over the substep, and the largest distance of the former from `guess`:
    /// one pass over the whole state (a stepper overrides it with a vector pass over its arrays).
    fn since(&self, at: &Soa, guess: Vec3) -> Since
    where
        Self: Sized,
    {
        let mut out = Since::default();
        self.paths(|i, start, end| {
            let moved = end - at.get(i);
            out.moved += moved;
            out.step += end - start;
            out.worst = out.worst.max(moved.distance_squared(guess));
        });
        out.checked()
    }
    /// Every particle's position now into `out` (by stored particle; resized to the state's
    /// length).
    fn ends(&self, out: &mut Soa)
    where
        Self: Sized,
    {
        out.resize(self.len());
        self.paths(|i, _, end| out.set(i, end));
    }
}

/// See [`Contacts::resolve_state`](super::Contacts::resolve_state). Before the exact test, a particle whose clearance (see
/// [`ContactState::clearances`]) from the collider's bounding ball or plane exceeds the ball's
/// radius, the margin and the collider's travel over the substep is skipped: no point of its path
/// comes within the margin, so the exact test would leave it alone. This bound holds for colliders
/// that do not rotate during the substep; rotating ones get the exact test everywhere.
///
/// Returns the work the colliders did on the particles' motion, J (see
/// [`push_out`](particles::push_out)).
pub(super) fn resolve<S: ContactState>(
    active: &mut [ActiveCollider],
    clearance: &mut Vec<f32>,
    t: (f32, f32, f32),
    triangles: &[u32],
    state: &mut S,
) -> f64 {
    resolve_among(active, clearance, t, triangles, state, None)
}

/// [`resolve`] for the stored particles `only` (where given; the triangles, for the colliders
/// that test them, all the same): after a pass over every particle, those that something else
/// moved since (each listed once).
pub(super) fn resolve_among<S: ContactState>(
    active: &mut [ActiveCollider],
    clearance: &mut Vec<f32>,
    (t0, t1, h): (f32, f32, f32),
    triangles: &[u32],
    state: &mut S,
    only: Option<&[u32]>,
) -> f64 {
    let mut work = 0.0;
    // Sized with the cloth (`Contacts::new`), so this allocates only for a state of another size.
    clearance.resize(state.len(), 0.0);
    for c in active.iter_mut() {
        let before = c.reaction;
        let pose0 = c.collider.start.lerp(&c.collider.end, t0);
        let pose1 = c.collider.start.lerp(&c.collider.end, t1);
        let poses = (&pose0, &pose1, h);
        let visit = match only {
            Some(only) => Visit::Only(only),
            None if pose0.rotation == pose1.rotation => {
                let (near, radius) = c.collider.shape.near(&pose1);
                Visit::Near(near, radius)
            }
            None => Visit::All,
        };
        let run = (visit, &mut *clearance);
        // The shape's distance is chosen once per collider, so that the loop over the particles
        // has it inline (the same arithmetic as `Shape::signed_distance`). A copy of the shape
        // (an `Arc` for a surface), since the loop also updates the collider's reaction.
        let shape = c.collider.shape.clone();
        work += match &shape {
            Shape::Primitive(ColliderShape::HalfSpace(plane)) => {
                let plane = Plane(Vec3::from(plane.normal));
                collide_particles(c, (&shape, plane), poses, state, run)
            }
            Shape::Primitive(primitive) => {
                collide_particles(c, (&shape, *primitive), poses, state, run)
            }
            Shape::Surface(_) => collide_particles(c, (&shape, &shape), poses, state, run),
        };
        if c.triangles {
            for _ in 0..TRIANGLE_PASSES {
                if !collide_triangles(c, (&pose0, &pose1, h), triangles, state, &mut work) {
                    break;
                }
            }
        }
        c.give_way(&before, (t0, t1));
    }
    work
}

/// A shape's signed distance and outward normal at a local point (see
/// [`ColliderShape::signed_distance`]), called inline by the contact loops: a call that is not
/// inlined returns its result through memory, where the caller's wider loads of it stall.
trait Distance {
    fn at(&self, p: Vec3) -> (f32, Vec3);

    /// [`Self::at`] of each point (a shape whose distance runs in vectors overrides it).
    #[inline(always)]
    fn at_each(&self, p: &[Vec3; BATCH]) -> [(f32, Vec3); BATCH] {
        std::array::from_fn(|k| self.at(p[k]))
    }
}

impl Distance for ColliderShape {
    #[inline(always)]
    fn at(&self, p: Vec3) -> (f32, Vec3) {
        self.signed_distance(p)
    }

    /// Spheres and capsules in vectors (see [`ColliderShape::signed_distances`]).
    #[inline(always)]
    fn at_each(&self, p: &[Vec3; BATCH]) -> [(f32, Vec3); BATCH] {
        self.signed_distances(p)
    }
}

impl Distance for &Shape {
    #[inline(always)]
    fn at(&self, p: Vec3) -> (f32, Vec3) {
        self.signed_distance(p)
    }
}

/// A half-space through the origin with this outward unit normal: its distance without the
/// match over the kinds of primitive.
struct Plane(Vec3);

impl Distance for Plane {
    #[inline(always)]
    fn at(&self, p: Vec3) -> (f32, Vec3) {
        (p.dot(self.0), self.0)
    }
}

/// Which particles a collider's contacts look at in a substep.
#[derive(Clone, Copy)]
enum Visit<'a> {
    /// These (stored particles, each once: a batch reads all its particles before it moves any).
    Only(&'a [u32]),
    /// Those whose clearance from what the collider stays clear of, less its radius (see
    /// `ColliderShape::near`), may be within reach (a collider that does not turn in the substep).
    Near(Near, f32),
    /// Every particle.
    All,
}
