//! Scene files: a RON description of one cloth and its surroundings, used by `cloth_cli`, the tests
//! and the presets in `assets/scenes/`. Parsing and validation only; spawning is a few lines of ECS.
//!
//! ```ron
//! (
//!     cloth: Grid((nx: 16, ny: 16, spacing: 0.1)),
//!     translation: (0.0, 2.0, 0.0),
//!     pins: [0, 15],
//!     dt: 0.016666668,
//!     solver: (substeps: 20, stiffness: (structural: 5000.0, shear: 5000.0, bend: 50.0)),
//!     colliders: [
//!         (shape: Sphere(radius: 0.4), translation: (0.0, 1.0, 0.0), margin: 0.01),
//!         (shape: Plane(normal: (0.0, 1.0, 0.0)), friction: (static_coefficient: 0.8, kinetic_coefficient: 0.6)),
//!     ],
//! )
//! ```

use std::path::Path;

use bevy::app::{App, FixedUpdate, Plugin};
use bevy::ecs::prelude::*;
use bevy::math::primitives::{Capsule3d, Cuboid, InfinitePlane3d, Sphere};
use bevy::math::{Dir3, Quat, Vec3};
use bevy::time::Time;
use bevy::transform::components::Transform;
use serde::{Deserialize, Serialize};

use crate::components::{Cloth, ClothCollider, ClothConfig, ClothPins, DEFAULT_COLLIDER_MARGIN};
use crate::error::{ClothError, finite_vec3};
use crate::plugin::ClothSystems;
use crate::sim::{ClothModel, ColliderShape, Friction, GridSpec, SolverSettings};

/// The cloth of a scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum SceneCloth {
    /// The canonical grid cloth.
    Grid(GridSpec),
}

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
}

impl SceneCollider {
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
        finite_vec3(
            ["translation.x", "translation.y", "translation.z"],
            self.translation,
        )?;
        finite_vec3(
            [
                "rotation_degrees.x",
                "rotation_degrees.y",
                "rotation_degrees.z",
            ],
            self.rotation_degrees,
        )?;
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
/// stepped (so a collider's first step is from where it was spawned). Added by [`ScenePlugin`]; used by scene colliders with a `velocity`.
#[derive(Component, Debug, Clone, Copy, PartialEq, Default)]
pub struct ConstantVelocity(pub Vec3);

fn move_at_constant_velocity(
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

/// What scenes need beyond [`crate::ClothPlugin`]: moving [`ConstantVelocity`] entities in
/// `FixedUpdate` after [`ClothSystems::Step`].
#[derive(Debug, Default, Clone, Copy)]
pub struct ScenePlugin;

impl Plugin for ScenePlugin {
    fn build(&self, app: &mut App) {
        app.add_systems(
            FixedUpdate,
            move_at_constant_velocity.after(ClothSystems::Step),
        );
    }
}

fn placement(translation: Vec3, rotation_degrees: Vec3) -> Transform {
    let r = rotation_degrees * (std::f32::consts::PI / 180.0);
    Transform::from_translation(translation).with_rotation(Quat::from_euler(
        bevy::math::EulerRot::XYZ,
        r.x,
        r.y,
        r.z,
    ))
}

/// Wind in a scene. No wind model exists yet, so a scene's `wind` must be `None`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum SceneWind {}

fn default_dt() -> f32 {
    1.0 / 60.0
}

/// One simulated cloth with its settings and environment, as stored in a `.ron` file.
///
/// Every field but `cloth` has a default; unknown fields are an error.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClothScene {
    /// What to simulate.
    pub cloth: SceneCloth,
    /// Where the cloth's local origin is placed in the world, m.
    #[serde(default)]
    pub translation: Vec3,
    /// Rotation of the cloth, as Euler angles XYZ in degrees.
    #[serde(default)]
    pub rotation_degrees: Vec3,
    /// Particles pinned at their initial positions.
    #[serde(default)]
    pub pins: Vec<u32>,
    /// The fixed time step, s: [`MIN_FIXED_STEP`](crate::plugin::MIN_FIXED_STEP)`..=`
    /// [`MAX_FIXED_STEP`](crate::plugin::MAX_FIXED_STEP).
    #[serde(default = "default_dt")]
    pub dt: f32,
    /// Integrator, substeps, iterations, stiffness, mass, damping, gravity.
    #[serde(default)]
    pub solver: SolverSettings,
    /// Kinematic colliders.
    #[serde(default)]
    pub colliders: Vec<SceneCollider>,
    /// Wind (none exists yet).
    #[serde(default)]
    pub wind: Option<SceneWind>,
}

impl ClothScene {
    /// Parses and validates a scene from RON text.
    pub fn from_ron(text: &str) -> Result<Self, ClothError> {
        let scene: Self = ron::from_str(text).map_err(|e| ClothError::Scene(e.to_string()))?;
        scene.validate()?;
        Ok(scene)
    }

    /// Reads, parses and validates a scene file.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, ClothError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path)
            .map_err(|e| ClothError::Scene(format!("cannot read {}: {e}", path.display())))?;
        Self::from_ron(&text).map_err(|e| ClothError::Scene(format!("{}: {e}", path.display())))
    }

