//! [`ClothPlugin`]: scheduling, the [`ClothSystems`] sets and the thin systems that move data between
//! the ECS and [`crate::sim`]. Systems gather inputs into plain data, call the solver and write
//! meshes; they hold no formulas.

use bevy::app::{App, First, FixedUpdate, Plugin, PostUpdate};
use bevy::asset::{AssetEventSystems, Assets, Handle};
use bevy::ecs::intern::Interned;
use bevy::ecs::prelude::*;
use bevy::ecs::schedule::ScheduleLabel;
use bevy::log::{error, warn};
use bevy::math::Vec3;
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::mesh::{Mesh, Mesh3d};
use bevy::tasks::{ComputeTaskPool, TaskPool};
use bevy::time::{Fixed, Time};
use bevy::transform::TransformSystems;
use bevy::transform::components::GlobalTransform;
use bevy::transform::helper::TransformHelper;

use crate::components::*;
use crate::components::{RenderSubdivision, mapped_particle};
use crate::error::{ClothError, count_in};
use crate::render;
use crate::sim::contact::Pose;
use crate::sim::{
    ClothModel, ClothSim, Collider, Environment, GridNormals, OtherCloth, PlacedWindZone,
    SolverSettings, Spread, WindField, compute_normals,
};
use crate::skin::{Attachment, influences_from_mesh, weights_from_mesh};
use crate::subdivision::Subdivider;

/// System sets of the cloth pipeline, public so games can order their own systems around them.
///
/// In the plugin's simulation schedule (default [`FixedUpdate`]), chained in this order:
/// - [`Prepare`](Self::Prepare): apply edited configs and pin sets, resolve pin anchors (rest,
///   world, or another entity's global transform) into targets for this step, and take the poses
///   of the [`ClothCollider`]s.
/// - [`Step`](Self::Step): advance every cloth by the schedule's time step (substeps inside), in
///   parallel across cloths.
/// - [`Subdivide`](Self::Subdivide): compute the render positions and normals of the new state.
///
/// In [`PostUpdate`], after transform propagation and before asset events (so that bounds and GPU
/// buffers follow the same frame), chained:
/// - [`Build`](Self::Build): build new or replaced cloths, and report failures (each once, as
///   [`ClothInvalid`]).
/// - [`Writeback`](Self::Writeback): write positions and normals into each cloth's `Mesh` in place,
///   interpolated between the last two steps when [`ClothConfig::interpolate`] is on.
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ClothSystems {
    /// Apply edits and gather pin targets.
    Prepare,
    /// Step the solvers.
    Step,
    /// Produce render positions and normals.
    Subdivide,
    /// Create and rebuild cloths; report failures.
    Build,
    /// Write meshes.
    Writeback,
}

/// Adds cloth simulation to an app.
///
/// # Example
/// ```
/// use bevy::prelude::*;
/// use bevy_cloth::prelude::*;
///
/// App::new()
///     .add_plugins((MinimalPlugins, TransformPlugin, AssetPlugin::default()))
///     .add_plugins((bevy::mesh::MeshPlugin, ClothPlugin::default()));
/// ```
///
/// # Frame hitches
/// After a long frame, [`FixedUpdate`] runs as many steps as it takes to catch up (Bevy's virtual
/// clock clamps a frame to 250 ms: 15 steps at 60 Hz). Cloths step at most
/// [`max_steps_per_frame`](Self::max_steps_per_frame) times per frame (default
/// [`DEFAULT_MAX_STEPS_PER_FRAME`]); the steps beyond it are skipped, so after a hitch the cloth's
/// time runs behind the game's instead of the hitch costing many steps at once (which would make
/// the next frame long too). Pins and colliders that moved meanwhile are caught up in the next step
/// taken. [`ClothStepBudget`] counts the skipped steps.
#[derive(Debug, Clone)]
pub struct ClothPlugin {
    /// The schedule that steps the simulation, [`FixedUpdate`] by default. With any other
    /// schedule the step uses that schedule's `Time` delta and display interpolation is off.
    pub schedule: Interned<dyn ScheduleLabel>,
    /// Most cloth steps per frame (at least 1).
    pub max_steps_per_frame: u32,
}

/// The default of [`ClothPlugin::max_steps_per_frame`].
pub const DEFAULT_MAX_STEPS_PER_FRAME: u32 = 4;

impl Default for ClothPlugin {
    fn default() -> Self {
        Self {
            schedule: FixedUpdate.intern(),
            max_steps_per_frame: DEFAULT_MAX_STEPS_PER_FRAME,
        }
    }
}

