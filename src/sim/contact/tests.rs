use super::narrow::closest_point_on_triangle;
use super::*;
use crate::sim::simd::Build;
use bevy::math::Dir3;
use bevy::math::primitives::{Capsule3d, Cuboid, InfinitePlane3d, Sphere};
use glam::{Quat, Vec3A};

fn shapes() -> [ColliderShape; 4] {
    [
        ColliderShape::Sphere(Sphere::new(0.5)),
        ColliderShape::Capsule(Capsule3d::new(0.3, 1.0)),
        ColliderShape::Cuboid(Cuboid::new(1.0, 0.4, 0.6)),
        ColliderShape::HalfSpace(InfinitePlane3d::new(Vec3::new(0.0, 1.0, 1.0))),
    ]
}

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

fn active(collider: Collider, dt: f32, max_edge: f32) -> Contacts {
    let mut contacts = Contacts::new(1, max_edge);
    contacts.begin_step(
        &[collider],
        (u32::MAX, true),
        (Vec3::ZERO, Vec3::ZERO),
        10.0,
        dt,
    );
    contacts
}

#[test]
fn a_particle_is_pushed_out_and_loses_only_inward_velocity() {
    let collider = Collider::fixed(
        ColliderShape::Sphere(Sphere::new(1.0)),
        Pose::IDENTITY,
        Friction::NONE,
        0.05,
    );
    let contacts = active(collider, 0.01, 0.1);
    let (mut x, mut v) = ([Vec3::new(0.0, 0.99, 0.0)], [Vec3::new(2.0, -3.0, 0.0)]);
    let mut c = contacts;
    c.begin_substep(&[Vec3::new(-0.02, 1.02, 0.0)]);
    c.resolve(0.0, 1.0, 0.01, &[], &[1.0], (&mut x, &mut v), None);
    assert!((x[0].length() - 1.05).abs() < 1e-6);
    // Frictionless: the tangential velocity survives, the inward normal part is gone.
    let n = x[0].normalize();
    assert!(v[0].dot(n).abs() < 1e-5);
    assert!((v[0] - n * v[0].dot(n)).length() > 1.9);
    // Outward velocity is left alone.
    let (mut x, mut v) = ([Vec3::new(0.0, 1.0, 0.0)], [Vec3::new(0.0, 4.0, 0.0)]);
    c.resolve(0.0, 1.0, 0.01, &[], &[1.0], (&mut x, &mut v), None);
    assert_eq!(v[0], Vec3::new(0.0, 4.0, 0.0));
}

#[test]
fn a_fast_particle_cannot_tunnel_through_a_thin_box() {
    // A 2 cm slab; the particle crosses it entirely within one substep.
    let collider = Collider::fixed(
        ColliderShape::Cuboid(Cuboid::new(2.0, 0.02, 2.0)),
        Pose::IDENTITY,
        Friction::NONE,
        0.01,
    );
    let mut c = active(collider, 0.01, 0.1);
    c.begin_substep(&[Vec3::new(0.1, 0.5, 0.0)]);
    let (mut x, mut v) = ([Vec3::new(0.1, -0.5, 0.0)], [Vec3::new(0.0, -100.0, 0.0)]);
    c.resolve(0.0, 1.0, 0.01, &[], &[1.0], (&mut x, &mut v), None);
    assert!(x[0].y >= 0.01 + 0.01 - 1e-5, "{}", x[0]);
    assert!(v[0].y >= 0.0);
}

#[test]
fn a_particle_ending_inside_a_thin_box_goes_back_to_the_side_it_came_from() {
    // A 6 cm slab; the particle falls 5 cm into it from above in one substep and ends 1 cm from
    // the bottom face, the nearest one: pushing it out there would let it through.
    let collider = Collider::fixed(
        ColliderShape::Cuboid(Cuboid::new(2.0, 0.06, 2.0)),
        Pose::IDENTITY,
        Friction::NONE,
        0.005,
    );
    let mut c = active(collider, 0.01, 0.1);
    c.begin_substep(&[Vec3::new(0.1, 0.031, 0.0)]);
    let (mut x, mut v) = ([Vec3::new(0.1, -0.02, 0.0)], [Vec3::new(0.0, -5.0, 0.0)]);
    c.resolve(0.0, 1.0, 0.01, &[], &[1.0], (&mut x, &mut v), None);
    assert!((x[0].y - 0.035).abs() < 1e-4, "{}", x[0]);
    assert!(v[0].y >= 0.0);
}

