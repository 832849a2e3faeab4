//! Inertia: how much of its reference frame's motion a cloth feels.

use super::*;

/// The settings of [`ride`]: gravity tilted out of the curtain's plane and strong damping, so
/// that the curtain settles into one shape. (Hanging in its plane, a curtain that sags buckles
/// out of it either way and rounding alone decides which; lightly damped, it swings so that
/// rounding differences grow by orders of magnitude within the run. Either would hide what is
/// measured here; CHANGELOG.md, 2026-11-24, has the figures.) Implicit Euler gets enough
/// conjugate-gradient iterations to converge, so that its first guess, not the frame, does not
/// decide the result.
fn ride_settings(integrator: Integrator, inertia: Inertia) -> SolverSettings {
    SolverSettings {
        integrator,
        inertia,
        gravity: GRAVITY_TILTED,
        damping: 5.0,
        iterations: if integrator == Integrator::ImplicitEuler {
            50
        } else {
            1
        },
        sleep_speed: 0.0,
        ..SolverSettings::default()
    }
}

/// A curtain pinned along its top row to a frame that moves by `motion(t)` (its pose at time
/// t), felt with `inertia`: the particle positions in the frame's coordinates after each step.
fn ride(
    integrator: Integrator,
    inertia: Inertia,
    motion: impl Fn(f32) -> Pose,
    steps: u32,
) -> Vec<Vec<Vec3>> {
    ride_among(integrator, inertia, motion, steps, &[])
}

/// [`ride`] among still `colliders`.
fn ride_among(
    integrator: Integrator,
    inertia: Inertia,
    motion: impl Fn(f32) -> Pose,
    steps: u32,
    colliders: &[Collider],
) -> Vec<Vec<Vec3>> {
    let env = Environment {
        colliders,
        ..Default::default()
    };
    let settings = ride_settings(integrator, inertia);
    let (spec, mut sim) = curtain(10, 10, 0.04, settings);
    let rest = sim.positions().to_vec();
    let pins: Vec<u32> = (0..spec.nx).map(|i| spec.index(i, 0)).collect();
    sim.set_pins(pins.iter().map(|&p| (p, rest[p as usize])))
        .unwrap();
    sim.move_frame(motion(0.0));
    let mut out = Vec::new();
    for step in 1..=steps {
        let pose = motion(step as f32 * DT);
        sim.move_frame(pose);
        sim.move_pins(
            pins.iter()
                .map(|&p| pose.rotation * rest[p as usize] + pose.translation),
        );
        sim.step_in(DT, &env).unwrap();
        let inverse = pose.rotation.inverse();
        out.push(
            sim.positions()
                .iter()
                .map(|x| inverse * (*x - pose.translation))
                .collect(),
        );
    }
    out
}

/// The largest distance between corresponding particles of two runs, over every step.
fn largest_gap(a: &[Vec<Vec3>], b: &[Vec<Vec3>]) -> f32 {
    a.iter()
        .zip(b)
        .flat_map(|(a, b)| a.iter().zip(b).map(|(p, q)| p.distance(*q)))
        .fold(0.0, f32::max)
}

#[test]
fn with_no_linear_inertia_a_frame_moving_at_constant_speed_changes_nothing() {
    let still = |_: f32| Pose::IDENTITY;
    let moving = |t: f32| Pose::from_translation(Vec3::new(5.0 * t, 0.0, 0.0));
    let no_linear = Inertia {
        linear: 0.0,
        angular: 1.0,
    };
    for integrator in [
        Integrator::Auto,
        Integrator::Xpbd,
        Integrator::Verlet,
        Integrator::ImplicitEuler,
    ] {
        let reference = ride(integrator, no_linear, still, 120);
        let carried = ride(integrator, no_linear, moving, 120);
        let gap = largest_gap(&reference, &carried);
        let felt = largest_gap(
            &reference,
            &ride(integrator, Inertia::default(), moving, 120),
        );
        println!(
            "{}: inertia 0 {gap:e} m, inertia 1 {felt:e} m",
            integrator.name()
        );
        assert!(
            gap <= 1e-3,
            "{}: {gap} m from the still frame's run",
            integrator.name()
        );
        // The check can fail: felt in full, the same motion drags the cloth behind its pins
        // (damping acts on its world velocity) far more than that.
        assert!(
            felt > 1e-3,
            "{}: full inertia moved only {felt} m",
            integrator.name()
        );
    }
}

