//! The engine-free cloth solver: topology ([`ClothModel`]), particle state and time stepping
//! ([`ClothSim`]) with four integrators behind one [`Integrator`] enum, an f64 reference integrator
//! ([`reference`](mod@reference)), the accuracy benchmark scenes ([`scenes`]) and the stress suite
//! ([`stress`]). Plain data in, plain data out;
//! nothing here knows about ECS, assets or meshes, so it can be unit-tested and benchmarked on its
//! own. Every formula of the simulation lives here.

pub mod aero;
pub mod collision;
mod disc;
mod explicit;
mod forces;
mod implicit;
mod model;
mod parallel;
pub mod reference;
pub mod scenes;
mod solver;
pub mod stress;
pub mod wind;
mod xpbd;

pub use aero::{AeroParams, Gusts};
pub use collision::{Collider, ColliderShape, Friction, Pose};
pub use disc::{DiscSpec, MAX_DISC_RINGS, MAX_DISC_SECTORS, MIN_DISC_SECTORS};
pub use implicit::CG_TOLERANCE;
pub use model::{
    ClothModel, DEGENERATE_TRIANGLE_RATIO, GridPlane, GridSpec, MAX_PARTICLES, SpringKind, Springs,
    SubdividedModel, compute_normals,
};
pub use parallel::{ScopedThread, Spread};
pub use scenes::{AccuracyScene, relative_rms_error};
pub use solver::{
    AUTO_MAX_STRETCH, ClothSim, Energy, Environment, Integrator, MAX_ITERATIONS, MAX_SUBSTEPS,
    STABILITY_FRACTION, SolverSettings, Stiffness,
};
pub use wind::{PlacedWindZone, WindField, WindZoneShape};