impl ClothPlugin {
    /// Steps cloths in `schedule` instead of [`FixedUpdate`].
    pub fn in_schedule(schedule: impl ScheduleLabel) -> Self {
        Self {
            schedule: schedule.intern(),
            ..Self::default()
        }
    }

    /// Sets [`max_steps_per_frame`](Self::max_steps_per_frame) (values below 1 count as 1).
    pub fn with_max_steps_per_frame(mut self, steps: u32) -> Self {
        self.max_steps_per_frame = steps;
        self
    }
}

/// How many cloth steps this frame has taken, and how many were skipped because a frame asked for
/// more than [`ClothPlugin::max_steps_per_frame`].
#[derive(Resource, Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClothStepBudget {
    /// Most steps per frame.
    pub max_per_frame: u32,
    /// Steps asked for in the current frame (taken or not).
    pub this_frame: u32,
    /// Steps skipped since the app started.
    pub skipped: u64,
}

/// Starts a frame's step count.
fn reset_step_budget(mut budget: ResMut<ClothStepBudget>) {
    budget.this_frame = 0;
}

/// Counts a step of the simulation schedule, and the skipped ones.
fn count_step(mut budget: ResMut<ClothStepBudget>) {
    budget.this_frame += 1;
    if budget.this_frame > budget.max_per_frame {
        budget.skipped += 1;
    }
}

/// Whether this step is within the frame's budget.
fn step_allowed(budget: Res<ClothStepBudget>) -> bool {
    budget.this_frame <= budget.max_per_frame
}

/// Whether the simulation runs in [`FixedUpdate`] (so that display interpolation makes sense).
#[derive(Resource, Debug, Clone, Copy)]
struct SteppedInFixedUpdate(bool);

impl Plugin for ClothPlugin {
    fn build(&self, app: &mut App) {
        #[cfg(feature = "avian")]
        app.insert_resource(ClothSchedule(self.schedule));
        app.register_type::<Cloth>()
            .register_type::<ClothConfig>()
            .register_type::<ClothPins>()
            .register_type::<ClothSubdivision>()
            .register_type::<ClothCollider>()
            .register_type::<ClothPushesBodies>()
            .register_type::<Wind>()
            .register_type::<WindZone>()
            .init_resource::<WindSnapshot>()
            .insert_resource(SteppedInFixedUpdate(self.schedule == FixedUpdate.intern()))
            .insert_resource(ClothStepBudget {
                max_per_frame: self.max_steps_per_frame.max(1),
                this_frame: 0,
                skipped: 0,
            })
            .init_resource::<ColliderSnapshot>()
            .configure_sets(
                self.schedule,
                (
                    ClothSystems::Prepare,
                    ClothSystems::Step,
                    ClothSystems::Subdivide,
                )
                    .chain()
                    .run_if(step_allowed),
            )
            .configure_sets(
                PostUpdate,
                (ClothSystems::Build, ClothSystems::Writeback)
                    .chain()
                    .after(TransformSystems::Propagate)
                    .before(AssetEventSystems),
            )
            .add_systems(
                self.schedule,
                (
                    (
                        apply_edits,
                        resolve_pin_targets,
                        gather_colliders.run_if(colliders_present),
                        gather_wind.run_if(wind_present),
                    )
                        .chain()
                        .in_set(ClothSystems::Prepare),
                    step_cloths.in_set(ClothSystems::Step),
                    update_render_buffers.in_set(ClothSystems::Subdivide),
                )
                    .run_if(any_with_component::<ClothState>),
            )
            .add_systems(First, reset_step_budget)
            .add_systems(self.schedule, count_step.before(ClothSystems::Prepare))
            .add_systems(
                PostUpdate,
                (
                    (adopt_skins, build_cloths)
                        .chain()
                        .in_set(ClothSystems::Build),
                    write_meshes
                        .in_set(ClothSystems::Writeback)
                        .run_if(any_with_component::<ClothState>),
                ),
            );
    }
}

/// The global pose of an entity now: computed from its `Transform` and its ancestors' (so an
/// entity moved earlier in this fixed step counts), else its last propagated `GlobalTransform`.
fn current_global(
    entity: Entity,
    helper: &TransformHelper,
    globals: &Query<&GlobalTransform>,
) -> Option<GlobalTransform> {
    helper
        .compute_global_transform(entity)
        .ok()
        .or_else(|| globals.get(entity).ok().copied())
}

/// Whether there are colliders to gather, or last step's must be cleared (including those another
/// physics engine's colliders added after them).
fn colliders_present(
    colliders: Query<(), With<ClothCollider>>,
    snapshot: Res<ColliderSnapshot>,
) -> bool {
    !(colliders.is_empty() && snapshot.0.is_empty())
}

