//! Stepping (in [`ClothSystems::Step`](super::ClothSystems::Step)): every running cloth advanced
//! by one step on the compute task pool, in parallel across cloths, then the cloths that meet
//! each other one after the other.

use std::time::Duration;

use bevy::ecs::prelude::*;
use bevy::log::warn;
use bevy::math::Vec3;
use bevy::platform::time::Instant;
use bevy::tasks::{ComputeTaskPool, TaskPool};
use bevy::time::Time;

use super::inputs::{ColliderSnapshot, WindSnapshot};
use crate::components::{ClothConfig, ClothInvalid, ClothPushesBodies, ClothState};
use crate::lod::LodLevel;
use crate::sim::{Environment, OtherCloth, Spread};

/// A Bevy task pool lends one of its threads to a step: `helper` runs as a task on the pool, `main`
/// on the calling thread (which, if it is one of the pool's, runs `helper` itself while it waits,
/// should no other thread have taken it).
impl Spread for TaskPool {
    fn join(&self, helper: &(dyn Fn() + Sync), main: &mut dyn FnMut()) {
        self.scope(|s| {
            s.spawn(async move { helper() });
            main();
        });
    }
}

/// Advances every running cloth by one step of the schedule's clock: the cloths that meet no other
/// cloth in parallel (a large cloth's XPBD colours on two threads where the compute pool has
/// more threads than there are cloths), then those that do ([`ClothConfig::cloth_layers`]) one
/// after the other in the order of their entities, each among the others' motion.
pub(crate) fn step_cloths(
    time: Res<Time>,
    colliders: Res<ColliderSnapshot>,
    wind: Res<WindSnapshot>,
    mut cloths: Query<
        (
            Entity,
            &ClothConfig,
            &mut ClothState,
            Has<ClothPushesBodies>,
        ),
        Without<ClothInvalid>,
    >,
    mut layered: Local<LayeredCloths>,
) {
    let dt = time.delta_secs();
    if dt <= 0.0 {
        return;
    }
    layered.gather(&cloths);
    let env = |config: &ClothConfig, two_way: bool| Environment {
        colliders: &colliders.0,
        collision_mask: config.collision_mask,
        wind: wind.0.as_ref(),
        two_way,
        cloths: &[],
    };
    // Threads left over after one per cloth go to large cloths' colours; with as many cloths as
    // threads, a helper spinning through another cloth's step would only keep a cloth waiting.
    let solo = cloths.iter().count() - layered.cloths.len();
    let pool = ComputeTaskPool::try_get();
    let spread = pool
        .filter(|pool| pool.thread_num() > solo)
        .map(|pool| -> &dyn Spread { &**pool });
    let layered_entities = &layered.cloths;
    cloths
        .par_iter_mut()
        .for_each(|(entity, config, mut state, two_way)| {
            if state.failure.is_none()
                && layered_entities
                    .binary_search_by_key(&entity, |c| c.entity)
                    .is_err()
            {
                step_one(&mut state, dt, &env(config, two_way), spread);
            }
        });
    // One at a time: the pool's threads are all free for each.
    let spread = pool
        .filter(|pool| pool.thread_num() > 1)
        .map(|pool| -> &dyn Spread { &**pool });
    for i in 0..layered.cloths.len() {
        let Ok((_, config, mut state, two_way)) = cloths.get_mut(layered.cloths[i].entity) else {
            continue;
        };
        if state.failure.is_some() {
            continue;
        }
        let me = &layered.cloths[i];
        let others: Vec<OtherCloth> = layered
            .cloths
            .iter()
            .enumerate()
            .filter(|(j, other)| *j != i && other.layers & me.layers != 0)
            .map(|(_, other)| OtherCloth {
                triangles: &other.triangles,
                start: &other.start,
                end: &other.end,
                thickness: other.thickness,
                friction: other.friction,
            })
            .collect();
        let env = Environment {
            cloths: &others,
            ..env(config, two_way)
        };
        step_one(&mut state, dt, &env, spread);
        // Those stepping later meet where this one went.
        let me = &mut layered.cloths[i];
        me.end.clear();
        me.end.extend_from_slice(state.sim.positions());
    }
}

