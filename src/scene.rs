//! Scene files: a RON description of one cloth and its surroundings (colliders, wind), used by `cloth_cli`, the tests
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
//!     wind: Some((velocity: (6.0, 0.0, 0.0), gusts: Some((seed: 7)))),
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

use crate::components::{
    AIR_DENSITY, Cloth, ClothCollider, ClothConfig, ClothPins, ClothTargets,
    DEFAULT_COLLIDER_MARGIN, TargetWeights, Wind, WindZone,
};
use crate::error::{ClothError, finite_vec3, non_negative, positive};
use crate::plugin::ClothSystems;
use crate::sim::{
    ClothModel, ColliderShape, Friction, GridSpec, Gusts, SolverSettings, WindZoneShape,
};

/// Largest scene file [`ClothScene::load`] reads, bytes (64 MiB: room for the pins and target
/// weights of a cloth of [`MAX_PARTICLES`](crate::sim::MAX_PARTICLES) particles written out).
pub const MAX_SCENE_BYTES: usize = 64 << 20;

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

/// Checks that a translation and Euler angles (degrees) are finite; the error names the component.
fn finite_placement(translation: Vec3, rotation_degrees: Vec3) -> Result<(), ClothError> {
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

fn placement(translation: Vec3, rotation_degrees: Vec3) -> Transform {
    let r = rotation_degrees * (std::f32::consts::PI / 180.0);
    Transform::from_translation(translation).with_rotation(Quat::from_euler(
        bevy::math::EulerRot::XYZ,
        r.x,
        r.y,
        r.z,
    ))
}

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
    /// Target weights, one per particle ([`ClothTargets`] with [`TargetWeights::Values`]): each
    /// particle with a weight stays near its rest position under the cloth's transform (weight 0
    /// pins it; a negative weight leaves it free). None by default.
    #[serde(default)]
    pub target_weights: Option<Vec<f32>>,
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
    /// Wind and wind zones; none by default (no aerodynamic forces at all).
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

    /// Reads, parses and validates a scene file of at most [`MAX_SCENE_BYTES`] (a longer one is
    /// refused without being read).
    pub fn load(path: impl AsRef<Path>) -> Result<Self, ClothError> {
        use std::io::Read;
        let path = path.as_ref();
        let cannot =
            |e: std::io::Error| ClothError::Scene(format!("cannot read {}: {e}", path.display()));
        let mut text = String::new();
        std::fs::File::open(path)
            .map_err(cannot)?
            .take(MAX_SCENE_BYTES as u64 + 1)
            .read_to_string(&mut text)
            .map_err(cannot)?;
        crate::error::at_most("scene file bytes", text.len(), MAX_SCENE_BYTES, || {
            format!("MAX_SCENE_BYTES; reading {} stopped there", path.display())
        })?;
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
        crate::error::at_most("pins", self.pins.len(), count, || {
            format!("one per particle of the cloth, which has {count}")
        })?;
        if let Some(&index) = self.pins.iter().find(|&&p| p as usize >= count) {
            return Err(ClothError::PinOutOfRange { index, count });
        }
        if let Some(weights) = &self.target_weights {
            if weights.len() != count {
                return Err(ClothError::InvalidTargets {
                    what: format!(
                        "target_weights has {} weights for a cloth of {count} particles",
                        weights.len()
                    ),
                });
            }
            if let Some(&w) = weights.iter().find(|w| !w.is_finite()) {
                return Err(ClothError::InvalidValue {
                    field: "target_weights",
                    expected: "finite",
                    value: w as f64,
                });
            }
        }
        finite_placement(self.translation, self.rotation_degrees)?;
        for (i, c) in self.colliders.iter().enumerate() {
            c.validate().map_err(|e| ClothError::InScene {
                location: format!("colliders[{i}]"),
                error: Box::new(e),
            })?;
        }
        if let Some(wind) = &self.wind {
            wind.validate()?;
        }
        Ok(())
    }

    /// The cloth's placement.
    pub fn transform(&self) -> Transform {
        placement(self.translation, self.rotation_degrees)
    }

    /// Spawns the scene into a world (validated when parsed): the cloth entity, returned, its
    /// colliders, and its wind (the [`Wind`] resource, replacing any, and [`WindZone`] entities).
    /// Moving colliders need [`ScenePlugin`] (which the harness' `headless_app` adds).
    pub fn spawn(&self, world: &mut World) -> Result<Entity, ClothError> {
        for c in &self.colliders {
            world.spawn(c.bundle()?);
        }
        if let Some(wind) = &self.wind {
            wind.validate()?;
            for z in &wind.zones {
                world.spawn(z.bundle()?);
            }
            world.insert_resource(wind.resource());
        }
        let mut cloth = world.spawn(self.bundle());
        if let Some(targets) = self.targets() {
            cloth.insert(targets);
        }
        Ok(cloth.id())
    }

    /// The cloth's targets, when the scene gives target weights.
    pub fn targets(&self) -> Option<ClothTargets> {
        self.target_weights.as_ref().map(|w| ClothTargets {
            weights: TargetWeights::Values(w.clone()),
        })
    }

    /// The cloth's topology.
    pub fn model(&self) -> Result<ClothModel, ClothError> {
        match &self.cloth {
            SceneCloth::Grid(spec) => ClothModel::grid(spec),
        }
    }

    /// The components of the scene's cloth entity (but its [`targets`](Self::targets), which
    /// [`spawn`](Self::spawn) adds). Display interpolation is off, so the mesh shows exactly the
    /// simulated state.
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
    fn wind_parses_with_defaults() {
        let s = ClothScene::from_ron(
            "(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)), wind: Some((
                velocity: (6.0, 0.0, 0.0),
                gusts: Some((seed: 7, strength: 0.4)),
                zones: [
                    (shape: Sphere(radius: 0.5), translation: (0.0, 1.0, 0.0), velocity: (0.0, 2.0, 0.0)),
                    (shape: Cuboid(half_size: (1.0, 0.5, 1.0)), rotation_degrees: (0.0, 45.0, 0.0),
                     velocity: (1.0, 0.0, 0.0), gusts: Some(()), falloff: 0.0),
                ],
            )))",
        )
        .unwrap();
        let wind = s.wind.as_ref().unwrap();
        let resource = wind.resource();
        assert_eq!(resource.velocity, Vec3::new(6.0, 0.0, 0.0));
        assert_eq!(resource.air_density, AIR_DENSITY);
        assert!(resource.enabled);
        let gusts = resource.gusts.unwrap();
        assert_eq!((gusts.seed, gusts.strength), (7, 0.4));
        assert_eq!(gusts.frequency, Gusts::default().frequency);
        let zone = wind.zones[0].component().unwrap();
        assert_eq!(zone.shape, WindZoneShape::Sphere(0.5));
        assert_eq!(zone.falloff, DEFAULT_SCENE_WIND_ZONE_FALLOFF);
        assert_eq!(zone.gusts, None);
        let boxed = wind.zones[1].component().unwrap();
        assert_eq!(boxed.shape, WindZoneShape::Cuboid(Vec3::new(1.0, 0.5, 1.0)));
        assert_eq!(boxed.gusts, Some(Gusts::default()));
        // An empty wind is still air of the default density; `None` is no air at all.
        let still =
            ClothScene::from_ron("(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)), wind: Some(()))")
                .unwrap();
        assert_eq!(still.wind, Some(SceneWind::default()));
        let none = ClothScene::from_ron("(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)), wind: None)")
            .unwrap();
        assert_eq!(none.wind, None);
    }

    #[test]
    fn bad_wind_values_name_the_field() {
        let scene = |wind: &str| {
            ClothScene::from_ron(&format!(
                "(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)), wind: Some({wind}))"
            ))
        };
        for (wind, field) in [
            ("(air_density: -1.0)", "wind.air_density"),
            ("(velocity: (inf, 0.0, 0.0))", "wind.velocity"),
            ("(gusts: Some((strength: -0.5)))", "wind.gusts.strength"),
            ("(gusts: Some((frequency: NaN)))", "wind.gusts.frequency"),
            ("(gusts: Some((turbulence: -1.0)))", "wind.gusts.turbulence"),
            (
                "(zones: [(shape: Sphere(radius: 0.0), velocity: (1.0, 0.0, 0.0))])",
                "wind.zones.shape.radius",
            ),
            (
                "(zones: [(shape: Cuboid(half_size: (1.0, -1.0, 1.0)), velocity: (1.0, 0.0, 0.0))])",
                "wind.zones.shape.half_size",
            ),
            (
                "(zones: [(shape: Sphere(radius: 1.0), velocity: (1.0, 0.0, 0.0), falloff: 1.5)])",
                "wind.zones.falloff",
            ),
            (
                "(zones: [(shape: Sphere(radius: 1.0), velocity: (NaN, 0.0, 0.0))])",
                "wind.zones.velocity",
            ),
            (
                "(zones: [(shape: Sphere(radius: 1.0), velocity: (1.0, 0.0, 0.0), gusts: Some((strength: -2.0)))])",
                "wind.zones.gusts.strength",
            ),
            // Unknown and missing fields are named by the parser.
            ("(speed: 3.0)", "speed"),
            ("(gusts: Some((sead: 3)))", "sead"),
            ("(zones: [(shape: Sphere(radius: 1.0))])", "velocity"),
        ] {
            let e = scene(wind).unwrap_err();
            assert!(e.to_string().contains(field), "{wind}: {e}");
        }
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
