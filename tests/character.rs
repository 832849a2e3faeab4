//! Character cloth on the solver: targets with a maximum distance and a backstop, tethers to the
//! pins, and inertia relative to a moving reference frame.

use bevy::math::primitives::InfinitePlane3d;
use bevy::math::{Quat, Vec3};
use bevy_cloth::sim::{
    ClothModel, ClothSim, Collider, ColliderShape, Environment, Friction, GridPlane, GridSpec,
    Inertia, Integrator, Pose, SolverSettings, SpringKind, Target, TargetLimits, Tethers,
};

mod common;

const DT: f32 = 1.0 / 60.0;
/// Gravity as usual.
const DOWN: Vec3 = Vec3::new(0.0, -9.81, 0.0);
/// Gravity tilted out of a curtain's plane (see [`ride`]).
const GRAVITY_TILTED: Vec3 = Vec3::new(0.0, -9.81, -3.0);
/// Gravity pulling a curtain in the XY plane backwards, into its animated surface.
const BACK: Vec3 = Vec3::new(0.0, -2.0, -9.6);

/// A curtain of `nx` × `ny` particles, `spacing` apart, hanging in the XY plane with its top row at
/// y = 0 (row `j` at y = −j·spacing).
fn curtain(nx: u32, ny: u32, spacing: f32, settings: SolverSettings) -> (GridSpec, ClothSim) {
    let spec = GridSpec::new(nx, ny, spacing).with_plane(GridPlane::Vertical);
    let model = ClothModel::grid(&spec).unwrap();
    let top = (ny - 1) as f32 * spacing / 2.0;
    let sim = ClothSim::new(model, settings, |p| p - Vec3::Y * top).unwrap();
    (spec, sim)
}

/// The top row's particles and their positions now.
fn top_row(spec: &GridSpec, sim: &ClothSim) -> Vec<(u32, Vec3)> {
    (0..spec.nx)
        .map(|i| spec.index(i, 0))
        .map(|p| (p, sim.positions()[p as usize]))
        .collect()
}

/// For a curtain pinned along its top row: the largest ratio over its particles of the distance
/// now to the top-row particle above it over their rest distance (the geodesic rest distance to
/// the nearest pin on a flat sheet pinned along a straight edge).
fn worst_tether_ratio(spec: &GridSpec, sim: &ClothSim) -> f32 {
    let x = sim.positions();
    let mut worst: f32 = 0.0;
    for j in 1..spec.ny {
        for i in 0..spec.nx {
            let d = x[spec.index(i, j) as usize].distance(x[spec.index(i, 0) as usize]);
            worst = worst.max(d / (j as f32 * spec.spacing));
        }
    }
    worst
}

/// A 32×48 cape pinned along its top edge, XPBD with 1 iteration and 4 substeps (springs that
/// alone stretch a lot), its anchor accelerated from rest to 8 m/s in 0.2 s and held there: the
/// worst stretch ratio of any particle against the nearest pin over 1 s.
fn sprint(tethers: Tethers) -> f32 {
    let settings = SolverSettings {
        integrator: Integrator::Xpbd,
        substeps: 4,
        iterations: 1,
        tethers,
        sleep_speed: 0.0,
        ..SolverSettings::default()
    };
    let (spec, mut sim) = curtain(32, 48, 0.015, settings);
    let pins = top_row(&spec, &sim);
    sim.set_pins(pins.iter().copied()).unwrap();
    let mut worst: f32 = 0.0;
    let mut offset = 0.0;
    for step in 1..=60 {
        let t = step as f32 * DT;
        let speed = 8.0 * (t / 0.2).min(1.0);
        offset += speed * DT;
        sim.move_pins(pins.iter().map(|(_, p)| *p + Vec3::Z * offset));
        sim.step(DT).unwrap();
        worst = worst.max(worst_tether_ratio(&spec, &sim));
    }
    worst
}

#[test]
fn tethers_hold_a_sprinting_cape_within_five_percent_of_its_rest_distances() {
    let on = sprint(Tethers {
        enabled: true,
        slack: 0.02,
    });
    let off = sprint(Tethers::default());
    println!("worst stretch against the nearest pin: tethers on {on:.4}, off {off:.4}");
    assert!(
        on <= 1.05,
        "with tethers a particle reached {on:.4}× its rest distance"
    );
    // The check can fail: without tethers the same sprint stretches the cape much further.
    assert!(
        off > 1.05,
        "without tethers the cape stretched only {off:.4}×"
    );
}