#[test]
fn a_particle_in_contact_cannot_pass_through_a_thin_box_or_cut_its_corner() {
    // Resting on the top face of a 6 cm slab (within the margin), it moves in one substep to
    // beyond the bottom face, to beside a side face through the slab's inside, or to just past
    // the slab's middle (where the bottom face is nearest).
    let collider = Collider::fixed(
        ColliderShape::Cuboid(Cuboid::new(0.4, 0.06, 0.4)),
        Pose::IDENTITY,
        Friction::NONE,
        0.005,
    );
    let start = Vec3::new(0.15, 0.034, 0.0);
    let ends = [
        Vec3::new(0.15, -0.04, 0.0),
        Vec3::new(0.21, 0.0, 0.0),
        Vec3::new(0.15, -0.005, 0.0),
    ];
    for end in ends {
        let mut c = active(collider.clone(), 0.01, 0.1);
        c.begin_substep(&[start]);
        let (mut x, mut v) = ([end], [(end - start) / 0.01]);
        c.resolve(0.0, 1.0, 0.01, &[], &[1.0], (&mut x, &mut v), None);
        // Back up to the top face plus the margin, keeping its motion along the face.
        let expected = Vec3::new(end.x, 0.035, end.z);
        assert!((x[0] - expected).length() < 1e-4, "{end}: {}", x[0]);
        assert!(v[0].y >= 0.0, "{end}: {}", v[0]);
    }
    // Sliding along the face and off its edge is not passing through.
    let mut c = active(collider, 0.01, 0.1);
    c.begin_substep(&[start]);
    let end = Vec3::new(0.25, 0.04, 0.0);
    let (mut x, mut v) = ([end], [(end - start) / 0.01]);
    c.resolve(0.0, 1.0, 0.01, &[], &[1.0], (&mut x, &mut v), None);
    assert_eq!(x[0], end);
}

#[test]
fn a_particle_pulled_across_a_capsule_goes_back_to_the_side_it_came_from() {
    // Resting on the side of a capsule (radius 0.3, axis along y, 0.35 from its centre to each
    // cap's), it is pulled in one substep past the axis to end inside nearer the top cap, whose
    // surface faces up, not away from its start: pushing it out there would let it through.
    let collider = Collider::fixed(
        ColliderShape::Capsule(Capsule3d::new(0.3, 0.7)),
        Pose::IDENTITY,
        Friction::NONE,
        0.005,
    );
    let start = Vec3::new(0.0, -0.2, 0.304);
    let end = Vec3::new(0.05, 0.5, 0.05);
    let mut c = active(collider, 0.01, 0.1);
    c.begin_substep(&[start]);
    let (mut x, mut v) = ([end], [(end - start) / 0.01]);
    c.resolve(0.0, 1.0, 0.01, &[], &[1.0], (&mut x, &mut v), None);
    // Out to the side's tangent plane where it started, plus the margin.
    let expected = Vec3::new(0.05, 0.5, 0.305);
    assert!((x[0] - expected).length() < 1e-4, "{}", x[0]);
    assert!(v[0].z >= 0.0, "{}", v[0]);
}

#[test]
fn friction_sticks_below_the_cone_and_slides_above() {
    let plane = ColliderShape::HalfSpace(InfinitePlane3d::new(Dir3::Y));
    for (mu, sticks) in [(0.8, true), (0.3, false)] {
        let collider = Collider::fixed(plane, Pose::IDENTITY, Friction::new(mu), 0.0);
        let mut c = active(collider, 0.01, 0.1);
        // Moved 0.5 mm sideways while sinking 1 mm: the tangent/normal ratio is 0.5.
        c.begin_substep(&[Vec3::new(0.0, 0.0, 0.0)]);
        let (mut x, mut v) = (
            [Vec3::new(0.0005, -0.001, 0.0)],
            [Vec3::new(0.05, -0.1, 0.0)],
        );
        c.resolve(0.0, 1.0, 0.01, &[], &[1.0], (&mut x, &mut v), None);
        assert!(x[0].y.abs() < 1e-7);
        if sticks {
            assert!(x[0].x.abs() < 1e-7 && v[0].x.abs() < 1e-6);
        } else {
            // Kinetic: the tangential velocity loses μ times the normal velocity removed.
            assert!((v[0].x - (0.05 - mu * 0.1)).abs() < 1e-4, "{}", v[0]);
        }
    }
}

