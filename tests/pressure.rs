//! Closed cloths with air inside ([`Pressure`]): which cloths can hold it, a kept volume under a
//! load, the ideal gas's law measured through the springs that hold it, and a bouncing ball that
//! never gains energy; each with every integrator.

use bevy::math::primitives::InfinitePlane3d;
use bevy_cloth::ClothError;
use bevy_cloth::sim::{
    ClothModel, ClothSim, Collider, ColliderShape, Environment, Friction, Integrator, Pose,
    Pressure, STANDARD_ATMOSPHERE, SolverSettings,
};
use glam::Vec3;

const INTEGRATORS: [Integrator; 4] = [
    Integrator::Xpbd,
    Integrator::Verlet,
    Integrator::SymplecticEuler,
    Integrator::ImplicitEuler,
];

fn settings(integrator: Integrator, pressure: Pressure) -> SolverSettings {
    SolverSettings {
        integrator,
        iterations: if integrator == Integrator::ImplicitEuler {
            60
        } else {
            1
        },
        pressure,
        sleep_speed: 0.0,
        ..Default::default()
    }
}

fn not_closed(e: ClothError, words: &[&str]) {
    let ClothError::NotClosed { what } = &e else {
        panic!("expected NotClosed, got {e:?}");
    };
    for w in words {
        assert!(what.contains(w), "{what:?} should name {w:?}");
    }
}

#[test]
fn an_icosphere_and_a_box_are_closed_and_enclose_their_volume() {
    for (subdivisions, particles) in [(0, 12), (3, 642), (4, 2562)] {
        let sphere = ClothModel::icosphere(0.5, subdivisions).unwrap();
        assert_eq!(sphere.particle_count(), particles);
        let v = sphere.check_closed().unwrap();
        let ball = 4.0 / 3.0 * std::f32::consts::PI * 0.125;
        // Inscribed in the sphere, and closer to it with every subdivision.
        assert!(
            v < ball && v > [0.6, 0.0, 0.0, 0.98, 0.99][subdivisions as usize] * ball,
            "{subdivisions}: {v} vs {ball}"
        );
    }
    let cushion = ClothModel::cuboid(Vec3::new(0.5, 0.15, 0.4), 0.05).unwrap();
    // The surface of an 11 × 4 × 9 lattice of points.
    assert_eq!(cushion.particle_count(), 11 * 4 * 9 - 9 * 2 * 7);
    let v = cushion.check_closed().unwrap();
    assert!((v - 0.5 * 0.15 * 0.4).abs() < 1e-6, "{v}");
}

#[test]
fn a_cloth_that_is_not_closed_and_wound_outward_is_refused_air() {
    let air = settings(Integrator::Xpbd, Pressure::gas(0.5, 1000.0));
    // A grid is open.
    let grid = ClothModel::grid(&bevy_cloth::sim::GridSpec::new(4, 4, 0.1)).unwrap();
    not_closed(
        ClothSim::new(grid, air, |p| p).unwrap_err(),
        &["borders only triangle"],
    );
    // A hole: one triangle left out names one of its edges.
    let sphere = ClothModel::icosphere(0.5, 1).unwrap();
    let mut holed = sphere.clone();
    holed.triangles.truncate(holed.triangles.len() - 3);
    not_closed(
        holed.check_closed().unwrap_err(),
        &["borders only triangle", "open"],
    );
    // One triangle wound the other way.
    let mut flipped = sphere.clone();
    flipped.triangles.swap(30, 31);
    not_closed(
        flipped.check_closed().unwrap_err(),
        &["10", "wound against"],
    );
    // All of them: a closed surface inside out.
    let mut inside_out = sphere.clone();
    for t in inside_out.triangles.chunks_exact_mut(3) {
        t.swap(0, 1);
    }
    not_closed(inside_out.check_closed().unwrap_err(), &["clockwise"]);
    // A mirroring transform turns a closed cloth inside out in the world.
    let mirrored = ClothSim::new(sphere.clone(), air, |p| p * Vec3::new(-1.0, 1.0, 1.0));
    not_closed(mirrored.unwrap_err(), &["mirrored"]);
    // Turning air on later is checked the same way, and changes nothing when refused.
    let grid = ClothModel::grid(&bevy_cloth::sim::GridSpec::new(4, 4, 0.1)).unwrap();
    let mut sim = ClothSim::new(grid, SolverSettings::default(), |p| p).unwrap();
    not_closed(sim.set_settings(air).unwrap_err(), &["borders only"]);
    assert_eq!(sim.settings().pressure, Pressure::Off);
    // A closed cloth takes it, and reports its volume and pressure.
    let volume = sphere.check_closed().unwrap();
    let mut sim = ClothSim::new(sphere, SolverSettings::default(), |p| p).unwrap();
    assert!(sim.pressure().is_none() && sim.volume() == Some(volume));
    let air = settings(Integrator::Xpbd, Pressure::gas(volume, 1000.0));
    sim.set_settings(air).unwrap();
    let p = sim.pressure().unwrap();
    assert!((p - 1000.0).abs() < 1.0, "{p}");
}

