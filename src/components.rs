//! The ECS-facing types a game spawns and edits: [`Cloth`], [`ClothConfig`], [`ClothPins`], and the
//! read-only [`ClothState`] / [`ClothInvalid`] the plugin attaches. No formulas live here: the
//! solver is in [`crate::sim`].

use std::sync::Arc;
use std::time::Duration;

use bevy::asset::Handle;
use bevy::ecs::prelude::*;
use bevy::math::Vec3;
use bevy::math::primitives::{Capsule3d, Cuboid, InfinitePlane3d, Sphere};
use bevy::mesh::Mesh;
use bevy::reflect::prelude::*;
use bevy::transform::components::{GlobalTransform, Transform};

use crate::error::ClothError;
pub use crate::sim::aero::AIR_DENSITY;
use crate::sim::contact::Pose;
use crate::sim::{
    ClothModel, ClothSim, ColliderShape, Friction, GridSpec, Gusts, SolverSettings, WindZoneShape,
};
use crate::subdivision::{BoundaryMode, Subdivider, VertexRule};

/// Where a cloth's particles and triangles come from.
#[derive(Debug, Clone, PartialEq, Reflect)]
pub enum ClothSource {
    /// The canonical grid cloth (see [`GridSpec`]); the plugin creates its mesh.
    Grid(GridSpec),
    /// A triangle-list mesh asset: one particle per vertex. The plugin copies the mesh into a new
    /// asset that it then deforms, so other users of the handle are not affected; the copy keeps the
    /// vertex count, index buffer and every other attribute. The mesh is checked as
    /// [`ClothModel::from_mesh`](crate::sim::ClothModel::from_mesh) describes (degenerate faces,
    /// zero-length and non-manifold edges are errors; coincident vertices that no edge joins are a
    /// seam that can open).
    Mesh(Handle<Mesh>),
    /// A prebuilt [`ClothModel`]: one particle per model vertex, and the model's own faces (quads
    /// stay quads, so subdivision refines them as quads). This is how a quad or triangle polygon
    /// mesh becomes a cloth ([`ClothModel::from_mesh`]), or a round one ([`ClothModel::disc`]).
    /// The plugin checks the model ([`ClothModel::validate`]) and renders it into a new mesh.
    Model(SharedClothModel),
}

/// A [`ClothModel`] behind an [`Arc`], so that a [`Cloth`] component stays cheap to clone and many
/// cloths can share one model. Two values are equal when they share the same model.
///
/// Reflected as an opaque value: the inspector and scene tools see it, but not inside it.
#[derive(Clone, Reflect)]
#[reflect(opaque, Debug, PartialEq, Clone)]
pub struct SharedClothModel(pub Arc<ClothModel>);

impl SharedClothModel {
    /// Shares `model`.
    pub fn new(model: ClothModel) -> Self {
        Self(Arc::new(model))
    }

    /// The model.
    pub fn model(&self) -> &ClothModel {
        &self.0
    }
}

impl From<ClothModel> for SharedClothModel {
    fn from(model: ClothModel) -> Self {
        Self::new(model)
    }
}

impl From<Arc<ClothModel>> for SharedClothModel {
    fn from(model: Arc<ClothModel>) -> Self {
        Self(model)
    }
}

impl PartialEq for SharedClothModel {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }
}

impl std::fmt::Debug for SharedClothModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ClothModel")
            .field("particles", &self.0.particle_count())
            .field("faces", &(self.0.faces.len() / self.0.face_size.max(1)))
            .field("face_size", &self.0.face_size)
            .field("springs", &self.0.springs.len())
            .finish()
    }
}

