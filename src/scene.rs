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
//! )
//! ```

use std::path::Path;

use bevy::ecs::prelude::*;
use bevy::math::{Quat, Vec3};
use bevy::transform::components::Transform;
use serde::{Deserialize, Serialize};

use crate::components::{Cloth, ClothConfig, ClothPins};
use crate::error::{ClothError, positive};
use crate::sim::{ClothModel, GridSpec, SolverSettings};

/// The cloth of a scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum SceneCloth {
    /// The canonical grid cloth.
    Grid(GridSpec),
}

/// A collider in a scene. No collider shapes exist yet, so a scene's `colliders` list must be empty.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum SceneCollider {}

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
    /// The fixed time step, s.
    #[serde(default = "default_dt")]
    pub dt: f32,
    /// Integrator, substeps, iterations, stiffness, mass, damping, gravity.
    #[serde(default)]
    pub solver: SolverSettings,
    /// Colliders (none exist yet).
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

    /// Checks every value the scene carries, including that the pins exist.
    pub fn validate(&self) -> Result<(), ClothError> {
        positive("dt", self.dt)?;
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
        if !(self.translation.is_finite() && self.rotation_degrees.is_finite()) {
            return Err(ClothError::InvalidValue {
                field: "translation/rotation_degrees",
                expected: "finite",
                value: f64::NAN,
            });
        }
        Ok(())
    }

    /// The cloth's placement.
    pub fn transform(&self) -> Transform {
        let r = self.rotation_degrees * (std::f32::consts::PI / 180.0);
        Transform::from_translation(self.translation).with_rotation(Quat::from_euler(
            bevy::math::EulerRot::XYZ,
            r.x,
            r.y,
            r.z,
        ))
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
    }
}