#[test]
fn a_moving_collider_drags_the_cloth_within_the_friction_cone() {
    let plane = ColliderShape::HalfSpace(InfinitePlane3d::new(Dir3::Y));
    // The particle sinks 1 mm in a 10 ms substep (normal velocity 0.1 m/s removed), μ = 1.
    for (slide, expected) in [(0.0005, 0.05), (0.01, 0.1)] {
        let collider = Collider {
            end: Pose::from_translation(Vec3::new(slide, 0.0, 0.0)),
            ..Collider::fixed(plane, Pose::IDENTITY, Friction::new(1.0), 0.0)
        };
        let mut c = active(collider, 0.01, 0.1);
        c.begin_substep(&[Vec3::ZERO]);
        let (mut x, mut v) = ([Vec3::new(0.0, -0.001, 0.0)], [Vec3::new(0.0, -0.1, 0.0)]);
        c.resolve(0.0, 1.0, 0.01, &[], &[1.0], (&mut x, &mut v), None);
        // Slow collider: the particle sticks and moves with it. Fast: kinetic friction gives it
        // μ times the normal velocity removed.
        assert!(
            (v[0] - Vec3::new(expected, 0.0, 0.0)).length() < 1e-4,
            "{}",
            v[0]
        );
        assert!(v[0].x <= slide / 0.01 + 1e-6);
    }
}

#[test]
fn a_push_reports_the_work_of_the_surface_that_made_it() {
    let plane = ColliderShape::HalfSpace(InfinitePlane3d::new(Dir3::Y));
    // A floor rising 2 cm in a 10 ms substep meets a particle of 0.5 kg falling at 1 m/s and
    // leaves it at the floor's 2 m/s: impulse 1.5 N s, work 1.5 × 2 = 3 J, of which the particle
    // keeps ½ · 0.5 · (2² − 1²) = 0.75 J (an inelastic impact).
    let collider = Collider {
        end: Pose::from_translation(Vec3::new(0.0, 0.02, 0.0)),
        ..Collider::fixed(plane, Pose::IDENTITY, Friction::NONE, 0.0)
    };
    let mut c = active(collider, 0.01, 0.1);
    c.begin_substep(&[Vec3::new(0.0, 0.02, 0.0)]);
    let (mut x, mut v) = ([Vec3::new(0.0, 0.01, 0.0)], [Vec3::new(0.0, -1.0, 0.0)]);
    let work = c.resolve(0.0, 1.0, 0.01, &[], &[2.0], (&mut x, &mut v), None);
    assert!((v[0].y - 2.0).abs() < 1e-4, "{}", v[0]);
    assert!((work - 3.0).abs() < 1e-3, "{work}");
    // A floor at rest does no work, whatever velocity its response removes.
    let mut c = active(
        Collider::fixed(plane, Pose::IDENTITY, Friction::new(0.5), 0.0),
        0.01,
        0.1,
    );
    c.begin_substep(&[Vec3::new(0.0, 0.02, 0.0)]);
    let (mut x, mut v) = ([Vec3::new(0.0, -0.01, 0.0)], [Vec3::new(1.0, -3.0, 0.0)]);
    let work = c.resolve(0.0, 1.0, 0.01, &[], &[2.0], (&mut x, &mut v), None);
    assert!(v[0].y >= 0.0 && v[0].x < 1.0, "{}", v[0]);
    assert_eq!(work, 0.0);
}

/// [`Vectors`] without the clearance skip: every particle gets the exact test.
struct Exact<'a>(Vectors<'a>);

impl ContactState for Exact<'_> {
    fn len(&self) -> usize {
        self.0.len()
    }
    fn inv_mass(&self, i: usize) -> f32 {
        self.0.inv_mass(i)
    }
    fn slot(&self, p: u32) -> usize {
        self.0.slot(p)
    }
    fn start(&self, i: usize) -> Vec3 {
        self.0.start(i)
    }
    fn position(&self, i: usize) -> Vec3 {
        self.0.position(i)
    }
    fn velocity(&self, i: usize) -> Vec3 {
        self.0.velocity(i)
    }
    fn set(&mut self, i: usize, x: Vec3, v: Vec3) {
        self.0.set(i, x, v);
    }
    fn clearances(&self, _: Near, _: f32, out: &mut [f32]) {
        out.fill(f32::NEG_INFINITY);
    }
}

/// Reproducible draws uniform in `[lo, hi)` (xorshift from `seed`, which must not be 0).
fn uniform_draws(mut seed: u64) -> impl FnMut(f32, f32) -> f32 {
    move |lo, hi| {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        lo + (hi - lo) * (seed >> 40) as f32 / (1u64 << 24) as f32
    }
}

