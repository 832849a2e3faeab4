//! Scene files: a RON description of a cloth, the copies of it to lay out, its surroundings
//! (colliders, wind) and further cloths beside it, used by `cloth_cli`, the tests and the presets
//! in `assets/scenes/`. Parsing and validation, and spawning into a world.
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
//!
//! A closed cloth with the air inside it, and a hundred of them on a floor they share:
//!
//! ```ron
//! (
//!     cloth: Icosphere(radius: 0.15, subdivisions: 3),
//!     translation: (0.0, 0.5, 0.0),
//!     solver: (pressure: Volume(scale: 1.0, bulk_modulus: 100000.0)),
//!     copies: (count: 100, spacing: 0.5),
//!     colliders: [(shape: Plane(normal: (0.0, 1.0, 0.0)), shared: true)],
//! )
//! ```
//!
//! A crowd: a hundred characters in capes walking circles, each a third of a second ahead of the
//! one before, and beside them a flag in the wind:
//!
//! ```ron
//! (
//!     cloth: Cape(nx: 20, ny: 25),
//!     walk: (speed: 1.0, radius: 2.0, sway: 0.3),
//!     copies: (count: 100, spacing: 6.0, phase: 0.33),
//!     also: [(
//!         cloth: Grid((nx: 32, ny: 24, spacing: 0.05, plane: Vertical)),
//!         translation: (-6.0, 3.0, 0.0),
//!         pins: [0, 31],
//!     )],
//!     wind: Some((velocity: (4.0, 0.0, 1.0), gusts: Some((seed: 7)))),
//! )
//! ```

pub mod character;
mod colliders;
mod viewer;
mod wind;

use std::path::Path;

use bevy::app::{App, FixedUpdate, Plugin};
use bevy::ecs::prelude::*;
use bevy::math::Vec3;
use bevy::transform::components::Transform;
use serde::{Deserialize, Serialize};

pub use character::{SceneWalk, Walker};
pub use colliders::{ConstantVelocity, SceneCollider, SceneShape};
pub use viewer::{Flight, SceneViewer};
pub use wind::{DEFAULT_SCENE_WIND_ZONE_FALLOFF, SceneWind, SceneWindZone, SceneWindZoneShape};

use crate::components::{Cloth, ClothConfig, ClothPins, ClothTargets, TargetWeights};
use crate::error::{ClothError, finite, positive};
use crate::lod::{ClothBudget, ClothLod};
use crate::plugin::ClothSystems;
use crate::sim::{ClothModel, GridSpec, SolverSettings};
use colliders::{finite_placement, move_at_constant_velocity, placement};

/// Largest scene file [`ClothScene::load`] reads, bytes (64 MiB: room for the pins and target
/// weights of a cloth of [`MAX_PARTICLES`](crate::sim::MAX_PARTICLES) particles written out).
pub const MAX_SCENE_BYTES: usize = 64 << 20;

/// Most copies a scene lays out ([`SceneCopies::count`]).
pub const MAX_SCENE_COPIES: u32 = 10_000;

/// Most particles of all of a scene's copies together (16 × [`MAX_PARTICLES`](crate::sim::MAX_PARTICLES)).
pub const MAX_SCENE_PARTICLES: usize = 16 * crate::sim::MAX_PARTICLES;

/// The cloth of a scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum SceneCloth {
    /// The canonical grid cloth.
    Grid(GridSpec),
    /// A closed sphere ([`ClothModel::icosphere`]), centred on the cloth's origin.
    Icosphere {
        /// Radius, m.
        radius: f32,
        /// Times the icosahedron's triangles are split in four (3: 642 particles).
        subdivisions: u32,
    },
    /// A closed box ([`ClothModel::cuboid`]), centred on the cloth's origin.
    Cuboid {
        /// Size along X, Y and Z, m.
        size: Vec3,
        /// Side of its quads, about, m.
        spacing: f32,
    },
    /// A character's cape ([`character::Cape`]) of `nx` × `ny` particles (at least 2 each),
    /// skinned to a two-joint torso that walks as the scene's [`walk`](ClothScene::walk) says; its
    /// collar is pinned to the skin and the rest held near it ([`SolverSettings::targets`]).
    Cape {
        /// Particles across.
        nx: u32,
        /// Particles down.
        ny: u32,
    },
}

