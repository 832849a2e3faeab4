//! Limits on where a particle may go, resolved every substep with the contacts (before the
//! colliders, so that a collider has the last word):
//! - **targets**: a particle tied to an animated target (its skinned position, say) stays within
//!   a maximum distance of it, and outside a backstop sphere behind it (along the target's
//!   normal), so a cape follows its character without sinking into its back;
//! - **tethers** (long-range attachments): a free particle stays within its geodesic rest
//!   distance, times `1 + slack`, of the nearest pinned particle, so that stretch under a sudden
//!   pull does not depend on how many iterations the springs get. XPBD projects them itself,
//!   after the springs of every substep (`integrate/xpbd/tethers.rs`); for the other
//!   integrators they act here, at the end of every substep, so that no particle overshoots a
//!   tether by more than a substep's motion (projected back from a whole step's overshoot, an
//!   explicit integrator's cloth gains energy).
//!
//! Each limit is a one-sided distance constraint between the particle and a point that moves on
//! its own (the target, interpolated across the step like a pin; the pinned anchor, already at
//! the substep's end): a particle past it is projected back onto it, and its velocity relative
//! to that point loses the component that would carry it out again (the same inelastic response
//! as a contact, so a limit never adds energy of its own).

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use glam::Vec3;

use super::narrow::ContactState;
use crate::sim::model::compute_normals;
use crate::sim::settings::{TargetLimits, Tethers};
use crate::sim::state::between;
use batch::resolve_targets;

mod batch;

/// A particle tied to an animated target (see [`crate::sim::ClothSim::set_targets`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Target {
    /// The particle.
    pub particle: u32,
    /// Its weight: it stays within `weight × max_distance_scale` of the target (0: on it).
    pub weight: f32,
    /// The target's position, m (world space).
    pub position: Vec3,
    /// The animated surface's normal at the target (the backstop lies behind it); any length,
    /// zero for no backstop.
    pub normal: Vec3,
}

/// A target's state over a step: where it is at the step's start and end.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Moving {
    particle: u32,
    weight: f32,
    from: Vec3,
    to: Vec3,
    normal_from: Vec3,
    normal_to: Vec3,
}

/// A tether: `particle` stays within `length` of `anchor` (a pinned particle).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Tether {
    particle: u32,
    anchor: u32,
    length: f32,
}

/// A cloth's targets and tethers, with the settings they are resolved with.
#[derive(Debug, Clone, Default)]
pub(crate) struct Limits {
    targets: Vec<Moving>,
    /// Whether a target may have moved since the last [`Self::end_step`] (when not, none moves
    /// during the next step, and [`Self::moving`] need not look).
    touched: bool,
    /// Whether no particle has more than one target (then the targets are independent of each
    /// other and are resolved a batch at a time, see [`resolve_targets`]).
    distinct: bool,
    /// Per particle, whether a target was seen (scratch of [`Self::targets_changed`], which a
    /// coarse cloth calls every step).
    seen: Vec<bool>,
    tethers: Vec<Tether>,
    settings: TargetLimits,
}

impl Limits {
    /// Whether there is nothing to resolve.
    pub fn is_empty(&self) -> bool {
        self.targets.is_empty() && self.tethers.is_empty()
    }

    /// Number of targets and of tethers.
    pub fn counts(&self) -> (usize, usize) {
        (self.targets.len(), self.tethers.len())
    }

    /// Sets how far targeted particles may leave their targets.
    pub fn set_settings(&mut self, settings: TargetLimits) {
        self.settings = settings;
    }

    /// Replaces the targets; each starts the next step where it is given (no motion).
    pub fn set_targets(&mut self, targets: impl IntoIterator<Item = Target>) {
        self.targets.clear();
        self.targets.extend(targets.into_iter().map(|t| Moving {
            particle: t.particle,
            weight: t.weight,
            from: t.position,
            to: t.position,
            normal_from: t.normal,
            normal_to: t.normal,
        }));
        self.targets_changed();
    }

    /// Notes that the targeted particles may have changed.
    fn targets_changed(&mut self) {
        self.touched = true;
        let count = self.targets.iter().map(|t| t.particle as usize + 1).max();
        let seen = &mut self.seen;
        seen.clear();
        seen.resize(count.unwrap_or(0), false);
        self.distinct =
            (self.targets.iter()).all(|t| !std::mem::replace(&mut seen[t.particle as usize], true));
    }