#[test]
fn the_clearance_skip_changes_no_contact() {
    // Particles scattered around each shape, some inside, some grazing it, some far, moving
    // up to 0.6 m in the substep; colliders at rest, translating and rotating.
    let mut uniform = uniform_draws(0x2545_f491_4f6c_dd1d);
    let n = 3000;
    let start: Vec<Vec3> = (0..n)
        .map(|_| Vec3::new(uniform(-1.1, 1.1), uniform(-1.1, 1.1), uniform(-1.1, 1.1)))
        .collect();
    let end: Vec<Vec3> = start
        .iter()
        .map(|s| *s + 0.2 * Vec3::new(uniform(-1.0, 1.0), uniform(-1.0, 1.0), uniform(-1.0, 1.0)))
        .collect();
    let v0: Vec<Vec3> = (0..n)
        .map(|_| Vec3::new(uniform(-3.0, 3.0), uniform(-3.0, 3.0), uniform(-3.0, 3.0)))
        .collect();
    let inv_mass: Vec<f32> = (0..n)
        .map(|i| if i % 50 == 0 { 0.0 } else { 1.0 })
        .collect();
    let pose = Pose {
        rotation: Quat::from_rotation_y(0.4) * Quat::from_rotation_x(0.3),
        translation: Vec3::new(0.1, -0.2, 0.05),
    };
    let motions = [
        pose,
        Pose {
            translation: pose.translation + Vec3::new(1.2, 0.4, -0.8),
            ..pose
        },
        Pose {
            rotation: Quat::from_rotation_z(0.5) * pose.rotation,
            ..pose
        },
    ];
    for shape in shapes() {
        for end_pose in motions {
            let collider = Collider {
                end: end_pose,
                ..Collider::fixed(shape, pose, Friction::new(0.5), 0.02)
            };
            let mut contacts = active(collider, 1.0 / 60.0, 0.1);
            let mut run = |exact: bool| {
                let (mut x, mut v) = (end.clone(), v0.clone());
                let state = Vectors {
                    x: &mut x,
                    v: &mut v,
                    start: &start,
                    inv_mass: &inv_mass,
                    touches: None,
                };
                let (active, clearance) = (&mut contacts.active, &mut contacts.clearance);
                let t = (0.25, 0.5, 1.0 / 240.0);
                if exact {
                    resolve(active, clearance, t, &[], &mut Exact(state));
                } else {
                    resolve(active, clearance, t, &[], &mut { state });
                }
                (x, v)
            };
            let (skipped, exact) = (run(false), run(true));
            assert_eq!(skipped, exact, "{shape:?} moving to {end_pose:?}");
            let moved = (0..n).filter(|&i| exact.0[i] != end[i]).count();
            assert!(
                moved > 50 && moved < n - 50,
                "{shape:?}: {moved} of {n} in contact"
            );
        }
    }
}

#[test]
fn the_broad_phase_skips_far_and_masked_colliders() {
    let near = Collider::fixed(
        ColliderShape::Sphere(Sphere::new(0.5)),
        Pose::from_translation(Vec3::new(0.0, -0.55, 0.0)),
        Friction::NONE,
        0.01,
    );
    let far = Collider {
        start: Pose::from_translation(Vec3::new(50.0, 0.0, 0.0)),
        end: Pose::from_translation(Vec3::new(50.0, 0.0, 0.0)),
        ..near.clone()
    };
    let masked = Collider {
        layers: 2,
        ..near.clone()
    };
    let below = Collider::fixed(
        ColliderShape::HalfSpace(InfinitePlane3d::new(Dir3::Y)),
        Pose::from_translation(Vec3::new(0.0, -10.0, 0.0)),
        Friction::NONE,
        0.01,
    );
    let touching = Collider {
        start: below.start,
        end: Pose::from_translation(Vec3::new(0.0, -0.055, 0.0)),
        ..below.clone()
    };
    let mut c = Contacts::new(2, 0.1);
    let cloth = [Vec3::ZERO, Vec3::new(1.0, 0.0, 1.0)];
    c.begin_step(
        &[near.clone(), far, masked, below, touching.clone()],
        (1, false),
        bounds(&cloth),
        0.05,
        0.01,
    );
    assert_eq!(c.active_count(), 2);
    assert_eq!(c.active[0].collider, near);
    assert_eq!(c.active[1].collider, touching);
}

