//! The narrow phase and response against colliders: push-outs, sweeps, friction, shells.

use super::*;

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
