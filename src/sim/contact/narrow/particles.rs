//! The contacts of particles with a collider: found, then answered (steps 2 and 3 of the
//! pipeline in the module docs of [`contact`](crate::sim::contact)).

use glam::Vec3;

use super::{ActiveCollider, ContactState, Distance, MAX_SWEEP_STEPS, Reaction, Visit};
use crate::sim::contact::shapes::{Friction, Pose, Shape};

/// The contacts with collider `c` over a substep between `poses` (`h` long) of the particles of
/// `visit` (`clearance` is scratch of one per particle). `distance` is `shape`'s signed distance.
/// Returns the collider's work (see [`push_out`]).
/// The free particles to test are taken [`BATCH`] at a time ([`collide_batch`]).
pub(super) fn collide_particles<S: ContactState, D: Distance>(
    c: &mut ActiveCollider,
    shape: (&Shape, D),
    (pose0, pose1, h): (&Pose, &Pose, f32),
    state: &mut S,
    (visit, clearance): (Visit, &mut Vec<f32>),
) -> f64 {
    let still = pose0 == pose1;
    let mut work = 0.0;
    let mut batch = Batch::default();
    let shape = (shape.0, &shape.1);
    let poses = (pose0, pose1, still);
    let mut collide = |c: &mut ActiveCollider, state: &mut S, i: usize| {
        if state.inv_mass(i) > 0.0 && batch.add(i) {
            work += collide_batch(c, shape, poses, h, state, batch.take());
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
    work + collide_batch(c, shape, poses, h, state, batch.take())
}

/// Particles tested together: each one's contact is a chain of square roots and divisions, and
/// running the stages of several side by side lets the processor overlap their chains.
pub(super) const BATCH: usize = 8;

/// Up to [`BATCH`] stored particles waiting for their contact test.
#[derive(Default)]
struct Batch {
    lanes: [usize; BATCH],
    len: usize,
}

impl Batch {
    /// Adds particle `i`; true when the batch is full.
    #[inline(always)]
    fn add(&mut self, i: usize) -> bool {
        self.lanes[self.len] = i;
        self.len += 1;
        self.len == BATCH
    }

    /// The particles added since the last take, emptying it.
    #[inline(always)]
    fn take(&mut self) -> &[usize] {
        let len = std::mem::take(&mut self.len);
        &self.lanes[..len]
    }
}

/// The contacts of the distinct free particles `lanes` with collider `c`, each exactly as
/// [`collide_particle`] alone would resolve it and in the same order (so the collider's reaction
/// sums the same impulses in the same order): every particle's contact is found, then every
/// response computed, then each applied. A particle whose path must be searched (a sweep from
/// clear, or a test of whether it went through) is resolved alone, in its turn.
fn collide_batch<S: ContactState, D: Distance>(
    c: &mut ActiveCollider,
    shape: (&Shape, &D),
    poses: (&Pose, &Pose, bool),
    h: f32,
    state: &mut S,
    lanes: &[usize],
) -> f64 {
    let (margin, (pose0, pose1, still)) = (c.collider.margin, poses);
    let mut paths = [Path::default(); BATCH];
    for (p, &i) in paths.iter_mut().zip(lanes) {
        *p = Path::of(&*state, i, (pose0, pose1));
    }
    let ends = shape.1.at_each(&paths.map(|p| p.local));
    let starts = shape.1.at_each(&paths.map(|p| p.local0));
    let mut found = [Found::Clear; BATCH];
    for (k, f) in found.iter_mut().enumerate().take(lanes.len()) {
        *f = find(margin, shape, still, (paths[k], ends[k], starts[k]), false);
    }
    let mut responses = [Response::default(); BATCH];
    for ((r, f), &i) in responses.iter_mut().zip(&found).zip(lanes) {
        if let Found::Contact(hit) = *f {
            *r = response(c, hit, (poses.1, h), &*state, i);
        }
    }
    let mut work = 0.0;
    for ((r, f), &i) in responses.iter().zip(&found).zip(lanes) {
        work += match f {
            Found::Clear => 0.0,
            Found::Contact(_) => push_out(state, i, (r.x, r.v), (r.normal, r.vc), c.reacted()),
            Found::Search => collide_particle(c, shape, poses, h, state, i),
        };
    }
    work
}

/// Where a particle touches a collider, in the collider's frame at the end of the substep.
#[derive(Clone, Copy)]
struct Hit {
    /// The particle's point on its path nearest the surface (where it ended, unless it
    /// tunnelled), local.
    local: Vec3,
    /// Its signed distance from the surface.
    d: f32,
    /// The outward normal it is pushed out along, local.
    normal: Vec3,
    /// Where the particle started the substep, world.
    start: Vec3,
}

/// What [`find`] found for a particle.
#[derive(Clone, Copy)]
enum Found {
    /// It stays clear of the collider.
    Clear,
    /// It is pushed out from this hit.
    Contact(Hit),
    /// Its path must be searched first (only where the search was not allowed).
    Search,
}

/// A particle's response to its [`Hit`]: its new position and velocity, the world normal and the
/// surface's velocity there.
#[derive(Clone, Copy, Default)]
struct Response {
    x: Vec3,
    v: Vec3,
    normal: Vec3,
    vc: Vec3,
}

/// Moves particle `i` (free) to `x` with velocity `v`, the response to a collider whose surface
/// moves at `vc` pushing it out along the outward `normal`, and adds the response's impulse to
/// the collider's `reaction` (its moment about `origin`, the collider's origin at the end of the
/// step). Returns the work that surface did on the particle's motion, J: the impulse times `vc`.
/// The kinetic energy [`respond`] adds is never more (removing inward relative velocity and friction both move the velocity towards
/// the surface's), so this bounds what a contact gives the cloth even where the response also
/// takes away energy the springs had just put in (a moving collider pressing the cloth against
/// its springs does its work that way).
#[inline(always)]
pub(super) fn push_out<S: ContactState>(
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
fn collide_particle<S: ContactState, D: Distance>(
    c: &mut ActiveCollider,
    shape: (&Shape, &D),
    poses: (&Pose, &Pose, bool),
    h: f32,
    state: &mut S,
    i: usize,
) -> f64 {
    let path = Path::of(&*state, i, (poses.0, poses.1));
    let (end, start) = (shape.1.at(path.local), shape.1.at(path.local0));
    match find(c.collider.margin, shape, poses.2, (path, end, start), true) {
        Found::Contact(hit) => {
            let r = response(c, hit, (poses.1, h), &*state, i);
            push_out(state, i, (r.x, r.v), (r.normal, r.vc), c.reacted())
        }
        Found::Clear | Found::Search => 0.0,
    }
}

/// A particle's path over a substep: where it starts and ends, in the world and in the
/// collider's frame at the substep's start and end.
#[derive(Clone, Copy, Default)]
struct Path {
    start: Vec3,
    end: Vec3,
    local0: Vec3,
    local: Vec3,
}

impl Path {
    /// Particle `i`'s path against a collider moving from `pose0` to `pose1`.
    #[inline(always)]
    fn of<S: ContactState>(state: &S, i: usize, (pose0, pose1): (&Pose, &Pose)) -> Self {
        let (end, start) = (state.position(i), state.start(i));
        Self {
            start,
            end,
            local0: pose0.inverse_transform_point(start),
            local: pose1.inverse_transform_point(end),
        }
    }
}

/// Whether a particle on `path` touches a collider with `margin` (`still` if it does not move
/// in the substep), and where; `end` and `start` are the collider's distance and normal at the
/// path's ends. A particle that started the substep clear goes back to where its
/// path first came within the margin; without `search`, such a path, and one that must be
/// searched for whether it went through, is left as [`Found::Search`].
#[inline(always)]
fn find<D: Distance>(
    margin: f32,
    (shape, distance): (&Shape, &D),
    still: bool,
    (path, end, start): (Path, (f32, Vec3), (f32, Vec3)),
    search: bool,
) -> Found {
    let Path {
        start: x0,
        end: x,
        local0,
        mut local,
    } = path;
    let ((mut d, mut normal), (d0, n0)) = (end, start);
    // The signed distance changes no faster than the point moves: a particle that ends the
    // substep farther from a collider at rest than it travelled cannot have passed through it.
    if d >= margin && still && d - margin > x.distance(x0) {
        return Found::Clear;
    }
    // A particle that started the substep clear goes back to where its path (in the collider's
    // frame) first came within the margin, whether it ends outside (it passed through) or
    // inside: the nearest surface of its end point may be the far side of a thin collider.
    if !search && d0 > margin && (local - local0).length() > margin {
        return Found::Search;
    }
    // A path that started in contact, or (left unsearched above) is too short, has nothing to
    // sweep.
    let swept = (search && d0 > margin)
        .then(|| sweep(distance, (local0, d0), local, margin))
        .flatten();
    match swept {
        Some((hit, hit_d, hit_n)) => (local, d, normal) = (hit, hit_d, hit_n),
        None => {
            // Started in contact: it went through if it ends inside where the nearest surface
            // faces away from (or across) the one it started at, or, inside or out, having been
            // deeper on the way than at its end.
            let through = d0 <= margin
                && ((d < margin && normal.dot(n0) <= 0.0)
                    || match went_through(
                        (shape, distance),
                        (local0, d0),
                        (local, d),
                        margin,
                        search,
                    ) {
                        Some(through) => through,
                        None => return Found::Search,
                    });
            if through {
                // Out to the tangent plane where it started, plus the margin: the shape lies
                // behind that plane (it is convex), so the particle ends clear of it on its own
                // side, keeping the motion along the surface.
                (d, normal) = (d0 + (local - local0).dot(n0), n0);
            } else if d >= margin {
                return Found::Clear;
            }
            // Otherwise it started in contact (resting, or reached by the collider's own
            // motion) and goes out along the nearest surface.
        }
    }
    Found::Contact(Hit {
        local,
        d,
        normal,
        start: x0,
    })
}

/// The response of particle `i` to `hit` on collider `c` at `pose1`, over a substep `h` long:
/// out along the normal to the margin, then [`respond`].
#[inline(always)]
fn response<S: ContactState>(
    c: &ActiveCollider,
    hit: Hit,
    (pose1, h): (&Pose, f32),
    state: &S,
    i: usize,
) -> Response {
    let Hit {
        local,
        d,
        normal,
        start,
    } = hit;
    let mut x = pose1.transform_point(local + normal * (c.collider.margin - d));
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
    Response { x, v, normal, vc }
}

/// The response of a contact just pushed out by `push` along the outward normal `n`, against a
/// surface moving at `vc`: Coulomb friction on the tangential displacement relative to the surface
/// over the substep (`h` long, the particle starting at `start`), and removal of the inward
/// relative normal velocity. See the module docs.
#[inline(always)]
pub(super) fn respond(
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
/// `distance` is `shape`'s signed distance. Without `search`, a path that must be searched gives
/// `None`.
fn went_through(
    (shape, distance): (&Shape, &impl Distance),
    (from, d0): (Vec3, f32),
    (to, d): (Vec3, f32),
    margin: f32,
    search: bool,
) -> Option<bool> {
    let length = from.distance(to);
    match shape {
        // Ending inside such a surface is left to the caller's test of the normals.
        Shape::Surface(s) if s.is_shell() || !s.is_convex() => {
            let reaches = d >= margin && length >= d0 + d;
            if !reaches {
                return Some(false);
            }
            search.then(|| s.crosses(from, to))
        }
        _ => {
            let floor = d.min(0.0) - margin;
            let reaches = length > d0 + d - 2.0 * floor;
            if !reaches {
                return Some(false);
            }
            search.then(|| convex_minimum(|t| distance.at(from.lerp(to, t)).0) < floor)
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
    distance: &impl Distance,
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
        let (d, n) = distance.at(p);
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