/// A simulated cloth. Spawn it with a [`Transform`] that places the rest shape in the world; the
/// plugin builds the simulation on the next frame and adds a `Mesh3d` showing it (give the entity a
/// material to render it).
///
/// Replacing this component rebuilds the cloth from scratch.
///
/// # Example
/// ```
/// use bevy::prelude::*;
/// use bevy_cloth::prelude::*;
///
/// fn spawn(mut commands: Commands) {
///     commands.spawn((
///         Cloth::grid(GridSpec::new(32, 32, 0.05)),
///         ClothPins::new([0, 31]),
///         Transform::from_xyz(0.0, 2.0, 0.0),
///     ));
/// }
/// # bevy::ecs::system::assert_is_system(spawn);
/// ```
#[derive(Component, Debug, Clone, PartialEq, Reflect)]
#[reflect(Component, Debug)]
#[require(ClothConfig, ClothPins, Transform)]
pub struct Cloth {
    /// The rest shape.
    pub source: ClothSource,
}

impl Cloth {
    /// A grid cloth.
    pub fn grid(spec: GridSpec) -> Self {
        Self {
            source: ClothSource::Grid(spec),
        }
    }

    /// A cloth from a triangle-list mesh asset.
    pub fn from_mesh(mesh: Handle<Mesh>) -> Self {
        Self {
            source: ClothSource::Mesh(mesh),
        }
    }

    /// A cloth from a prebuilt [`ClothModel`] (or an `Arc` of one, to share it between cloths).
    /// Use it for polygon meshes that a triangle-list `Mesh` cannot carry, such as quads:
    ///
    /// ```
    /// use bevy::prelude::*;
    /// use bevy_cloth::prelude::*;
    /// use bevy_cloth::sim::{ClothModel, DiscSpec};
    ///
    /// fn spawn(mut commands: Commands) -> Result {
    ///     // Two quads side by side, 10 cm each, facing +Y.
    ///     let positions = [
    ///         Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.1, 0.0, 0.0), Vec3::new(0.2, 0.0, 0.0),
    ///         Vec3::new(0.0, 0.0, 0.1), Vec3::new(0.1, 0.0, 0.1), Vec3::new(0.2, 0.0, 0.1),
    ///     ];
    ///     let quads = [0, 3, 4, 1, 1, 4, 5, 2];
    ///     let model = ClothModel::from_mesh(&positions, None, &quads, 4)?;
    ///     commands.spawn((Cloth::from_model(model), Transform::from_xyz(0.0, 1.0, 0.0)));
    ///     // A round tablecloth whose centre has valence 5, subdivided as quads.
    ///     commands.spawn((
    ///         Cloth::from_model(ClothModel::disc(&DiscSpec::new(5, 12, 0.8))?),
    ///         ClothSubdivision {
    ///             level: 2,
    ///             rule: VertexRule::Tuned,
    ///             boundary: BoundaryMode::EdgeOnly,
    ///             ..default()
    ///         },
    ///         Transform::from_xyz(2.0, 1.0, 0.0),
    ///     ));
    ///     Ok(())
    /// }
    /// # bevy::ecs::system::assert_is_system::<(), Result, _>(spawn);
    /// ```
    pub fn from_model(model: impl Into<SharedClothModel>) -> Self {
        Self {
            source: ClothSource::Model(model.into()),
        }
    }
}

/// Runtime-editable settings of one cloth. Changes apply at the next fixed step.
///
/// # Example
/// ```
/// use bevy_cloth::prelude::*;
///
/// let config = ClothConfig {
///     solver: SolverSettings { substeps: 30, damping: 1.0, ..Default::default() },
///     ..Default::default()
/// };
/// assert!(config.solver.validate().is_ok());
/// ```
#[derive(Component, Debug, Clone, Copy, PartialEq, Reflect)]
#[reflect(Component, Default, Debug)]
pub struct ClothConfig {
    /// Integrator, substeps, stiffness, mass, damping and gravity.
    pub solver: SolverSettings,
    /// Display the state interpolated between the last two fixed steps, so motion is smooth at any
    /// frame rate (it lags real time by at most one step). Off: show the latest step.
    pub interpolate: bool,
    /// Collision layers this cloth collides with: a [`ClothCollider`] touches the cloth when its
    /// `layers` share a bit with this mask. Every layer by default.
    pub collision_mask: u32,
    /// Layers this cloth is on for other cloths: two cloths keep apart when their `cloth_layers`
    /// share a bit, at the mean of their thicknesses (two edges 0.9 of it, as within a cloth) and
    /// with the mean of their frictions ([`SelfCollision`](crate::sim::SelfCollision)'s
    /// `thickness` and `friction`, whether or not self-collision is on). 0, the default, meets no
    /// other cloth. Cloths that meet another step one after the other, in the order of their
    /// entities, so the result does not depend on the thread count.
    pub cloth_layers: u32,
}

