//! Determinism: the same scene gives bit-identical positions whether it runs alone or beside
//! unrelated cloths and colliders, and whether its steps run on Bevy's task-pool threads (several
//! cloths in parallel, or one large cloth's colours on two threads) or in a plain loop on the
//! test's thread.

use bevy::prelude::*;
use bevy::tasks::{ComputeTaskPool, TaskPoolBuilder};
use bevy_cloth::prelude::*;
use bevy_cloth::sim::{ClothModel, ClothSim, Environment, OtherCloth};

mod common;
use common::*;

const STEPS: u32 = 120;

/// A headless app whose compute pool has three threads (every test of this file sets it up the
/// same way, whichever runs first): several cloths step in parallel, and a single large cloth
/// gets a second thread for its colours.
fn app() -> App {
    ComputeTaskPool::get_or_init(|| TaskPoolBuilder::new().num_threads(3).build());
    bevy_cloth::harness::headless_app(1.0 / 60.0)
}

fn bits(p: &[Vec3]) -> Vec<[u32; 3]> {
    p.iter().map(|v| v.to_array().map(f32::to_bits)).collect()
}

/// A 20×20 cloth pinned at two corners at `x`, falling onto a sphere below its middle.
fn draped_at(app: &mut App, x: f32) -> Entity {
    app.world_mut().spawn((
        ClothCollider::sphere(0.25),
        Transform::from_xyz(x, 1.3, 0.0),
    ));
    app.world_mut()
        .spawn((
            Cloth::grid(GridSpec::new(20, 20, 0.05)),
            ClothPins::new([0, 19]),
            Transform::from_xyz(x, 1.8, 0.0),
        ))
        .id()
}

fn gusty_wind() -> Wind {
    Wind {
        velocity: Vec3::new(3.0, 0.0, 1.0),
        gusts: Some(Gusts {
            seed: 7,
            ..default()
        }),
        ..default()
    }
}

fn final_positions(extra_cloths: u32) -> Vec<[u32; 3]> {
    let mut app = app();
    app.insert_resource(gusty_wind());
    // Unrelated cloths (with their own spheres) before and after the one we watch.
    for k in 0..extra_cloths / 2 {
        draped_at(&mut app, -10.0 * (k + 1) as f32);
    }
    let watched = draped_at(&mut app, 0.0);
    for k in extra_cloths / 2..extra_cloths {
        draped_at(&mut app, 10.0 * (k + 1) as f32);
    }
    run(&mut app, STEPS);
    bits(app.world().get::<ClothState>(watched).unwrap().positions())
}

#[test]
fn unrelated_cloths_and_colliders_change_nothing() {
    let alone = final_positions(0);
    assert_eq!(alone, final_positions(0), "two runs differ");
    assert_eq!(
        alone,
        final_positions(5),
        "unrelated cloths changed the result"
    );
}

#[test]
fn task_pool_threads_match_a_plain_loop() {
    // Four identical cloths stepped in parallel by the plugin...
    matches_a_plain_loop(4, 16, STEPS);
}

#[test]
fn one_large_cloth_on_two_threads_matches_a_plain_loop() {
    // 64×64: 23,938 springs, which the plugin shares between two of the pool's threads.
    matches_a_plain_loop(1, 64, 40);
    assert_eq!(ComputeTaskPool::get().thread_num(), 3);
}

/// `copies` identical `n`×`n` cloths stepped `steps` times by the plugin end bit for bit where the
/// same cloth stepped here, one step per frame, does.
fn matches_a_plain_loop(copies: usize, n: u32, steps: u32) {
    let mut app = app();
    let spec = GridSpec::new(n, n, 0.8 / n as f32);
    let transform = Transform::from_xyz(0.0, 2.0, 0.0);
    let cloths: Vec<Entity> = (0..copies)
        .map(|_| {
            app.world_mut()
                .spawn((Cloth::grid(spec), ClothPins::new([0, n - 1]), transform))
                .id()
        })
        .collect();
    app.update();
    run(&mut app, steps);
    let dt = app.world().resource::<Time<Fixed>>().delta_secs();
    // ...and the same cloth stepped here, one step per frame.
    let model = ClothModel::grid(&spec).unwrap();
    let mut sim = ClothSim::new(model, SolverSettings::default(), |p| {
        transform.transform_point(p)
    })
    .unwrap();
    let pins = [0u32, n - 1].map(|i| (i, sim.positions()[i as usize]));
    sim.set_pins(pins).unwrap();
    for _ in 0..steps {
        sim.step_in(dt, &Environment::default()).unwrap();
    }
    let expected = bits(sim.positions());
    for e in cloths {
        let state = app.world().get::<ClothState>(e).unwrap();
        assert_eq!(state.steps(), steps as u64);
        assert_eq!(bits(state.positions()), expected);
    }
}

#[test]
fn cloths_that_meet_match_a_plain_loop_in_entity_order() {
    // Two cloths on one layer, the second dropped across the first, which hangs from two corners:
    // the plugin steps them one after the other on the pool's threads...
    let mut app = app();
    let spec = GridSpec::new(12, 12, 0.05);
    let transforms = [
        Transform::from_xyz(0.0, 1.0, 0.0),
        Transform::from_xyz(0.1, 1.15, 0.05).with_rotation(Quat::from_rotation_y(0.8)),
    ];
    let config = ClothConfig {
        cloth_layers: 1,
        ..default()
    };
    let cloths = transforms.map(|t| {
        app.world_mut()
            .spawn((Cloth::grid(spec), config, ClothPins::new([0, 11]), t))
            .id()
    });
    app.update();
    let steps = 60;
    run(&mut app, steps);
    let dt = app.world().resource::<Time<Fixed>>().delta_secs();
    // ...and here, in the order of their entities, each among the other: the later one where it
    // is, the earlier one as it went.
    let mut sims = transforms.map(|t| {
        let model = ClothModel::grid(&spec).unwrap();
        // Placed as the plugin places it, through the global transform.
        let g = GlobalTransform::from(t);
        let mut sim =
            ClothSim::new(model, SolverSettings::default(), |p| g.transform_point(p)).unwrap();
        let pins = [0u32, 11].map(|i| (i, sim.positions()[i as usize]));
        sim.set_pins(pins).unwrap();
        sim
    });
    // The plugin steps the lower entity first.
    let (a, b) = if cloths[0] < cloths[1] {
        (0, 1)
    } else {
        (1, 0)
    };
    fn other<'a>(sim: &'a ClothSim, start: &'a [Vec3], end: &'a [Vec3]) -> OtherCloth<'a> {
        OtherCloth {
            triangles: &sim.model().triangles,
            start,
            end,
            thickness: SelfCollision::default().thickness,
            friction: SelfCollision::default().friction,
        }
    }
    for _ in 0..steps {
        let later = sims[b].clone();
        let others = [other(&later, later.positions(), later.positions())];
        let env = Environment {
            cloths: &others,
            ..default()
        };
        let start = sims[a].positions().to_vec();
        sims[a].step_in(dt, &env).unwrap();
        let earlier = sims[a].clone();
        let others = [other(&earlier, &start, earlier.positions())];
        let env = Environment {
            cloths: &others,
            ..default()
        };
        sims[b].step_in(dt, &env).unwrap();
    }
    for (e, sim) in cloths.iter().zip(&sims) {
        let state = app.world().get::<ClothState>(*e).unwrap();
        assert_eq!(bits(state.positions()), bits(sim.positions()));
    }
    // They met: the cloths were pushed apart at some point (the upper one rests on the lower).
    assert!(sims[b].cloth_contact_searches() > 0);
}
