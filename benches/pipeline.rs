//! The whole per-frame pipeline of the source paper's scene (`assets/scenes/drape.ron`, the
//! `drape` example: a 32×32 cloth pinned at its corners above a sphere, and the floor), headless:
//! the time of one `App::update()` that runs exactly one 1/60 s fixed step — pins, collider and
//! wind gathering, the XPBD solver (20 substeps) with sphere and floor collisions, Catmull-Clark
//! stencils (levels 0, 1, 2 and each vertex rule), normals, and the in-place mesh write in
//! `PostUpdate`, plus Bevy's scheduling. No renderer: nothing is drawn or uploaded to a GPU.
//! The `simulated` case refines the cloth itself once (`SubdivisionTarget::Simulation`, level 1:
//! 63×63 particles) instead of its rendered surface.
//!
//! `cargo bench --bench pipeline` (about a minute). The timed frames are always the `WINDOW`
//! frames after the first `SETTLE_FRAMES + 1` of a fresh scene (about 0.5 s to 4.5 s after the
//! cloth is let go: it lands on the sphere, drapes and swings), whatever the number of iterations
//! criterion asks for: a new app is built (untimed) every `WINDOW` frames. So every case times the
//! same motion, and a cloth that comes to rest (and might be put to sleep) is never timed.

use std::time::{Duration, Instant};

use bevy::prelude::*;
use bevy_cloth::harness::headless_app;
use bevy_cloth::prelude::*;
use bevy_cloth::scene::ClothScene;
use criterion::{Criterion, criterion_group, criterion_main};

/// The paper's scene, shared with the `drape` example.
const PAPER_SCENE: &str = include_str!("../assets/scenes/drape.ron");

/// Frames simulated before timing: the cloth reaches the sphere after about 10.
const SETTLE_FRAMES: u32 = 30;

/// Frames timed on one app before a fresh one is built.
const WINDOW: u32 = 240;

/// A headless app with the paper's scene, its cloth subdivided at `level` with `rule` for
/// `target`, after [`SETTLE_FRAMES`] frames (and one more that checks the app).
fn paper_scene(level: u32, rule: VertexRule, target: SubdivisionTarget) -> App {
    let scene = ClothScene::from_ron(PAPER_SCENE).expect("the bundled scene is valid");
    let mut app = headless_app(scene.dt);
    let cloth = scene
        .spawn(app.world_mut())
        .expect("the bundled scene spawns");
    app.world_mut().entity_mut(cloth).insert(ClothSubdivision {
        level,
        rule,
        target,
        ..default()
    });
    for _ in 0..SETTLE_FRAMES {
        app.update();
    }
    // Every update runs exactly one fixed step, and the cloth is running, not stopped.
    let steps = |app: &App| {
        assert!(app.world().get::<ClothInvalid>(cloth).is_none());
        app.world()
            .get::<ClothState>(cloth)
            .expect("the cloth is built")
            .steps()
    };
    let before = steps(&app);
    app.update();
    assert_eq!(steps(&app), before + 1);
    app
}

fn pipeline(c: &mut Criterion) {
    let mut group = c.benchmark_group("paper_scene_frame");
    group
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3))
        .sample_size(50);
    let render = SubdivisionTarget::Render;
    let mut cases = vec![(0, VertexRule::Original, render)];
    for level in [1, 2] {
        cases.extend(VertexRule::ALL.map(|rule| (level, rule, render)));
    }
    cases.push((1, VertexRule::Original, SubdivisionTarget::Simulation));
    for (level, rule, target) in cases {
        let mut app = paper_scene(level, rule, target);
        let name = match (level, target) {
            (0, _) => "level_0".to_string(),
            (_, SubdivisionTarget::Simulation) => format!("level_{level}_{rule:?}_simulated"),
            _ => format!("level_{level}_{rule:?}"),
        };
        let mut frames = 0;
        group.bench_function(name, |b| {
            b.iter_custom(|iters| {
                let mut timed = Duration::ZERO;
                for _ in 0..iters {
                    if frames == WINDOW {
                        app = paper_scene(level, rule, target);
                        frames = 0;
                    }
                    let start = Instant::now();
                    app.update();
                    timed += start.elapsed();
                    frames += 1;
                }
                timed
            })
        });
    }
    group.finish();
}

criterion_group!(benches, pipeline);
criterion_main!(benches);