/// Whether there is wind to sample, or last step's must be cleared.
fn wind_present(
    wind: Option<Res<Wind>>,
    zones: Query<(), With<WindZone>>,
    snapshot: Res<WindSnapshot>,
) -> bool {
    wind.is_some() || !zones.is_empty() || snapshot.0.is_some()
}

/// The colliders of this step, with their poses at its start and end: the [`ClothCollider`]s,
/// then (with the `avian` feature) avian's.
#[derive(Resource, Debug, Default)]
pub(crate) struct ColliderSnapshot(pub(crate) Vec<Collider>);

/// The schedule the cloths step in ([`ClothPlugin::schedule`]), for plugins that add to it.
#[cfg(feature = "avian")]
#[derive(Resource, Debug, Clone, Copy)]
pub(crate) struct ClothSchedule(pub(crate) Interned<dyn ScheduleLabel>);

/// Takes every [`ClothCollider`]'s pose now as the end of this step's motion, and its pose at the
/// previous fixed step as the start. Bad colliders are reported once and left out.
pub(crate) fn gather_colliders(
    mut snapshot: ResMut<ColliderSnapshot>,
    mut colliders: Query<(Entity, &ClothCollider, &mut ColliderMotion)>,
    helper: TransformHelper,
    globals: Query<&GlobalTransform>,
) {
    snapshot.0.clear();
    for (entity, collider, mut motion) in &mut colliders {
        let Some(global) = current_global(entity, &helper, &globals) else {
            continue;
        };
        let (scale, rotation, translation) = global.to_scale_rotation_translation();
        let end = Pose {
            rotation,
            translation,
        };
        let sim = Collider {
            shape: collider.shape.scaled(scale).into(),
            start: motion.previous.unwrap_or(end),
            end,
            friction: collider.friction,
            margin: collider.margin,
            layers: collider.layers,
            filters: u32::MAX,
            inv_mass: 0.0,
            inv_inertia: bevy::math::Mat3::ZERO,
            acceleration: Vec3::ZERO,
        };
        motion.previous = Some(end);
        match sim.validate() {
            Ok(()) => {
                snapshot.0.push(sim);
                motion.reported = false;
            }
            Err(e) if !motion.reported => {
                error!("cloth collider {entity}: {e}; it is ignored until fixed");
                motion.reported = true;
            }
            Err(_) => {}
        }
    }
}

/// The air of this step: `None` without a [`Wind`] resource (or with it disabled) and without
/// [`WindZone`]s.
#[derive(Resource, Debug, Default)]
pub(crate) struct WindSnapshot(Option<WindField>);

/// Samples the [`Wind`] resource and the [`WindZone`]s into this step's wind field. Bad wind is
/// reported once and switched off until fixed.
fn gather_wind(
    mut snapshot: ResMut<WindSnapshot>,
    wind: Option<Res<Wind>>,
    zones: Query<(Entity, &WindZone)>,
    time: Res<Time>,
    helper: TransformHelper,
    globals: Query<&GlobalTransform>,
    mut reported: Local<bool>,
) {
    let global = wind.as_deref().filter(|w| w.enabled);
    if global.is_none() && zones.is_empty() {
        snapshot.0 = None;
        return;
    }
    let field = snapshot.0.get_or_insert_with(WindField::default);
    // Zones alone blow in still air of the default density.
    let still = Wind::default();
    let w = global.unwrap_or(&still);
    field.velocity = w.velocity;
    field.gusts = w.gusts;
    field.air_density = w.air_density;
    field.time = time.elapsed_secs();
    field.zones.clear();
    for (entity, zone) in &zones {
        if let Some(g) = current_global(entity, &helper, &globals) {
            field.zones.push(PlacedWindZone {
                shape: zone.shape,
                to_local: g.affine().inverse(),
                velocity: zone.velocity,
                gusts: zone.gusts,
                falloff: zone.falloff,
            });
        }
    }
    match field.validate() {
        Ok(()) => *reported = false,
        Err(e) => {
            if !*reported {
                error!("wind: {e}; no wind until it is fixed");
                *reported = true;
            }
            snapshot.0 = None;
        }
    }
}

