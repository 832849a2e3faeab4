//! The test and benchmark harness (feature `harness`; the crate's own tests, benchmarks and
//! `cloth_cli` turn it on): a [`headless_app`] that steps one fixed step per update, the
//! skinned [`character`] cape, the ECS edit [`fuzz`]er, the [`stress`] suite, the accuracy
//! [`scenes`] and their f64 [`reference`](mod@reference) solution, and state fingerprints for
//! bit-for-bit regression checks ([`stress::state_hash`], [`scene_state_hash`]).
//! None of it is needed to simulate cloth in a game.

pub use crate::scene::character;
pub mod fuzz;
pub mod reference;
pub mod scenes;
pub mod stress;

use bevy::app::App;
use bevy::time::{Fixed, Time};

use crate::components::{ClothInvalid, ClothState};
use crate::error::ClothError;
use crate::plugin::validate_fixed_step;
#[cfg(doc)]
use crate::plugin::{MAX_FIXED_STEP, MIN_FIXED_STEP};

/// A terrain as a triangle list: `n` × `n` vertices over a `size` × `size` m square centred on
/// the origin in the XZ plane, vertex `(i, j)` at `x = -size/2 + i·step`, `z = -size/2 + j·step`
/// and height `height(x, z)`, stored at index `j·n + i`; each square of four is split into two
/// triangles along its diagonal from vertex `(i + 1, j)` to `(i, j + 1)`, wound to face +Y.
pub fn heightfield_mesh(
    n: u32,
    size: f32,
    height: impl Fn(f32, f32) -> f32,
) -> (Vec<glam::Vec3>, Vec<[u32; 3]>) {
    let step = size / n.saturating_sub(1).max(1) as f32;
    let vertices = (0..n * n)
        .map(|k| {
            let (x, z) = (
                -0.5 * size + step * (k % n) as f32,
                -0.5 * size + step * (k / n) as f32,
            );
            glam::Vec3::new(x, height(x, z), z)
        })
        .collect();
    let mut triangles = Vec::new();
    for j in 0..n.saturating_sub(1) {
        for i in 0..n - 1 {
            let k = j * n + i;
            triangles.push([k, k + n, k + 1]);
            triangles.push([k + 1, k + n, k + n + 1]);
        }
    }
    (vertices, triangles)
}

/// Sets `app` up for a machine with few cores: every schedule on Bevy's single-threaded executor
/// (systems one after another on the calling thread), and Bevy's static-scene transform tracking
/// off. On a machine with few cores, the multi-threaded executor's handing of each system to a
/// worker thread and back can cost more than a small cloth's whole step, and the tracking
/// (`StaticTransformOptimizations`) hands a task to the compute pool and back every frame, which
/// only pays in scenes with many still entities under parents. A
/// query's parallel iteration still uses the compute pool where it has more than one thread.
pub fn use_single_threaded_frame(app: &mut App) {
    let mut schedules = app
        .world_mut()
        .resource_mut::<bevy::ecs::schedule::Schedules>();
    for (_, schedule) in schedules.iter_mut() {
        schedule.set_executor(bevy::ecs::schedule::SingleThreadedExecutor::new());
    }
    app.insert_resource(bevy::transform::StaticTransformOptimizations::Disabled);
}

/// [`try_headless_app`] for a step known to be valid.
///
/// # Panics
/// If `dt` is outside [`MIN_FIXED_STEP`]`..=`[`MAX_FIXED_STEP`] (NaN included).
pub fn headless_app(dt: f32) -> App {
    try_headless_app(dt).unwrap_or_else(|e| panic!("headless_app: {e}"))
}

/// A windowless app ready for cloths: `MinimalPlugins`, transforms, assets, meshes,
/// [`ClothPlugin`](crate::ClothPlugin) and [`ScenePlugin`](crate::scene::ScenePlugin), with a fixed step of `dt` seconds and manual time so that every `update()` runs
/// exactly one fixed step. It has already been updated once (Bevy's first update has zero delta).
/// A cloth spawned now is built at the end of the next `update()` (after that update's fixed step),
/// so it starts at rest and steps from the update after. A step outside
/// [`MIN_FIXED_STEP`]`..=`[`MAX_FIXED_STEP`] is an error (see [`validate_fixed_step`]).
///
pub fn try_headless_app(dt: f32) -> Result<App, ClothError> {
    try_headless_app_with(dt, ())
}

/// [`try_headless_app`] with `plugins` added before the app is finished (a glTF loader, say).
pub fn try_headless_app_with<M>(
    dt: f32,
    plugins: impl bevy::app::Plugins<M>,
) -> Result<App, ClothError> {
    validate_fixed_step(dt)?;
    let mut app = App::new();
    app.add_plugins((
        bevy::MinimalPlugins,
        bevy::transform::TransformPlugin,
        bevy::asset::AssetPlugin::default(),
        bevy::mesh::MeshPlugin,
        crate::ClothPlugin::default(),
        crate::scene::ScenePlugin,
    ))
    .add_plugins(plugins)
    .insert_resource(Time::<Fixed>::from_seconds(dt as f64))
    .insert_resource(bevy::time::TimeUpdateStrategy::FixedTimesteps(1));
    app.finish();
    app.cleanup();
    app.update();
    Ok(app)
}

/// Loads the RON scene at `path` into a [`headless_app`], runs `frames` fixed steps and returns
/// the [`state_hash`](stress::state_hash) of its cloth (of several copies, their hashes folded
/// in order): a bit-for-bit fingerprint of the whole plugin path (pins, colliders, wind,
/// scheduling) for regression checks.
pub fn scene_state_hash(path: &std::path::Path, frames: u32) -> Result<u64, ClothError> {
    let scene = crate::scene::ClothScene::load(path)?;
    let mut app = try_headless_app(scene.dt)?;
    let entities = scene.spawn_copies(app.world_mut())?;
    for _ in 0..=frames {
        app.update();
    }
    let mut folded = 0u64;
    for entity in entities {
        if let Some(ClothInvalid(e)) = app.world().get::<ClothInvalid>(entity) {
            return Err(e.clone());
        }
        let state =
            app.world()
                .get::<ClothState>(entity)
                .ok_or_else(|| ClothError::InvalidMesh {
                    what: format!("{}: the cloth was not built", path.display()),
                })?;
        folded = folded.rotate_left(17) ^ stress::state_hash(state.sim());
    }
    Ok(folded)
}