#[test]
fn with_no_linear_inertia_a_frame_sliding_over_a_floor_changes_nothing() {
    // The frame lowers the curtain's last rows gently onto a rough floor and then moves along
    // it at 5 m/s. Unfelt, that motion is no slip on the floor, so that the swept tests and
    // friction must leave it out: each integrator's contacts start a substep where the frame
    // has carried the cloth.
    let floor = [Collider::fixed(
        ColliderShape::HalfSpace(InfinitePlane3d::new(Vec3::Y)),
        Pose::from_translation(Vec3::new(0.0, -0.4, 0.0)),
        Friction::new(1.0),
        0.005,
    )];
    let lowered = |t: f32| Pose::from_translation(Vec3::new(0.0, -0.1 * (t / 0.5).min(1.0), 0.0));
    let sliding = |t: f32| Pose::from_translation(lowered(t).translation + Vec3::X * 5.0 * t);
    let no_linear = Inertia {
        linear: 0.0,
        angular: 1.0,
    };
    for (integrator, tolerance) in [
        (Integrator::Auto, 1e-3),
        (Integrator::Xpbd, 1e-3),
        (Integrator::ImplicitEuler, 1e-3),
        // The explicit integrators' runs on the floor part by rounding that the contacts grow,
        // as much at 5 cm/s as at 5 m/s (CHANGELOG.md, 2026-12-01); friction that felt
        // the frame's motion parts them by far more.
        (Integrator::SymplecticEuler, 1e-2),
        (Integrator::Verlet, 1e-2),
    ] {
        let ride =
            |motion: &dyn Fn(f32) -> Pose| ride_among(integrator, no_linear, motion, 120, &floor);
        let reference = ride(&lowered);
        // The check can fail: the curtain rests on the floor, which holds its lowest point at
        // the margin above it, 0.295 m below the pins in the frame's coordinates (hanging
        // free, it would reach lower).
        let lowest = reference[119].iter().map(|p| p.y).fold(f32::MAX, f32::min);
        assert!(
            (lowest + 0.295).abs() < 2e-3,
            "{}: the lowest point at {lowest} m",
            integrator.name()
        );
        let gap = largest_gap(&reference, &ride(&sliding));
        println!("{}: {gap:e} m", integrator.name());
        assert!(
            gap <= tolerance,
            "{}: {gap} m from the run in a frame that does not slide",
            integrator.name()
        );
    }
}

#[test]
fn with_no_angular_inertia_a_turning_frame_changes_nothing_but_the_pins_chords() {
    // The frame turns about the axis of gravity (so that gravity does not turn in it) at
    // 3 rad/s, a spine's 90° in half a second.
    let still = |_: f32| Pose::IDENTITY;
    let turning = |t: f32| Pose {
        rotation: Quat::from_axis_angle(GRAVITY_TILTED.normalize(), 3.0 * t),
        translation: Vec3::ZERO,
    };
    let none = Inertia {
        linear: 0.0,
        angular: 0.0,
    };
    for integrator in Integrator::CHOICES {
        let reference = ride(integrator, none, still, 120);
        let gap = largest_gap(&reference, &ride(integrator, none, turning, 120));
        let felt = largest_gap(
            &reference,
            &ride(integrator, Inertia::default(), turning, 120),
        );
        println!(
            "{}: inertia 0 {gap:e} m, inertia 1 {felt:e} m",
            integrator.name()
        );
        // Pins travel straight between their targets at the ends of a step while the frame
        // turns along an arc, so they cut inside it; the cloth's answer shrinks as the turn
        // rate squared (CHANGELOG.md, 2026-11-24).
        assert!(
            gap <= 2e-3,
            "{}: {gap} m from the still frame's run",
            integrator.name()
        );
        assert!(
            felt > 20.0 * gap,
            "{}: felt in full, the turn moved the cloth {felt} m",
            integrator.name()
        );
    }
}

#[test]
fn full_inertia_is_bit_for_bit_world_space() {
    let moving = |t: f32| Pose {
        rotation: Quat::from_rotation_y(t),
        translation: Vec3::new(2.0 * t * t, 0.0, 0.0),
    };
    for integrator in Integrator::CHOICES {
        let with_frame = ride(integrator, Inertia::default(), moving, 30);
        // The same pins' motion, no frame given at all.
        let settings = ride_settings(integrator, Inertia::default());
        let (spec, mut sim) = curtain(10, 10, 0.04, settings);
        let rest = sim.positions().to_vec();
        let pins: Vec<u32> = (0..spec.nx).map(|i| spec.index(i, 0)).collect();
        sim.set_pins(pins.iter().map(|&p| (p, rest[p as usize])))
            .unwrap();
        for (step, expected) in with_frame.iter().enumerate() {
            let pose = moving((step + 1) as f32 * DT);
            sim.move_pins(
                pins.iter()
                    .map(|&p| pose.rotation * rest[p as usize] + pose.translation),
            );
            sim.step(DT).unwrap();
            let inverse = pose.rotation.inverse();
            for (x, e) in sim.positions().iter().zip(expected) {
                assert_eq!(
                    (inverse * (*x - pose.translation)).to_array(),
                    e.to_array(),
                    "{}: step {step}",
                    integrator.name()
                );
            }
        }
    }
}
