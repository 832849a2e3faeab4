//! Times bevy_silk 0.10 on the cloth of `assets/scenes/silk_compare64.ron`: a 1 m square of 64×64
//! particles, lying flat at first, hanging from the two corners of its first row, at 60 Hz, with
//! bevy_silk's default settings. Prints one JSON line: the median milliseconds of the whole
//! headless App frame (bevy_silk's step, its normals and its mesh write), of the step alone (the
//! calls bevy_silk's update system makes, on the same cloth, without the ECS), and the median
//! strain of the grid's row and column edges after the run, and of all its sticks.
//!
//! `cargo run --release -- [FRAMES]` (600 timed frames by default, after 10 untimed ones).

use std::time::{Duration, Instant};

use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_silk::components::cloth::Cloth;
use bevy_silk::prelude::*;

const N: usize = 64;
const SIDE: f32 = 1.0;
const DT: f64 = 1.0 / 60.0;
const WARM_UP: usize = 10;

fn main() {
    let frames: usize = std::env::args()
        .nth(1)
        .map_or(600, |a| a.parse().expect("FRAMES is a whole number"));
    let spacing = SIDE / (N - 1) as f32;

    let mut app = App::new();
    app.add_plugins((MinimalPlugins, TransformPlugin, AssetPlugin::default()))
        .init_asset::<Mesh>()
        .add_plugins(ClothPlugin)
        .insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(
            DT,
        )));
    let mesh = rectangle_mesh((N, N), (Vec3::X * spacing, Vec3::Z * spacing), Vec3::Y);
    let handle = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
    let cloth = app
        .world_mut()
        .spawn((
            Mesh3d(handle),
            ClothBuilder::new().with_pinned_vertex_ids([0, N - 1].into_iter()),
            Transform::from_xyz(-SIDE / 2.0, 2.0, -SIDE / 2.0),
        ))
        .id();

    for _ in 0..WARM_UP {
        app.update();
    }
    let mut frame_ms = Vec::with_capacity(frames);
    for _ in 0..frames {
        let t = Instant::now();
        app.update();
        frame_ms.push(t.elapsed().as_secs_f64() * 1e3);
    }
    let built = app.world().get::<Cloth>(cloth).expect("cloth built");
    let strain = median_strain(&built.current_point_positions, spacing);
    let stick_strain = median_stick_strain(built);

    // The step alone, from the state the App frames ended in: the same calls as bevy_silk's
    // update system, with its default config and no wind.
    let config = ClothConfig::default();
    let transform = *app
        .world()
        .get::<GlobalTransform>(cloth)
        .expect("transform");
    let mut alone = app
        .world()
        .get::<Cloth>(cloth)
        .expect("cloth built")
        .clone();
    let mut step_ms = Vec::with_capacity(frames);
    for _ in 0..frames {
        let t = Instant::now();
        alone.update_points(
            1.0 - config.friction.clamp(0.0, 1.0),
            config.smoothed_acceleration(config.gravity, DT as f32),
        );
        alone.update_anchored_points(&transform, |_| None);
        alone.update_sticks(config.sticks_computation_depth);
        step_ms.push(t.elapsed().as_secs_f64() * 1e3);
    }
    std::hint::black_box(&alone);

    println!(
        "{{\"crate\":\"bevy_silk 0.10.0\",\"frames\":{frames},\"app_frame_median_ms\":{:.4},\"step_median_ms\":{:.4},\"median_strain\":{:.6},\"median_stick_strain\":{:.6}}}",
        median(&mut frame_ms),
        median(&mut step_ms),
        strain,
        stick_strain
    );
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Median of `|length / rest - 1|` over all of the cloth's sticks, each against its own rest
/// length (with bevy_silk's default stick generation, the quads' edges: the grid's rows and
/// columns).
fn median_stick_strain(cloth: &Cloth) -> f64 {
    let sticks = cloth
        .stick_lengths
        .iter()
        .map(|(&[a, b], &rest)| (a, b, rest));
    median_edge_strain(&cloth.current_point_positions, sticks)
}

/// Median of `|length / rest - 1|` over the row and column edges of the `N × N` grid.
fn median_strain(x: &[Vec3], spacing: f32) -> f64 {
    let rows = (0..N).flat_map(|j| (0..N - 1).map(move |i| (j * N + i, j * N + i + 1)));
    let columns = (0..N - 1).flat_map(|j| (0..N).map(move |i| (j * N + i, (j + 1) * N + i)));
    let edges = rows.chain(columns).map(|(a, b)| (a, b, spacing));
    median_edge_strain(x, edges)
}

/// Median of `|length / rest - 1|` over `edges` (two point indices and a rest length each).
fn median_edge_strain(x: &[Vec3], edges: impl Iterator<Item = (usize, usize, f32)>) -> f64 {
    let mut strain: Vec<f64> = edges
        .map(|(a, b, rest)| f64::from((x[a].distance(x[b]) / rest - 1.0).abs()))
        .collect();
    median(&mut strain)
}