/// The median of `|length / rest − 1|` over the rows' and columns' springs.
fn median_structural_strain(sim: &ClothSim) -> f32 {
    let mut strain: Vec<f32> = sim.strains(SpringKind::Structural).map(f32::abs).collect();
    strain.sort_by(f32::total_cmp);
    strain[strain.len() / 2]
}

/// A 1 m square curtain of 40×40 particles hanging from the two corners of its top row (the
/// side-by-side cloth of `compare/bevy_silk`, smaller), the default XPBD (20 substeps, one
/// iteration), 3 s: the median strain of its rows and columns, and how far past its tether's
/// length any particle ended a step (with `tethers` on).
fn hang_from_two_corners(tethers: Tethers) -> (f32, f32) {
    let settings = SolverSettings {
        integrator: Integrator::Xpbd,
        tethers,
        sleep_speed: 0.0,
        ..SolverSettings::default()
    };
    let n = 40;
    let (spec, mut sim) = curtain(n, n, 1.0 / (n - 1) as f32, settings);
    let corners = [spec.index(0, 0), spec.index(n - 1, 0)];
    let pins: Vec<(u32, Vec3)> = corners.map(|p| (p, sim.positions()[p as usize])).to_vec();
    sim.set_pins(pins.iter().copied()).unwrap();
    let rest = sim.positions().to_vec();
    let mut past: f32 = 0.0;
    for _ in 0..180 {
        sim.step(DT).unwrap();
        let x = sim.positions();
        for (i, p) in rest.iter().enumerate() {
            // On a flat sheet the geodesic to a corner is the straight line at rest.
            let (length, anchor) = corners
                .iter()
                .map(|&c| (p.distance(rest[c as usize]), c))
                .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
                .unwrap();
            let now = x[i].distance(x[anchor as usize]);
            past = past.max(now / length.max(1e-6) - 1.0 - tethers.slack);
        }
    }
    (median_structural_strain(&sim), past)
}

#[test]
fn tethers_projected_every_substep_keep_a_hanging_cloth_from_stretching() {
    let (off, _) = hang_from_two_corners(Tethers::default());
    let (on, past) = hang_from_two_corners(Tethers {
        enabled: true,
        slack: 0.0,
    });
    println!(
        "median strain of rows and columns: tethers on {on:.5}, off {off:.5}; past a tether by {past:.2e} of its length"
    );
    // One sweep a substep leaves a cloth hanging from two corners stretched by its whole weight;
    // tethers without slack take the pull from the corners to every particle at once.
    assert!(on < off / 3.0, "tethers on {on}, off {off}");
    assert!(
        past <= 1e-4,
        "a particle ended a step {past} past its tether"
    );
}

#[test]
fn tethers_are_built_from_the_pins_and_only_when_enabled() {
    let settings = SolverSettings {
        tethers: Tethers {
            enabled: true,
            slack: 0.0,
        },
        ..SolverSettings::default()
    };
    let (spec, mut sim) = curtain(8, 6, 0.05, settings);
    // Nothing pinned: nothing to tie to.
    assert_eq!(sim.limit_counts(), (0, 0));
    let pins = top_row(&spec, &sim);
    sim.set_pins(pins.iter().copied()).unwrap();
    assert_eq!(sim.limit_counts(), (0, 8 * 5));
    let mut off = *sim.settings();
    off.tethers.enabled = false;
    sim.set_settings(off).unwrap();
    assert_eq!(sim.limit_counts(), (0, 0));
}

