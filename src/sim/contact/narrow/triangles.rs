//! The contacts of triangles with a sphere smaller than the cloth's longest edge.

use glam::Vec3;

use super::particles::{push_out, respond};
use super::{ActiveCollider, ContactState};
use crate::sim::contact::shapes::{ColliderShape, Pose, Shape};

/// Particle–triangle contact with a small sphere: each triangle closer to the centre than radius +
/// margin is pushed away, its three vertices moved in proportion to barycentric weight and inverse
/// mass so that the touching point moves exactly out of contact (Bridson et al. 2002's impulse
/// distribution). The side the sphere must stay on is the one its centre was on at the start of
/// the substep (the direction from the triangle's closest point to the centre then), so neither a
/// fast sphere nor a triangle folding over it lets it pop through. The moved vertices get the same response as
/// particle contacts (friction, inward velocity removed), their work added to `work`. Returns whether
/// any triangle was moved.
pub(super) fn collide_triangles<S: ContactState>(
    c: &mut ActiveCollider,
    (pose0, pose1, h): (&Pose, &Pose, f32),
    triangles: &[u32],
    state: &mut S,
    work: &mut f64,
) -> bool {
    let Shape::Primitive(ColliderShape::Sphere(sphere)) = c.collider.shape else {
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
            *work += push_out(state, i, (x, v), (-dir, vc), c.reacted());
        }
    }
    moved
}

/// The point of triangle `abc` closest to `p`, with its barycentric coordinates (Ericson,
/// "Real-Time Collision Detection", §5.1.5: Voronoi regions of vertices, then edges, then the face).
pub(in crate::sim::contact) fn closest_point_on_triangle(
    p: Vec3,
    a: Vec3,
    b: Vec3,
    c: Vec3,
) -> (Vec3, Vec3) {
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