impl ClothConfig {
    /// Checks the settings; the error names the first bad field (only
    /// [`solver`](Self::solver) has values that can be wrong: see [`SolverSettings::validate`]).
    pub fn validate(&self) -> Result<(), ClothError> {
        self.solver.validate()
    }
}

impl Default for ClothConfig {
    fn default() -> Self {
        Self {
            solver: SolverSettings::default(),
            interpolate: true,
            collision_mask: u32::MAX,
            cloth_layers: 0,
        }
    }
}

/// A kinematic collider that cloths collide with: put it on any entity with a transform (a child of
/// a moving entity works). Its velocity, which moving colliders pass on to the cloth through
/// friction, comes from how its global pose changes between fixed steps; the shape is scaled by the
/// entity's global scale (see [`ColliderShape::scaled`]). Adding, moving, editing and removing
/// colliders at runtime all take effect at the next fixed step.
///
/// On a character, make the colliders children of its joints (a capsule under each leg's hip
/// and knee joints, a sphere or capsule under the spine): each fixed step takes their pose through
/// the joints' current transforms, and the contact test sweeps each collider from its pose at the
/// last step to its pose now, substep by substep, so a leg kicking through a skirt pushes it
/// rather than passing through it.
///
/// # Example
/// ```
/// use bevy::prelude::*;
/// use bevy_cloth::prelude::*;
///
/// fn spawn(mut commands: Commands) {
///     // A ball the cloth can drape over, with a 1 cm skin and grippy friction.
///     commands.spawn((
///         ClothCollider::sphere(0.5).with_margin(0.01).with_friction(Friction::new(0.8)),
///         Transform::from_xyz(0.0, 1.0, 0.0),
///     ));
///     // The floor: the half-space below the plane y = 0.
///     commands.spawn(ClothCollider::half_space(Vec3::Y));
/// }
/// # bevy::ecs::system::assert_is_system(spawn);
/// ```
#[derive(Component, Debug, Clone, Copy, PartialEq, Reflect)]
#[reflect(Component, Debug)]
#[require(Transform, ColliderMotion)]
pub struct ClothCollider {
    /// Shape in the entity's local frame.
    pub shape: ColliderShape,
    /// Coulomb friction against cloth.
    pub friction: Friction,
    /// Distance kept between the surface and the cloth's particles, m (the cloth's thickness).
    pub margin: f32,
    /// Collision layers (see [`ClothConfig::collision_mask`]); every layer by default.
    pub layers: u32,
}

/// Default [`ClothCollider::margin`], m.
pub const DEFAULT_COLLIDER_MARGIN: f32 = 0.01;

impl ClothCollider {
    /// A collider of the given shape with default friction and margin, on every layer.
    pub fn new(shape: ColliderShape) -> Self {
        Self {
            shape,
            friction: Friction::default(),
            margin: DEFAULT_COLLIDER_MARGIN,
            layers: u32::MAX,
        }
    }

    /// A ball of radius `radius` centred on the entity.
    pub fn sphere(radius: f32) -> Self {
        Self::new(ColliderShape::Sphere(Sphere::new(radius)))
    }

    /// A capsule along the entity's local Y axis: `half_length` from the centre to each cap's
    /// centre.
    pub fn capsule(radius: f32, half_length: f32) -> Self {
        Self::new(ColliderShape::Capsule(Capsule3d {
            radius,
            half_length,
        }))
    }

    /// A box with the given half extents.
    pub fn cuboid(half_size: Vec3) -> Self {
        Self::new(ColliderShape::Cuboid(Cuboid { half_size }))
    }