/// Targets at the curtain's rest shape carried by a moving, turning transform (a character's
/// back), weights growing from 0 at the second row to 1 at the bottom, and the curtain's top row
/// pinned to the same transform. Returns, over the ends of all steps, how far a particle went
/// past its maximum distance from its target under `checked`'s scale, and how deep into
/// `checked`'s backstop (the cloth itself runs with `limits`).
fn follow_targets(
    integrator: Integrator,
    (limits, gravity): (TargetLimits, Vec3),
    checked: TargetLimits,
) -> (f32, f32) {
    let settings = SolverSettings {
        integrator,
        gravity,
        targets: limits,
        sleep_speed: 0.0,
        ..SolverSettings::default()
    };
    let (spec, mut sim) = curtain(12, 12, 0.04, settings);
    let rest = sim.positions().to_vec();
    let pins: Vec<u32> = (0..spec.nx).map(|i| spec.index(i, 0)).collect();
    let weight = |p: u32| (p / spec.nx) as f32 / (spec.ny - 1) as f32;
    let pose = |t: f32| Pose {
        rotation: Quat::from_rotation_y(2.0 * t) * Quat::from_rotation_x(0.3 * (5.0 * t).sin()),
        translation: Vec3::new(3.0 * t, 0.2 * (7.0 * t).sin(), 0.0),
    };
    let place = |pose: &Pose, p: Vec3| pose.rotation * p + pose.translation;
    let targets = |t: f32| -> Vec<Target> {
        let pose = pose(t);
        (spec.nx..spec.nx * spec.ny)
            .map(|p| Target {
                particle: p,
                weight: weight(p),
                position: place(&pose, rest[p as usize]),
                normal: pose.rotation * Vec3::Z,
            })
            .collect()
    };
    sim.set_pins(pins.iter().map(|&p| (p, rest[p as usize])))
        .unwrap();
    sim.set_targets(&targets(0.0)).unwrap();
    let (mut worst_excess, mut worst_backstop): (f32, f32) = (f32::MIN, f32::MIN);
    for step in 1..=180 {
        let t = step as f32 * DT;
        let now = targets(t);
        let pose_now = pose(t);
        sim.move_pins(pins.iter().map(|&p| place(&pose_now, rest[p as usize])));
        sim.move_targets(now.iter().map(|t| (t.position, t.normal)));
        sim.step(DT).unwrap();
        let x = sim.positions();
        for target in &now {
            let p = x[target.particle as usize];
            let excess = p.distance(target.position) - target.weight * checked.max_distance_scale;
            worst_excess = worst_excess.max(excess);
            if checked.backstop_radius > 0.0 {
                let centre = target.position
                    - target.normal * (checked.backstop_radius + checked.backstop_offset);
                worst_backstop = worst_backstop.max(checked.backstop_radius - p.distance(centre));
            }
        }
    }
    (worst_excess, worst_backstop)
}

#[test]
fn targets_keep_every_particle_within_its_max_distance_in_every_integrator() {
    let limits = TargetLimits {
        max_distance_scale: 0.05,
        ..TargetLimits::default()
    };
    for integrator in Integrator::CHOICES {
        let (excess, _) = follow_targets(integrator, (limits, DOWN), limits);
        println!(
            "{}: worst excess over the max distance {excess:e} m",
            integrator.name()
        );
        assert!(
            excess <= 1e-4,
            "{}: a particle strayed {excess} m past its max distance",
            integrator.name()
        );
    }
    // The check can fail: with the default 1 m per unit weight the same motion carries
    // particles well past 5 cm per unit weight.
    let (excess, _) = follow_targets(Integrator::Auto, (TargetLimits::default(), DOWN), limits);
    assert!(
        excess > 1e-2,
        "unbound particles stayed within {excess} m of the tight limit"
    );
}

#[test]
fn the_backstop_keeps_particles_in_front_of_the_animated_surface() {
    // Gravity pulls the cloth backwards into the surface; the backstop sphere of 1 m behind
    // each target keeps it out.
    let limits = TargetLimits {
        max_distance_scale: 0.1,
        backstop_radius: 1.0,
        backstop_offset: 0.0,
    };
    for integrator in [
        Integrator::Xpbd,
        Integrator::Verlet,
        Integrator::ImplicitEuler,
    ] {
        let (excess, inside) = follow_targets(integrator, (limits, BACK), limits);
        println!(
            "{}: worst excess {excess:e} m, worst depth in the backstop {inside:e} m",
            integrator.name()
        );
        assert!(
            excess <= 1e-4,
            "{}: {excess} m past the max distance",
            integrator.name()
        );
        assert!(
            inside <= 1e-4,
            "{}: {inside} m inside the backstop",
            integrator.name()
        );
    }
    // The check can fail: without a backstop the cloth sinks behind the surface.
    let none = TargetLimits {
        backstop_radius: 0.0,
        ..limits
    };
    let (_, inside) = follow_targets(Integrator::Xpbd, (none, BACK), limits);
    assert!(
        inside > 1e-2,
        "without a backstop the cloth stayed out of it ({inside} m)"
    );
}