#[test]
fn settings_out_of_range_name_the_field() {
    for (pressure, field) in [
        (
            Pressure::Volume {
                scale: 0.0,
                bulk_modulus: 1e5,
            },
            "pressure.scale",
        ),
        (
            Pressure::Volume {
                scale: 1.0,
                bulk_modulus: f32::INFINITY,
            },
            "pressure.bulk_modulus",
        ),
        (
            Pressure::Gas {
                nrt: -1.0,
                ambient: 0.0,
            },
            "pressure.nrt",
        ),
        (
            Pressure::Gas {
                nrt: 1.0,
                ambient: f32::NAN,
            },
            "pressure.ambient",
        ),
    ] {
        let e = SolverSettings {
            pressure,
            ..Default::default()
        }
        .validate()
        .unwrap_err();
        assert!(
            matches!(e, ClothError::InvalidValue { field: f, .. } if f == field),
            "{e:?}"
        );
    }
}

/// A `size` box cloth resting on a floor at y = 0, its top face carrying `load` kg in all.
fn cushion(load: f32) -> (ClothModel, f32) {
    let size = Vec3::new(0.4, 0.12, 0.4);
    let model = ClothModel::cuboid(size, 0.04).unwrap();
    let top: Vec<usize> = (0..model.particle_count())
        .filter(|&i| model.rest_positions[i].y > 0.5 * size.y - 1e-4)
        .collect();
    let light = 0.002;
    let mut masses = vec![light; model.particle_count()];
    for &i in &top {
        masses[i] = load / top.len() as f32;
    }
    let model = model.with_particle_masses(masses).unwrap();
    (model, 0.5 * size.y)
}

fn floor() -> Collider {
    Collider::fixed(
        ColliderShape::HalfSpace(InfinitePlane3d::new(Vec3::Y)),
        Pose::IDENTITY,
        Friction::default(),
        0.0,
    )
}

/// Steps `sim` on `colliders` for `seconds` at 60 Hz.
fn run(sim: &mut ClothSim, colliders: &[Collider], seconds: f32) {
    let env = Environment {
        colliders,
        ..Default::default()
    };
    for _ in 0..(seconds * 60.0) as u32 {
        sim.step_in(1.0 / 60.0, &env).unwrap();
    }
}

/// The cushion under its load after 2 s at rest (`substeps` per 60 Hz step; 0 for the
/// default), with `pressure`: its volume, the volume it keeps, the pressure inside and its kinetic
/// energy.
fn loaded_cushion(integrator: Integrator, pressure: Pressure, substeps: u32) -> [f32; 4] {
    let (model, half_height) = cushion(10.0);
    let mut s = settings(integrator, pressure);
    s.damping = 4.0;
    if substeps > 0 {
        s.substeps = substeps;
    }
    let mut sim = ClothSim::new(model, s, |p| p + Vec3::Y * (half_height + 0.002)).unwrap();
    let kept = sim.built_volume().unwrap();
    run(&mut sim, &[floor()], 2.0);
    let v = sim.volume().unwrap();
    let p = sim.pressure().unwrap_or(0.0);
    let kinetic = sim.kinetic_energy();
    eprintln!(
        "{integrator:?} at {substeps} substeps: volume {v:.6} of {kept:.6} ({:.3}% less), \
         pressure {p:.0} Pa, kinetic {kinetic:.2e} J",
        100.0 * (kept - v) / kept
    );
    [v, kept, p, kinetic]
}

#[test]
fn a_cushion_under_a_ten_kilogram_box_keeps_its_volume() {
    let pressure = Pressure::Volume {
        scale: 1.0,
        bulk_modulus: 4.0e5,
    };
    let mut pressures = Vec::new();
    for integrator in INTEGRATORS {
        let [v, kept, p, kinetic] = loaded_cushion(integrator, pressure, 0);
        let deficit = (kept - v) / kept;
        assert!(
            deficit.abs() < 0.005,
            "{integrator:?}: volume off by {:.3}%",
            100.0 * deficit
        );
        assert!(kinetic < 1e-3, "{integrator:?} not at rest: {kinetic}");
        pressures.push(p);
    }
    // The air carries most of the load (the walls' bending holds a little), and the force
    // integrators come to rest at the same equilibrium of the same energy.
    let weight_pressure = 10.0 * 9.81 / (0.4 * 0.4);
    let forces = &pressures[1..];
    for p in forces {
        assert!(
            (p - forces[0]).abs() < 0.02 * forces[0],
            "force integrators disagree: {pressures:?}"
        );
        assert!(
            *p > 0.75 * weight_pressure && *p < 1.25 * weight_pressure,
            "{p} Pa for a load of {weight_pressure} Pa"
        );
    }
    // XPBD projects the air once per substep after the springs: at 20 substeps it rests with the
    // cushion softer than its bulk modulus, and it comes to the same rest as substeps grow.
    let [.., fine, _] = loaded_cushion(Integrator::Xpbd, pressure, 320);
    assert!(
        (fine - forces[0]).abs() < 0.05 * forces[0]
            && (fine - forces[0]).abs() < (pressures[0] - forces[0]).abs(),
        "XPBD at 320 substeps {fine} Pa, at 20 {} Pa, the force integrators {}",
        pressures[0],
        forces[0]
    );
    // Without the air the same cushion is a sack: the load flattens it.
    let [v, kept, ..] = loaded_cushion(Integrator::Xpbd, Pressure::Off, 0);
    assert!(v < 0.7 * kept, "without air: {v} of {kept}");
}

