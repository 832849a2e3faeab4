//! Entity poses as the systems read them mid-step: an entity's global transform now, and the
//! rotation and translation the solver takes. Shared by the phases; imports none of them.

use bevy::ecs::prelude::*;
use bevy::transform::components::GlobalTransform;
use bevy::transform::helper::TransformHelper;

use crate::sim::contact::Pose;

/// The global pose of an entity now: computed from its `Transform` and its ancestors' (so an
/// entity moved earlier in this fixed step counts), else its last propagated `GlobalTransform`;
/// `None` for a missing entity or a pose that is not finite.
pub(super) fn current_global(
    entity: Entity,
    helper: &TransformHelper,
    globals: &Query<&GlobalTransform>,
) -> Option<GlobalTransform> {
    helper
        .compute_global_transform(entity)
        .ok()
        .or_else(|| globals.get(entity).ok().copied())
        .filter(|g| g.affine().is_finite())
}

/// Whether a cloth entity's transform maps its local space one to one: finite, and not scaled
/// to zero along any axis (its mesh is written through the inverse).
pub(super) fn invertible(global: &GlobalTransform) -> bool {
    let affine = global.affine();
    affine.is_finite() && affine.matrix3.determinant().abs() > f32::MIN_POSITIVE
}

/// The rotation and translation of a global transform (its scale left out).
pub(super) fn pose_of(global: &GlobalTransform) -> Pose {
    let (_, rotation, translation) = global.to_scale_rotation_translation();
    Pose {
        rotation,
        translation,
    }
}