#[test]
fn bad_targets_are_errors_that_change_nothing() {
    let (_, mut sim) = curtain(4, 4, 0.1, SolverSettings::default());
    let good = Target {
        particle: 3,
        weight: 0.5,
        position: Vec3::ZERO,
        normal: Vec3::Z,
    };
    for bad in [
        Target {
            particle: 16,
            ..good
        },
        Target {
            weight: -1.0,
            ..good
        },
        Target {
            weight: f32::NAN,
            ..good
        },
        Target {
            position: Vec3::new(0.0, f32::INFINITY, 0.0),
            ..good
        },
        Target {
            normal: Vec3::new(f32::NAN, 0.0, 0.0),
            ..good
        },
    ] {
        let e = sim.set_targets(&[good, bad]).unwrap_err();
        assert!(e.to_string().contains("target"), "{e}");
        assert_eq!(sim.limit_counts(), (0, 0), "{e}");
    }
    sim.set_targets(&[good]).unwrap();
    assert_eq!(sim.limit_counts(), (1, 0));
    for bad in [
        Inertia {
            linear: 1.5,
            angular: 1.0,
        },
        Inertia {
            linear: 1.0,
            angular: f32::NAN,
        },
        Inertia {
            linear: -0.1,
            angular: 0.0,
        },
    ] {
        let settings = SolverSettings {
            inertia: bad,
            ..SolverSettings::default()
        };
        assert!(settings.validate().is_err(), "{bad:?} accepted");
    }
    for bad in [
        Tethers {
            enabled: true,
            slack: -0.1,
        },
        Tethers {
            enabled: false,
            slack: f32::NAN,
        },
    ] {
        let settings = SolverSettings {
            tethers: bad,
            ..SolverSettings::default()
        };
        assert!(settings.validate().is_err(), "{bad:?} accepted");
    }
}

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

/// A skinned cape in a headless App.
mod skinned {
    use bevy::mesh::skinning::SkinnedMesh;
    use bevy::prelude::*;
    use bevy_cloth::harness::character::{Cape, SpawnedCape, spawn_cape, torso_pose};
    use bevy_cloth::prelude::*;

    use super::common;

    const NX: usize = 16;
    const NY: usize = 24;

    #[test]
    fn a_cape_on_a_turning_walking_torso_stays_on_its_skin() {
        // The root walks at 3 m/s while the spine turns 90° every half second.
        let pose = |t: f32| torso_pose(t, 3.0, std::f32::consts::PI);
        let mut app = common::app();
        let cape = Cape::new(NX, NY);
        let mut config = ClothConfig {
            interpolate: false,
            ..ClothConfig::default()
        };
        config.solver.targets.max_distance_scale = 0.3;
        let SpawnedCape { cloth, root, spine } = spawn_cape(app.world_mut(), &cape, config);
        app.update();
        assert!(app.world().get::<ClothInvalid>(cloth).is_none());
        let Cape {
            rest,
            joints,
            weights,
            inverse_bindposes: bind,
            ..
        } = cape;
        // The skin moved to the cloth; the renderer has nothing to skin.
        assert!(app.world().get::<SkinnedMesh>(cloth).is_none());
        assert!(app.world().get::<ClothSkin>(cloth).is_some());
        let targets: Vec<_> = common::state(&app, cloth).targets().collect();
        assert_eq!(targets.len(), NX * NY);
        assert_eq!(targets.iter().filter(|t| t.weight == 0.0).count(), NX);
        assert_eq!(common::sim(&app, cloth).pinned().count(), NX);

        let (mut worst_pin, mut worst_excess, mut worst_skin): (f32, f32, f32) =
            (0.0, f32::MIN, 0.0);
        for step in 1..=600 {
            let t = step as f32 / 60.0;
            let (root_pose, spine_pose) = pose(t);
            *app.world_mut().get_mut::<Transform>(root).unwrap() = root_pose;
            *app.world_mut().get_mut::<Transform>(spine).unwrap() = spine_pose;
            app.update();
            // An independent skinning of every vertex: joint world matrices from the poses.
            let world = [
                root_pose.to_matrix(),
                root_pose.to_matrix() * spine_pose.to_matrix(),
            ];
            let skinned = |v: usize| -> Vec3 {
                (0..4)
                    .map(|k| {
                        let j = joints[v][k] as usize;
                        weights[v][k] * (world[j] * bind[j]).transform_point3(rest[v])
                    })
                    .sum()
            };
            let state = common::state(&app, cloth);
            let x = state.positions();
            assert!(x.iter().all(|p| p.is_finite()), "step {step}: not finite");
            for target in state.targets() {
                let v = target.particle as usize;
                let expected = skinned(v);
                worst_skin = worst_skin.max(target.position.distance(expected));
                let d = x[v].distance(expected);
                if target.weight == 0.0 {
                    worst_pin = worst_pin.max(d);
                } else {
                    worst_excess = worst_excess.max(d - 0.3 * target.weight);
                }
            }
        }
        println!(
            "skinning {worst_skin:e} m, pins {worst_pin:e} m, past the max distance {worst_excess:e} m"
        );
        assert!(
            worst_skin <= 1e-5,
            "the plugin's skinning is {worst_skin} m off"
        );
        assert!(
            worst_pin <= 1e-3,
            "a weight-0 vertex was {worst_pin} m off its skin"
        );
        assert!(
            worst_excess <= 1e-3,
            "a vertex went {worst_excess} m past its max distance"
        );
    }