#[test]
fn the_catch_up_resolves_dropped_colliders_a_particle_outran() {
    // A floor 1 m below a cloth whose reach this step is 5 cm: the broad phase drops it. One
    // particle is flung 1.5 m down anyway (as a stretched spring can do) and one stays put.
    let floor = Collider::fixed(
        ColliderShape::HalfSpace(InfinitePlane3d::new(Dir3::Y)),
        Pose::from_translation(Vec3::new(0.0, -1.0, 0.0)),
        Friction::NONE,
        0.01,
    );
    let far = Collider::fixed(
        ColliderShape::Sphere(Sphere::new(0.5)),
        Pose::from_translation(Vec3::new(50.0, 0.0, 0.0)),
        Friction::NONE,
        0.01,
    );
    let start = [Vec3::ZERO, Vec3::X];
    let mut c = Contacts::new(2, 0.1);
    c.begin_step(
        &[floor.clone(), far.clone()],
        (1, false),
        bounds(&start),
        0.05,
        0.01,
    );
    assert_eq!(c.active_count(), 0);
    assert!(c.dropped());
    let (mut x, mut v) = (
        [Vec3::new(0.0, -1.5, 0.0), Vec3::X],
        [Vec3::new(0.0, -150.0, 0.0), Vec3::ZERO],
    );
    c.catch_up(
        &[floor.clone(), far.clone()],
        1,
        0.01,
        &[],
        &[1.0, 1.0],
        &start,
        (&mut x, &mut v),
    );
    assert!((x[0].y - (-1.0 + 0.01)).abs() < 1e-5, "{}", x[0]);
    assert!(v[0].y >= 0.0, "{}", v[0]);
    assert_eq!((x[1], v[1]), (Vec3::X, Vec3::ZERO));
    // Within its reach nothing is resolved again: a particle that moved 4 cm is left alone, even
    // inside a collider (the substeps own those).
    let (mut x, mut v) = ([Vec3::new(0.0, -0.04, 0.0), Vec3::X], [Vec3::ZERO; 2]);
    let close = Collider {
        start: Pose::from_translation(Vec3::new(0.0, -0.03, 0.0)),
        end: Pose::from_translation(Vec3::new(0.0, -0.03, 0.0)),
        ..floor
    };
    c.begin_step(
        &[close.clone(), far.clone()],
        (1, false),
        bounds(&start),
        0.05,
        0.01,
    );
    c.catch_up(
        &[close, far],
        1,
        0.01,
        &[],
        &[1.0, 1.0],
        &start,
        (&mut x, &mut v),
    );
    assert_eq!(x[0], Vec3::new(0.0, -0.04, 0.0));
}

/// The clearances' signs of 103 particles (a partial last batch) from `near` against 0.05 m, by
/// the kernel's `build` (`AHEAD` as the kernel's), if the CPU has it.
fn clearances_in<const AHEAD: bool>(build: Build, near: Near) -> Option<Vec<u32>> {
    let n = 103;
    let mut x = Soa::new(n);
    let mut d = Soa::new(n);
    for i in 0..n {
        let t = i as f32;
        x.set(i, Vec3::new(t.sin(), 0.1 * t, (0.3 * t).cos()));
        d.set(i, 1e-2 * Vec3::new((1.3 * t).cos(), -0.5, (2.1 * t).sin()));
    }
    let mut out = vec![0.0; n];
    let kernel = Clearances::<AHEAD> {
        x: &x,
        d: &d,
        near,
        within: 0.05,
        out: &mut out,
    };
    simd::run_as(build, kernel).then(|| out.iter().map(|c| c.to_bits()).collect())
}

#[test]
fn the_clearance_kernels_sign_is_the_clearance_test_without_square_roots() {
    // Particles near a point and a plane, some inside, some grazing, some far, moving up to
    // 0.3 m; the sign against `within` must be the test on `distance(end) − |end − start|`
    // wherever that clearance is not within rounding of `within`.
    let mut uniform = uniform_draws(0x9e37_79b9_7f4a_7c15);
    let n = 4000;
    let (mut x, mut d) = (Soa::new(n), Soa::new(n));
    for i in 0..n {
        let at = Vec3::new(uniform(-1.0, 1.0), uniform(-1.0, 1.0), uniform(-1.0, 1.0));
        let moved = Vec3::new(uniform(-1.0, 1.0), uniform(-1.0, 1.0), uniform(-1.0, 1.0));
        // A few particles that do not move at all.
        let moved = if i % 37 == 0 {
            Vec3::ZERO
        } else {
            0.15 * moved
        };
        x.set(i, at);
        d.set(i, moved);
    }
    let nears = [
        Near::Point(Vec3::new(0.1, -0.2, 0.05)),
        Near::Plane(Vec3::new(0.0, 0.1, 0.0), Vec3::new(0.6, 0.8, 0.0)),
    ];
    let mut out = vec![0.0; n];
    let (mut close, mut far) = (0, 0);
    for near in nears {
        for within in [0.0, 0.05, 0.4] {
            for ahead in [false, true] {
                if ahead {
                    soa_clearances::<true>(&x, &d, (near, within), &mut out);
                } else {
                    soa_clearances::<false>(&x, &d, (near, within), &mut out);
                }
                for (i, &sign) in out.iter().enumerate() {
                    let (at, moved) = (x.get(i), d.get(i));
                    let end = if ahead { at + moved } else { at };
                    let clearance = near.distance(end) - moved.length();
                    if (clearance - within).abs() < 1e-5 {
                        continue;
                    }
                    let near_it = clearance <= within;
                    assert_eq!(
                        sign <= 0.0 || sign.is_nan(),
                        near_it,
                        "particle {i}, {near:?}, within {within}: clearance {clearance}"
                    );
                    (close, far) = (close + usize::from(near_it), far + usize::from(!near_it));
                }
            }
        }
    }
    assert!(close > 2000 && far > 2000, "{close} near, {far} not");
}

