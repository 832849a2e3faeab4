//! `ClothScene::from_ron` on arbitrary text. A scene that parses has passed validation, so
//! everything built from it must build: its cloth model, its colliders, its entities and the
//! simulation; and (when small enough to be quick) one step must not panic (diverging is fine).
#![no_main]

use bevy::ecs::world::World;
use bevy_cloth::scene::ClothScene;
use bevy_cloth::sim::ClothSim;
use libfuzzer_sys::fuzz_target;

/// Largest cloth the target builds, in particles (validation accepts far larger grids).
const MAX_PARTICLES: u64 = 4096;
/// Largest particles × substeps × iterations the target steps.
const MAX_WORK: u64 = 200_000;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(scene) = ClothScene::from_ron(text) else {
        return;
    };
    // The step must make a valid Bevy fixed clock (`Time::<Fixed>::from_seconds` panics on a
    // step that is zero in nanoseconds or overflows a `Duration`).
    let step = std::time::Duration::try_from_secs_f64(scene.dt as f64);
    assert!(step.is_ok_and(|d| !d.is_zero()), "dt {}", scene.dt);
    for c in &scene.colliders {
        c.component().expect("a validated collider builds");
    }
    let bevy_cloth::scene::SceneCloth::Grid(spec) = &scene.cloth;
    let particles = spec.nx as u64 * spec.ny as u64;
    if particles > MAX_PARTICLES {
        return;
    }
    let mut world = World::new();
    scene.spawn(&mut world).expect("a validated scene spawns");
    let model = scene.model().expect("a validated scene builds its model");
    let transform = scene.transform();
    let mut sim = ClothSim::new(model, scene.solver, |p| transform.transform_point(p))
        .expect("a validated scene builds its simulation");
    let pins: Vec<_> = scene
        .pins
        .iter()
        .map(|&p| (p, sim.positions()[p as usize]))
        .collect();
    sim.set_pins(pins).expect("validated pins");
    let work =
        particles * sim.substeps_for(scene.dt) as u64 * scene.solver.iterations.max(1) as u64;
    if work <= MAX_WORK {
        let _ = sim.step(scene.dt);
    }
});