    /// A 12×16 cape in the XY plane, weights from 0 on its top row to 1 at its hem.
    fn grid_cape() -> (GridSpec, Vec<f32>) {
        let spec = GridSpec::new(12, 16, 0.03).with_plane(GridPlane::Vertical);
        let weights = (0..12 * 16).map(|p| (p / 12) as f32 / 15.0).collect();
        (spec, weights)
    }

    #[test]
    fn without_a_skin_targets_follow_the_cloth_transform() {
        let mut app = common::app();
        let (spec, weights) = grid_cape();
        let mut config = ClothConfig {
            interpolate: false,
            ..ClothConfig::default()
        };
        config.solver.targets.max_distance_scale = 0.05;
        let cloth = common::spawn_valid(
            &mut app,
            (
                Cloth::grid(spec),
                ClothTargets {
                    weights: TargetWeights::Values(weights),
                },
                // Two of the top row's weight-0 vertices are also pinned by hand: once each.
                ClothPins::new([0, 1]),
                config,
            ),
        );
        assert_eq!(common::sim(&app, cloth).pinned().count(), 12);
        let rest = common::sim(&app, cloth).model().rest_positions.clone();
        let mut worst: f32 = f32::MIN;
        for step in 1..=120 {
            let t = step as f32 / 60.0;
            let pose = Transform::from_xyz(2.0 * t, 0.0, 0.0)
                .with_rotation(Quat::from_rotation_y(2.0 * t));
            *app.world_mut().get_mut::<Transform>(cloth).unwrap() = pose;
            app.update();
            let state = common::state(&app, cloth);
            for target in state.targets() {
                let v = target.particle as usize;
                let expected = pose.transform_point(rest[v]);
                assert!(target.position.distance(expected) < 1e-5, "target of {v}");
                let d = state.positions()[v].distance(expected);
                worst = worst.max(d - 0.05 * target.weight);
            }
        }
        println!("worst excess over the max distance {worst:e} m");
        assert!(
            worst <= 1e-3,
            "a particle went {worst} m past its max distance"
        );
    }

    #[test]
    fn with_no_linear_inertia_a_cloth_entity_at_constant_speed_hangs_as_if_still() {
        // Pinned along its top row to its rest shape (so the pins move with the entity), the
        // cloth's shape relative to its entity matches a still one's.
        let run = |speed: f32, inertia: Inertia| -> Vec<Vec3> {
            let mut app = common::app();
            let (spec, _) = grid_cape();
            let mut config = ClothConfig::default();
            config.solver.inertia = inertia;
            config.solver.gravity = Vec3::new(0.0, -9.81, -3.0);
            config.solver.damping = 5.0;
            config.solver.sleep_speed = 0.0;
            let cloth =
                common::spawn_valid(&mut app, (Cloth::grid(spec), ClothPins::new(0..12), config));
            for step in 1..=120 {
                let t = step as f32 / 60.0;
                app.world_mut()
                    .get_mut::<Transform>(cloth)
                    .unwrap()
                    .translation = Vec3::new(speed * t, 0.0, 0.0);
                app.update();
            }
            let offset = Vec3::new(speed * 2.0, 0.0, 0.0);
            common::state(&app, cloth)
                .positions()
                .iter()
                .map(|p| *p - offset)
                .collect()
        };
        let gap = |a: &[Vec3], b: &[Vec3]| {
            a.iter()
                .zip(b)
                .map(|(p, q)| p.distance(*q))
                .fold(0.0, f32::max)
        };
        let none = Inertia {
            linear: 0.0,
            angular: 1.0,
        };
        let still = run(0.0, none);
        let carried = gap(&still, &run(5.0, none));
        let felt = gap(&still, &run(5.0, Inertia::default()));
        println!("inertia 0: {carried:e} m, inertia 1: {felt:e} m");
        assert!(carried <= 1e-3, "{carried} m from the still cloth");
        assert!(
            felt > 1e-2,
            "felt in full, the motion moved the cloth only {felt} m"
        );
    }

