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

#[path = "character/inertia.rs"]
mod inertia;

#[path = "character/skinned.rs"]
mod skinned;

#[path = "character/crowd.rs"]
mod crowd;

#[path = "character/lod.rs"]
mod lod;
