//! The stress suite: seeded random cloths at the edges of what the solver accepts, stepped while
//! their invariants are checked. Used by the `stress` tests and by `cloth_cli stress`.
//!
//! Each case draws, from its seed and index: the integrator, a time step of 1/240–1/15 s, 1–64
//! substeps, a structural stiffness of 1–10⁹ N/m (shear and bend below it), particle masses whose
//! neighbours differ up to 1000:1, a grid of 2×2 to 128×128 particles (shrunk to a work budget),
//! pins oscillating at up to 20 m/s, a collider (sphere, capsule, box or floor) sweeping through
//! the cloth at up to half its thickness per substep (the tunnelling limit of the swept test is a
//! whole thickness), wind of up to 50 m/s with gusts, and tethers to the pins (a quarter of the
//! cases, slack 0–0.2).
//!
//! A case fails if stepping panics, a position or velocity becomes non-finite without a typed
//! error, a free particle ends a step inside a collider by more than [`CLEARANCE_TOLERANCE`]
//! (measured with the suite's own distance functions, not the solver's), a free particle's
//! straight path over a step of one substep passes through a collider's core (tunnelling), a
//! pinned particle is off its target, the energy grows without an outside source, or
//! (with an outside source) the kinetic energy of the cloth, or of any one particle, exceeds the
//! whole cloth moving at [`RUNAWAY_SPEED_FACTOR`] times every driving speed added up plus the work
//! a moving collider's contacts did (none for a collider at rest), both times a symplectic
//! integrator's kinetic-energy inflation (a runaway check). Every check applies to
//! every step that returns `Ok`, past an explicit integrator's stability bound too. An explicit
//! integrator that reports [`ClothError::Unstable`] or [`ClothError::Diverged`] past its
//! stability bound `h ω_max ≥ 2`, or `Unstable` where its bound asks for more than
//! [`MAX_SUBSTEPS`] substeps, is not a failure: that is the detection working, and the case
//! records where the limit lies.
//!
//! `case` holds what a case is and builds its cloth, `draw` draws it, `run` steps and checks it
//! (with `penetration`'s distance functions), and `result` is what it reports.

mod case;
mod draw;
mod penetration;
mod result;
mod run;

#[cfg(doc)]
use crate::{error::ClothError, sim::MAX_SUBSTEPS};
pub use case::{StressAir, StressCase, StressCollider, StressLimits};
pub use draw::draw_case;
pub use penetration::CLEARANCE_TOLERANCE;
pub use result::{StressOutcome, StressResult, state_hash, trace_line};
pub use run::{RUNAWAY_SPEED_FACTOR, run_case, trace_case};