    #[test]
    fn bad_target_weights_make_the_cloth_invalid() {
        let (spec, weights) = grid_cape();
        let mut nan = weights.clone();
        nan[30] = f32::NAN;
        for (what, weights) in [
            (
                "too few weights",
                TargetWeights::Values(weights[1..].to_vec()),
            ),
            ("a NaN weight", TargetWeights::Values(nan)),
            ("colours of a grid", TargetWeights::Color(0)),
            (
                "an attribute of a grid",
                TargetWeights::Attribute("weights".into()),
            ),
        ] {
            let mut app = common::app();
            let cloth = common::spawn(&mut app, (Cloth::grid(spec), ClothTargets { weights }));
            let invalid = app.world().get::<ClothInvalid>(cloth);
            assert!(invalid.is_some(), "{what} accepted");
            println!("{what}: {}", invalid.unwrap().0);
        }
    }

    #[test]
    fn a_skirt_stays_outside_legs_that_kick_through_it() {
        // A skirt: a tube of radius 0.2 m from the waist (y = 1) down to y = 0.45, pinned along
        // its waist. Two legs, capsules of radius 6 cm hanging 0.8 m from hip joints at
        // x = ±0.1, swing ±45° about X at 1.5 Hz in opposite phase (the feet reach 5.6 m/s, a
        // capsule surface moves up to 9 cm in a step): they are moved by their joints, the
        // colliders' own transforms never change.
        use bevy_cloth::sim::ClothModel;
        let (around, rows) = (32usize, 12usize);
        let mut positions = Vec::new();
        for j in 0..rows {
            for i in 0..around {
                let a = std::f32::consts::TAU * i as f32 / around as f32;
                let y = 1.0 - 0.55 * j as f32 / (rows - 1) as f32;
                positions.push(Vec3::new(0.2 * a.cos(), y, 0.2 * a.sin()));
            }
        }
        let mut indices = Vec::new();
        for j in 0..rows - 1 {
            for i in 0..around {
                let (a, b) = (
                    (j * around + i) as u32,
                    (j * around + (i + 1) % around) as u32,
                );
                let (c, d) = (a + around as u32, b + around as u32);
                indices.extend([a, c, b, b, c, d]);
            }
        }
        let model = ClothModel::from_mesh(&positions, None, &indices, 3).unwrap();
        let mut app = common::app();
        let (radius, half_length) = (0.06, 0.34);
        let hips: Vec<Entity> = [-0.1f32, 0.1]
            .iter()
            .map(|&x| {
                let hip = app.world_mut().spawn(Transform::from_xyz(x, 1.0, 0.0)).id();
                app.world_mut().spawn((
                    ClothCollider::capsule(radius, half_length),
                    Transform::from_xyz(0.0, -0.4, 0.0),
                    ChildOf(hip),
                ));
                hip
            })
            .collect();
        let cloth = common::spawn_valid(
            &mut app,
            (
                Cloth::from_model(model),
                ClothPins::new(0..around as u32),
                ClothConfig {
                    interpolate: false,
                    ..ClothConfig::default()
                },
            ),
        );
        let swing = |t: f32, k: usize| {
            let phase = if k == 0 { 0.0 } else { std::f32::consts::PI };
            std::f32::consts::FRAC_PI_4 * (std::f32::consts::TAU * 1.5 * t + phase).sin()
        };
        let (mut deepest, mut touching): (f32, usize) = (f32::MIN, 0);
        for step in 1..=240 {
            let t = step as f32 / 60.0;
            for (k, &hip) in hips.iter().enumerate() {
                app.world_mut().get_mut::<Transform>(hip).unwrap().rotation =
                    Quat::from_rotation_x(swing(t, k));
            }
            app.update();
            let x = common::state(&app, cloth).positions();
            for (k, hip) in [-0.1f32, 0.1].iter().enumerate() {
                // The leg's axis now, from the hip's pose.
                let turn = Quat::from_rotation_x(swing(t, k));
                let centre = Vec3::new(*hip, 1.0, 0.0) + turn * Vec3::new(0.0, -0.4, 0.0);
                let axis = turn * Vec3::Y * half_length;
                for p in x {
                    let along = (*p - centre).dot(axis) / axis.length_squared();
                    let nearest = centre + axis * along.clamp(-1.0, 1.0);
                    let depth = radius - p.distance(nearest);
                    deepest = deepest.max(depth);
                    touching += usize::from(depth > -0.02);
                }
            }
        }
        println!(
            "deepest inside a leg {deepest:e} m; particle-steps within 2 cm of one {touching}"
        );
        assert!(
            touching > 1000,
            "the legs hardly touched the skirt ({touching})"
        );
        assert!(
            deepest <= 1e-3,
            "a particle ended a step {deepest} m inside a leg"
        );
    }