/// Where each pin, target and reference frame should be at the end of this step.
#[allow(clippy::type_complexity)]
fn resolve_pin_targets(
    mut cloths: Query<
        (
            Entity,
            &ClothPins,
            &GlobalTransform,
            Option<&ClothSkin>,
            Option<&ClothFrame>,
            &mut ClothState,
        ),
        Without<ClothInvalid>,
    >,
    helper: TransformHelper,
    anchors: Query<&GlobalTransform>,
) {
    for (entity, pins, transform, skin, frame, mut state) in &mut cloths {
        // The cloth's pose now (moved earlier in this step, or since the last propagation).
        let transform = &helper
            .compute_global_transform(entity)
            .unwrap_or(*transform);
        let state = &mut *state;
        let rest = &state.sim.model().rest_positions;
        let map = state.particle_map.as_deref();
        for (pin, target) in pins.pins.iter().zip(state.pin_targets.iter_mut()) {
            let resolved = pin.anchor.target(
                || {
                    mapped_particle(map, rest.len(), pin.particle)
                        .map(|i| transform.transform_point(rest[i]))
                },
                |entity| current_global(entity, &helper, &anchors),
            );
            // A vanished anchor entity leaves the pin where it was.
            if let Some(p) = resolved {
                *target = p;
            }
        }
        if let Some(attachment) = &mut state.attachment {
            let joints = skin.map_or(&[][..], |s| &s.joints[..]);
            attachment.update(&transform.affine(), |j| {
                let entity = *joints.get(j)?;
                current_global(entity, &helper, &anchors).map(|g| g.affine())
            });
            let user = pins.pins.len();
            for (target, &k) in state.pin_targets[user..].iter_mut().zip(&state.target_pins) {
                *target = attachment.targets[k].0;
            }
            state
                .sim
                .move_targets(attachment.limited().map(|t| (t.position, t.normal)));
        }
        state.sim.move_pins(state.pin_targets.iter().copied());
        let frame = frame.map_or(Some(*transform), |f| current_global(f.0, &helper, &anchors));
        if let Some(frame) = frame {
            state.sim.move_frame(pose_of(&frame));
        }
    }
}

/// The rotation and translation of a global transform (its scale left out).
fn pose_of(global: &GlobalTransform) -> Pose {
    let (_, rotation, translation) = global.to_scale_rotation_translation();
    Pose {
        rotation,
        translation,
    }
}

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

