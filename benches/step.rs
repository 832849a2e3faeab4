//! Time per simulated 1/60 s frame of the canonical grid cloth at 20 substeps (XPBD, one
//! iteration), on one thread: the solver alone, without ECS overhead. Then the same 64×64 frame
//! among colliders (none, a sphere it drapes over, 100 far away) and in wind.

use std::hint::black_box;

use bevy::math::Vec3;
use bevy::math::primitives::Sphere;
use bevy_cloth::sim::{
    ClothModel, ClothSim, Collider, ColliderShape, Environment, Friction, GridSpec, Integrator,
    Pose, SolverSettings, WindField,
};
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};

fn hanging(n: u32) -> ClothSim {
    let model = ClothModel::grid(&GridSpec::new(n, n, 1.0 / (n - 1) as f32)).unwrap();
    let settings = SolverSettings {
        integrator: Integrator::Xpbd,
        substeps: 20,
        iterations: 1,
        ..Default::default()
    };
    let mut sim = ClothSim::new(model, settings, |p| p).unwrap();
    let (a, b) = (sim.positions()[0], sim.positions()[n as usize - 1]);
    sim.set_pins([(0, a), (n - 1, b)]).unwrap();
    // Start from a moving, stretched state rather than rest.
    for _ in 0..30 {
        sim.step(1.0 / 60.0).unwrap();
    }
    sim
}

fn step(c: &mut Criterion) {
    let mut group = c.benchmark_group("xpbd_frame_20_substeps");
    for n in [32u32, 64, 128] {
        let mut sim = hanging(n);
        group.throughput(Throughput::Elements(sim.model().springs.len() as u64 * 20));
        group.bench_with_input(
            BenchmarkId::from_parameter(format!("{n}x{n}")),
            &n,
            |b, _| b.iter(|| sim.step(black_box(1.0 / 60.0)).unwrap()),
        );
    }
    group.finish();
}

fn sphere_at(centre: Vec3) -> Collider {
    Collider::fixed(
        ColliderShape::Sphere(Sphere::new(0.3)),
        Pose::from_translation(centre),
        Friction::default(),
        0.01,
    )
}

fn environment(c: &mut Criterion) {
    let n = 64;
    let mut group = c.benchmark_group("xpbd_64x64_frame_environment");
    group.throughput(Throughput::Elements((n * n) as u64));
    // Under the sagging middle of the cloth, so that it drapes over the sphere.
    let touching = [sphere_at(Vec3::new(0.0, -0.4, 0.0))];
    let far: Vec<Collider> = (0..100)
        .map(|k| sphere_at(Vec3::new(50.0 + k as f32, 0.0, 0.0)))
        .collect();
    let wind = WindField {
        velocity: Vec3::new(5.0, 0.0, 2.0),
        air_density: 1.225,
        ..Default::default()
    };
    let cases: [(&str, Environment); 4] = [
        ("nothing", Environment::default()),
        (
            "one_sphere",
            Environment {
                colliders: &touching,
                ..Default::default()
            },
        ),
        (
            "100_far_spheres",
            Environment {
                colliders: &far,
                ..Default::default()
            },
        ),
        (
            "wind",
            Environment {
                wind: Some(&wind),
                ..Default::default()
            },
        ),
    ];
    for (name, env) in cases {
        let mut sim = hanging(n);
        group.bench_function(name, |b| {
            b.iter(|| sim.step_in(black_box(1.0 / 60.0), &env).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, step, environment);
criterion_main!(benches);