    /// The solid half-space behind the plane through the entity's origin with the given normal (in
    /// the entity's local frame): a floor for `Vec3::Y`. A zero or non-finite normal becomes +Y.
    pub fn half_space(normal: Vec3) -> Self {
        Self::new(ColliderShape::HalfSpace(InfinitePlane3d {
            normal: bevy::math::Dir3::new(normal).unwrap_or(bevy::math::Dir3::Y),
        }))
    }

    /// With other friction.
    pub fn with_friction(mut self, friction: Friction) -> Self {
        self.friction = friction;
        self
    }

    /// With another margin.
    pub fn with_margin(mut self, margin: f32) -> Self {
        self.margin = margin;
        self
    }

    /// On other layers.
    pub fn with_layers(mut self, layers: u32) -> Self {
        self.layers = layers;
        self
    }
}

/// The global wind. Insert it to give every cloth aerodynamic forces (drag and lift per triangle,
/// see [`crate::sim::aero`]); without it (and without [`WindZone`]s) no aerodynamic work is done at
/// all. With zero velocity the cloths still feel the drag of still air.
///
/// # Example
/// ```
/// use bevy::prelude::*;
/// use bevy_cloth::prelude::*;
///
/// let mut app = App::new();
/// app.insert_resource(Wind {
///     velocity: Vec3::new(6.0, 0.0, 0.0),
///     gusts: Some(Gusts { seed: 7, ..default() }),
///     ..default()
/// });
/// ```
#[derive(Resource, Debug, Clone, Copy, PartialEq, Reflect)]
#[reflect(Resource, Default, Debug)]
pub struct Wind {
    /// Mean wind velocity, m/s.
    pub velocity: Vec3,
    /// Smooth, seeded gusts on top of the mean wind (deterministic for a given seed).
    pub gusts: Option<Gusts>,
    /// Air density, kg/m³.
    pub air_density: f32,
    /// Switch the air off without removing the resource.
    pub enabled: bool,
}

impl Default for Wind {
    fn default() -> Self {
        Self {
            velocity: Vec3::ZERO,
            gusts: None,
            air_density: AIR_DENSITY,
            enabled: true,
        }
    }
}

/// A local wind: inside its shape (placed by the entity's transform) `velocity` is added to the
/// global [`Wind`], fading out over the outer `falloff` fraction of the zone.
#[derive(Component, Debug, Clone, Copy, PartialEq, Reflect)]
#[reflect(Component, Debug)]
#[require(Transform)]
pub struct WindZone {
    /// Extent, in the entity's frame.
    pub shape: WindZoneShape,
    /// Wind added inside the zone, m/s, world frame.
    pub velocity: Vec3,
    /// Gusts of the zone's wind.
    pub gusts: Option<Gusts>,
    /// Fraction (0..=1) of the zone's size over which its wind fades out at the boundary.
    pub falloff: f32,
}

/// On a cloth: the bodies of another physics engine that it touches take the opposite of the
/// impulses it took from them, and give way to them within the cloth's step (two-way coupling;
/// with the `avian` feature, avian's dynamic bodies). Without it, such bodies move the cloth and
/// feel nothing.
#[derive(Component, Debug, Default, Clone, Copy, PartialEq, Eq, Reflect)]
#[reflect(Component, Debug, Default)]
pub struct ClothPushesBodies;

/// Where a [`ClothCollider`] was at the last fixed step, kept by the plugin to derive its velocity.
#[derive(Component, Debug, Clone, Copy, Default)]
pub struct ColliderMotion {
    pub(crate) previous: Option<Pose>,
    /// Whether a bad collider was already reported.
    pub(crate) reported: bool,
}

/// What a pinned particle is held to.
#[derive(Debug, Clone, Copy, PartialEq, Reflect)]
pub enum PinAnchor {
    /// The particle's rest position under the cloth entity's own transform: move the cloth entity
    /// and its pinned particles follow.
    Rest,
    /// A fixed point in world space.
    World(Vec3),
    /// A point fixed to another entity: `offset` in that entity's local space, followed through its
    /// `GlobalTransform`. If the entity disappears, the pin holds its last position.
    Entity {
        /// The entity to follow.
        entity: Entity,
        /// Offset in the entity's local space.
        offset: Vec3,
    },
}