    /// Moves the targets, in the order [`Self::set_targets`] took them, to `(position, normal)`
    /// at the end of the next step. Non-finite values are ignored.
    pub fn move_targets(&mut self, moves: impl IntoIterator<Item = (Vec3, Vec3)>) {
        self.touched = true;
        for (t, (position, normal)) in self.targets.iter_mut().zip(moves) {
            if position.is_finite() {
                t.to = position;
            }
            if normal.is_finite() {
                t.normal_to = normal;
            }
        }
    }

    /// Takes `other`'s targets and their motion (same settings and tethers assumed).
    pub fn sync_targets(&mut self, other: &Limits) {
        self.touched = true;
        self.targets.clone_from(&other.targets);
        self.distinct = other.distinct;
    }

    /// Takes `other`'s targets and gives each copy a tear made (`(particle, copy)`, in order) the
    /// targets of its particle, after them.
    pub fn inherit_targets(&mut self, other: &Limits, copies: &[(u32, u32)]) {
        self.targets.clone_from(&other.targets);
        for &(particle, copy) in copies {
            for t in other.targets.iter().filter(|t| t.particle == particle) {
                self.targets.push(Moving {
                    particle: copy,
                    ..*t
                });
            }
        }
        self.targets_changed();
    }

    /// Takes the targets of `other`'s particles that `index` maps to a particle here (those
    /// mapped to `u32::MAX` are left out), with their motion.
    pub fn restrict_targets(&mut self, other: &Limits, index: &[u32]) {
        let touched = self.touched | other.touched;
        self.targets.clear();
        self.targets.extend(other.targets.iter().filter_map(|t| {
            let particle = *index.get(t.particle as usize)?;
            (particle != u32::MAX).then_some(Moving { particle, ..*t })
        }));
        self.targets_changed();
        self.touched = touched;
    }

    /// The particles with a target and the target's weight, in order.
    pub fn targeted(&self) -> impl Iterator<Item = (u32, f32)> + '_ {
        self.targets.iter().map(|t| (t.particle, t.weight))
    }

    /// Keeps the targets of the particles `keep` holds to, drops the others.
    pub fn retain_targets(&mut self, keep: impl Fn(u32) -> bool) {
        self.targets.retain(|t| keep(t.particle));
        self.targets_changed();
    }

    /// Whether a target moves during the next step.
    pub fn moving(&self) -> bool {
        self.touched
            && self
                .targets
                .iter()
                .any(|t| t.from != t.to || t.normal_from != t.normal_to)
    }

    /// The farthest any target moves during the next step, m.
    pub fn max_jump(&self) -> f32 {
        self.targets
            .iter()
            .map(|t| t.from.distance(t.to))
            .fold(0.0, f32::max)
    }

    /// Ends a step: the targets' end becomes the next step's start.
    pub fn end_step(&mut self) {
        self.touched = false;
        for t in &mut self.targets {
            t.from = t.to;
            t.normal_from = t.normal_to;
        }
    }

    /// Lengthens each tether that its particle, at `x`, is farther from its anchor than: a tear
    /// lengthens paths along the cloth and may tie a particle to another pin, which must not pull
    /// it in all at once.
    pub fn fit_tethers(&mut self, x: &[Vec3]) {
        for t in &mut self.tethers {
            t.length = t
                .length
                .max(x[t.particle as usize].distance(x[t.anchor as usize]));
        }
    }

    /// Ties every particle that a path along the `triangles`' edges joins to a pinned particle
    /// (`pinned[i]`) to the nearest such one, at `1 + slack` times their distance along the
    /// edges at rest (`rest`); or drops every tether when `tethers` is off or nothing is pinned.
    pub fn set_tethers(
        &mut self,
        tethers: Tethers,
        (triangles, rest): (&[u32], &[Vec3]),
        pinned: &[bool],
    ) {
        self.tethers.clear();
        if !tethers.enabled || !pinned.contains(&true) {
            return;
        }
        let (nearest, distance) = geodesic_to_nearest(triangles, rest, pinned);
        let stretch = 1.0 + tethers.slack;
        for (i, (&anchor, &d)) in nearest.iter().zip(&distance).enumerate() {
            if anchor != u32::MAX && !pinned[i] {
                self.tethers.push(Tether {
                    particle: i as u32,
                    anchor,
                    length: d * stretch,
                });
            }
        }
    }

    /// The tethers: (particle, anchor, length).
    pub fn tethers(&self) -> impl Iterator<Item = (u32, u32, f32)> + '_ {
        self.tethers
            .iter()
            .map(|t| (t.particle, t.anchor, t.length))
    }

    /// Projects every free particle that has left its limits back onto them at the end of the
    /// substep `[t0, t1]` (fractions of the step) of length `h`: its targets, and its tether
    /// unless the stepper projects the tethers itself ([`ContactState::projects_tethers`]).
    pub fn resolve<S: ContactState>(&self, (t0, t1, h): (f32, f32, f32), state: &mut S) {
        let inv_h = 1.0 / h;
        let tethers = if !state.projects_tethers() {
            &self.tethers[..]
        } else {
            &[]
        };
        for t in tethers {
            let i = state.slot(t.particle);
            if state.inv_mass(i) == 0.0 {
                continue;
            }
            let a = state.slot(t.anchor);
            let (centre, velocity) = (state.position(a), state.velocity(a));
            within(state, i, (centre, velocity), t.length);
        }
        if self.distinct {
            resolve_targets(&self.targets, self.settings, (t0, t1, inv_h), state);
            return;
        }
        for t in &self.targets {
            resolve_target(t, self.settings, (t0, t1, inv_h), state);
        }
    }
}