/// The pressure inside a closed cloth at rest with nothing but its springs and its air acting on
/// it, measured through the springs: at equilibrium `Σ x·F = 0`, and the air's part is
/// `3 (p − ambient) V` (the volume is homogeneous of degree 3), the springs' `−Σ k (|d| − L)|d|`.
fn pressure_from_springs(sim: &ClothSim) -> f64 {
    let model = sim.model();
    let s = &model.springs;
    let stiffness = sim.settings().stiffness;
    let x = sim.positions();
    let tension: f64 = (0..s.len())
        .map(|k| {
            let length = x[s.a[k] as usize].distance(x[s.b[k] as usize]) as f64;
            stiffness.of(s.kind[k]) as f64 * (length - s.rest[k] as f64) * length
        })
        .sum();
    tension / (3.0 * sim.volume().unwrap() as f64)
}

#[test]
fn at_rest_an_ideal_gas_keeps_p_v_equal_to_nrt_under_three_loads() {
    let model = ClothModel::icosphere(0.3, 2).unwrap();
    let built = model.check_closed().unwrap();
    for integrator in INTEGRATORS {
        // Three loads on the springs: the gas a little, more and much above the air outside.
        for gauge in [500.0, 1500.0, 4000.0] {
            let nrt = (STANDARD_ATMOSPHERE + gauge) * built;
            let pressure = Pressure::Gas {
                nrt,
                ambient: STANDARD_ATMOSPHERE,
            };
            let mut s = settings(integrator, pressure);
            s.gravity = Vec3::ZERO;
            s.damping = 6.0;
            s.stiffness.bend = 0.0;
            let mut sim = ClothSim::new(model.clone(), s, |p| p).unwrap();
            run(&mut sim, &[], 2.0);
            let v = sim.volume().unwrap() as f64;
            let p = STANDARD_ATMOSPHERE as f64 + pressure_from_springs(&sim);
            let error = (p * v - nrt as f64) / nrt as f64;
            eprintln!(
                "{integrator:?} gauge {gauge}: V/V₀ {:.4}, pV/nRT − 1 = {error:.2e}",
                v / built as f64
            );
            assert!(
                error.abs() < 0.02,
                "{integrator:?} at {gauge} Pa: pV off nRT by {:.2}%",
                100.0 * error
            );
        }
    }
}

#[test]
fn a_dropped_ball_never_bounces_higher() {
    for integrator in INTEGRATORS {
        let model = ClothModel::icosphere(0.2, 2).unwrap();
        let built = model.check_closed().unwrap();
        let mut s = settings(integrator, Pressure::gas(built, 4000.0));
        s.damping = 0.0;
        s.stiffness.structural = 2000.0;
        s.stiffness.shear = 2000.0;
        let mut sim = ClothSim::new(model, s, |p| p + Vec3::Y * 0.6).unwrap();
        let floor = [Collider::fixed(
            ColliderShape::HalfSpace(InfinitePlane3d::new(Vec3::Y)),
            Pose::IDENTITY,
            Friction::NONE,
            0.0,
        )];
        let env = Environment {
            colliders: &floor,
            ..Default::default()
        };
        let height = |sim: &ClothSim| {
            sim.positions().iter().map(|p| p.y).sum::<f32>() / sim.positions().len() as f32
        };
        let airborne = |sim: &ClothSim| sim.positions().iter().all(|p| p.y > 0.005);
        // A bounce's height: the centre's highest point while the ball is off the floor (a
        // ball at rest still wobbles, which is not a bounce).
        let (mut peaks, mut last, mut rising) = (Vec::new(), height(&sim), false);
        for _ in 0..6 * 60 {
            sim.step_in(1.0 / 60.0, &env).unwrap();
            let h = height(&sim);
            if rising && h < last && airborne(&sim) {
                peaks.push(last);
            }
            rising = h > last;
            last = h;
        }
        eprintln!("{integrator:?}: peaks {peaks:?}");
        assert!(peaks.len() >= 3, "{integrator:?}: {peaks:?}");
        for pair in peaks.windows(2) {
            assert!(
                pair[1] <= pair[0] + 1e-4,
                "{integrator:?} bounced higher: {peaks:?}"
            );
        }
    }
}
