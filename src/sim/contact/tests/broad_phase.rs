//! The broad phase, the catch-up of dropped colliders, and colliders after the layers.

use super::*;

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
    let mut c = Contacts::new(2, (0.1, 0.0));
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
    let mut c = Contacts::new(2, (0.1, 0.0));
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
    let mut c = Contacts::new(6, (1.0, 0.0));
    c.set_self_contacts(Some(SelfContacts::new(&tris, &start, 0.005, 0.0).unwrap()));
    c.begin_step(&[floor], (u32::MAX, true), bounds(&start), 10.0, 0.01);
    c.begin_self_step(0.02);
    c.begin_substep(&start);
    c.resolve(0.0, 1.0, 0.01, &tris, &w, (&mut x, &mut v), None);
    // The layers acted (the triangle went up), and the vertex they pushed down is out of the
    // floor again (the colliders have the last word).
    assert!(x[..3].iter().all(|p| p.y > 0.012), "{:?}", &x[..3]);
    assert!(x[3].y >= 0.01 - 1e-6, "{}", x[3]);
}