/// One cloth's step; a failure stops it.
fn step_one(state: &mut ClothState, dt: f32, env: &Environment, spread: Option<&dyn Spread>) {
    let stepped = match spread {
        Some(spread) => state.sim.step_in_parallel(dt, env, spread),
        None => state.sim.step_in(dt, env),
    };
    state.failure = stepped.err();
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

/// Keeps the last two render states (positions and normals) for display interpolation.
fn update_render_buffers(mut cloths: Query<&mut ClothState, Without<ClothInvalid>>) {
    cloths.par_iter_mut().for_each(|mut state| {
        if state.failure.is_some() {
            return;
        }
        let s = &mut *state;
        // A sleeping cloth did not move: one refresh makes both render states its resting pose,
        // after which there is nothing to compute until it wakes.
        if s.sim.slept_last_step() {
            if s.at_rest {
                return;
            }
            s.at_rest = true;
        } else {
            s.at_rest = false;
        }
        std::mem::swap(&mut s.render_prev, &mut s.render_curr);
        std::mem::swap(&mut s.normals_prev, &mut s.normals_curr);
        s.failure = refresh_render(s).err();
        s.dirty = true;
    });
}

/// Computes the current render positions and normals from the particles: copied, or evaluated
/// through the subdivision stencils.
fn refresh_render(s: &mut ClothState) -> Result<(), ClothError> {
    let positions = s.sim.positions();
    match &mut s.subdivision {
        None => {
            s.render_curr.copy_from_slice(positions);
            let by_grid = s
                .grid_normals
                .as_mut()
                .is_some_and(|g| g.compute(&s.render_curr, &mut s.normals_curr));
            if !by_grid {
                compute_normals(
                    &s.render_curr,
                    &s.sim.model().triangles,
                    &mut s.normals_curr,
                );
            }
        }
        Some(r) => {
            r.subdivider.apply(positions, &mut r.positions)?;
            r.subdivider.compute_normals(&r.positions, &mut r.normals)?;
            let layout = r.subdivider.topology().render_mesh();
            layout.expand(&r.positions, &mut s.render_curr)?;
            layout.expand(&r.normals, &mut s.normals_curr)?;
        }
    }
    Ok(())
}

/// Sets up the render side of a cloth (subdivision stencils, buffers, a new mesh asset) for its
/// current particles, and returns the mesh handle. Unsubdivided, the cloth renders into `user_mesh`
/// when given (a copy of the user's source mesh, keeping all its attributes).
fn rebuild_render(
    state: &mut ClothState,
    subdivision: Option<&ClothSubdivision>,
    user_mesh: Option<Mesh>,
    meshes: &mut Assets<Mesh>,
) -> Result<Handle<Mesh>, ClothError> {
    let model = state.sim.model();
    let render_level = |s: &&ClothSubdivision| s.level > 0 && s.target == SubdivisionTarget::Render;
    state.subdivision = match subdivision.filter(render_level) {
        None => None,
        Some(sub) => {
            check_level(sub)?;
            let subdivider =
                Subdivider::new(&model.control_mesh()?, sub.level, sub.rule, sub.boundary)?;
            let n = subdivider.refined_vertex_count();
            Some(RenderSubdivision {
                subdivider,
                positions: vec![Vec3::ZERO; n],
                normals: vec![Vec3::Y; n],
            })
        }
    };
    state.grid_normals = match state.subdivision {
        None => GridNormals::new(model),
        Some(_) => None,
    };
    let mesh = match (&state.subdivision, user_mesh) {
        (None, Some(user_mesh)) => user_mesh,
        (None, None) => render::mesh_for_model(model),
        (Some(r), _) => render::mesh_for_subdivision(&r.subdivider),
    };
    let count = mesh.count_vertices();
    for buffer in [
        &mut state.render_prev,
        &mut state.render_curr,
        &mut state.normals_prev,
        &mut state.normals_curr,
    ] {
        buffer.resize(count, Vec3::ZERO);
    }
    refresh_render(state)?;
    state.render_prev.copy_from_slice(&state.render_curr);
    state.normals_prev.copy_from_slice(&state.normals_curr);
    state.dirty = true;
    state.mesh = meshes.add(mesh);
    Ok(state.mesh.clone())
}

/// Applies edited [`ClothConfig`]s and [`ClothPins`] to running cloths before they step. A bad edit
/// stops the cloth (reported by [`build_cloths`]).
#[allow(clippy::type_complexity)]
fn apply_edits(
    mut cloths: Query<
        (
            Ref<ClothConfig>,
            Ref<ClothPins>,
            &GlobalTransform,
            &mut ClothState,
        ),
        Without<ClothInvalid>,
    >,
) {
    for (config, pins, transform, mut state) in &mut cloths {
        if state.failure.is_some() || !(config.is_changed() || pins.is_changed()) {
            continue;
        }
        let mut result = Ok(());
        if config.is_changed() {
            let settings = run_settings(&config, state.mass_scale);
            result = state.sim.set_settings(settings);
        }
        if result.is_ok() && pins.is_changed() {
            result = apply_pins(&mut state, &pins, transform);
        }
        state.failure = result.err();
    }
}

type BuildQuery<'a> = (
    Entity,
    (Ref<'a, Cloth>, Ref<'a, ClothConfig>, Ref<'a, ClothPins>),
    &'a GlobalTransform,
    Option<Ref<'a, ClothSubdivision>>,
    (
        Option<Ref<'a, ClothTargets>>,
        Option<Ref<'a, ClothSkin>>,
        Option<&'a ClothFrame>,
    ),
    Option<&'a mut ClothState>,
    Has<ClothInvalid>,
);

/// A cloth spawned on a skinned mesh keeps the skin for its targets ([`ClothSkin`]); the
/// renderer must not skin the simulated mesh again.
fn adopt_skins(mut commands: Commands, cloths: Query<(Entity, &SkinnedMesh), With<Cloth>>) {
    for (entity, skinned) in &cloths {
        commands
            .entity(entity)
            .remove::<SkinnedMesh>()
            .insert(ClothSkin {
                joints: skinned.joints.clone(),
                inverse_bindposes: skinned.inverse_bindposes.clone(),
            });
    }
}

/// What building a cloth reads besides its own components: mesh assets (and where new meshes
/// go), the skins' inverse bind poses, and joints' global transforms.
struct BuildInputs<'a, 'w, 's> {
    meshes: &'a mut Assets<Mesh>,
    bindposes: &'a Assets<SkinnedMeshInverseBindposes>,
    globals: &'a Query<'w, 's, &'static GlobalTransform>,
}