#[test]
fn every_build_of_the_clearance_kernel_gives_the_same_bits() {
    let nears = [
        Near::Point(Vec3::new(0.2, 3.0, -0.4)),
        Near::Plane(Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.6, 0.8, 0.0)),
    ];
    for near in nears {
        for build in [Build::Avx2, Build::Avx512] {
            let plain = (
                clearances_in::<false>(Build::Plain, near),
                clearances_in::<true>(Build::Plain, near),
            );
            let wide = (
                clearances_in::<false>(build, near),
                clearances_in::<true>(build, near),
            );
            if wide.0.is_some() {
                assert_eq!(wide, plain, "{build:?} against the plain build, {near:?}");
            }
        }
    }
}

/// [`soa_since`] by the kernel's `build` (`AHEAD` as the kernel's), if the CPU has it.
fn since_in<const AHEAD: bool>(
    build: Build,
    x: &Soa,
    d: &Soa,
    at: &Soa,
    guess: Vec3,
) -> Option<Since> {
    let mut out = Since::default();
    let kernel = SinceKernel::<AHEAD> {
        x,
        d,
        at,
        guess,
        out: &mut out,
    };
    simd::run_as(build, kernel).then(|| out.checked())
}

#[test]
fn the_since_kernel_sees_every_particle_in_every_build() {
    // 37 particles (two whole blocks and a partial one), each in turn the one that moved far.
    let n = 37;
    let (mut x, mut d, mut at) = (Soa::new(n), Soa::new(n), Soa::new(n));
    for i in 0..n {
        let t = i as f32;
        at.set(i, Vec3::new(t.sin(), 0.1 * t, (0.3 * t).cos()));
        d.set(i, 1e-3 * Vec3::new((1.3 * t).cos(), -0.5, (2.1 * t).sin()));
    }
    let guess = Vec3::new(0.01, -0.02, 0.005);
    for far in 0..n {
        for i in 0..n {
            let jump = if i == far {
                Vec3::new(0.3, 0.4, 0.0)
            } else {
                Vec3::ZERO
            };
            x.set(i, at.get(i) + guess + jump);
        }
        for build in [Build::Plain, Build::Avx2, Build::Avx512] {
            let Some(s) = since_in::<false>(build, &x, &d, &at, guess) else {
                continue;
            };
            // Every particle but `far` sits at the guess; `far` 0.5 m from it.
            assert!(
                (s.worst - 0.25).abs() < 1e-5,
                "{build:?}, {far}: {}",
                s.worst
            );
            let moved = guess * n as f32 + Vec3::new(0.3, 0.4, 0.0);
            assert!(s.moved.distance(moved) < 1e-5, "{build:?}: {}", s.moved);
            let step: Vec3 = d.iter().sum();
            assert!(s.step.distance(step) < 1e-6, "{build:?}: {}", s.step);
            // Ahead of the end by `d` (the end is `x + d`), the same moves shifted by `d`.
            let ahead = since_in::<true>(build, &x, &d, &at, guess).unwrap();
            assert!(ahead.moved.distance(moved + step) < 1e-5, "{}", ahead.moved);
            let plain = since_in::<false>(Build::Plain, &x, &d, &at, guess);
            assert_eq!(Some(s), plain, "{build:?} against the plain build");
        }
    }
    // A position that is not a number is seen even where a maximum would drop it.
    x.set(20, Vec3::NAN);
    assert_eq!(soa_since::<false>(&x, &d, &at, guess).worst, f32::INFINITY);
}

#[test]
fn the_arrays_displacements_are_those_of_the_particles_paths() {
    // 9 particles at `x` displaced by `d` over the substep, found at `found`: the arrays' loop
    // against the trait's default on the same paths (ending at `x`, or with `AHEAD` at `x + d`).
    let n = 9;
    let (mut x, mut d) = (Soa::new(n), Soa::new(n));
    let found: Vec<Vec3> = (0..n)
        .map(|i| Vec3::new((i as f32).cos(), 0.2 * i as f32, 1.0))
        .collect();
    for (i, at) in found.iter().enumerate() {
        let t = i as f32;
        x.set(i, *at + Vec3::new(0.1 * t, -0.03, 0.01 * t * t));
        d.set(i, Vec3::new(0.002 * t, 0.001, -0.003));
    }
    for ahead in [false, true] {
        let (start, mut end): (Vec<Vec3>, Vec<Vec3>) = (x.iter().zip(d.iter()))
            .map(|(x, d)| if ahead { (x, x + d) } else { (x - d, x) })
            .unzip();
        let (mut v, w) = (vec![Vec3::ZERO; n], vec![1.0; n]);
        let paths = Vectors {
            x: &mut end,
            v: &mut v,
            start: &start,
            inv_mass: &w,
            touches: None,
        };
        let mut expected = vec![Vec3A::NAN; n];
        let sums = paths.displaced(&found, &mut expected);
        let mut moved = vec![Vec3A::NAN; n];
        let m = if ahead {
            soa_displaced::<true>(&x, &d, &found, &mut moved)
        } else {
            soa_displaced::<false>(&x, &d, &found, &mut moved)
        };
        assert_eq!((moved, m), (expected, sums), "ahead: {ahead}");
    }
}