    #[test]
    fn a_ron_scene_gives_a_cloth_its_target_weights() {
        let mut app = common::app();
        let scene = bevy_cloth::scene::ClothScene::from_ron(
            "(cloth: Grid((nx: 4, ny: 3, spacing: 0.1, plane: Vertical)), \
             target_weights: Some([0, 0, 0, 0, 0.5, 0.5, 0.5, 0.5, 1, 1, 1, -1]), \
             solver: (targets: (max_distance_scale: 0.2), tethers: (enabled: true)))",
        )
        .unwrap();
        let cloth = scene.spawn(app.world_mut()).unwrap();
        app.update();
        let state = common::state(&app, cloth);
        // Eleven weighted particles, the four of weight 0 pinned; the last one is free.
        assert_eq!(state.targets().count(), 11);
        assert_eq!(state.sim().pinned().count(), 4);
        // Seven targets with a max distance, and a tether for each of the eight free particles.
        assert_eq!(state.sim().limit_counts(), (7, 8));
    }

    #[test]
    fn weights_come_from_a_named_vertex_attribute() {
        // A cape mesh without a skin whose weights sit in a custom float attribute (as a glTF
        // exporter's custom attribute arrives through the loader): the top row pinned, the rest
        // held near the rest shape under the cloth's transform.
        use bevy::mesh::{MeshVertexAttribute, VertexFormat};
        const WEIGHT: MeshVertexAttribute =
            MeshVertexAttribute::new("_CLOTH_WEIGHT", 988_540_917, VertexFormat::Float32);
        let cape = Cape::new(8, 6);
        let weights: Vec<f32> = (0..48).map(|v| (v / 8) as f32 / 5.0).collect();
        let mut mesh = cape.mesh.clone();
        mesh.insert_attribute(WEIGHT, weights.clone());
        let mut app = common::app();
        let handle = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
        let mut config = ClothConfig::default();
        config.solver.targets.max_distance_scale = 0.1;
        let cloth = common::spawn_valid(
            &mut app,
            (
                Cloth::from_mesh(handle),
                ClothTargets {
                    weights: TargetWeights::Attribute("_CLOTH_WEIGHT".into()),
                },
                config,
            ),
        );
        common::run(&mut app, 60);
        let state = common::state(&app, cloth);
        let read: Vec<f32> = state.targets().map(|t| t.weight).collect();
        assert_eq!(read, weights);
        assert_eq!(state.sim().pinned().count(), 8);
        for t in state.targets() {
            let d = state.positions()[t.particle as usize].distance(t.position);
            assert!(
                d <= 0.1 * t.weight + 1e-3,
                "vertex {} is {d} m from its target",
                t.particle
            );
        }
        // A name the mesh does not have, or a colour channel past alpha, is an error naming it.
        for (weights, named) in [
            (TargetWeights::Attribute("_MISSING".into()), "_MISSING"),
            (TargetWeights::Color(7), "channel 7"),
        ] {
            let mut app = common::app();
            let handle = app
                .world_mut()
                .resource_mut::<Assets<Mesh>>()
                .add(cape.mesh.clone());
            let cloth = common::spawn(
                &mut app,
                (Cloth::from_mesh(handle), ClothTargets { weights }),
            );
            let invalid = app.world().get::<ClothInvalid>(cloth).expect("invalid");
            assert!(invalid.0.to_string().contains(named), "{}", invalid.0);
        }
    }
}