/// Builds new and replaced cloths (and invalid ones that were edited), and turns failures into
/// [`ClothInvalid`], logged once per failure.
fn build_cloths(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    bindposes: Res<Assets<SkinnedMeshInverseBindposes>>,
    mut cloths: Query<BuildQuery>,
    globals: Query<&'static GlobalTransform>,
) {
    for (
        entity,
        (cloth, config, pins),
        transform,
        subdivision,
        (targets, skin, frame),
        mut state,
        invalid,
    ) in &mut cloths
    {
        let subdivision_changed = match (&subdivision, &state) {
            (Some(s), _) => s.is_changed(),
            (None, Some(state)) => state.subdivision.is_some() || state.particle_map.is_some(),
            (None, None) => false,
        };
        // Targets added, edited or removed, or a skin: the cloth is rebuilt.
        let targets_changed = targets.as_ref().is_some_and(|t| t.is_changed())
            || skin.as_ref().is_some_and(|s| s.is_changed())
            || targets.is_none() && state.as_ref().is_some_and(|s| s.attachment.is_some());
        let edited = cloth.is_changed()
            || config.is_changed()
            || pins.is_changed()
            || subdivision_changed
            || targets_changed;
        let failure = state
            .as_mut()
            .filter(|s| s.failure.is_some())
            .and_then(|s| s.failure.take());
        // New, replaced, waiting for its mesh asset, or edited after being invalid; or its
        // subdivision changed while (or to) refining the simulation itself.
        let refines_sim = |s: &ClothSubdivision| s.target == SubdivisionTarget::Simulation;
        let rebuild = match &state {
            Some(state) => {
                cloth.is_changed()
                    || targets_changed
                    || subdivision_changed
                        && (state.particle_map.is_some()
                            || subdivision.as_deref().is_some_and(refines_sim))
            }
            None => !invalid || edited,
        };
        let subdivision = subdivision.as_deref();
        let mut inputs = BuildInputs {
            meshes: &mut meshes,
            bindposes: &bindposes,
            globals: &globals,
        };
        let result = match (failure, state) {
            (Some(e), _) => Err(e),
            (None, _) if rebuild => build_state(
                (&cloth, &config, &pins),
                subdivision,
                (targets.as_deref(), skin.as_deref(), frame),
                transform,
                &mut inputs,
            )
            .map(|built| {
                if let Some((state, mesh)) = built {
                    commands
                        .entity(entity)
                        .remove::<ClothInvalid>()
                        .insert((state, Mesh3d(mesh)));
                }
            }),
            (None, Some(mut state)) if subdivision_changed => {
                rebuild_render(&mut state, subdivision, None, inputs.meshes).map(|mesh| {
                    commands.entity(entity).insert(Mesh3d(mesh));
                })
            }
            (None, _) => Ok(()),
        };
        if let Err(e) = result {
            error!("cloth {entity}: {e}; the cloth is skipped until it is edited");
            commands
                .entity(entity)
                .remove::<ClothState>()
                .insert(ClothInvalid(e));
        }
    }
}

/// Builds the simulation and mesh of a cloth. `Ok(None)` means its mesh asset (or its skin's
/// inverse bind poses) is not loaded yet.
fn build_state(
    (cloth, config, pins): (&Cloth, &ClothConfig, &ClothPins),
    subdivision: Option<&ClothSubdivision>,
    (targets, skin, frame): (
        Option<&ClothTargets>,
        Option<&ClothSkin>,
        Option<&ClothFrame>,
    ),
    transform: &GlobalTransform,
    inputs: &mut BuildInputs,
) -> Result<Option<(ClothState, Handle<Mesh>)>, ClothError> {
    let meshes = &mut *inputs.meshes;
    let source_mesh = match &cloth.source {
        ClothSource::Mesh(handle) => meshes.get(handle),
        _ => None,
    };
    let (model, user_mesh) = match (&cloth.source, source_mesh) {
        (ClothSource::Grid(spec), _) => (ClothModel::grid(spec)?, None),
        (ClothSource::Mesh(_), None) => return Ok(None),
        (ClothSource::Mesh(_), Some(source)) => {
            let model = render::model_from_mesh(source)?;
            if model.triangles.len() > 3 && shares_no_vertex(&model.triangles) {
                warn!(
                    "a cloth mesh shares no vertex between its triangles, so its triangles move \
                     apart; was it exported without normals (Bevy's glTF loader then splits \
                     every vertex) or unwelded?"
                );
            }
            (model, Some(render::prepare_user_mesh(source.clone())))
        }
        (ClothSource::Model(shared), _) => {
            shared.model().validate()?;
            (shared.model().clone(), None)
        }
    };
    let (model, user_mesh, particle_map, mass_scale) =
        match subdivision.filter(|s| s.level > 0 && s.target == SubdivisionTarget::Simulation) {
            None => (model, user_mesh, None, 1.0),
            Some(sub) => {
                check_level(sub)?;
                if targets.is_some() {
                    return Err(ClothError::InvalidTargets {
                        what: "a cloth with targets is simulated at its own resolution \
                               (subdivide its render mesh instead)"
                            .into(),
                    });
                }
                let refined = model.subdivided(sub.level, sub.rule, sub.boundary)?;
                // The user's mesh no longer matches the particles: render the refined model.
                (
                    refined.model,
                    None,
                    Some(refined.particle_map),
                    refined.mass_scale,
                )
            }
        };
    let attachment = match targets {
        None => None,
        Some(targets) => {
            let skin = match skin {
                None => None,
                Some(skin) => match inputs.bindposes.get(&skin.inverse_bindposes) {
                    Some(bind) => Some((skin, &bind[..])),
                    None => return Ok(None),
                },
            };
            let mut attachment = build_attachment(&model, targets, source_mesh, skin)?;
            let joints = skin.map_or(&[][..], |(s, _)| &s.joints[..]);
            let globals = inputs.globals;
            attachment.update(&transform.affine(), |j| {
                globals.get(*joints.get(j)?).ok().map(|g| g.affine())
            });
            Some(attachment)
        }
    };
    let meshes = &mut *inputs.meshes;
    let mut sim = ClothSim::new(model, run_settings(config, mass_scale), |p| {
        transform.transform_point(p)
    })?;
    // The reference frame starts where it is now.
    let frame = frame.map_or(Some(*transform), |f| inputs.globals.get(f.0).ok().copied());
    if let Some(frame) = frame {
        sim.move_frame(pose_of(&frame));
    }
    if let Some(a) = &attachment {
        sim.set_targets(&a.limited().collect::<Vec<_>>())?;
    }
    let mut state = ClothState {
        sim,
        mesh: Handle::default(),
        subdivision: None,
        grid_normals: None,
        particle_map,
        mass_scale,
        render_prev: Vec::new(),
        render_curr: Vec::new(),
        normals_prev: Vec::new(),
        normals_curr: Vec::new(),
        pin_targets: Vec::new(),
        attachment,
        target_pins: Vec::new(),
        failure: None,
        dirty: true,
        at_rest: false,
    };
    apply_pins(&mut state, pins, transform)?;
    let mesh = rebuild_render(&mut state, subdivision, user_mesh, meshes)?;
    Ok(Some((state, mesh)))
}