impl SceneCloth {
    /// Checks the values and returns the number of particles, without building a large cloth
    /// (a box is built; its size is bounded as it is).
    pub fn particle_count(&self) -> Result<usize, ClothError> {
        match self {
            SceneCloth::Grid(spec) => {
                spec.validate()?;
                Ok(spec.nx as usize * spec.ny as usize)
            }
            &SceneCloth::Icosphere {
                radius,
                subdivisions,
            } => {
                positive("icosphere radius", radius)?;
                ClothModel::icosphere_particle_count(subdivisions)
            }
            SceneCloth::Cuboid { .. } => Ok(self.model()?.particle_count()),
            &SceneCloth::Cape { nx, ny } => {
                let count = nx as u64 * ny as u64;
                if nx < 2 || ny < 2 || count > crate::sim::MAX_PARTICLES as u64 {
                    return Err(ClothError::InvalidValue {
                        field: "cape nx × ny",
                        expected: "at least 2 each and at most MAX_PARTICLES in all",
                        value: count as f64,
                    });
                }
                Ok(count as usize)
            }
        }
    }

    /// The cloth's topology.
    pub fn model(&self) -> Result<ClothModel, ClothError> {
        match *self {
            SceneCloth::Grid(spec) => ClothModel::grid(&spec),
            SceneCloth::Icosphere {
                radius,
                subdivisions,
            } => ClothModel::icosphere(radius, subdivisions),
            SceneCloth::Cuboid { size, spacing } => ClothModel::cuboid(size, spacing),
            SceneCloth::Cape { nx, ny } => {
                self.particle_count()?;
                let cape = character::Cape::new(nx as usize, ny as usize);
                let indices: Vec<u32> = cape
                    .mesh
                    .indices()
                    .map_or_else(Vec::new, |i| i.iter().map(|i| i as u32).collect());
                ClothModel::from_mesh(&cape.rest, None, &indices, 3)
            }
        }
    }

    /// The cloth component: a grid, or the model (built here) of a closed shape; `None` for a
    /// cape, whose cloth is its mesh asset (spawned by [`ClothScene::spawn_copies`]).
    pub fn component(&self) -> Result<Option<Cloth>, ClothError> {
        Ok(match self {
            SceneCloth::Grid(spec) => Some(Cloth::grid(*spec)),
            SceneCloth::Cape { .. } => None,
            _ => Some(Cloth::from_model(self.model()?)),
        })
    }
}

fn default_count() -> u32 {
    1
}

fn default_copy_spacing() -> f32 {
    DEFAULT_COPY_SPACING
}

/// Default [`SceneCopies::spacing`], m: copies of a scene a few metres across never meet.
pub const DEFAULT_COPY_SPACING: f32 = 100.0;

/// Copies of a scene's cloth laid out on a square grid in the XZ plane: copy `k` sits in column
/// `k % columns` (along +X) and row `k / columns` (along +Z), `spacing` apart, the first where the
/// scene puts it, its character's walk `k × phase` seconds ahead of the first's. Each copy brings
/// its own colliders (but those marked [`shared`](SceneCollider::shared)) and wind zones; the
/// global wind is one.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneCopies {
    /// Number of copies, 1..=[`MAX_SCENE_COPIES`]; default 1.
    #[serde(default = "default_count")]
    pub count: u32,
    /// Copies per row; default the smallest square that holds them (`⌈√count⌉`).
    #[serde(default)]
    pub columns: Option<u32>,
    /// Distance between neighbouring copies, m; default [`DEFAULT_COPY_SPACING`].
    #[serde(default = "default_copy_spacing")]
    pub spacing: f32,
    /// Seconds each copy's walk ([`ClothScene::walk`]) runs ahead of the copy before it; 0 by
    /// default (all in step).
    #[serde(default)]
    pub phase: f32,
}

impl Default for SceneCopies {
    fn default() -> Self {
        Self {
            count: 1,
            columns: None,
            spacing: DEFAULT_COPY_SPACING,
            phase: 0.0,
        }
    }
}

impl SceneCopies {
    /// Checks the count, columns and spacing; the error names the field.
    pub fn validate(&self) -> Result<(), ClothError> {
        if !(1..=MAX_SCENE_COPIES).contains(&self.count) {
            return Err(ClothError::InvalidValue {
                field: "copies.count",
                expected: "1..=MAX_SCENE_COPIES (10000)",
                value: self.count as f64,
            });
        }
        if self.columns == Some(0) {
            return Err(ClothError::InvalidValue {
                field: "copies.columns",
                expected: "at least 1",
                value: 0.0,
            });
        }
        positive("copies.spacing", self.spacing)?;
        finite("copies.phase", self.phase)
    }

    /// The offset of copy `k` from the first, m.
    pub fn offset(&self, k: u32) -> Vec3 {
        let columns = self
            .columns
            .unwrap_or_else(|| (self.count as f64).sqrt().ceil() as u32)
            .max(1);
        Vec3::new((k % columns) as f32, 0.0, (k / columns) as f32) * self.spacing
    }
}

