//! The engine-free cloth solver. Plain data in, plain data out: nothing here knows about ECS,
//! assets or meshes, so it can be unit-tested and benchmarked on its own, and every formula of the
//! simulation lives here. A cloth is a [`ClothModel`] (topology, built once) stepped by a
//! [`ClothSim`] (state, settings and one stepper per integrator) among the colliders and air of an
//! [`Environment`].
//!
//! # Modules, bottom up
//! Each module uses only the ones above it in this list; nothing imports back (`tests/house.rs`
//! reads the source and checks it against the same order).
//!
//! | module | what it holds | uses |
//! | --- | --- | --- |
//! | `soa`, `simd`, `runs` | storage: vectors as one array per coordinate; runtime-dispatched vector builds of a kernel; runs of springs a kernel loads as whole vectors | — |
//! | [`model`] | topology: grids, meshes, discs, subdivided cloths; springs and their colouring | — |
//! | [`settings`] | [`Integrator`], [`Stiffness`], [`SolverSettings`] and their validation | `model` (spring kinds) |
//! | `forces` | the spring-force kernel, its linearisation, energy and frequency bound | `soa`, `simd`, `runs`, `model` |
//! | `state` | particles, pins, [`Energy`] | `forces` |
//! | `pressure` | the air inside a closed cloth ([`Pressure`]): its force, XPBD's volume constraint, its energy | `soa`, `model`, `settings` |
//! | [`contact`] | collider shapes; broad phase, narrow phase and response on any particle layout; self-contacts; limits (targets with a maximum distance and backstop, tethers) | `soa`, `simd`, `settings` |
//! | [`aero`], [`wind`] | aerodynamic forces; the wind field (`wind` uses `aero`) | — |
//! | `integrate` | one stepper per integrator, each owning its scratch: `xpbd/` (layout, kernel, threads, driver), `explicit`, `implicit`; the [`Spread`] of threads | all of the above |
//! | `cloth_sim` | [`ClothSim`]: chooses the integrator and substeps (fixed, or by a tolerance: `cloth_sim/adaptive.rs`), runs the broad phase and wind, sleep, the runaway watchdog | all of the above |
//!
//! # Where a new constraint goes
//! A constraint on particle positions (a tether, a maximum distance from a target, a
//! self-contact) is data built once with the model or by `ClothSim` (beside the springs), plus a
//! projection run every substep on the stepper's own layout through `contact::ContactState`: the
//! position-based stepper (`integrate/xpbd`) runs it after the spring sweeps of a substep, the
//! force-based ones after their substep (`SoaState::resolve_contacts`, `Contacts::resolve`).
//! Targets and tethers (`contact/limits.rs`) and self-contacts are resolved that way, inside
//! `Contacts::resolve_state`, so every stepper has them. What a stepper needs beyond that pass
//! (the moving frame of [`settings::Inertia`]) reaches it through `integrate::Step`, the one
//! struct every stepper is handed; settings join [`SolverSettings`] and are validated there.

pub mod aero;
mod cloth_sim;
pub mod contact;
mod forces;
mod integrate;
pub mod model;
mod pressure;
mod runs;
pub mod settings;
mod simd;
mod soa;
mod state;
pub mod wind;

pub use aero::{AeroParams, GustSampler, Gusts};
pub use cloth_sim::{
    AccuracyReport, COARSE_FADE_STEPS, ClothSim, Cut, Environment, SelfContactStats, Split,
};
pub use contact::{
    Collider, ColliderShape, Friction, OtherCloth, Pose, Reaction, Shape, Surface, Target,
};
pub use integrate::{CG_TOLERANCE, ScopedThread, Spread};
pub use model::{
    ClothModel, DEGENERATE_TRIANGLE_RATIO, DiscSpec, GridNormals, GridPlane, GridSpec,
    MAX_DISC_RINGS, MAX_DISC_SECTORS, MAX_ICOSPHERE_SUBDIVISIONS, MAX_PARTICLES,
    MAX_SPRINGS_PER_PARTICLE, MIN_DISC_SECTORS, SpringKind, Springs, SubdividedModel,
    compute_normals,
};
pub use settings::{
    AUTO_MAX_STRETCH, Accuracy, ErrorUnit, Inertia, Integrator, MAX_ITERATIONS, MAX_SUBSTEPS,
    MAX_THICKNESS_PER_EDGE, NONLINEAR_STABILITY_FRACTION, Pressure, STABILITY_FRACTION,
    STANDARD_ATMOSPHERE, SelfCollision, SolverSettings, Stiffness, TargetLimits, TearSprings,
    Tearing, Tethers,
};
pub use state::Energy;
pub use wind::{MAX_WIND_ZONES, PlacedWindZone, WindField, WindZoneShape};