/// Whether no vertex is used by more than one of the `triangles` (a mesh split into loose
/// triangles).
fn shares_no_vertex(triangles: &[u32]) -> bool {
    let mut seen = vec![false; triangles.iter().max().map_or(0, |&m| m as usize + 1)];
    triangles
        .iter()
        .all(|&v| !std::mem::replace(&mut seen[v as usize], true))
}

/// The weighted particles of a cloth with `targets`, from its model and (for weights or a skin
/// read from it) its source mesh, skinned by `skin` and its inverse bind poses when given.
fn build_attachment(
    model: &ClothModel,
    targets: &ClothTargets,
    source: Option<&Mesh>,
    skin: Option<(&ClothSkin, &[bevy::math::Mat4])>,
) -> Result<Attachment, ClothError> {
    let n = model.particle_count();
    let from_mesh = |what: &str| {
        source.ok_or_else(|| ClothError::InvalidTargets {
            what: format!("{what} needs a cloth made from a mesh asset"),
        })
    };
    let weights = match &targets.weights {
        TargetWeights::Values(w) => w.clone(),
        TargetWeights::Color(channel) => weights_from_mesh(
            from_mesh("weights from vertex colours")?,
            None,
            *channel as usize,
        )?,
        TargetWeights::Attribute(name) => {
            weights_from_mesh(from_mesh("weights from a vertex attribute")?, Some(name), 0)?
        }
    };
    if weights.len() != n {
        return Err(ClothError::InvalidTargets {
            what: format!("{} weights for a cloth of {n} particles", weights.len()),
        });
    }
    // A negative weight leaves the particle free; NaN is refused by the attachment.
    let weights: Vec<Option<f32>> = weights
        .iter()
        .map(|&w| (w.is_nan() || w >= 0.0).then_some(w))
        .collect();
    let mut normals = vec![Vec3::ZERO; n];
    compute_normals(&model.rest_positions, &model.triangles, &mut normals);
    let skin = match skin {
        None => None,
        Some((skin, bind)) => {
            let influences = influences_from_mesh(from_mesh("a skin")?)?;
            if bind.len() != skin.joints.len() {
                return Err(ClothError::InvalidTargets {
                    what: format!(
                        "the skin has {} joints but {} inverse bind poses",
                        skin.joints.len(),
                        bind.len()
                    ),
                });
            }
            Some((influences, bind))
        }
    };
    Attachment::new(&weights, (&model.rest_positions, &normals), skin)
}

/// Checks a subdivision level against [`MAX_CLOTH_SUBDIVISION_LEVEL`].
fn check_level(sub: &ClothSubdivision) -> Result<(), ClothError> {
    count_in(
        "subdivision.level",
        sub.level,
        0,
        MAX_CLOTH_SUBDIVISION_LEVEL,
    )
}

