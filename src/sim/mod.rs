//! The engine-free cloth solver: topology ([`ClothModel`]), particle state and time stepping
//! ([`ClothSim`]). Plain data in, plain data out; nothing here knows about ECS, assets or meshes, so
//! it can be unit-tested and benchmarked on its own. Every formula of the simulation lives here.

mod model;
mod solver;

pub use model::{ClothModel, GridPlane, GridSpec, SpringKind, Springs, compute_normals};
pub use solver::{ClothSim, Integrator, MAX_ITERATIONS, MAX_SUBSTEPS, SolverSettings, Stiffness};