/// One cloth's step, then its tears (its cuts, and with tearing on its overstretched springs); a
/// failed step stops the cloth, a tear that cannot be made leaves it untorn.
fn step_one(state: &mut ClothState, dt: f32, env: &Environment, spread: Option<&dyn Spread>) {
    // A frozen cloth's step was its carrying; a culled one takes none.
    match state.lod.level {
        LodLevel::Frozen => return,
        LodLevel::Culled => {
            state.step_time = Duration::ZERO;
            return;
        }
        LodLevel::Full | LodLevel::Reduced | LodLevel::Coarse => {}
    }
    let started = Instant::now();
    let stepped = match spread {
        Some(spread) => state.sim.step_in_parallel(dt, env, spread),
        None => state.sim.step_in(dt, env),
    };
    if stepped.is_ok() && (state.sim.settings().tearing.enabled || !state.cuts.is_empty()) {
        match state.sim.tear(&state.cuts) {
            Ok(splits) => state.splits.extend(splits),
            Err(e) => warn!("a cloth could not tear and runs on untorn: {e}"),
        }
        state.cuts.clear();
    }
    state.step_time = started.elapsed();
    state.failure = stepped.err();
    let level = state.lod.level;
    let ms = state.step_time.as_secs_f32() * 1e3;
    state.lod.measured(level, state.sim.detail(), ms);
    state.lod.bound = None;
}

/// The cloths that meet another cloth this step ([`ClothConfig::cloth_layers`]), in the order of
/// their entities, with what each one's step needs of the others (their buffers kept between
/// steps).
#[derive(Default)]
pub(crate) struct LayeredCloths {
    cloths: Vec<LayeredCloth>,
    /// Scratch: the candidates (entity, layers) of this step.
    candidates: Vec<(Entity, u32)>,
}

/// One cloth as the others see it during a step.
struct LayeredCloth {
    entity: Entity,
    layers: u32,
    triangles: Vec<u32>,
    start: Vec<Vec3>,
    /// Where it is, until it has stepped; then where it went.
    end: Vec<Vec3>,
    thickness: f32,
    friction: f32,
}

impl LayeredCloths {
    /// Finds the running cloths whose layers meet another's and takes their state at the start of
    /// a step.
    #[allow(clippy::type_complexity)]
    fn gather(
        &mut self,
        cloths: &Query<
            (
                Entity,
                &ClothConfig,
                &mut ClothState,
                Has<ClothPushesBodies>,
            ),
            Without<ClothInvalid>,
        >,
    ) {
        self.candidates.clear();
        self.candidates.extend(
            cloths
                .iter()
                .filter(|(_, config, state, _)| config.cloth_layers != 0 && state.failure.is_none())
                .map(|(entity, config, _, _)| (entity, config.cloth_layers)),
        );
        self.candidates.sort_unstable_by_key(|c| c.0);
        let candidates = &self.candidates;
        let meets = |i: usize| {
            candidates
                .iter()
                .enumerate()
                .any(|(j, c)| j != i && c.1 & candidates[i].1 != 0)
        };
        let mut kept = 0;
        for (i, &(entity, layers)) in candidates.iter().enumerate() {
            if !meets(i) {
                continue;
            }
            let Ok((_, config, state, _)) = cloths.get(entity) else {
                continue;
            };
            if kept == self.cloths.len() {
                self.cloths.push(LayeredCloth {
                    entity,
                    layers,
                    triangles: Vec::new(),
                    start: Vec::new(),
                    end: Vec::new(),
                    thickness: 0.0,
                    friction: 0.0,
                });
            }
            let c = &mut self.cloths[kept];
            kept += 1;
            let sim = &state.sim;
            c.entity = entity;
            c.layers = layers;
            // The same cloth's triangles do not change from step to step.
            if c.triangles != sim.model().triangles {
                c.triangles.clear();
                c.triangles.extend_from_slice(&sim.model().triangles);
            }
            c.start.clear();
            c.start.extend_from_slice(sim.positions());
            c.end.clear();
            c.end.extend_from_slice(sim.positions());
            let layer = &config.solver.self_collision;
            (c.thickness, c.friction) = (layer.thickness, layer.friction);
        }
        self.cloths.truncate(kept);
    }
}
