//! The response to one vertex–triangle or edge–edge pair (the push apart on the side the pair
//! started on, the approaching velocity removed, Coulomb friction), and the Gauss-Seidel passes
//! that repeat it until the pairs settle.

use glam::Vec3;

use super::geometry::closest_on_segments;
use super::map_four;
use crate::sim::contact::narrow::ContactState;

/// Gauss-Seidel passes over the candidate pairs per substep (stopping early once no pair is
/// pushed by more than [`CONVERGED_PUSH`] of its kept distance).
pub(in crate::sim::contact) const MAX_PASSES: u32 = 4;

/// A later pass that pushes no pair out by more than this fraction of its kept distance is the
/// last: what is left is far below anything a crossing could come from.
pub(in crate::sim::contact) const CONVERGED_PUSH: f32 = 1e-3;

/// The passes after a substep's first, over the candidates `acting` that acted in it, until
/// `pair(k)` (resolving candidate `k`: how far it pushed the pair out, as a fraction of its kept
/// distance) pushes none by more than [`CONVERGED_PUSH`], at most [`MAX_PASSES`] in all.
pub(in crate::sim::contact) fn later_passes(acting: &[u32], mut pair: impl FnMut(usize) -> f32) {
    for _ in 1..MAX_PASSES {
        let mut moved = false;
        for &k in acting {
            moved |= pair(k as usize) > CONVERGED_PUSH;
        }
        if !moved {
            break;
        }
    }
}

/// The share of the thickness that two edges are kept apart. Resting layers are held the
/// thickness apart by their vertex–triangle pairs, which puts the edges of one layer that
/// thickness from the other's too: kept a little less apart, those edge pairs do not act and
/// are mostly not tested, while edges that come closer (where no vertex is over a triangle) are
/// still kept from passing through each other.
pub(in crate::sim::contact) const EDGES_APART_SHARE: f32 = 0.9;

/// A vertex counts as over a triangle's interior when none of its barycentric coordinates is
/// below this (a vertex just past an edge is caught by the edge–edge pairs of that edge).
const INTERIOR_TOLERANCE: f32 = -1e-3;

/// How far apart a pair of layers is kept and the friction between them: the response to one
/// vertex–triangle or edge–edge pair, shared by a cloth's contacts with itself and with other
/// cloths.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(in crate::sim::contact) struct LayerSpacing {
    /// Distance kept between the layers, m.
    pub thickness: f32,
    /// Coulomb friction between them.
    pub friction: f32,
}

impl LayerSpacing {
    /// How far apart a pair is kept, m: a vertex from a triangle (`vertex`) the thickness, two
    /// edges [`EDGES_APART_SHARE`] of it.
    #[inline(always)]
    pub(in crate::sim::contact) fn kept(&self, vertex: bool) -> f32 {
        if vertex {
            self.thickness
        } else {
            EDGES_APART_SHARE * self.thickness
        }
    }

    /// Whether edge–edge pair `s` is clear on a quick test (most tested pairs are): edges on
    /// lines at least their kept distance ([`Self::kept`]) apart (not nearly parallel, where that
    /// distance is lost to rounding), or with boxes that far apart, are at least that apart; if
    /// their ends also moved less than half of it in the substep, the gap between their closest
    /// points differs from its start by less than its length, so it did not turn, and
    /// [`Self::edge_edge`] leaves them alone. Decided without the closest points.
    #[inline(always)]
    fn edge_edge_clear<S: ContactState>(&self, state: &S, s: [usize; 4]) -> bool {
        let [a, b, c, d] = map_four(s, |i| state.position(i));
        let [a0, b0, c0, d0] = map_four(s, |i| state.start(i));
        let kept = self.kept(false);
        let kept2 = kept * kept;
        let (ab, cd) = (b - a, d - c);
        let across = ab.cross(cd);
        let apart = (a - c).dot(across);
        let [ma, mb, mc, md] = map_four([a - a0, b - b0, c - c0, d - d0], Vec3::length_squared);
        let moved = ma.max(mb).max(mc).max(md);
        let across2 = across.length_squared();
        let lines_apart = across2 > 1e-4 * ab.length_squared() * cd.length_squared()
            && apart * apart >= kept2 * across2;
        // The distance between the edges' boxes is a lower bound too.
        let boxes = (c.min(d) - a.max(b))
            .max(a.min(b) - c.max(d))
            .max(Vec3::ZERO);
        (lines_apart || boxes.length_squared() >= kept2) && 4.0 * moved < kept2
    }

