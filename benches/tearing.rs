//! The cost of tearing on the shipped 64×64 cloth (2 cm spacing, hanging from its top corners,
//! settled for a second), rendered as a level-2 subdivision surface:
//! - `tear_grid64/one split`: one particle split by a short cut at the cloth's edge, and
//!   everything built from the topology rebuilt: the torn model, the solver (springs and their
//!   colouring, steppers, contacts), and the subdivision stencils of the render mesh brought up
//!   to date ([`Subdivider::follow`]);
//! - `tear_grid64/row cut`: the same for a cut across the whole cloth (64 splits);
//! - `tear_grid64/strain check`: the check a step with tearing on makes when nothing tears;
//! - `tear_grid64/frame, whole` and `frame, cut in two`: one 1/60 s step of the cloth before and
//!   after the row cut.

use std::hint::black_box;

use bevy_cloth::sim::{ClothModel, ClothSim, Cut, GridPlane, GridSpec, SolverSettings, Tearing};
use bevy_cloth::subdivision::{BoundaryMode, Subdivider, VertexRule};
use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use glam::Vec3;

const N: u32 = 64;
const SPACING: f32 = 0.02;

fn settled() -> ClothSim {
    let spec = GridSpec::new(N, N, SPACING).with_plane(GridPlane::Vertical);
    let settings = SolverSettings {
        sleep_speed: 0.0,
        tearing: Tearing {
            enabled: true,
            max_stretch: 10.0,
            ..Tearing::default()
        },
        ..SolverSettings::default()
    };
    let mut sim = ClothSim::new(ClothModel::grid(&spec).unwrap(), settings, |p| p).unwrap();
    let top = [0, N - 1].map(|i| (i, sim.positions()[i as usize]));
    sim.set_pins(top).unwrap();
    for _ in 0..60 {
        sim.step(1.0 / 60.0).unwrap();
    }
    sim
}

/// The render stencils of `sim`'s cloth at level 2.
fn subdivider(sim: &ClothSim) -> Subdivider {
    let mesh = sim.model().control_mesh().unwrap();
    Subdivider::new(&mesh, 2, VertexRule::Original, BoundaryMode::EdgeAndCorner).unwrap()
}

/// Tears `sim` along `cut` and brings its render stencils up to date; returns the refined vertex
/// count.
fn tear_and_render((mut sim, mut subdivider): (ClothSim, Subdivider), cut: Cut) -> usize {
    let splits = sim.tear(&[cut]).unwrap();
    assert!(!splits.is_empty());
    subdivider
        .follow(&sim.model().control_mesh().unwrap())
        .unwrap();
    subdivider.refined_vertex_count()
}

fn tearing(c: &mut Criterion) {
    let sim = settled();
    let row = (N / 2 * N) as usize;
    let edge = sim.positions()[row];
    let across = sim.positions()[row + 1] - edge;
    let one = Cut::Segment {
        start: edge - across,
        end: edge + 0.3 * across,
        radius: 0.3 * SPACING,
    };
    let whole = Cut::Plane {
        point: sim.positions()[row + 7],
        normal: Vec3::Y,
    };
    {
        let mut check = sim.clone();
        assert_eq!(check.tear(&[one]).unwrap().len(), 1, "one split");
    }
    let render = subdivider(&sim);
    let mut group = c.benchmark_group("tear_grid64");
    for (name, cut) in [("one split", one), ("row cut", whole)] {
        group.bench_function(name, |b| {
            b.iter_batched(
                || (sim.clone(), render.clone()),
                |sim| black_box(tear_and_render(sim, cut)),
                BatchSize::LargeInput,
            )
        });
    }
    // The two halves of one split apart: the solver's rebuild, and the render stencils.
    group.bench_function("one split, solver only", |b| {
        b.iter_batched(
            || sim.clone(),
            |mut sim| black_box(sim.tear(&[one]).unwrap().len()),
            BatchSize::LargeInput,
        )
    });
    let torn = {
        let mut torn = sim.clone();
        torn.tear(&[one]).unwrap();
        torn.model().control_mesh().unwrap()
    };
    group.bench_function("one split, render stencils only", |b| {
        b.iter_batched(
            || render.clone(),
            |mut subdivider| black_box(subdivider.follow(&torn).unwrap()),
            BatchSize::LargeInput,
        )
    });
    // A frame of the cloth before and after the row cut: a torn grid keeps the grid's colouring
    // and storage order, so its step costs what the grid's does.
    let mut cut = sim.clone();
    cut.tear(&[whole]).unwrap();
    for (name, cloth) in [("frame, whole", &sim), ("frame, cut in two", &cut)] {
        group.bench_function(name, |b| {
            b.iter_batched(
                || cloth.clone(),
                |mut cloth| cloth.step(1.0 / 60.0).unwrap(),
                BatchSize::LargeInput,
            )
        });
    }
    group.bench_function("strain check", |b| {
        let mut sim = sim.clone();
        b.iter(|| black_box(sim.tear(&[]).unwrap().len()))
    });
    group.finish();
}

criterion_group!(benches, tearing);
criterion_main!(benches);
