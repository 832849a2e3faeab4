//! The narrow phase and the response (steps 2 and 3 of the pipeline in the module docs of
//! [`contact`](super)), on any particle layout a stepper keeps ([`ContactState`]).

use glam::{Quat, Vec3, Vec3A};

use super::shapes::{Collider, ColliderShape, Friction, Near, Pose, Shape};
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
/// Returns the work the colliders did on the particles' motion, J (see [`push_out`]).
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
/// moved since.
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
                let n = Vec3::from(plane.normal);
                collide_particles(c, (&shape, |p: Vec3| (p.dot(n), n)), poses, state, run)
            }
            Shape::Primitive(primitive) => collide_particles(
                c,
                (&shape, |p| primitive.signed_distance(p)),
                poses,
                state,
                run,
            ),
            Shape::Surface(_) => {
                collide_particles(c, (&shape, |p| shape.signed_distance(p)), poses, state, run)
            }
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

/// Which particles a collider's contacts look at in a substep.
#[derive(Clone, Copy)]
enum Visit<'a> {
    /// These (stored particles).
    Only(&'a [u32]),
    /// Those whose clearance from what the collider stays clear of, less its radius (see
    /// `ColliderShape::near`), may be within reach (a collider that does not turn in the substep).
    Near(Near, f32),
    /// Every particle.
    All,
}

/// The contacts with collider `c` over a substep between `poses` (`h` long) of the particles of
/// `visit` (`clearance` is scratch of one per particle). `distance` is `shape`'s signed distance.
/// Returns the collider's work (see [`push_out`]).
fn collide_particles<S: ContactState, D: Fn(Vec3) -> (f32, Vec3)>(
    c: &mut ActiveCollider,
    shape: (&Shape, D),
    (pose0, pose1, h): (&Pose, &Pose, f32),
    state: &mut S,
    (visit, clearance): (Visit, &mut Vec<f32>),
) -> f64 {
    let still = pose0 == pose1;
    let mut work = 0.0;
    let mut collide = |c: &mut ActiveCollider, state: &mut S, i: usize| {
        if state.inv_mass(i) > 0.0 {
            work += collide_particle(c, (shape.0, &shape.1), (pose0, pose1, still), h, state, i);
        }
    };
    match visit {
        Visit::Only(only) => {
            for &i in only {
                collide(c, state, i as usize);
            }
        }
        Visit::Near(near, radius) => {
            let travel = pose0.translation.distance(pose1.translation);
            // Rounding in the exact test is far below this slack (relative to the coordinates).
            let slack = 1e-5 * (pose1.translation.abs().max_element() + radius + travel + 1.0);
            let skip = radius + c.collider.margin + travel + slack;
            state.clearances(near, skip, clearance);
            // Sixteen signs tested at a time (vector code), then the few close ones visited.
            for (k, chunk) in clearance.chunks(16).enumerate() {
                let mut close = chunk.iter().enumerate().fold(0u32, |m, (l, &gap)| {
                    m | (u32::from(gap <= 0.0 || gap.is_nan()) << l)
                });
                while close != 0 {
                    let i = 16 * k + close.trailing_zeros() as usize;
                    close &= close - 1;
                    collide(c, state, i);
                }
            }
        }
        Visit::All => {
            for i in 0..state.len() {
                collide(c, state, i);
            }
        }
    }
    work
}

/// Moves particle `i` (free) to `x` with velocity `v`, the response to a collider whose surface
/// moves at `vc` pushing it out along the outward `normal`, and adds the response's impulse to
/// the collider's `reaction` (its moment about `origin`, the collider's origin at the end of the
/// step). Returns the work that surface did on the particle's motion, J: the impulse times `vc`.
/// The kinetic energy [`respond`] adds is never more (removing inward relative velocity and friction both move the velocity towards
/// the surface's), so this bounds what a contact gives the cloth even where the response also
/// takes away energy the springs had just put in (a moving collider pressing the cloth against
/// its springs does its work that way).
#[inline]
fn push_out<S: ContactState>(
    state: &mut S,
    i: usize,
    (x, v): (Vec3, Vec3),
    (normal, vc): (Vec3, Vec3),
    (reaction, origin): (&mut Reaction, Vec3),
) -> f64 {
    let impulse = (v - state.velocity(i)) / state.inv_mass(i);
    reaction.impulse += impulse;
    reaction.moment += (x - origin).cross(impulse);
    state.set(i, x, v);
    state.touched(i, normal, vc);
    f64::from(impulse.dot(vc))
}