    /// Checks every value the scene carries, including that the pins exist. The error names the
    /// field and value; an error in a collider is a [`ClothError::InScene`] saying which one
    /// (`colliders[2]`).
    pub fn validate(&self) -> Result<(), ClothError> {
        crate::plugin::validate_fixed_step(self.dt)?;
        self.solver.validate()?;
        let count = match &self.cloth {
            SceneCloth::Grid(spec) => {
                spec.validate()?;
                spec.nx as usize * spec.ny as usize
            }
        };
        if let Some(&index) = self.pins.iter().find(|&&p| p as usize >= count) {
            return Err(ClothError::PinOutOfRange { index, count });
        }
        finite_vec3(
            ["translation.x", "translation.y", "translation.z"],
            self.translation,
        )?;
        finite_vec3(
            [
                "rotation_degrees.x",
                "rotation_degrees.y",
                "rotation_degrees.z",
            ],
            self.rotation_degrees,
        )?;
        for (i, c) in self.colliders.iter().enumerate() {
            c.validate().map_err(|e| ClothError::InScene {
                location: format!("colliders[{i}]"),
                error: Box::new(e),
            })?;
        }
        Ok(())
    }

    /// The cloth's placement.
    pub fn transform(&self) -> Transform {
        placement(self.translation, self.rotation_degrees)
    }

    /// Spawns the scene into a world (validated when parsed): the cloth entity, returned, and its
    /// colliders. Moving colliders need [`ScenePlugin`] (which [`crate::plugin::headless_app`]
    /// adds).
    pub fn spawn(&self, world: &mut World) -> Result<Entity, ClothError> {
        for c in &self.colliders {
            world.spawn(c.bundle()?);
        }
        Ok(world.spawn(self.bundle()).id())
    }

    /// The cloth's topology.
    pub fn model(&self) -> Result<ClothModel, ClothError> {
        match &self.cloth {
            SceneCloth::Grid(spec) => ClothModel::grid(spec),
        }
    }

    /// The components of the scene's cloth entity. Display interpolation is off, so the mesh
    /// shows exactly the simulated state.
    pub fn bundle(&self) -> impl Bundle {
        let cloth = match &self.cloth {
            SceneCloth::Grid(spec) => Cloth::grid(*spec),
        };
        (
            cloth,
            ClothConfig {
                solver: self.solver,
                interpolate: false,
                ..Default::default()
            },
            ClothPins::new(self.pins.iter().copied()),
            self.transform(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn minimal_scene_gets_defaults() {
        let s = ClothScene::from_ron("(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)))").unwrap();
        assert_eq!(s.solver, SolverSettings::default());
        assert_eq!(s.dt, 1.0 / 60.0);
    }

    #[test]
    fn unknown_fields_and_bad_values_are_errors() {
        let e = ClothScene::from_ron("(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)), colour: 3)")
            .unwrap_err();
        assert!(e.to_string().contains("colour"), "{e}");
        let e = ClothScene::from_ron("(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)), pins: [12])")
            .unwrap_err();
        assert!(e.to_string().contains("12"), "{e}");
        let e = ClothScene::from_ron("(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)), dt: -1.0)")
            .unwrap_err();
        assert!(e.to_string().contains("dt"), "{e}");
        let e = ClothScene::from_ron(
            "(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)), solver: (substeps: 0))",
        )
        .unwrap_err();
        assert!(e.to_string().contains("substeps"), "{e}");
        assert!(ClothScene::from_ron("(cloth: Grid((nx: 4, ny: 3").is_err());
        let e = ClothScene::from_ron(
            "(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)), colliders: [(shape: Sphere(radius: -1.0))])",
        )
        .unwrap_err();
        assert!(e.to_string().contains("collider.radius"), "{e}");
        let e = ClothScene::from_ron(
            "(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)), colliders: [(shape: Plane(normal: (0.0, 0.0, 0.0)))])",
        )
        .unwrap_err();
        assert!(e.to_string().contains("normal"), "{e}");
    }

    #[test]
    fn colliders_parse_with_defaults() {
        let s = ClothScene::from_ron(
            "(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)), colliders: [
                (shape: Sphere(radius: 0.5), translation: (0.0, 1.0, 0.0)),
                (shape: Capsule(radius: 0.1, half_length: 0.3), velocity: (1.0, 0.0, 0.0)),
                (shape: Cuboid(half_size: (1.0, 0.5, 1.0)), friction: (static_coefficient: 0.9, kinetic_coefficient: 0.7)),
                (shape: Plane(normal: (0.0, 2.0, 0.0)), margin: 0.02),
            ])",
        )
        .unwrap();
        assert_eq!(s.colliders.len(), 4);
        assert_eq!(s.colliders[0].margin, DEFAULT_COLLIDER_MARGIN);
        assert_eq!(s.colliders[1].velocity, Vec3::X);
        let plane = s.colliders[3].component().unwrap();
        assert_eq!(
            plane.shape,
            ColliderShape::HalfSpace(InfinitePlane3d::new(Vec3::Y))
        );
    }
}