    /// Keeps vertex `s[0]` at least the thickness from triangle `s[1..]` on the side it started
    /// the substep on, when it is over the triangle's interior. Returns how far it pushed the
    /// pair out, as a fraction of the thickness (0: nothing moved).
    pub(in crate::sim::contact) fn vertex_triangle<S: ContactState>(
        &self,
        state: &mut S,
        s: [usize; 4],
        inv_h: f32,
        drift: &mut [f32],
    ) -> f32 {
        let over = VertexOverTriangle::of(state, s);
        if over.clear(self.thickness) {
            return 0.0;
        }
        let w = map_four(s, |i| state.inv_mass(i));
        if w == [0.0; 4] || !(over.area2 > 0.0 && over.area2.is_finite()) {
            return 0.0;
        }
        // Not clear, so over the interior: the coordinates are all at least `INTERIOR_TOLERANCE`.
        let inv_length = over.area2.sqrt().recip();
        let (n, dist) = (over.area * inv_length, over.above * inv_length);
        let [u, v, t] = over.scaled;
        let [u, v, t] = [u / over.area2, v / over.area2, t / over.area2];
        // The side it started on: that of the start's plane, through the start triangle (a
        // degenerate one has none; then the side it ends on).
        let side = if over.area0_2 > 0.0 {
            if over.above0 >= 0.0 { 1.0 } else { -1.0 }
        } else {
            dist.signum()
        };
        let weights = [1.0, -u, -v, -t];
        let apart = (side * n, side * dist, self.kept(true));
        self.separate(state, s, (w, weights), apart, inv_h, drift)
    }

    /// Keeps edge `s[0..2]` at least [`EDGES_APART_SHARE`] of the thickness from edge `s[2..]` on the
    /// side it started the substep on. Returns how far it pushed the pair out, as a fraction of
    /// that distance (0: nothing moved).
    pub(in crate::sim::contact) fn edge_edge<S: ContactState>(
        &self,
        state: &mut S,
        s: [usize; 4],
        inv_h: f32,
        drift: &mut [f32],
    ) -> f32 {
        if self.edge_edge_clear(state, s) {
            return 0.0;
        }
        let w = map_four(s, |i| state.inv_mass(i));
        if w == [0.0; 4] {
            return 0.0;
        }
        let [a, b, c, d] = map_four(s, |i| state.position(i));
        let [a0, b0, c0, d0] = map_four(s, |i| state.start(i));
        let kept = self.kept(false);
        let (u, t) = closest_on_segments(a, b, c, d);
        let gap = a.lerp(b, u) - c.lerp(d, t);
        let gap0 = a0.lerp(b0, u) - c0.lerp(d0, t);
        // Otherwise clear pairs are decided without the square root.
        if gap.length_squared() >= kept * kept && gap.dot(gap0) >= 0.0 {
            return 0.0;
        }
        let length = gap.length();
        // The direction apart: the gap's, turned to the starting side; the start's if the gap
        // has closed to nothing.
        let (n, dist) = if length > 1e-9 {
            let side = if gap.dot(gap0) >= 0.0 { 1.0 } else { -1.0 };
            (gap * (side / length), side * length)
        } else {
            match gap0.try_normalize() {
                Some(n0) => (n0, gap.dot(n0)),
                None => return 0.0,
            }
        };
        let weights = [1.0 - u, u, t - 1.0, -t];
        let apart = (n, dist, kept);
        self.separate(state, s, (w, weights), apart, inv_h, drift)
    }