/// What scenes need beyond [`crate::ClothPlugin`], in `FixedUpdate`: moving [`ConstantVelocity`]
/// entities after [`ClothSystems::Step`], and posing [`Walker`]s and flying [`Flight`] viewers
/// before the cloths step.
#[derive(Debug, Default, Clone, Copy)]
pub struct ScenePlugin;

impl Plugin for ScenePlugin {
    fn build(&self, app: &mut App) {
        app.add_systems(
            FixedUpdate,
            (
                move_at_constant_velocity.after(ClothSystems::Step),
                character::walk_characters.before(ClothSystems::Prepare),
                viewer::fly_viewers.before(ClothSystems::Prepare),
            ),
        );
    }
}

fn default_dt() -> f32 {
    1.0 / 60.0
}

/// A simulated cloth with its settings and environment, how many copies of it to lay out, and
/// further cloths beside it, as stored in a `.ron` file.
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
    /// How a [`SceneCloth::Cape`]'s character moves; standing still by default.
    #[serde(default)]
    pub walk: SceneWalk,
    /// Copies of the cloth, with its colliders and wind zones, side by side; one by default.
    #[serde(default)]
    pub copies: SceneCopies,
    /// Level of detail for each of the copies ([`ClothLod`]); none by default (full quality).
    #[serde(default)]
    pub lod: Option<ClothLod>,
    /// The viewer the levels of detail are chosen for; none by default.
    #[serde(default)]
    pub viewer: Option<SceneViewer>,
    /// A budget for all cloths' steps, ms a frame ([`ClothBudget::new`]: 10% headroom); none by
    /// default.
    #[serde(default)]
    pub budget_ms: Option<f32>,
    /// Further cloths, each a scene of its own (with its colliders, copies and level of detail)
    /// but for the time step, the wind, the viewer and the budget, which are this scene's: each
    /// one's `dt` must equal this one's and the others must be left out. None by default.
    #[serde(default)]
    pub also: Vec<ClothScene>,
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
        self.validate_one()?;
        let mut all = self.particles_of_copies()?;
        for (i, other) in self.also.iter().enumerate() {
            let location = || format!("also[{i}]");
            let nested = |what: &'static str, value: f64| ClothError::InScene {
                location: location(),
                error: Box::new(ClothError::InvalidValue {
                    field: what,
                    expected: "left out: the enclosing scene's applies",
                    value,
                }),
            };
            if other.dt != self.dt {
                return Err(nested("dt", other.dt as f64));
            }
            if other.wind.is_some() {
                return Err(nested("wind", 1.0));
            }
            if other.viewer.is_some() {
                return Err(nested("viewer", 1.0));
            }
            if let Some(ms) = other.budget_ms {
                return Err(nested("budget_ms", ms as f64));
            }
            if !other.also.is_empty() {
                return Err(nested("also", other.also.len() as f64));
            }
            other
                .validate_one()
                .and_then(|()| other.particles_of_copies())
                .map(|count| all = all.saturating_add(count))
                .map_err(|e| ClothError::InScene {
                    location: location(),
                    error: Box::new(e),
                })?;
        }
        crate::error::at_most("particles of all cloths", all, MAX_SCENE_PARTICLES, || {
            "MAX_SCENE_PARTICLES".to_string()
        })
    }

    /// The particles of the scene's own copies.
    fn particles_of_copies(&self) -> Result<usize, ClothError> {
        let all = self
            .cloth
            .particle_count()?
            .saturating_mul(self.copies.count as usize);
        crate::error::at_most("particles of all copies", all, MAX_SCENE_PARTICLES, || {
            "MAX_SCENE_PARTICLES".to_string()
        })?;
        Ok(all)
    }

    /// [`validate`](Self::validate) but for the further cloths.
    fn validate_one(&self) -> Result<(), ClothError> {
        crate::plugin::validate_fixed_step(self.dt)?;
        self.solver.validate()?;
        let count = self.cloth.particle_count()?;
        self.copies.validate()?;
        self.walk.validate()?;
        let is_cape = matches!(self.cloth, SceneCloth::Cape { .. });
        if !is_cape && self.walk != SceneWalk::default() {
            return Err(ClothError::Scene(
                "walk moves a character: it needs a Cape cloth".to_string(),
            ));
        }
        if is_cape && self.target_weights.is_some() {
            return Err(ClothError::Scene(
                "a Cape takes its target weights from its mesh: leave target_weights out"
                    .to_string(),
            ));
        }
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
        if let Some(lod) = &self.lod {
            lod.validate()?;
        }
        if let Some(viewer) = &self.viewer {
            viewer.validate()?;
        }
        if let Some(ms) = self.budget_ms {
            positive("budget_ms", ms)?;
        }
        Ok(())
    }

    /// The cloth's placement.
    pub fn transform(&self) -> Transform {
        placement(self.translation, self.rotation_degrees)
    }

    /// Spawns the scene into a world (validated when parsed): its cloths, their colliders, and its
    /// wind (the [`Wind`](crate::components::Wind) resource, replacing any, and
    /// [`WindZone`](crate::components::WindZone) entities), and returns the first cloth; see
    /// [`spawn_copies`](Self::spawn_copies) for all of them. Moving colliders need
    /// [`ScenePlugin`] (which the harness' `headless_app` adds).
    pub fn spawn(&self, world: &mut World) -> Result<Entity, ClothError> {
        Ok(self.spawn_copies(world)?[0])
    }

    /// [`spawn`](Self::spawn), returning every copy's cloth entity in the order of
    /// [`SceneCopies`] (never empty), then those of the further cloths ([`also`](Self::also)), in
    /// order. The copies of a cloth share one model.
    pub fn spawn_copies(&self, world: &mut World) -> Result<Vec<Entity>, ClothError> {
        self.copies.validate()?;
        if let Some(wind) = &self.wind {
            wind.validate()?;
            world.insert_resource(wind.resource());
        }
        if let Some(viewer) = &self.viewer {
            world.spawn(viewer.bundle());
        }
        if let Some(ms) = self.budget_ms {
            world.insert_resource(ClothBudget::new(ms));
        }
        let mut cloths = self.spawn_own(world)?;
        for other in &self.also {
            cloths.extend(other.spawn_own(world)?);
        }
        Ok(cloths)
    }

    /// Spawns this scene's own copies with their colliders and wind zones.
    fn spawn_own(&self, world: &mut World) -> Result<Vec<Entity>, ClothError> {
        for c in self.colliders.iter().filter(|c| c.shared) {
            world.spawn(c.bundle()?);
        }
        let (config, pins) = self.settings();
        let cloth = self.cloth.component()?;
        let targets = self.targets();
        let cape = match self.cloth {
            SceneCloth::Cape { nx, ny } => Some(character::cape_assets(
                world,
                &character::Cape::new(nx as usize, ny as usize),
            )),
            _ => None,
        };
        let mut cloths = Vec::with_capacity(self.copies.count as usize);
        for k in 0..self.copies.count {
            let offset = self.copies.offset(k);
            for c in self.colliders.iter().filter(|c| !c.shared) {
                world.spawn(c.moved(offset).bundle()?);
            }
            for z in self.wind.iter().flat_map(|w| &w.zones) {
                let mut zone = z.clone();
                zone.translation += offset;
                world.spawn(zone.bundle()?);
            }
            let mut transform = self.transform();
            transform.translation += offset;
            let placed = (config, pins.clone(), transform);
            let entity = match (&cloth, &cape) {
                (Some(cloth), _) => world.spawn((cloth.clone(), placed)).id(),
                (None, Some(cape)) => {
                    let phase = self.copies.phase * k as f32;
                    character::spawn_character(world, cape, placed, self.walk, phase)
                }
                (None, None) => unreachable!("only a cape has no cloth component"),
            };
            if let Some(targets) = &targets {
                world.entity_mut(entity).insert(targets.clone());
            }
            if let Some(lod) = self.lod {
                world.entity_mut(entity).insert(lod);
            }
            cloths.push(entity);
        }
        Ok(cloths)
    }

    /// The cloth's targets, when the scene gives target weights.
    pub fn targets(&self) -> Option<ClothTargets> {
        self.target_weights.as_ref().map(|w| ClothTargets {
            weights: TargetWeights::Values(w.clone()),
        })
    }

    /// The cloth's topology.
    pub fn model(&self) -> Result<ClothModel, ClothError> {
        self.cloth.model()
    }

    /// The components of the scene's (first) cloth entity (but its [`targets`](Self::targets),
    /// which [`spawn`](Self::spawn) adds). Display interpolation is off, so the mesh shows exactly
    /// the simulated state. A [`SceneCloth::Cape`] has none: it is spawned with its torso by
    /// [`spawn`](Self::spawn).
    pub fn bundle(&self) -> Result<impl Bundle, ClothError> {
        let cloth = self.cloth.component()?.ok_or_else(|| {
            ClothError::Scene("a Cape is spawned with its torso: use ClothScene::spawn".to_string())
        })?;
        let (config, pins) = self.settings();
        Ok((cloth, config, pins, self.transform()))
    }

    fn settings(&self) -> (ClothConfig, ClothPins) {
        let config = ClothConfig {
            solver: self.solver,
            interpolate: false,
            ..Default::default()
        };
        (config, ClothPins::new(self.pins.iter().copied()))
    }
}

#[cfg(test)]
mod tests;
