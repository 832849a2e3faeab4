//! The geometry of the pairs: the distance from a point to a triangle, the closest points of
//! two segments, and a mesh's unique edges with the keys that pair two indices.

use glam::Vec3;

/// The unique edges of triangles `tris` (lower particle first, sorted) into `edges`, and for each
/// triangle the edge from each of its corners to the next (an index into `edges`; `u32::MAX` where
/// an earlier triangle that shares it owns it) into `tri_edges`; `keyed` is left holding each
/// triangle side's edge key and place (`3 × triangle + corner`), sorted by key.
pub(in crate::sim::contact) fn edge_table(
    tris: &[[u32; 3]],
    keyed: &mut Vec<(u64, usize)>,
    edges: &mut Vec<[u32; 2]>,
    tri_edges: &mut Vec<[u32; 3]>,
) {
    keyed.clear();
    for (t, tri) in tris.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            keyed.push((pair_key(a.min(b), a.max(b)), 3 * t + k));
        }
    }
    keyed.sort_unstable();
    edges.clear();
    tri_edges.clear();
    tri_edges.resize(tris.len(), [u32::MAX; 3]);
    for (i, &(key, at)) in keyed.iter().enumerate() {
        if i == 0 || keyed[i - 1].0 != key {
            edges.push([(key >> 32) as u32, key as u32]);
            tri_edges[at / 3][at % 3] = (edges.len() - 1) as u32;
        }
    }
}

/// The key of pair `(a, b)` in the exemption lists.
pub(in crate::sim::contact) fn pair_key(a: u32, b: u32) -> u64 {
    (a as u64) << 32 | b as u64
}

/// The unit normal of triangle `abc` (`None` for a degenerate one).
fn unit_normal(a: Vec3, b: Vec3, c: Vec3) -> Option<Vec3> {
    (b - a).cross(c - a).try_normalize()
}

/// Barycentric coordinates of `q` (in the plane of `abc`) with respect to `a`, `b`, `c`.
fn barycentric(q: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Option<[f32; 3]> {
    let (e1, e2, r) = (b - a, c - a, q - a);
    let (d00, d01, d11) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (d20, d21) = (r.dot(e1), r.dot(e2));
    let denom = d00 * d11 - d01 * d01;
    if denom.is_nan() || denom <= 0.0 {
        return None;
    }
    let v = (d11 * d20 - d01 * d21) / denom;
    let w = (d00 * d21 - d01 * d20) / denom;
    Some([1.0 - v - w, v, w])
}

/// Distance from `p` to triangle `abc` (to its nearest edge or vertex when `p` is not over it).
pub(in crate::sim::contact) fn point_triangle_distance(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> f32 {
    if let Some(n) = unit_normal(a, b, c) {
        let dist = (p - a).dot(n);
        if let Some([u, v, w]) = barycentric(p - dist * n, a, b, c)
            && u >= 0.0
            && v >= 0.0
            && w >= 0.0
        {
            return dist.abs();
        }
    }
    [(a, b), (b, c), (c, a)]
        .into_iter()
        .map(|(e0, e1)| {
            let d = e1 - e0;
            let t = if d.length_squared() > 0.0 {
                ((p - e0).dot(d) / d.length_squared()).clamp(0.0, 1.0)
            } else {
                0.0
            };
            p.distance(e0 + t * d)
        })
        .fold(f32::INFINITY, f32::min)
}

/// The parameters `(s, t)` of the closest points `a + s (b − a)` and `c + t (d − c)` of segments
/// `ab` and `cd`, both in `0..=1`.
pub(in crate::sim::contact) fn closest_on_segments(
    a: Vec3,
    b: Vec3,
    c: Vec3,
    d: Vec3,
) -> (f32, f32) {
    let (d1, d2, r) = (b - a, d - c, a - c);
    let (aa, ee, f) = (d1.dot(d1), d2.dot(d2), d2.dot(r));
    const TINY: f32 = 1e-20;
    if aa <= TINY && ee <= TINY {
        return (0.0, 0.0);
    }
    if aa <= TINY {
        return (0.0, (f / ee).clamp(0.0, 1.0));
    }
    let cc = d1.dot(r);
    if ee <= TINY {
        return ((-cc / aa).clamp(0.0, 1.0), 0.0);
    }
    let bb = d1.dot(d2);
    let denom = aa * ee - bb * bb;
    // The reciprocals are independent of each other, so their divisions overlap rather than
    // queue behind `s`.
    let (inv_aa, inv_ee) = (1.0 / aa, 1.0 / ee);
    let mut s = if denom > TINY * aa * ee {
        ((bb * f - cc * ee) / denom).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let mut t = (bb * s + f) * inv_ee;
    if t < 0.0 {
        t = 0.0;
        s = (-cc * inv_aa).clamp(0.0, 1.0);
    } else if t > 1.0 {
        t = 1.0;
        s = ((bb - cc) * inv_aa).clamp(0.0, 1.0);
    }
    (s, t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closest_points_of_crossing_and_parallel_segments() {
        let (s, t) = closest_on_segments(
            Vec3::new(-1.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.5, -1.0, 0.2),
            Vec3::new(0.5, 1.0, 0.2),
        );
        assert!((s - 0.75).abs() < 1e-6 && (t - 0.5).abs() < 1e-6, "{s} {t}");
        let (s, t) = closest_on_segments(
            Vec3::ZERO,
            Vec3::X,
            Vec3::new(2.0, 0.1, 0.0),
            Vec3::new(3.0, 0.1, 0.0),
        );
        assert_eq!((s, t), (1.0, 0.0));
    }

    #[test]
    fn point_triangle_distance_over_the_face_and_past_an_edge() {
        let (a, b, c) = (Vec3::ZERO, Vec3::X, Vec3::Y);
        assert!((point_triangle_distance(Vec3::new(0.2, 0.2, -0.3), a, b, c) - 0.3).abs() < 1e-6);
        let d = point_triangle_distance(Vec3::new(2.0, 0.0, 0.0), a, b, c);
        assert!((d - 1.0).abs() < 1e-6);
    }
}
