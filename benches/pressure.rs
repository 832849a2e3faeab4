//! The cost of the air inside a closed cloth: a 2,562-particle sphere cloth (an icosphere of
//! four subdivisions, 0.3 m) at rest in space, one 1/60 s frame, without air, with a kept volume
//! and with an ideal gas at the air outside's pressure, under XPBD at 20 substeps and under Verlet
//! at its stable substeps (which the air's stiffness raises). At rest, with nothing touching it,
//! every run does the same work but the pressure pass (a volume and gradient from the triangles,
//! and the projection or force, every substep), so the difference at equal substeps is its cost.

use std::hint::black_box;

use bevy::math::Vec3;
use bevy_cloth::sim::{ClothModel, ClothSim, Integrator, Pressure, SolverSettings};
use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};

/// The ball with `pressure` under `integrator`, weightless, stepped for a second.
fn ball(integrator: Integrator, pressure: Pressure) -> ClothSim {
    let model = ClothModel::icosphere(0.3, 4).unwrap();
    let built = model.check_closed().unwrap();
    let pressure = match pressure {
        Pressure::Gas { .. } => Pressure::gas(built, 0.0),
        other => other,
    };
    let settings = SolverSettings {
        integrator,
        pressure,
        gravity: Vec3::ZERO,
        // Never asleep: these benchmarks time steps.
        sleep_speed: 0.0,
        ..Default::default()
    };
    let mut sim = ClothSim::new(model, settings, |p| p).unwrap();
    for _ in 0..60 {
        sim.step(1.0 / 60.0).unwrap();
    }
    sim
}

fn pressure(c: &mut Criterion) {
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
            let mut sim = ball(integrator, air);
            let id = format!("{} {name}", integrator.name());
            let substeps = sim.substeps_for(1.0 / 60.0);
            group.bench_function(BenchmarkId::new(id, substeps), |b| {
                b.iter(|| sim.step(black_box(1.0 / 60.0)).unwrap())
            });
        }
    }
    group.finish();
}

criterion_group!(benches, pressure);
criterion_main!(benches);
