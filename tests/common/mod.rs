//! Helpers the integration tests share: a headless app that runs one fixed step per update, and
//! spawning, stepping and reading cloths in it.
#![allow(dead_code)]

use bevy::prelude::*;
use bevy_cloth::prelude::*;
use bevy_cloth::sim::ClothSim;

/// The fixed step of [`app`], s.
pub const DT: f32 = 1.0 / 60.0;

/// A headless app at 60 Hz in which every `update()` runs one fixed step.
pub fn app() -> App {
    bevy_cloth::harness::headless_app(DT)
}

/// Runs `steps` updates of one fixed step each. (Several steps per update would be clamped by
/// `Time<Virtual>`'s 250 ms maximum frame time.)
pub fn run(app: &mut App, steps: u32) {
    for _ in 0..steps {
        app.update();
    }
}

/// Spawns and builds a cloth; it starts at rest (the update's fixed step runs before the build).
pub fn spawn(app: &mut App, bundle: impl Bundle) -> Entity {
    let e = app.world_mut().spawn(bundle).id();
    app.update();
    e
}

/// [`spawn`] for a cloth that must be valid.
pub fn spawn_valid(app: &mut App, bundle: impl Bundle) -> Entity {
    let e = spawn(app, bundle);
    assert!(
        app.world().get::<ClothInvalid>(e).is_none(),
        "the cloth is valid"
    );
    e
}

/// The state of cloth `e`, which has been built.
pub fn state(app: &App, e: Entity) -> &ClothState {
    app.world()
        .get::<ClothState>(e)
        .expect("cloth has been built")
}

/// The simulation of cloth `e`, which has been built.
pub fn sim(app: &App, e: Entity) -> &ClothSim {
    state(app, e).sim()
}

/// The mean particle position of cloth `e`.
pub fn centre_of_mass(app: &App, e: Entity) -> Vec3 {
    let p = state(app, e).positions();
    p.iter().sum::<Vec3>() / p.len() as f32
}
