//! Pin targets (in [`ClothSystems::Prepare`](super::ClothSystems::Prepare)): where each pin,
//! skinned target and reference frame should be at the end of the step, handed to the solver.

use bevy::ecs::prelude::*;
use bevy::time::Time;
use bevy::transform::components::GlobalTransform;
use bevy::transform::helper::TransformHelper;

use super::poses::{current_global, pose_of};
use crate::components::{ClothFrame, ClothInvalid, ClothSkin, ClothState, mapped_particle};

/// Where each pin, target and reference frame should be at the end of this step; a frozen cloth
/// is carried there ([`LodLevel::Frozen`](crate::LodLevel::Frozen)), a culled one left alone.
#[allow(clippy::type_complexity)]
pub(super) fn resolve_pin_targets(
    time: Res<Time>,
    mut cloths: Query<
        (
            Entity,
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
    for (entity, transform, skin, frame, mut state) in &mut cloths {
        super::lod::capture_pose(&mut state, &transform.affine());
        if state.lod.level == crate::LodLevel::Culled {
            continue;
        }
        // The cloth's pose now (moved earlier in this step, or since the last propagation).
        let transform = &helper
            .compute_global_transform(entity)
            .unwrap_or(*transform);
        let state = &mut *state;
        let rest = &state.sim.model().rest_positions;
        let map = state.particle_map.as_deref();
        for (pin, target) in state.pins.iter().zip(state.pin_targets.iter_mut()) {
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
            let moved = attachment.update(&transform.affine(), |j| {
                let entity = *joints.get(j)?;
                current_global(entity, &helper, &anchors).map(|g| g.affine())
            });
            // Asleep on targets that stand still: the pins and targets it has are these.
            if moved || !state.sim.is_sleeping() {
                let user = state.pins.len();
                for (target, &k) in state
                    .pin_targets
                    .iter_mut()
                    .skip(user)
                    .zip(&state.target_pins)
                {
                    *target = attachment.targets[k].0;
                }
                state
                    .sim
                    .move_targets(attachment.limited().map(|t| (t.position, t.normal)));
            }
        }
        state.sim.move_pins(state.pin_targets.iter().copied());
        let frame = frame.map_or(Some(*transform), |f| current_global(f.0, &helper, &anchors));
        if let Some(frame) = frame {
            state.sim.move_frame(pose_of(&frame));
        }
        if state.lod.level == crate::LodLevel::Frozen {
            super::lod::follow_carriers(state, &transform.affine(), time.delta_secs());
        }
        super::lod::carry_blend(state, &transform.affine());
    }
}