impl PinAnchor {
    /// Where the anchor holds its particle, in world space: `rest` gives the particle's rest
    /// position under the cloth's transform, `pose` an anchor entity's current transform. `None`
    /// where either has none.
    pub(crate) fn target(
        &self,
        rest: impl FnOnce() -> Option<Vec3>,
        pose: impl FnOnce(Entity) -> Option<GlobalTransform>,
    ) -> Option<Vec3> {
        match *self {
            PinAnchor::Rest => rest(),
            PinAnchor::World(p) => Some(p),
            PinAnchor::Entity { entity, offset } => pose(entity).map(|g| g.transform_point(offset)),
        }
    }
}

/// One pinned particle.
#[derive(Debug, Clone, Copy, PartialEq, Reflect)]
pub struct ClothPin {
    /// Particle index (for grids, `j * nx + i`).
    pub particle: u32,
    /// What it is held to.
    pub anchor: PinAnchor,
}

/// The pinned particles of a cloth. Edit it at runtime to pin, release or re-pin; released
/// particles keep their velocity, newly pinned ones travel to their anchor over one step.
///
/// # Example
/// ```
/// use bevy_cloth::prelude::*;
///
/// let mut pins = ClothPins::new([0, 15]);
/// pins.unpin(15);
/// assert!(pins.is_pinned(0) && !pins.is_pinned(15));
/// ```
#[derive(Component, Debug, Clone, Default, PartialEq, Reflect)]
#[reflect(Component, Default, Debug)]
pub struct ClothPins {
    /// The pins, at most one per particle.
    pub pins: Vec<ClothPin>,
}

impl ClothPins {
    /// Pins the given particles to their rest positions (anchored to the cloth's transform).
    pub fn new(particles: impl IntoIterator<Item = u32>) -> Self {
        let mut pins = Self::default();
        for p in particles {
            pins.pin(p, PinAnchor::Rest);
        }
        pins
    }

    /// Pins a particle, replacing any earlier pin of it.
    pub fn pin(&mut self, particle: u32, anchor: PinAnchor) -> &mut Self {
        self.unpin(particle);
        self.pins.push(ClothPin { particle, anchor });
        self
    }

    /// Releases a particle (no effect if it is not pinned).
    pub fn unpin(&mut self, particle: u32) -> &mut Self {
        self.pins.retain(|p| p.particle != particle);
        self
    }

    /// Releases every particle.
    pub fn release_all(&mut self) {
        self.pins.clear();
    }

    /// Releases the given particles (those not pinned are ignored).
    pub fn release(&mut self, particles: impl IntoIterator<Item = u32>) -> &mut Self {
        for p in particles {
            self.unpin(p);
        }
        self
    }

    /// Releases every pin for which `release` returns true: by anchor, by index range, or by
    /// region (with [`GridSpec::index`] or the rest positions of [`ClothState::sim`]).
    pub fn release_where(&mut self, mut release: impl FnMut(&ClothPin) -> bool) -> &mut Self {
        self.pins.retain(|p| !release(p));
        self
    }

    /// Whether a particle is pinned.
    pub fn is_pinned(&self, particle: u32) -> bool {
        self.pins.iter().any(|p| p.particle == particle)
    }
}

/// Where a cloth's per-particle weights come from (see [`ClothTargets`]).
#[derive(Debug, Clone, PartialEq, Reflect)]
pub enum TargetWeights {
    /// One weight per particle (for grids, `j * nx + i`); a negative weight leaves the particle
    /// free. For a mesh cloth, one per vertex.
    Values(Vec<f32>),
    /// A channel of the source mesh's vertex colours (`COLOR_0`, as the glTF loader reads it):
    /// 0 red, 1 green, 2 blue, 3 alpha. Painting weights in a vertex colour channel is the
    /// convention of bevy_silk and O3DE.
    Color(u8),
    /// A float vertex attribute of the source mesh, by name (a custom attribute registered with
    /// the glTF loader, for example).
    Attribute(String),
}

