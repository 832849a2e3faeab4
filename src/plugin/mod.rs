//! [`ClothPlugin`]: scheduling, the [`ClothSystems`] sets and the thin systems that move data between
//! the ECS and [`crate::sim`]. Systems gather inputs into plain data, call the solver and write
//! meshes; they hold no formulas.
//!
//! This file holds the plugin, its sets, the per-frame step budget and the wiring of the phases;
//! the systems live one module per phase: `build` (create and validate cloths), `edits` (runtime
//! edits of configs and pins), `pin_targets`, `inputs` (collider and wind snapshots), `step` (the
//! task pool), `mesh` (render sync and mesh write). `poses` lies below them all.

use bevy::app::{App, First, FixedUpdate, Plugin, PostUpdate};
use bevy::asset::AssetEventSystems;
use bevy::ecs::intern::Interned;
use bevy::ecs::prelude::*;
use bevy::ecs::schedule::ScheduleLabel;
use bevy::transform::TransformSystems;

use crate::components::{
    Cloth, ClothCollider, ClothConfig, ClothPins, ClothPushesBodies, ClothState, ClothSubdivision,
    Wind, WindZone,
};
use crate::error::ClothError;
use crate::tearing::{ClothCut, ClothTearWeights, ClothTorn};

mod build;
mod edits;
mod inputs;
mod lod;
mod mesh;
mod pin_targets;
mod poses;
mod step;
mod tears;

use build::{adopt_skins, build_cloths};
use edits::{apply_edits, restore_required};
use inputs::{WindSnapshot, colliders_present, gather_wind, wind_present};
use lod::{choose_levels, restore_full_quality};
use mesh::{SteppedInFixedUpdate, update_render_buffers, write_meshes};
use pin_targets::resolve_pin_targets;
use tears::{follow_tears, queue_cuts};

// For the avian coupling, which orders its systems around these.
pub(crate) use inputs::{ColliderSnapshot, gather_colliders};
pub(crate) use step::step_cloths;

/// System sets of the cloth pipeline, public so games can order their own systems around them.
///
/// In the plugin's simulation schedule (default [`FixedUpdate`]), chained in this order:
/// - [`Prepare`](Self::Prepare): apply edited configs and pin sets, resolve pin anchors (rest,
///   world, or another entity's global transform) into targets for this step, hand [`ClothCut`]s
///   to their cloths, and take the poses of the [`ClothCollider`]s.
/// - [`Step`](Self::Step): advance every cloth by the schedule's time step (substeps inside), in
///   parallel across cloths.
/// - [`Subdivide`](Self::Subdivide): follow the cloths that tore (new render meshes, pins and
///   targets, [`ClothTorn`]), then compute the render positions and normals of the new state.
///
/// In [`PostUpdate`], after transform propagation and before asset events (so that bounds and GPU
/// buffers follow the same frame), chained:
/// - [`Build`](Self::Build): build new or replaced cloths, and report failures (each once, as
///   [`ClothInvalid`](crate::ClothInvalid)).
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

impl Plugin for ClothPlugin {
    fn build(&self, app: &mut App) {
        #[cfg(feature = "avian")]
        app.insert_resource(ClothSchedule(self.schedule));
        app.register_type::<Cloth>()
            .register_type::<ClothConfig>()
            .register_type::<ClothPins>()
            .register_type::<ClothSubdivision>()
            .register_type::<ClothCollider>()
            .register_type::<ClothTearWeights>()
            .register_type::<ClothPushesBodies>()
            .register_type::<crate::ClothLod>()
            .register_type::<crate::ClothLodLevel>()
            .register_type::<crate::ClothViewer>()
            .register_type::<crate::ClothBudget>()
            .register_type::<Wind>()
            .register_type::<WindZone>()
            .add_message::<ClothCut>()
            .add_message::<ClothTorn>()
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
                        restore_required,
                        apply_edits,
                        restore_full_quality,
                        choose_levels.run_if(any_with_component::<crate::ClothLod>),
                        resolve_pin_targets,
                        queue_cuts,
                        gather_colliders.run_if(colliders_present),
                        gather_wind.run_if(wind_present),
                    )
                        .chain()
                        .in_set(ClothSystems::Prepare),
                    step_cloths.in_set(ClothSystems::Step),
                    (follow_tears, update_render_buffers)
                        .chain()
                        .in_set(ClothSystems::Subdivide),
                )
                    .run_if(any_with_component::<ClothState>),
            )
            .add_systems(First, reset_step_budget)
            .add_systems(self.schedule, count_step.before(ClothSystems::Prepare))
            .add_systems(
                PostUpdate,
                (
                    (adopt_skins, restore_required, build_cloths)
                        .chain()
                        .in_set(ClothSystems::Build),
                    write_meshes
                        .in_set(ClothSystems::Writeback)
                        .run_if(any_with_component::<ClothState>),
                ),
            );
    }
}

/// The schedule the cloths step in ([`ClothPlugin::schedule`]), for plugins that add to it.
#[cfg(feature = "avian")]
#[derive(Resource, Debug, Clone, Copy)]
pub(crate) struct ClothSchedule(pub(crate) Interned<dyn ScheduleLabel>);

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
