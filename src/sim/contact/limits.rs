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
        self.touched = true;
        self.targets.clear();
        self.targets.extend(targets.into_iter().map(|t| Moving {
            particle: t.particle,
            weight: t.weight,
            from: t.position,
            to: t.position,
            normal_from: t.normal,
            normal_to: t.normal,
        }));
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
    }

    /// Takes `other`'s targets and gives each copy a tear made (`(particle, copy)`, in order) the
    /// targets of its particle, after them.
    pub fn inherit_targets(&mut self, other: &Limits, copies: &[(u32, u32)]) {
        self.touched = true;
        self.targets.clone_from(&other.targets);
        for &(particle, copy) in copies {
            for t in other.targets.iter().filter(|t| t.particle == particle) {
                self.targets.push(Moving {
                    particle: copy,
                    ..*t
                });
            }
        }
    }

    /// Takes the targets of `other`'s particles that `index` maps to a particle here (those
    /// mapped to `u32::MAX` are left out), with their motion.
    pub fn restrict_targets(&mut self, other: &Limits, index: &[u32]) {
        self.touched |= other.touched;
        self.targets.clear();
        self.targets.extend(other.targets.iter().filter_map(|t| {
            let particle = *index.get(t.particle as usize)?;
            (particle != u32::MAX).then_some(Moving { particle, ..*t })
        }));
    }

    /// The particles with a target and the target's weight, in order.
    pub fn targeted(&self) -> impl Iterator<Item = (u32, f32)> + '_ {
        self.targets.iter().map(|t| (t.particle, t.weight))
    }

    /// Keeps the targets of the particles `keep` holds to, drops the others.
    pub fn retain_targets(&mut self, keep: impl Fn(u32) -> bool) {
        self.touched = true;
        self.targets.retain(|t| keep(t.particle));
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
        let s = self.settings;
        for t in &self.targets {
            let i = state.slot(t.particle);
            if state.inv_mass(i) == 0.0 {
                continue;
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
mod tests {
    use super::*;
    use crate::sim::model::{ClothModel, GridPlane, GridSpec};

    #[test]
    fn geodesic_distances_run_straight_across_a_flat_cloth_to_the_nearest_pin() {
        // A 5×4 grid of 0.1 m spacing pinned at its two top corners: each particle is tied to
        // the corner on its side, at the straight line's length (a path along the edges would
        // be up to 8% longer).
        let spec = GridSpec::new(5, 4, 0.1).with_plane(GridPlane::Vertical);
        let model = ClothModel::grid(&spec).unwrap();
        let rest = &model.rest_positions;
        let n = model.particle_count();
        let top = rest.iter().map(|q| q.y).fold(f32::MIN, f32::max);
        let corners: Vec<usize> = (0..n)
            .filter(|&i| rest[i].y == top && (i % 5 == 0 || i % 5 == 4))
            .collect();
        assert_eq!(corners.len(), 2);
        let mut pinned = vec![false; n];
        for &c in &corners {
            pinned[c] = true;
        }
        let (nearest, distance) = geodesic_to_nearest(&model.triangles, rest, &pinned);
        for i in 0..n {
            let a = nearest[i] as usize;
            assert!(corners.contains(&a), "particle {i} tied to {a}");
            if i % 5 != 2 {
                assert_eq!(
                    a.is_multiple_of(5),
                    i % 5 < 2,
                    "particle {i} tied to the far corner {a}"
                );
            }
            let straight = rest[i].distance(rest[a]);
            assert!(
                (distance[i] - straight).abs() <= 1e-6 * straight.max(1.0),
                "particle {i}: {} against the straight line {straight}",
                distance[i]
            );
        }
        // Nothing pinned: no anchor anywhere.
        let (nearest, _) = geodesic_to_nearest(&model.triangles, rest, &vec![false; n]);
        assert!(nearest.iter().all(|&a| a == u32::MAX));
    }

    #[test]
    fn geodesic_distances_follow_a_curved_cloth() {
        // A 24×6 grid of 0.1 m spacing rolled into half a cylinder around its columns, pinned at
        // one corner: unrolled, the cloth is flat, so each particle's geodesic is the straight
        // line of the flat grid. Straight lines through the air (the chord) would be up to a
        // third shorter across the roll, paths along the edges up to 8% longer.
        let (nx, ny, h) = (24, 6, 0.1);
        let spec = GridSpec::new(nx, ny, h).with_plane(GridPlane::Vertical);
        let model = ClothModel::grid(&spec).unwrap();
        let radius = (nx - 1) as f32 * h / std::f32::consts::PI;
        let flat = |p: u32| Vec3::new((p % nx) as f32 * h, (p / nx) as f32 * h, 0.0);
        let rest: Vec<Vec3> = (0..nx * ny)
            .map(|p| {
                let f = flat(p);
                let angle = f.x / radius;
                Vec3::new(radius * angle.sin(), f.y, radius * (1.0 - angle.cos()))
            })
            .collect();
        let mut pinned = vec![false; rest.len()];
        pinned[0] = true;
        let (nearest, distance) = geodesic_to_nearest(&model.triangles, &rest, &pinned);
        let mut shortest_chord: f32 = 1.0;
        for p in 1..nx * ny {
            let i = p as usize;
            assert_eq!(nearest[i], 0);
            let geodesic = flat(p).distance(flat(0));
            // The roll turns the normals by 7.8° a column, so the straight stretches bend at
            // particles, a little off the geodesic.
            assert!(
                (0.99 * geodesic..=1.04 * geodesic).contains(&distance[i]),
                "particle {p}: {} against the geodesic {geodesic}",
                distance[i]
            );
            assert!(distance[i] >= rest[i].distance(rest[0]) * (1.0 - 1e-6));
            shortest_chord = shortest_chord.min(rest[i].distance(rest[0]) / geodesic);
        }
        assert!(
            shortest_chord < 0.7,
            "the roll's chords are {shortest_chord} of its arcs"
        );
    }
}
