//! The suite's own distance functions, independent of the solver's: how deep a point is inside
//! a collider, and whether a particle's path over a substep went through one (tunnelling).

use glam::Vec3;

use crate::sim::ColliderShape;
use crate::sim::contact::convex_minimum;

/// How deep (m) a free particle may end a step inside a collider before the case fails.
pub const CLEARANCE_TOLERANCE: f32 = 1e-3;

/// Whether the straight path `from` → `to` (a particle's motion over one substep, in a shape's
/// own frame) passes through the shape's core, deeper than half its thickness: a particle that
/// stood outside and ends outside went through rather than around. A particle sliding along the
/// surface cuts the surface by its path's sagitta, far less than that; one that started inside
/// (a collider placed across the cloth) is pushed out, not through. Returns the depth the path
/// reached. The signed distance of a convex shape is convex along a line, so a ternary search finds
/// the deepest point of the path.
pub(super) fn tunnelled(shape: &ColliderShape, from: Vec3, to: Vec3) -> Option<f32> {
    let core = match shape {
        ColliderShape::Sphere(s) => 0.5 * s.radius,
        ColliderShape::Capsule(c) => 0.5 * c.radius,
        ColliderShape::Cuboid(b) => 0.5 * b.half_size.min_element(),
        // An infinite floor has no other side to reach.
        ColliderShape::HalfSpace(_) => return None,
    };
    if signed_distance(shape, from) < -CLEARANCE_TOLERANCE {
        return None;
    }
    let deepest = -convex_minimum(|t| signed_distance(shape, from.lerp(to, t)));
    (deepest > core).then_some(deepest)
}

/// Signed distance (m) from a point in a shape's own frame to its surface, negative inside: the
/// suite's own, so that an error in the solver's distance functions cannot hide a penetration.
pub(super) fn signed_distance(shape: &ColliderShape, p: Vec3) -> f32 {
    match shape {
        ColliderShape::Sphere(s) => p.length() - s.radius,
        ColliderShape::Capsule(c) => {
            let y = p.y.clamp(-c.half_length, c.half_length);
            p.distance(Vec3::new(0.0, y, 0.0)) - c.radius
        }
        ColliderShape::Cuboid(b) => {
            let q = p.abs() - b.half_size;
            q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
        }
        ColliderShape::HalfSpace(h) => p.dot(*h.normal),
    }
}