/// Contact of particle `i` with one collider over a substep: projection, then the velocity split
/// and Coulomb friction described in the module docs. Returns the collider's work (see
/// [`push_out`]).
fn collide_particle<S: ContactState, D: Fn(Vec3) -> (f32, Vec3)>(
    c: &mut ActiveCollider,
    (shape, distance): (&Shape, &D),
    (pose0, pose1, still): (&Pose, &Pose, bool),
    h: f32,
    state: &mut S,
    i: usize,
) -> f64 {
    let margin = c.collider.margin;
    let (x, start) = (state.position(i), state.start(i));
    let mut local = pose1.inverse_transform_point(x);
    let (mut d, mut normal) = distance(local);
    // The signed distance changes no faster than the point moves: a particle that ends the
    // substep farther from a collider at rest than it travelled cannot have passed through it.
    if d >= margin && still && d - margin > x.distance(start) {
        return 0.0;
    }
    // A particle that started the substep clear goes back to where its path (in the collider's
    // frame) first came within the margin, whether it ends outside (it passed through) or
    // inside: the nearest surface of its end point may be the far side of a thin collider.
    let local0 = pose0.inverse_transform_point(start);
    let (d0, n0) = distance(local0);
    match sweep(distance, (local0, d0), local, margin) {
        Some((hit, hit_d, hit_n)) => (local, d, normal) = (hit, hit_d, hit_n),
        None => {
            // Started in contact: it went through if it ends inside where the nearest surface
            // faces away from (or across) the one it started at, or, inside or out, having been
            // deeper on the way than at its end.
            let through = d0 <= margin
                && ((d < margin && normal.dot(n0) <= 0.0)
                    || went_through((shape, distance), (local0, d0), (local, d), margin));
            if through {
                // Out to the tangent plane where it started, plus the margin: the shape lies
                // behind that plane (it is convex), so the particle ends clear of it on its own
                // side, keeping the motion along the surface.
                (d, normal) = (d0 + (local - local0).dot(n0), n0);
            } else if d >= margin {
                return 0.0;
            }
            // Otherwise it started in contact (resting, or reached by the collider's own
            // motion) and goes out along the nearest surface.
        }
    }
    let mut x = pose1.transform_point(local + normal * (margin - d));
    let push = (x - state.position(i)).length();
    let mut v = state.velocity(i);
    let vc = c.velocity_at(x, pose1.translation);
    let normal = pose1.rotate(normal);
    respond(
        &c.collider.friction,
        normal,
        push,
        vc,
        (h, start),
        &mut x,
        &mut v,
    );
    push_out(state, i, (x, v), (normal, vc), (&mut c.reaction, c.origin))
}

/// The response of a contact just pushed out by `push` along the outward normal `n`, against a
/// surface moving at `vc`: Coulomb friction on the tangential displacement relative to the surface
/// over the substep (`h` long, the particle starting at `start`), and removal of the inward
/// relative normal velocity. See the module docs.
#[inline]
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

/// Whether a particle that started in contact, at `from` (distance `d0`), went through the shape
/// on its straight path to `to` (distance `d`): the path reaches below `min(d, 0) - margin`,
/// more than `margin` below the surface and deeper than its end. A particle sliding along the
/// surface and off it, or into it, cuts the surface by its path's sagitta, far less; one that
/// ends inside nearer another face than the one it started at (pulled across a capsule from its
/// side to its cap) passed the deepest point of its path on the way.
/// The signed distance of a convex shape is convex along a line, so a ternary search finds the
/// deepest point. The signed distance changes no faster than the point moves, so a path shorter
/// than the way down and back up (every resting particle's) is not searched.
/// A shell (an open [`Surface`](super::Surface)) has no inside to reach into, and a non-convex
/// surface's distance has no single minimum along a path: a path went through such a surface if
/// it crosses it, which a path shorter than the way to the surface and on cannot.
/// `distance` is `shape`'s signed distance.
fn went_through(
    (shape, distance): (&Shape, &impl Fn(Vec3) -> (f32, Vec3)),
    (from, d0): (Vec3, f32),
    (to, d): (Vec3, f32),
    margin: f32,
) -> bool {
    let length = from.distance(to);
    match shape {
        // Ending inside such a surface is left to the caller's test of the normals.
        Shape::Surface(s) if s.is_shell() || !s.is_convex() => {
            d >= margin && length >= d0 + d && s.crosses(from, to)
        }
        _ => {
            let floor = d.min(0.0) - margin;
            length > d0 + d - 2.0 * floor
                && convex_minimum(|t| distance(from.lerp(to, t)).0) < floor
        }
    }
}

/// The smallest value of a convex function on `[0, 1]` (a ternary search, to within 3e-6 of the
/// interval).
pub(crate) fn convex_minimum(f: impl Fn(f32) -> f32) -> f32 {
    let (mut lo, mut hi) = (0.0f32, 1.0f32);
    for _ in 0..32 {
        let (a, b) = (lo + (hi - lo) / 3.0, hi - (hi - lo) / 3.0);
        if f(a) < f(b) {
            hi = b;
        } else {
            lo = a;
        }
    }
    f(0.5 * (lo + hi))
}

/// Sphere tracing from `from` (at distance `d0`) to `to` (collider frame): the first point of the
/// path within `margin` of the surface, with its distance and normal; `None` if the path stays
/// clear or starts in contact.
fn sweep(
    distance: &impl Fn(Vec3) -> (f32, Vec3),
    (from, d0): (Vec3, f32),
    to: Vec3,
    margin: f32,
) -> Option<(Vec3, f32, Vec3)> {
    let delta = to - from;
    let len = delta.length();
    if len <= margin || d0 <= margin {
        return None;
    }
    let dir = delta / len;
    let min_step = 0.25 * margin.max(1e-4 * len);
    let mut t = 0.0;
    for _ in 0..MAX_SWEEP_STEPS {
        let p = from + dir * t;
        let (d, n) = distance(p);
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
/// particle contacts (friction, inward velocity removed), their work added to `work`. Returns whether
/// any triangle was moved.
fn collide_triangles<S: ContactState>(
    c: &mut ActiveCollider,
    (pose0, pose1, h): (&Pose, &Pose, f32),
    triangles: &[u32],
    state: &mut S,
    work: &mut f64,
) -> bool {
    let Shape::Primitive(ColliderShape::Sphere(sphere)) = c.collider.shape else {
        return false;
    };
    let origin = c.origin;
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
            *work += push_out(state, i, (x, v), (-dir, vc), (&mut c.reaction, origin));
        }
    }
    moved
}

/// The point of triangle `abc` closest to `p`, with its barycentric coordinates (Ericson,
/// "Real-Time Collision Detection", §5.1.5: Voronoi regions of vertices, then edges, then the face).
pub(super) fn closest_point_on_triangle(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> (Vec3, Vec3) {
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