/// A 2 m square sheet in the plane y = 0 (|x|, |z| ≤ 1) as a [`Surface`]: an open shell.
#[derive(Debug)]
struct Sheet;

impl Surface for Sheet {
    fn signed_distance(&self, p: Vec3) -> (f32, Vec3) {
        let on = Vec3::new(p.x.clamp(-1.0, 1.0), 0.0, p.z.clamp(-1.0, 1.0));
        let d = p.distance(on);
        let n = if d > 1e-9 { (p - on) / d } else { Vec3::Y };
        (d, n)
    }
    fn local_bounds(&self) -> (Vec3, Vec3) {
        (Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 0.0, 1.0))
    }
    fn is_convex(&self) -> bool {
        true
    }
    fn is_shell(&self) -> bool {
        true
    }
    fn crosses(&self, a: Vec3, b: Vec3) -> bool {
        if (a.y > 0.0) == (b.y > 0.0) {
            return false;
        }
        let at = a.lerp(b, a.y / (a.y - b.y));
        at.x.abs() <= 1.0 && at.z.abs() <= 1.0
    }
}

#[test]
fn a_particle_cannot_pass_through_a_shell_from_either_side() {
    let sheet = Collider::fixed(
        Shape::Surface(std::sync::Arc::new(Sheet)),
        Pose::IDENTITY,
        Friction::NONE,
        0.01,
    );
    // (start, end, side it must end on): resting on either side within the margin and pushed
    // through past the margin in one substep; arriving from afar; sliding off the edge.
    let cases = [
        (Vec3::new(0.2, 0.005, 0.0), Vec3::new(0.2, -0.03, 0.0), 1.0),
        (
            Vec3::new(0.2, -0.005, 0.0),
            Vec3::new(0.25, 0.03, 0.0),
            -1.0,
        ),
        (Vec3::new(0.2, 0.5, 0.0), Vec3::new(0.2, -0.5, 0.1), 1.0),
    ];
    for (start, end, side) in cases {
        let mut c = active(sheet.clone(), 0.01, 0.1);
        c.begin_substep(&[start]);
        let (mut x, mut v) = ([end], [(end - start) / 0.01]);
        c.resolve(0.0, 1.0, 0.01, &[], &[1.0], (&mut x, &mut v), None);
        assert!(
            x[0].y * side >= 0.01 - 1e-5,
            "{start} → {end}: ended at {}",
            x[0]
        );
        assert!(v[0].y * side >= 0.0, "{start} → {end}: {}", v[0]);
    }
    // Past the edge nothing stops it.
    let (start, end) = (Vec3::new(1.2, 0.005, 0.0), Vec3::new(1.2, -0.03, 0.0));
    let mut c = active(sheet, 0.01, 0.1);
    c.begin_substep(&[start]);
    let (mut x, mut v) = ([end], [(end - start) / 0.01]);
    c.resolve(0.0, 1.0, 0.01, &[], &[1.0], (&mut x, &mut v), None);
    assert_eq!(x[0], end);
}

#[test]
fn a_collider_that_gives_way_gains_its_acceleration_once_per_substep_and_slows_on_contact() {
    // A 1 kg ball falling at 1 m/s under 10 m/s², and one free 10 g particle.
    let ball = Collider {
        start: Pose::from_translation(Vec3::new(0.0, 0.5, 0.0)),
        end: Pose::from_translation(Vec3::new(0.0, 0.5 - 0.01, 0.0)),
        inv_mass: 1.0,
        acceleration: Vec3::new(0.0, -10.0, 0.0),
        ..Collider::fixed(
            ColliderShape::Sphere(Sphere::new(0.1)),
            Pose::IDENTITY,
            Friction::NONE,
            0.01,
        )
    };
    let dt = 0.01;
    let run = |particle: Vec3| {
        let mut c = active(ball.clone(), dt, 0.01);
        let (mut x, mut v) = ([particle], [Vec3::ZERO]);
        for k in 0..4 {
            let (t0, t1) = (k as f32 / 4.0, (k + 1) as f32 / 4.0);
            c.begin_substep(&x);
            // Twice, as a step whose self-contacts moved something does.
            for _ in 0..2 {
                c.resolve(t0, t1, dt / 4.0, &[], &[100.0], (&mut x, &mut v), None);
            }
        }
        (c.active[0].linear, v[0])
    };
    // Out of reach: 1 m/s plus 10 m/s² over the step, whatever the passes.
    let (free, _) = run(Vec3::new(5.0, 0.0, 0.0));
    assert!((free.y - (-1.0 - 10.0 * dt)).abs() < 1e-5, "{free}");
    // A particle just under the ball: the ball gives it momentum and slows by as much.
    let (slowed, pushed) = run(Vec3::new(0.0, 0.385, 0.0));
    assert!(pushed.y < -0.5, "{pushed}");
    let momentum = 1.0 * (slowed.y - free.y) + 0.01 * pushed.y;
    assert!(momentum.abs() < 1e-5, "{slowed} {pushed}: {momentum}");
}