/// Ties a cloth to an animated target, vertex by vertex, with a weight per vertex: weight 0 pins
/// the vertex to its target; weight `w > 0` lets it move at most `w ×`
/// [`TargetLimits::max_distance_scale`](crate::sim::TargetLimits) from it and keeps it out of the
/// backstop behind it (both in [`ClothConfig::solver`]`.targets`). The target is the vertex's
/// skinned position when the cloth has a [`ClothSkin`] (a cloth spawned on a skinned mesh gets
/// one), or else its rest position under the cloth's transform.
///
/// # Example
/// ```
/// use bevy::prelude::*;
/// use bevy_cloth::prelude::*;
///
/// fn spawn(mut commands: Commands) {
///     // A 16×24 cape: its top row follows the transform exactly, the rest may swing up to 30 cm
///     // at the hem.
///     let spec = GridSpec::new(16, 24, 0.03).with_plane(GridPlane::Vertical);
///     let weights = (0..16 * 24).map(|p| (p / 16) as f32 / 23.0).collect();
///     let mut config = ClothConfig::default();
///     config.solver.targets.max_distance_scale = 0.3;
///     commands.spawn((
///         Cloth::grid(spec),
///         ClothTargets { weights: TargetWeights::Values(weights) },
///         config,
///     ));
/// }
/// # bevy::ecs::system::assert_is_system(spawn);
/// ```
#[derive(Component, Debug, Clone, PartialEq, Reflect)]
#[reflect(Component, Debug)]
pub struct ClothTargets {
    /// The weights.
    pub weights: TargetWeights,
}

/// The skin a cloth's targets are animated by: its joints and their inverse bind poses, as a
/// [`SkinnedMesh`](bevy::mesh::skinning::SkinnedMesh) holds them (the cloth's source mesh
/// carries each vertex's joint indices and weights). A cloth spawned on an entity with a
/// `SkinnedMesh` has it moved here when it is built, since the cloth's mesh is simulated, not
/// skinned by the renderer. Each fixed step, every weighted vertex's target is computed on the
/// CPU: `Σ w · (joint's GlobalTransform · inverse bind pose) · rest position`.
#[derive(Component, Debug, Clone, PartialEq, Reflect)]
#[reflect(Component, Debug)]
pub struct ClothSkin {
    /// The joint entities, in the order the mesh's joint indices refer to.
    pub joints: Vec<Entity>,
    /// Their inverse bind poses.
    pub inverse_bindposes: Handle<bevy::mesh::skinning::SkinnedMeshInverseBindposes>,
}

/// The reference frame a cloth's [`Inertia`](crate::sim::Inertia) is measured in: the entity
/// whose motion the cloth feels only in part (a character's root or hip joint). Without it, the
/// cloth's own entity.
#[derive(Component, Debug, Clone, Copy, PartialEq, Reflect)]
#[reflect(Component, Debug)]
pub struct ClothFrame(pub Entity);

/// Renders a cloth as a Catmull-Clark subdivision surface of its simulated mesh. Only the render
/// mesh is refined: the simulation keeps its particles, and each step the refined positions are
/// computed from a stencil table built once. Editing this component rebuilds the render mesh
/// without resetting the simulation; level 0 renders the particles directly.
///
/// # Example
/// ```
/// use bevy::prelude::*;
/// use bevy_cloth::prelude::*;
///
/// fn spawn(mut commands: Commands) {
///     commands.spawn((
///         Cloth::grid(GridSpec::new(16, 16, 0.1)),
///         ClothSubdivision { level: 2, rule: VertexRule::Tuned, ..default() },
///     ));
/// }
/// # bevy::ecs::system::assert_is_system(spawn);
/// ```
#[derive(Component, Debug, Clone, Copy, PartialEq, Reflect)]
#[reflect(Component, Default, Debug)]
pub struct ClothSubdivision {
    /// Refinement level, 0 ..= [`MAX_CLOTH_SUBDIVISION_LEVEL`] (each level has about 4× the faces).
    pub level: u32,
    /// Vertex rule at interior vertices.
    pub rule: VertexRule,
    /// Boundary interpolation.
    pub boundary: BoundaryMode,
    /// Whether the rendered surface or the simulated cloth itself is refined.
    pub target: SubdivisionTarget,
}

