//! Time per simulated 1/60 s frame of the canonical grid cloth at 20 substeps (XPBD, one
//! iteration), on one thread: the solver alone, without ECS overhead.

use std::hint::black_box;

use bevy_cloth::sim::{ClothModel, ClothSim, GridSpec, Integrator, SolverSettings};
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

criterion_group!(benches, step);
criterion_main!(benches);
