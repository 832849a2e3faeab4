//! The shapes' signed distances, bounds and closest points.

use super::*;

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
                shape.signed_distance(p + Vec3::X * e).0 - shape.signed_distance(p - Vec3::X * e).0,
                shape.signed_distance(p + Vec3::Y * e).0 - shape.signed_distance(p - Vec3::Y * e).0,
                shape.signed_distance(p + Vec3::Z * e).0 - shape.signed_distance(p - Vec3::Z * e).0,
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
fn bounds_of_points_are_their_extremes_in_each_coordinate() {
    for n in [0, 1, 7, 8, 9, 23, 100] {
        let points: Vec<Vec3> = (0..n)
            .map(|i| {
                let f = i as f32;
                Vec3::new((f * 0.37).sin(), (f * 0.91).cos() * 2.0, f * 0.13 - 3.0)
            })
            .collect();
        let (lo, hi) = bounds(&points);
        if n == 0 {
            assert!(lo.cmpgt(hi).all(), "empty: {lo} > {hi}");
            continue;
        }
        for c in 0..3 {
            let values = points.iter().map(|p| p[c]);
            let (min, max) = values.fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            });
            assert_eq!((lo[c], hi[c]), (min, max), "{n} points, coordinate {c}");
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
            let dir = Vec3::new((f * 0.37).sin(), (f * 0.91).cos(), (f * 0.13).sin()).normalize();
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