/// What a [`ClothSubdivision`] refines.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Reflect)]
#[reflect(Default, Debug)]
pub enum SubdivisionTarget {
    /// The cloth simulates its own mesh; after each step its particles are the control points of
    /// a subdivision surface that is rendered. The simulation keeps its size: each step only adds
    /// the stencil evaluation and normals of the refined surface (`benches/subdivision.rs`
    /// times the evaluation).
    /// Changing the level only rebuilds the render mesh.
    #[default]
    Render,
    /// The rest mesh is refined once, before the simulation is built, and the cloth simulates
    /// (and renders) the refined mesh: about 4× the particles per level, finer folds and
    /// contacts, and a rest shape that is the smooth surface (see
    /// [`ClothModel::subdivided`](crate::sim::ClothModel::subdivided)). The total mass is kept;
    /// [`ClothPins`] still name particles of the unrefined cloth and pin the particles they
    /// became; [`ClothState::positions`] lists the refined particles. Any change to the
    /// subdivision restarts the cloth from its rest shape.
    Simulation,
}

/// Highest level accepted by [`ClothSubdivision`].
pub const MAX_CLOTH_SUBDIVISION_LEVEL: u32 = 4;

impl Default for ClothSubdivision {
    fn default() -> Self {
        Self {
            level: 2,
            rule: VertexRule::Original,
            boundary: BoundaryMode::EdgeAndCorner,
            target: SubdivisionTarget::Render,
        }
    }
}

/// The render-side subdivision of a running cloth: the stencils and refined scratch buffers.
#[derive(Debug)]
pub(crate) struct RenderSubdivision {
    pub(crate) subdivider: Subdivider,
    /// Refined positions and normals before seam vertices are appended.
    pub(crate) positions: Vec<Vec3>,
    pub(crate) normals: Vec<Vec3>,
}

/// The running simulation of a cloth, attached by the plugin. Read it for particle positions and
/// statistics; change the cloth through [`Cloth`], [`ClothConfig`] and [`ClothPins`].
#[derive(Component, Debug)]
pub struct ClothState {
    pub(crate) sim: ClothSim,
    pub(crate) mesh: Handle<Mesh>,
    /// Present when the render mesh is a subdivision surface.
    pub(crate) subdivision: Option<RenderSubdivision>,
    /// The grid normals kernel, when the unsubdivided render mesh is a canonical grid.
    pub(crate) grid_normals: Option<crate::sim::GridNormals>,
    /// Present when the simulation runs on a refined model
    /// ([`SubdivisionTarget::Simulation`]) or on its source mesh welded along its seams: for each
    /// particle of the unrefined model (each vertex of the source mesh), its particle in the
    /// simulation.
    pub(crate) particle_map: Option<Vec<u32>>,
    /// Whether the simulation runs on a refined model ([`SubdivisionTarget::Simulation`]).
    pub(crate) refined: bool,
    /// Present when the render mesh is the source mesh whose seams the simulation welded
    /// ([`ClothModel::weld_seams`](crate::sim::ClothModel::weld_seams)): the particles' normals
    /// (scratch), which each vertex takes from its particle in `particle_map`.
    pub(crate) seam_normals: Option<Vec<Vec3>>,
    /// Factor applied to [`SolverSettings::particle_mass`](crate::sim::SolverSettings) (below 1
    /// for a refined model, to keep the total mass).
    pub(crate) mass_scale: f32,
    /// Render positions (world space) after the previous and the latest step.
    pub(crate) render_prev: Vec<Vec3>,
    pub(crate) render_curr: Vec<Vec3>,
    /// Render normals after the previous and the latest step.
    pub(crate) normals_prev: Vec<Vec3>,
    pub(crate) normals_curr: Vec<Vec3>,
    /// The pin set the cloth runs: its [`ClothPins`] as last accepted (an edit that was rejected
    /// leaves them as they were).
    pub(crate) pins: Vec<ClothPin>,
    /// Pin targets resolved this tick: `pins` in their order, then the targets'
    /// weight-0 particles listed in `target_pins` (scratch buffer).
    pub(crate) pin_targets: Vec<Vec3>,
    /// The particles tied to targets ([`ClothTargets`]), when the cloth has any.
    pub(crate) attachment: Option<crate::skin::Attachment>,
    /// The entries of `attachment` pinned (weight 0 and not among the [`ClothPins`]).
    pub(crate) target_pins: Vec<usize>,
    /// Set when stepping failed; the cloth is then stopped.
    pub(crate) failure: Option<ClothError>,
    /// Cuts for the next step ([`ClothCut`](crate::ClothCut)s received).
    pub(crate) cuts: Vec<crate::sim::Cut>,
    /// The splits of the latest step, until the plugin follows them.
    pub(crate) splits: Vec<crate::sim::Split>,
    /// Wall time of the cloth's latest fixed step.
    pub(crate) step_time: Duration,
    /// Whether the mesh must be written this frame.
    pub(crate) dirty: bool,
    /// The cloth is asleep and both render states already hold its resting pose: nothing to
    /// refresh, interpolate or write until it wakes.
    pub(crate) at_rest: bool,
    /// Its level of detail ([`ClothLod`](crate::ClothLod)).
    pub(crate) lod: crate::lod::LodState,
    /// The transform the mesh was last written under.
    pub(crate) written_with: Option<bevy::math::Affine3A>,
}