#[test]
fn a_body_or_surface_with_bad_values_is_an_invalid_collider() {
    let ball = Collider::fixed(
        ColliderShape::Sphere(Sphere::new(0.1)),
        Pose::IDENTITY,
        Friction::NONE,
        0.01,
    );
    assert!(ball.validate().is_ok());
    let bad = [
        Collider {
            inv_mass: -1.0,
            ..ball.clone()
        },
        Collider {
            inv_mass: f32::NAN,
            ..ball.clone()
        },
        Collider {
            inv_inertia: glam::Mat3::from_diagonal(Vec3::new(1.0, f32::INFINITY, 1.0)),
            ..ball.clone()
        },
        Collider {
            acceleration: Vec3::new(0.0, f32::NAN, 0.0),
            ..ball.clone()
        },
    ];
    for c in bad {
        assert!(c.validate().is_err(), "{c:?}");
    }
    /// A surface whose bounds are not a box.
    #[derive(Debug)]
    struct Unbounded;
    impl Surface for Unbounded {
        fn signed_distance(&self, p: Vec3) -> (f32, Vec3) {
            (p.y, Vec3::Y)
        }
        fn local_bounds(&self) -> (Vec3, Vec3) {
            (Vec3::splat(f32::NEG_INFINITY), Vec3::splat(f32::INFINITY))
        }
        fn is_convex(&self) -> bool {
            true
        }
        fn is_shell(&self) -> bool {
            false
        }
        fn crosses(&self, _: Vec3, _: Vec3) -> bool {
            false
        }
    }
    let unbounded = Collider {
        shape: Shape::Surface(std::sync::Arc::new(Unbounded)),
        ..ball.clone()
    };
    assert!(unbounded.validate().is_err());
    let sheet = Collider {
        shape: Shape::Surface(std::sync::Arc::new(Sheet)),
        ..ball
    };
    assert!(sheet.validate().is_ok());
}

#[test]
fn a_particle_the_layers_push_into_a_collider_is_pushed_out_again() {
    // A vertex resting on a floor at its margin, and a triangle falling onto it from above: the
    // layers' push moves the vertex down into the floor, which must push it out again.
    let floor = Collider::fixed(
        ColliderShape::HalfSpace(InfinitePlane3d::new(Vec3::Y)),
        Pose::IDENTITY,
        Friction::NONE,
        0.01,
    );
    let start = vec![
        Vec3::new(0.0, 0.03, 0.0),
        Vec3::new(1.0, 0.03, 0.0),
        Vec3::new(0.0, 0.03, 1.0),
        Vec3::new(0.25, 0.01, 0.25),
        Vec3::new(2.0, 0.01, 2.0),
        Vec3::new(3.0, 0.01, 2.0),
    ];
    let tris = [0, 1, 2, 3, 4, 5];
    let mut x = start.clone();
    for p in &mut x[..3] {
        p.y = 0.012;
    }
    let mut v = vec![Vec3::ZERO; 6];
    for v in &mut v[..3] {
        v.y = -2.0;
    }
    let w = [1.0; 6];
    let mut c = Contacts::new(6, 1.0);
    c.set_self_contacts(Some(SelfContacts::new(&tris, &start, 0.005, 0.0)));
    c.begin_step(&[floor], (u32::MAX, true), bounds(&start), 10.0, 0.01);
    c.begin_self_step(0.02);
    c.begin_substep(&start);
    c.resolve(0.0, 1.0, 0.01, &tris, &w, (&mut x, &mut v), None);
    // The layers acted (the triangle went up), and the vertex they pushed down is out of the
    // floor again (the colliders have the last word).
    assert!(x[..3].iter().all(|p| p.y > 0.012), "{:?}", &x[..3]);
    assert!(x[3].y >= 0.01 - 1e-6, "{}", x[3]);
}
