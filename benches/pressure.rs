//! The cost of the air inside a closed cloth: a 2,562-particle sphere cloth (an icosphere of
//! four subdivisions, 0.3 m) resting on a floor, one 1/60 s frame, without air, with a kept
//! volume and with an ideal gas, under XPBD at 20 substeps and under Verlet at its stable
//! substeps. The difference is the pressure pass (a volume and gradient from the triangles, and
//! the projection or force, every substep).

use std::hint::black_box;

use bevy::math::Vec3;
use bevy::math::primitives::InfinitePlane3d;
use bevy_cloth::sim::{
    ClothModel, ClothSim, Collider, ColliderShape, Environment, Friction, Integrator, Pose,
    Pressure, SolverSettings,
};
use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};

fn floor() -> Collider {
    Collider::fixed(
        ColliderShape::HalfSpace(InfinitePlane3d::new(Vec3::Y)),
        Pose::IDENTITY,
        Friction::default(),
        0.0,
    )
}

/// The ball with `pressure` under `integrator`, settled on the floor for a second.
fn ball(integrator: Integrator, pressure: Pressure, floor: &[Collider]) -> ClothSim {
    let model = ClothModel::icosphere(0.3, 4).unwrap();
    let built = model.check_closed().unwrap();
    let pressure = match pressure {
        Pressure::Gas { .. } => Pressure::gas(built, 3000.0),
        other => other,
    };
    let settings = SolverSettings {
        integrator,
        pressure,
        // Never asleep: these benchmarks time steps.
        sleep_speed: 0.0,
        ..Default::default()
    };
    let mut sim = ClothSim::new(model, settings, |p| p + Vec3::Y * 0.31).unwrap();
    let env = Environment {
        colliders: floor,
        ..Default::default()
    };
    for _ in 0..60 {
        sim.step_in(1.0 / 60.0, &env).unwrap();
    }
    sim
}

fn pressure(c: &mut Criterion) {
    let floor = [floor()];
    let env = Environment {
        colliders: &floor,
        ..Default::default()
    };
    let mut group = c.benchmark_group("sphere_2562_frame");
    for integrator in [Integrator::Xpbd, Integrator::Verlet] {
        for (name, air) in [
            ("no air", Pressure::Off),
            (
                "kept volume",
                Pressure::Volume {
                    scale: 1.0,
                    bulk_modulus: 1.0e5,
                },
            ),
            (
                "ideal gas",
                Pressure::Gas {
                    nrt: 0.0,
                    ambient: 0.0,
                },
            ),
        ] {
            let mut sim = ball(integrator, air, &floor);
            let id = format!("{} {name}", integrator.name());
            let substeps = sim.substeps_for(1.0 / 60.0);
            group.bench_function(BenchmarkId::new(id, substeps), |b| {
                b.iter(|| sim.step_in(black_box(1.0 / 60.0), &env).unwrap())
            });
        }
    }
    group.finish();
}

criterion_group!(benches, pressure);
criterion_main!(benches);
