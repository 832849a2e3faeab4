//! Scene colliders: their shapes, placement and contact properties, and the constant velocity
//! that moves them.

use bevy::ecs::prelude::*;
use bevy::math::primitives::{Capsule3d, Cuboid, InfinitePlane3d, Sphere};
use bevy::math::{Dir3, Quat, Vec3};
use bevy::time::Time;
use bevy::transform::components::Transform;
use serde::{Deserialize, Serialize};

use crate::components::{ClothCollider, DEFAULT_COLLIDER_MARGIN};
use crate::error::{ClothError, finite_vec3};
use crate::sim::{ColliderShape, Friction};

/// The shape of a scene collider (see [`ColliderShape`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum SceneShape {
    /// A ball.
    Sphere {
        /// Radius, m.
        radius: f32,
    },
    /// A capsule along the collider's local Y axis.
    Capsule {
        /// Radius, m.
        radius: f32,
        /// Distance from the centre to each cap's centre, m.
        half_length: f32,
    },
    /// A box.
    Cuboid {
        /// Half extents, m.
        half_size: Vec3,
    },
    /// The solid half-space behind a plane through the collider's origin.
    Plane {
        /// Outward normal (need not be unit length).
        normal: Vec3,
    },
}

impl SceneShape {
    fn shape(&self) -> Result<ColliderShape, ClothError> {
        let shape = match *self {
            SceneShape::Sphere { radius } => ColliderShape::Sphere(Sphere { radius }),
            SceneShape::Capsule {
                radius,
                half_length,
            } => ColliderShape::Capsule(Capsule3d {
                radius,
                half_length,
            }),
            SceneShape::Cuboid { half_size } => ColliderShape::Cuboid(Cuboid { half_size }),
            SceneShape::Plane { normal } => {
                let normal = Dir3::new(normal).map_err(|_| ClothError::InvalidValue {
                    field: "collider.normal",
                    expected: "a non-zero finite vector",
                    value: normal.length() as f64,
                })?;
                ColliderShape::HalfSpace(InfinitePlane3d { normal })
            }
        };
        shape.validate()?;
        Ok(shape)
    }
}

fn default_margin() -> f32 {
    DEFAULT_COLLIDER_MARGIN
}

/// A collider in a scene: shape, placement, contact properties and an optional constant velocity.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneCollider {
    /// Shape in the collider's frame.
    pub shape: SceneShape,
    /// Position, m.
    #[serde(default)]
    pub translation: Vec3,
    /// Rotation as Euler angles XYZ, degrees.
    #[serde(default)]
    pub rotation_degrees: Vec3,
    /// Coulomb friction.
    #[serde(default)]
    pub friction: Friction,
    /// Thickness kept between surface and cloth, m.
    #[serde(default = "default_margin")]
    pub margin: f32,
    /// Constant velocity, m/s: the collider moves (kinematically) from its start placement.
    #[serde(default)]
    pub velocity: Vec3,
    /// One collider for all the scene's [copies](super::SceneCopies) (a floor under them all),
    /// rather than one per copy, moved with it; default false.
    #[serde(default)]
    pub shared: bool,
}

impl SceneCollider {
    /// The collider moved by `offset`, m.
    pub fn moved(&self, offset: Vec3) -> Self {
        Self {
            translation: self.translation + offset,
            ..self.clone()
        }
    }

    /// The collider component.
    pub fn component(&self) -> Result<ClothCollider, ClothError> {
        let collider = ClothCollider {
            margin: self.margin,
            friction: self.friction,
            ..ClothCollider::new(self.shape.shape()?)
        };
        collider.friction.validate()?;
        crate::error::non_negative("collider.margin", collider.margin)?;
        Ok(collider)
    }

    /// Checks the shape, friction, margin, placement and velocity; the error names the field.
    pub fn validate(&self) -> Result<(), ClothError> {
        self.component()?;
        finite_placement(self.translation, self.rotation_degrees)?;
        finite_vec3(["velocity.x", "velocity.y", "velocity.z"], self.velocity)
    }

    /// The components of the collider entity.
    pub fn bundle(&self) -> Result<impl Bundle, ClothError> {
        Ok((
            self.component()?,
            placement(self.translation, self.rotation_degrees),
            ConstantVelocity(self.velocity),
        ))
    }
}

/// Moves an entity's `Transform` at a constant velocity (m/s) every fixed step, after the cloths
/// stepped (so a collider's first step is from where it was spawned). Added by
/// [`ScenePlugin`](super::ScenePlugin); used by scene colliders with a `velocity`.
#[derive(Component, Debug, Clone, Copy, PartialEq, Default)]
pub struct ConstantVelocity(pub Vec3);

pub(super) fn move_at_constant_velocity(
    time: Res<Time>,
    mut query: Query<(&ConstantVelocity, &mut Transform)>,
) {
    let dt = time.delta_secs();
    for (velocity, mut transform) in &mut query {
        if velocity.0 != Vec3::ZERO {
            transform.translation += velocity.0 * dt;
        }
    }
}

/// Checks that a translation and Euler angles (degrees) are finite; the error names the component.
pub(super) fn finite_placement(
    translation: Vec3,
    rotation_degrees: Vec3,
) -> Result<(), ClothError> {
    finite_vec3(
        ["translation.x", "translation.y", "translation.z"],
        translation,
    )?;
    finite_vec3(
        [
            "rotation_degrees.x",
            "rotation_degrees.y",
            "rotation_degrees.z",
        ],
        rotation_degrees,
    )
}

pub(super) fn placement(translation: Vec3, rotation_degrees: Vec3) -> Transform {
    let r = rotation_degrees * (std::f32::consts::PI / 180.0);
    Transform::from_translation(translation).with_rotation(Quat::from_euler(
        bevy::math::EulerRot::XYZ,
        r.x,
        r.y,
        r.z,
    ))
}