/// Particle `index` of a cloth's unrefined model mapped through `map` (none: identity over
/// `count` particles); `None` when out of range.
pub(crate) fn mapped_particle(map: Option<&[u32]>, count: usize, index: u32) -> Option<usize> {
    match map {
        Some(map) => map.get(index as usize).map(|&p| p as usize),
        None => ((index as usize) < count).then_some(index as usize),
    }
}

impl ClothState {
    /// The simulation particle of particle `index` of the cloth's own (unrefined) model, the
    /// index [`ClothPins`] use; `None` when out of range.
    pub fn particle(&self, index: u32) -> Option<usize> {
        mapped_particle(
            self.particle_map.as_deref(),
            self.sim.positions().len(),
            index,
        )
    }

    /// The particles tied to targets ([`ClothTargets`]) and where their targets are after the
    /// last step (weight 0: pinned there).
    pub fn targets(&self) -> impl Iterator<Item = crate::sim::Target> + '_ {
        self.attachment.iter().flat_map(|a| a.all())
    }

    /// The simulation (positions, velocities, settings, statistics).
    pub fn sim(&self) -> &ClothSim {
        &self.sim
    }

    /// Current particle positions in world space, in particle index order.
    pub fn positions(&self) -> &[Vec3] {
        self.sim.positions()
    }

    /// Number of fixed steps this cloth has taken.
    pub fn steps(&self) -> u64 {
        self.sim.steps()
    }

    /// Wall time of the cloth's latest fixed step: what it costs a frame (with one fixed step a
    /// frame), next to nothing while it sleeps.
    pub fn last_step_time(&self) -> Duration {
        self.step_time
    }

    /// The mesh asset the plugin writes.
    pub fn mesh(&self) -> &Handle<Mesh> {
        &self.mesh
    }
}

/// Marks a cloth that could not be built or was stopped, with the reason. The plugin logs the error
/// once and skips the cloth; fixing the cause (replacing [`Cloth`], editing [`ClothConfig`] or
/// [`ClothPins`]) makes it try again.
#[derive(Component, Debug, Clone, PartialEq)]
pub struct ClothInvalid(pub ClothError);

/// Marks a running cloth whose latest edit was rejected, with the reason. The edit (of its
/// [`Cloth`], [`ClothConfig`], [`ClothPins`], [`ClothTargets`], [`ClothSubdivision`] or source
/// mesh) changed nothing: the cloth runs on as it was. The plugin logs each rejection once and
/// removes the marker when a later edit is accepted.
#[derive(Component, Debug, Clone, PartialEq)]
pub struct ClothEditRejected(pub ClothError);