/// Keeps the particle of target `t` within its limits at the end of the substep `[t0, t1]`:
/// within its maximum distance of the target, then outside the backstop.
fn resolve_target<S: ContactState>(
    t: &Moving,
    s: TargetLimits,
    (t0, t1, inv_h): (f32, f32, f32),
    state: &mut S,
) {
    let i = state.slot(t.particle);
    if state.inv_mass(i) == 0.0 {
        return;
    }
    let target = between(t.from, t.to, t1);
    let velocity = (target - between(t.from, t.to, t0)) * inv_h;
    within(
        state,
        i,
        (target, velocity),
        t.weight * s.max_distance_scale,
    );
    if s.backstop_radius > 0.0 {
        let normal = t.normal_from.lerp(t.normal_to, t1).normalize_or_zero();
        if normal != Vec3::ZERO {
            let centre = target - normal * (s.backstop_radius + s.backstop_offset);
            outside(state, i, (centre, velocity, normal), s.backstop_radius);
        }
    }
}

/// Keeps the particle at `i` within `radius` of `centre`, which moves at `velocity`.
fn within<S: ContactState>(state: &mut S, i: usize, (centre, velocity): (Vec3, Vec3), radius: f32) {
    let x = state.position(i);
    let offset = x - centre;
    let distance2 = offset.length_squared();
    if distance2 <= radius * radius {
        return;
    }
    let n = offset / distance2.sqrt();
    let mut v = state.velocity(i);
    let outward = (v - velocity).dot(n);
    if outward > 0.0 {
        v -= outward * n;
    }
    state.set(i, centre + n * radius, v);
}

/// Keeps the particle at `i` at least `radius` from `centre`, which moves at `velocity`; a
/// particle at the centre leaves along `normal`.
fn outside<S: ContactState>(
    state: &mut S,
    i: usize,
    (centre, velocity, normal): (Vec3, Vec3, Vec3),
    radius: f32,
) {
    let x = state.position(i);
    let offset = x - centre;
    let distance = offset.length();
    if distance >= radius {
        return;
    }
    let n = if distance > 1e-9 * radius {
        offset / distance
    } else {
        normal
    };
    let mut v = state.velocity(i);
    let inward = (v - velocity).dot(n);
    if inward < 0.0 {
        v -= inward * n;
    }
    state.set(i, centre + n * radius, v);
}

/// The cosine of the largest angle between the rest shape's normals at the start of a straight
/// stretch of a geodesic and at each particle it reaches.
const FLAT: f32 = std::f32::consts::FRAC_1_SQRT_2;

