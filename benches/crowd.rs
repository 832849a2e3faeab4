//! The crowd of `assets/scenes/crowd/crowd.ron` through the whole plugin in a headless App, as
//! `cloth_cli bench` runs it: N = 1, 10 and 100 walking characters in 500-particle capes (and the
//! scene's three flags), one App frame (one fixed step) each, at full quality and with the
//! scene's levels of detail for its viewer.

use bevy::app::App;
use bevy_cloth::scene::ClothScene;
use criterion::{Criterion, criterion_group, criterion_main};

/// The crowd with `n` characters, warmed up for 10 frames.
fn crowd(n: u32, levels: bool) -> App {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/scenes/crowd/crowd.ron");
    let mut scene = ClothScene::load(path).unwrap();
    scene.copies.count = n;
    if !levels {
        scene.lod = None;
        scene.viewer = None;
    }
    let mut app = bevy_cloth::harness::headless_app(scene.dt);
    scene.spawn_copies(app.world_mut()).unwrap();
    for _ in 0..10 {
        app.update();
    }
    app
}

fn crowds(c: &mut Criterion) {
    let mut group = c.benchmark_group("crowd");
    group.sample_size(10);
    for n in [1, 10, 100] {
        for (levels, name) in [(false, "full quality"), (true, "levels of detail")] {
            let mut app = crowd(n, levels);
            group.bench_function(format!("{n} characters, {name}"), |b| {
                b.iter(|| app.update())
            });
        }
    }
    group.finish();
}

criterion_group!(benches, crowds);
criterion_main!(benches);
