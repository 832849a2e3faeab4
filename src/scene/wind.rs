//! The air of a scene: the global wind and local wind zones.

use bevy::math::Vec3;
use bevy::prelude::Bundle;
use serde::{Deserialize, Serialize};

use super::colliders::placement;
use crate::components::{AIR_DENSITY, Wind, WindZone};
use crate::error::{ClothError, non_negative, positive};
use crate::sim::{Gusts, WindZoneShape};

/// The shape of a scene wind zone (see [`WindZoneShape`]), centred on the zone's translation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum SceneWindZoneShape {
    /// A ball.
    Sphere {
        /// Radius, m.
        radius: f32,
    },
    /// A box, turned by the zone's rotation.
    Cuboid {
        /// Half extents, m.
        half_size: Vec3,
    },
}

impl SceneWindZoneShape {
    fn shape(&self) -> Result<WindZoneShape, ClothError> {
        match *self {
            SceneWindZoneShape::Sphere { radius } => {
                positive("wind.zones.shape.radius", radius)?;
                Ok(WindZoneShape::Sphere(radius))
            }
            SceneWindZoneShape::Cuboid { half_size } => {
                for h in half_size.to_array() {
                    positive("wind.zones.shape.half_size", h)?;
                }
                Ok(WindZoneShape::Cuboid(half_size))
            }
        }
    }
}

fn default_falloff() -> f32 {
    DEFAULT_SCENE_WIND_ZONE_FALLOFF
}

/// Default [`SceneWindZone::falloff`]: the zone's wind fades out over its outer fifth.
pub const DEFAULT_SCENE_WIND_ZONE_FALLOFF: f32 = 0.2;

/// A local wind in a scene: a [`WindZone`] entity placed by `translation` and `rotation_degrees`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneWindZone {
    /// Extent of the zone.
    pub shape: SceneWindZoneShape,
    /// Centre of the zone, m.
    #[serde(default)]
    pub translation: Vec3,
    /// Rotation of the zone as Euler angles XYZ, degrees.
    #[serde(default)]
    pub rotation_degrees: Vec3,
    /// Wind added to the global wind inside the zone, m/s (world frame).
    pub velocity: Vec3,
    /// Gusts of the zone's wind (none by default).
    #[serde(default)]
    pub gusts: Option<Gusts>,
    /// Fraction (0..=1) of the zone's size over which its wind fades out at the edge; default
    /// [`DEFAULT_SCENE_WIND_ZONE_FALLOFF`].
    #[serde(default = "default_falloff")]
    pub falloff: f32,
}

impl SceneWindZone {
    /// The zone component; the error names the bad field.
    pub fn component(&self) -> Result<WindZone, ClothError> {
        let shape = self.shape.shape()?;
        finite_vec("wind.zones.velocity", self.velocity)?;
        finite_vec("wind.zones.translation", self.translation)?;
        finite_vec("wind.zones.rotation_degrees", self.rotation_degrees)?;
        if let Some(g) = &self.gusts {
            g.validate_as([
                "wind.zones.gusts.strength",
                "wind.zones.gusts.frequency",
                "wind.zones.gusts.turbulence",
            ])?;
        }
        if !(0.0..=1.0).contains(&self.falloff) {
            return Err(ClothError::InvalidValue {
                field: "wind.zones.falloff",
                expected: "in 0..=1",
                value: self.falloff as f64,
            });
        }
        Ok(WindZone {
            shape,
            velocity: self.velocity,
            gusts: self.gusts,
            falloff: self.falloff,
        })
    }

    /// The components of the zone's entity.
    pub fn bundle(&self) -> Result<impl Bundle, ClothError> {
        Ok((
            self.component()?,
            placement(self.translation, self.rotation_degrees),
        ))
    }
}

/// The air of a scene: the global [`Wind`] (mean velocity, gusts, air density) and any number of
/// local [`SceneWindZone`]s. Every field is optional; unknown fields are errors.
///
/// ```ron
/// wind: Some((
///     velocity: (7.0, 0.0, -1.5),
///     gusts: Some((seed: 42, strength: 0.45, frequency: 0.7, turbulence: 0.2)),
///     air_density: 1.225,
///     zones: [(shape: Sphere(radius: 0.6), translation: (1.2, 2.6, 0.0), velocity: (0.0, 3.0, 0.0))],
/// )),
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SceneWind {
    /// Mean wind velocity, m/s; default zero (still air, which still damps the cloth).
    pub velocity: Vec3,
    /// Seeded gusts on the mean wind; none by default. Fields as in [`Gusts`], each optional.
    pub gusts: Option<Gusts>,
    /// Air density, kg/m³; default [`AIR_DENSITY`].
    pub air_density: f32,
    /// Local winds.
    pub zones: Vec<SceneWindZone>,
}

impl Default for SceneWind {
    fn default() -> Self {
        Self {
            velocity: Vec3::ZERO,
            gusts: None,
            air_density: AIR_DENSITY,
            zones: Vec::new(),
        }
    }
}

impl SceneWind {
    /// Checks every value, including the zones'; the error names the bad field.
    pub fn validate(&self) -> Result<(), ClothError> {
        finite_vec("wind.velocity", self.velocity)?;
        non_negative("wind.air_density", self.air_density)?;
        if let Some(g) = &self.gusts {
            g.validate_as([
                "wind.gusts.strength",
                "wind.gusts.frequency",
                "wind.gusts.turbulence",
            ])?;
        }
        crate::sim::wind::validate_zone_count(self.zones.len())?;
        for z in &self.zones {
            z.component()?;
        }
        Ok(())
    }

    /// The global wind resource.
    pub fn resource(&self) -> Wind {
        Wind {
            velocity: self.velocity,
            gusts: self.gusts,
            air_density: self.air_density,
            enabled: true,
        }
    }
}

/// Checks that the three gust amplitudes and the rate are finite and not negative.
fn finite_vec(field: &'static str, v: Vec3) -> Result<(), ClothError> {
    match v.to_array().into_iter().find(|c| !c.is_finite()) {
        None => Ok(()),
        Some(c) => Err(ClothError::InvalidValue {
            field,
            expected: "finite",
            value: c as f64,
        }),
    }
}