/// For every particle, the nearest pinned particle along the rest shape (`u32::MAX` where no path
/// along the triangles' edges joins one to it) and the length of that path, by Dijkstra's
/// algorithm from all pinned particles at once. Ties go to the lower-numbered anchor, whatever
/// the order of work.
///
/// A path along the edges alone is up to 8% longer than the straight line across a flat grid,
/// which would leave a tether that much slack. So a path runs straight (any-angle, as in
/// Theta*) from the last point where it bent to each particle it reaches, as long as the rest
/// shape's normals there and at the bend are within 45° ([`FLAT`]); a stretch whose normals turn
/// by `θ` counts as the arc of a circle through its ends, `θ/2 / sin(θ/2)` times the straight
/// line (1 across a flat part of the cloth, the arc's length across a cylinder). A path is never
/// shorter than the straight line between its ends, so the rest shape meets every tether. (A
/// straight stretch may cut across a notch or hole of a flat cloth.)
fn geodesic_to_nearest(triangles: &[u32], rest: &[Vec3], pinned: &[bool]) -> (Vec<u32>, Vec<f32>) {
    let n = rest.len();
    let mut normal = vec![Vec3::ZERO; n];
    compute_normals(rest, triangles, &mut normal);
    // Each triangle's edges, both ways, as an adjacency list (compressed rows).
    let mut degree = vec![0u32; n + 1];
    let edges = triangles.chunks_exact(3).flat_map(|t| {
        [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])]
            .into_iter()
            .flat_map(|(a, b)| [(a, b), (b, a)])
    });
    for (a, _) in edges.clone() {
        degree[a as usize + 1] += 1;
    }
    for i in 0..n {
        degree[i + 1] += degree[i];
    }
    let mut fill = degree.clone();
    let mut neighbours = vec![0u32; degree[n] as usize];
    for (a, b) in edges {
        neighbours[fill[a as usize] as usize] = b;
        fill[a as usize] += 1;
    }

    /// A particle reached at `distance` from `anchor`, by a path whose last straight stretch
    /// starts at `bend`; ordered nearest first for the max-heap.
    #[derive(PartialEq)]
    struct Reached {
        distance: f32,
        anchor: u32,
        particle: u32,
        bend: u32,
    }
    impl Eq for Reached {}
    impl Ord for Reached {
        fn cmp(&self, other: &Self) -> Ordering {
            other
                .distance
                .total_cmp(&self.distance)
                .then(other.anchor.cmp(&self.anchor))
                .then(other.particle.cmp(&self.particle))
        }
    }
    impl PartialOrd for Reached {
        fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
            Some(self.cmp(other))
        }
    }

    let mut nearest = vec![u32::MAX; n];
    let mut distance = vec![f32::INFINITY; n];
    let mut done = vec![false; n];
    let mut heap = BinaryHeap::new();
    for (i, _) in pinned.iter().enumerate().filter(|(_, p)| **p) {
        heap.push(Reached {
            distance: 0.0,
            anchor: i as u32,
            particle: i as u32,
            bend: i as u32,
        });
    }
    while let Some(r) = heap.pop() {
        let p = r.particle as usize;
        if done[p] {
            continue;
        }
        done[p] = true;
        (nearest[p], distance[p]) = (r.anchor, r.distance);
        let bend = r.bend as usize;
        for &q in &neighbours[degree[p] as usize..degree[p + 1] as usize] {
            let q = q as usize;
            if done[q] {
                continue;
            }
            // Straight on from the last bend where the cloth between is flat, else bend at `p`.
            let turn = normal[bend].dot(normal[q]);
            let (d, via) = if turn >= FLAT {
                let chord = rest[bend].distance(rest[q]);
                (distance[bend] + chord * arc_over_chord(turn), bend)
            } else {
                (r.distance + rest[p].distance(rest[q]), p)
            };
            if d <= distance[q] {
                distance[q] = d;
                heap.push(Reached {
                    distance: d,
                    anchor: r.anchor,
                    particle: q as u32,
                    bend: via as u32,
                });
            }
        }
    }
    (nearest, distance)
}

/// The length of a circle's arc over its chord, for an arc whose normals turn by the angle whose
/// cosine is `cos`: `θ/2 / sin(θ/2)`, at least 1.
fn arc_over_chord(cos: f32) -> f32 {
    let half = 0.5 * cos.clamp(-1.0, 1.0).acos();
    if half < 1e-4 { 1.0 } else { half / half.sin() }
}

#[cfg(test)]
mod tests;
