//! Inputs of a step (in [`ClothSystems::Prepare`](super::ClothSystems::Prepare)): the colliders
//! and the wind gathered into plain snapshots for the solver, and the run conditions that skip
//! that work when a scene has neither.

use bevy::ecs::prelude::*;
use bevy::log::error;
use bevy::math::Vec3;
use bevy::time::Time;
use bevy::transform::components::GlobalTransform;
use bevy::transform::helper::TransformHelper;

use super::poses::current_global;
use crate::components::{ClothCollider, ColliderMotion, Wind, WindZone};
use crate::sim::contact::Pose;
use crate::sim::{Collider, PlacedWindZone, WindField};

/// Whether there are colliders to gather, or last step's must be cleared (including those another
/// physics engine's colliders added after them).
pub(super) fn colliders_present(
    colliders: Query<(), With<ClothCollider>>,
    snapshot: Res<ColliderSnapshot>,
) -> bool {
    !(colliders.is_empty() && snapshot.0.is_empty())
}

/// Whether there is wind to sample, or last step's must be cleared.
pub(super) fn wind_present(
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
pub(crate) struct WindSnapshot(pub(super) Option<WindField>);

/// Samples the [`Wind`] resource and the [`WindZone`]s into this step's wind field. Bad wind is
/// reported once and switched off until fixed.
pub(super) fn gather_wind(
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
