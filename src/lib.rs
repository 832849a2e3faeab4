//! # bevy_cloth
//!
//! Real-time mass-spring cloth for [Bevy](https://bevyengine.org) 0.19. Add [`ClothPlugin`], spawn
//! an entity with a [`Cloth`], and the plugin simulates it in `FixedUpdate` and renders it through an
//! ordinary `Mesh3d` that it updates in place every frame.
//!
//! ```
//! use bevy::prelude::*;
//! use bevy_cloth::prelude::*;
//!
//! let mut app = App::new();
//! app.add_plugins((MinimalPlugins, TransformPlugin, AssetPlugin::default()))
//!     .add_plugins((bevy::mesh::MeshPlugin, ClothPlugin::default()))
//!     .add_systems(Startup, |mut commands: Commands| {
//!         // A 1 m × 1 m sheet of 21 × 21 particles, pinned at two corners, 2 m above the origin.
//!         commands.spawn((
//!             Cloth::grid(GridSpec::new(21, 21, 0.05)),
//!             ClothPins::new([0, 20]),
//!             Transform::from_xyz(0.0, 2.0, 0.0),
//!         ));
//!     });
//! app.finish();
//! app.cleanup();
//! app.update();
//! ```
//!
//! The project grew out of a paper, *Cloth Simulation Using an Enhanced Catmull-Clark Subdivision
//! Scheme and Collision Detection in a Virtual Environment* (a mass-spring cloth, sphere
//! collision by bounding volume, wind, releasable pins and an "enhanced" Catmull-Clark rule); the
//! docs call it "the source paper".
//!
//! Layers: [`sim`] is the engine-free solver (plain data, every
//! formula); [`components`], [`plugin`] and the tearing types ([`ClothCut`], [`ClothTorn`],
//! [`ClothTearWeights`]) are the thin ECS layer; [`render`](crate::ClothState) writes meshes. Feature `render` brings Bevy's renderer for the windowed examples, `egui` the
//! inspector panel, `harness` the test and benchmark harness (`harness`), `avian` the coupling
//! with an avian3d physics world (`avian`).

#[cfg(feature = "avian")]
pub mod avian;
pub mod components;
pub mod error;
#[cfg(feature = "harness")]
pub mod harness;
mod hash;
#[cfg(feature = "egui")]
pub mod inspector;
mod limits;
mod lod;
pub mod plugin;
mod render;
pub mod scene;
pub mod sim;
mod skin;
pub mod subdivision;
mod tearing;

pub use components::*;
pub use error::ClothError;
pub use lod::{
    ClothBudget, ClothLod, ClothLodLevel, ClothViewer, CulledReturn, LodLevel, LodMetric,
};
pub use plugin::{ClothPlugin, ClothStepBudget, ClothSystems};
pub use tearing::{ClothCut, ClothTearWeights, ClothTorn};

/// Everything a game usually needs: `use bevy_cloth::prelude::*;`.
pub mod prelude {
    #[cfg(feature = "avian")]
    pub use crate::avian::{ClothAvianPlugin, ClothContact, NoClothContact};
    pub use crate::components::{
        Cloth, ClothCollider, ClothConfig, ClothEditRejected, ClothFrame, ClothInvalid, ClothPin,
        ClothPins, ClothPushesBodies, ClothSkin, ClothSource, ClothState, ClothSubdivision,
        ClothTargets, PinAnchor, SubdivisionTarget, TargetWeights, Wind, WindZone,
    };
    pub use crate::error::ClothError;
    pub use crate::lod::{
        ClothBudget, ClothLod, ClothLodLevel, ClothViewer, CulledReturn, LodLevel, LodMetric,
    };
    pub use crate::plugin::{ClothPlugin, ClothSystems};
    pub use crate::sim::{
        ClothModel, ColliderShape, DiscSpec, Friction, GridPlane, GridSpec, Gusts, Inertia,
        Integrator, Pressure, SelfCollision, SolverSettings, Stiffness, TargetLimits, Tearing,
        Tethers, WindZoneShape,
    };
    pub use crate::subdivision::{BoundaryMode, VertexRule};
    pub use crate::tearing::{ClothCut, ClothTearWeights, ClothTorn};
}

/// The README's code blocks, compiled as doctests so the quick-start snippet stays true.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;

/// The guide's code blocks (`docs/guide.md`), compiled as doctests.
#[cfg(doctest)]
#[doc = include_str!("../docs/guide.md")]
struct GuideDoctests;