/// The solver settings of `config` as a cloth runs them: the particle mass scaled by
/// `mass_scale` (below 1 for a cloth simulated at a subdivided resolution, to keep its mass).
fn run_settings(config: &ClothConfig, mass_scale: f32) -> SolverSettings {
    let mut settings = config.solver;
    settings.particle_mass *= mass_scale;
    settings
}

/// Replaces the pin set of a running cloth, each pin starting at its anchor's current position:
/// the [`ClothPins`], then the targets' weight-0 particles they do not pin.
fn apply_pins(
    state: &mut ClothState,
    pins: &ClothPins,
    transform: &GlobalTransform,
) -> Result<(), ClothError> {
    state.pin_targets.clear();
    let mut targets = Vec::with_capacity(pins.pins.len());
    for pin in &pins.pins {
        let Some(index) = state.particle(pin.particle) else {
            return Err(ClothError::PinOutOfRange {
                index: pin.particle,
                count: state
                    .particle_map
                    .as_ref()
                    .map_or(state.sim.positions().len(), Vec::len),
            });
        };
        let rest = state.sim.model().rest_positions[index];
        // An entity's anchor is resolved in `Prepare`; until then the particle stays where it is.
        let target = pin
            .anchor
            .target(|| Some(transform.transform_point(rest)), |_| None)
            .unwrap_or(state.sim.positions()[index]);
        state.pin_targets.push(target);
        targets.push((index as u32, target));
    }
    state.target_pins.clear();
    if let Some(a) = &state.attachment {
        let mut pinned = vec![false; state.sim.positions().len()];
        for &(p, _) in &targets {
            pinned[p as usize] = true;
        }
        for (k, (&(particle, weight), &(target, _))) in
            a.weighted.iter().zip(&a.targets).enumerate()
        {
            if weight == 0.0 && !pinned[particle as usize] {
                state.target_pins.push(k);
                state.pin_targets.push(target);
                targets.push((particle, target));
            }
        }
    }
    state.sim.set_pins(targets)
}

/// Writes each changed cloth's render state into its mesh, in the entity's local space.
fn write_meshes(
    fixed: Res<SteppedInFixedUpdate>,
    time: Res<Time<Fixed>>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut cloths: Query<(&ClothConfig, Ref<GlobalTransform>, &mut ClothState), Without<ClothInvalid>>,
) {
    let fraction = if fixed.0 {
        time.overstep_fraction()
    } else {
        1.0
    };
    for (config, transform, mut state) in &mut cloths {
        let interpolating = config.interpolate && fraction < 1.0 && !state.at_rest;
        if !(state.dirty || interpolating || transform.is_changed()) {
            continue;
        }
        let Some(mut mesh) = meshes.get_mut(&state.mesh) else {
            continue;
        };
        let alpha = if config.interpolate { fraction } else { 1.0 };
        let world_to_local = transform.affine().inverse();
        let s = &mut *state;
        // A mesh whose buffers were replaced or resized stops the cloth; `Build` reports it once.
        if let Err(e) = render::write_mesh(
            &mut mesh,
            &world_to_local,
            (&s.render_prev, &s.render_curr),
            (&s.normals_prev, &s.normals_curr),
            alpha,
        ) {
            s.failure = Some(e);
        }
        s.dirty = false;
    }
}

/// Shortest fixed time step accepted by scene files and the test harness' headless app, s (1 µs; Bevy's
/// fixed clock counts whole nanoseconds and rejects a zero step).
pub const MIN_FIXED_STEP: f32 = 1e-6;
/// Longest fixed time step accepted by scene files and the test harness' headless app, s.
pub const MAX_FIXED_STEP: f32 = 1.0;

/// Checks a fixed time step of `dt` seconds: in [`MIN_FIXED_STEP`]`..=`[`MAX_FIXED_STEP`].
pub fn validate_fixed_step(dt: f32) -> Result<(), ClothError> {
    if (MIN_FIXED_STEP..=MAX_FIXED_STEP).contains(&dt) {
        Ok(())
    } else {
        Err(ClothError::InvalidValue {
            field: "dt",
            expected: "in 1e-6..=1 s",
            value: dt as f64,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loose_triangles_share_no_vertex_and_a_welded_strip_does() {
        assert!(shares_no_vertex(&[0, 1, 2, 3, 4, 5]));
        assert!(!shares_no_vertex(&[0, 1, 2, 2, 1, 3]));
        assert!(shares_no_vertex(&[]));
    }
}