    /// The response to one pair: the combination `Σ weights[k] x[s[k]]` is `dist` along `n`;
    /// pushes it out to `kept`, then removes its approaching velocity along `n` and applies
    /// friction to its tangential velocity. `w` are the particles' inverse masses. Returns the
    /// push as a fraction of `kept` (0: nothing moved).
    fn separate<S: ContactState>(
        &self,
        state: &mut S,
        s: [usize; 4],
        (w, weights): ([f32; 4], [f32; 4]),
        (n, dist, kept): (Vec3, f32, f32),
        inv_h: f32,
        drift: &mut [f32],
    ) -> f32 {
        let depth = kept - dist;
        if depth.is_nan() || depth <= 0.0 {
            return 0.0;
        }
        let effective: f32 = (0..4).map(|k| weights[k] * weights[k] * w[k]).sum();
        if effective.is_nan() || effective <= 1e-12 {
            return 0.0;
        }
        let push = depth / effective;
        let v = map_four(s, |i| state.velocity(i));
        let relative: Vec3 = (0..4).map(|k| weights[k] * v[k]).sum();
        let normal = relative.dot(n);
        // The normal change in velocity units: the approach removed plus the push-out per substep.
        let removed = (-normal).max(0.0);
        let normal_change = removed + depth * inv_h;
        let tangential = relative - normal * n;
        let slide = tangential.length();
        let stop = if slide > 0.0 {
            (self.friction * normal_change).min(slide) / slide
        } else {
            0.0
        };
        // Velocity change of the pair's combination, spread like the push.
        let dv = removed * n - stop * tangential;
        let x = map_four(s, |i| state.position(i));
        for k in 0..4 {
            let g = weights[k] * w[k];
            if g == 0.0 {
                continue;
            }
            let scale = g / effective;
            state.set(s[k], x[k] + (push * g) * n, v[k] + scale * dv);
            drift[s[k]] += (push * g).abs();
        }
        depth / kept
    }
}

/// A vertex over a triangle (a vertex–triangle pair) at the end and the start of a substep,
/// nothing normalised: the triangle's area vector (its normal times twice its area), the
/// vertex's height over its plane times that area, and its barycentric coordinates in the plane
/// times the squared area.
struct VertexOverTriangle {
    area: Vec3,
    area2: f32,
    above: f32,
    scaled: [f32; 3],
    /// The same at the start (the area vector's squared length, the height).
    area0_2: f32,
    above0: f32,
}

impl VertexOverTriangle {
    /// Pair `s` (the vertex, then the triangle's corners) of `state`.
    #[inline(always)]
    fn of<S: ContactState>(state: &S, s: [usize; 4]) -> Self {
        let [p, a, b, c] = map_four(s, |i| state.position(i));
        let [p0, a0, b0, c0] = map_four(s, |i| state.start(i));
        let area = (b - a).cross(c - a);
        let area0 = (b0 - a0).cross(c0 - a0);
        Self {
            area,
            area2: area.length_squared(),
            above: (p - a).dot(area),
            scaled: [
                (c - b).cross(p - b).dot(area),
                (a - c).cross(p - c).dot(area),
                (b - a).cross(p - a).dot(area),
            ],
            area0_2: area0.length_squared(),
            above0: (p0 - a0).dot(area0),
        }
    }

    /// Whether the vertex is clear of the triangle at `thickness`: not over its interior, or at
    /// least the thickness from its plane on the side it started the substep on (the side of
    /// the start's plane, on which every point of the start triangle lies).
    #[inline(always)]
    fn clear(&self, thickness: f32) -> bool {
        let outside = INTERIOR_TOLERANCE * self.area2;
        let [u, v, t] = self.scaled;
        (self.above * self.above0 > 0.0
            && self.above * self.above >= thickness * thickness * self.area2)
            || u < outside
            || v < outside
            || t < outside
    }
}
