//! Tearing in the ECS: [`ClothCut`] messages queued for a cloth's next step (in
//! [`ClothSystems::Prepare`](super::ClothSystems::Prepare)), and each torn cloth's pins, targets
//! and render mesh following its new topology, announced as [`ClothTorn`] (in
//! [`ClothSystems::Subdivide`](super::ClothSystems::Subdivide), before the render positions).

use bevy::asset::Assets;
use bevy::ecs::prelude::*;
use bevy::log::warn;
use bevy::mesh::{Mesh, Mesh3d};
use bevy::transform::components::GlobalTransform;

use super::build::{follow_render, rebuild_render};
use super::edits::{commit_pins, plan_pins};
use crate::components::{ClothInvalid, ClothPins, ClothState, ClothSubdivision};
use crate::tearing::{ClothCut, ClothTorn};

/// Hands each valid [`ClothCut`] to its cloth for the next step.
pub(super) fn queue_cuts(
    mut cuts: MessageReader<ClothCut>,
    mut cloths: Query<&mut ClothState, Without<ClothInvalid>>,
) {
    for ClothCut { cloth, cut } in cuts.read() {
        if let Err(e) = cut.validate() {
            warn!("cloth {cloth}: cut dropped: {e}");
            continue;
        }
        match cloths.get_mut(*cloth) {
            Ok(mut state) => state.cuts.push(*cut),
            Err(_) => warn!("cut dropped: {cloth} is not a running cloth"),
        }
    }
}

/// After a step that tore cloths: their copies of targeted particles join the targets and the
/// pieces torn free leave them, as in the solver; pins are set again (weight-0 targets pin the
/// copies too); the render side is rebuilt for the new particles and faces, and a [`ClothTorn`]
/// is written.
#[allow(clippy::type_complexity)]
pub(super) fn follow_tears(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut torn: MessageWriter<ClothTorn>,
    mut cloths: Query<
        (
            Entity,
            &mut ClothState,
            &GlobalTransform,
            Option<&ClothSubdivision>,
        ),
        Without<ClothInvalid>,
    >,
) {
    for (entity, mut state, transform, subdivision) in &mut cloths {
        if state.splits.is_empty() || state.failure.is_some() {
            continue;
        }
        let state = &mut *state;
        let splits = std::mem::take(&mut state.splits);
        let result = (|| {
            if let Some(attachment) = &mut state.attachment {
                attachment.add_copies(splits.iter().map(|s| (s.particle, s.copy)));
                // The targets the solver kept (those of pieces torn free are gone); weight-0
                // ones are pins, which the solver's targets do not list.
                let kept: std::collections::HashSet<u32> = state.sim.targeted().collect();
                attachment.retain(|p, w| w == 0.0 || kept.contains(&p));
                let targets: Vec<_> = attachment.limited().collect();
                state.sim.set_targets(&targets)?;
            }
            // The pins the cloth runs, its weight-0 targets' copies among them.
            let running = ClothPins {
                pins: state.pins.clone(),
            };
            let plan = plan_pins(state, &running, transform)?;
            commit_pins(state, plan)?;
            // A torn mesh the subdivision cannot refine is drawn as it is.
            follow_render(state, subdivision, &mut meshes).or_else(|e| {
                warn!("cloth {entity}: its torn mesh is drawn unsubdivided: {e}");
                rebuild_render(state, None, (None, false), &mut meshes)
            })
        })();
        match result {
            Ok(mesh) => {
                commands.entity(entity).insert(Mesh3d(mesh));
                torn.write(ClothTorn {
                    cloth: entity,
                    splits,
                });
            }
            // The topology changed under the cloth: it cannot go on half followed.
            Err(e) => state.failure = Some(e),
        }
    }
}
