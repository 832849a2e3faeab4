//! The point of view of a scene: a [`ClothViewer`] that flies back and forth along a line, for
//! the level of detail of its cloths.

use bevy::ecs::prelude::*;
use bevy::math::Vec3;
use bevy::time::Time;
use bevy::transform::components::Transform;
use serde::{Deserialize, Serialize};

use crate::error::{ClothError, finite_vec3, positive};
use crate::lod::ClothViewer;

fn default_fov() -> f32 {
    45.0
}

fn default_aspect() -> f32 {
    16.0 / 9.0
}

/// A viewer that flies from `from` to `to` in `seconds`, then back, and so on, looking at
/// `look_at` (or ahead along its way); the cloths' [`ClothLod`](crate::ClothLod) levels are
/// chosen for it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneViewer {
    /// Where it starts, m.
    pub from: Vec3,
    /// Where it turns back, m.
    #[serde(default)]
    pub to: Option<Vec3>,
    /// Seconds from one end to the other.
    #[serde(default = "default_seconds")]
    pub seconds: f32,
    /// The point it looks at; ahead along its way (or down −Z, standing still) by default.
    #[serde(default)]
    pub look_at: Option<Vec3>,
    /// Vertical field of view, degrees.
    #[serde(default = "default_fov")]
    pub fov_y_degrees: f32,
    /// Width over height of the view.
    #[serde(default = "default_aspect")]
    pub aspect: f32,
}

fn default_seconds() -> f32 {
    60.0
}

impl SceneViewer {
    /// A viewer standing at `from`, looking down −Z with the default view.
    pub fn at(from: Vec3) -> Self {
        Self {
            from,
            to: None,
            seconds: default_seconds(),
            look_at: None,
            fov_y_degrees: default_fov(),
            aspect: default_aspect(),
        }
    }

    /// Checks the values.
    pub fn validate(&self) -> Result<(), ClothError> {
        finite_vec3(
            ["viewer.from.x", "viewer.from.y", "viewer.from.z"],
            self.from,
        )?;
        finite_vec3(
            ["viewer.to.x", "viewer.to.y", "viewer.to.z"],
            self.to.unwrap_or(self.from),
        )?;
        finite_vec3(
            ["viewer.look_at.x", "viewer.look_at.y", "viewer.look_at.z"],
            self.look_at.unwrap_or(Vec3::ZERO),
        )?;
        positive("viewer.seconds", self.seconds)?;
        positive("viewer.aspect", self.aspect)?;
        if !(self.fov_y_degrees > 0.0 && self.fov_y_degrees < 180.0) {
            return Err(ClothError::InvalidValue {
                field: "viewer.fov_y_degrees",
                expected: "in (0, 180)",
                value: self.fov_y_degrees as f64,
            });
        }
        Ok(())
    }

    /// Where it is at time `t`, s, and where it looks.
    pub fn pose(&self, t: f32) -> Transform {
        let to = self.to.unwrap_or(self.from);
        let phase = (t / self.seconds).rem_euclid(2.0);
        let (s, heading) = if phase <= 1.0 {
            (phase, to - self.from)
        } else {
            (2.0 - phase, self.from - to)
        };
        let at = self.from.lerp(to, s);
        let target = self
            .look_at
            .unwrap_or(at + heading.try_normalize().unwrap_or(Vec3::NEG_Z));
        let transform = Transform::from_translation(at);
        if (target - at).cross(Vec3::Y).length_squared() > 1e-12 {
            transform.looking_at(target, Vec3::Y)
        } else {
            transform.looking_at(target, Vec3::Z)
        }
    }

    /// The viewer entity's components.
    pub fn bundle(&self) -> impl Bundle {
        (
            self.pose(0.0),
            ClothViewer::perspective(self.fov_y_degrees.to_radians(), self.aspect),
            Flight(*self),
        )
    }
}

/// Flies a scene's viewer along its path.
#[derive(Component, Debug, Clone, Copy)]
pub struct Flight(pub SceneViewer);

/// Moves every flying viewer to where it is at the end of this step.
pub(super) fn fly_viewers(time: Res<Time>, mut viewers: Query<(&Flight, &mut Transform)>) {
    let t = time.elapsed_secs();
    for (flight, mut transform) in &mut viewers {
        *transform = flight.0.pose(t);
    }
}
