//! The steppers: one per integration method, each owning its scratch. `ClothSim` lends each step
//! a [`Step`] (the cloth's model, settings, particles, pins, wind and contacts) and
//! [`Steppers::step`] runs the chosen method on it.
//!
//! - `xpbd/`: XPBD, springs as compliant constraints, by coloured Gauss-Seidel (vector kernel,
//!   optionally on two threads);
//! - `explicit.rs`: symplectic Euler and position Verlet on the vector force kernel;
//! - `implicit.rs`: Baraff & Witkin implicit Euler, matrix-free conjugate gradients;
//! - `step.rs`: what they share ([`Step`], the vector steppers' coordinate arrays and their
//!   contact response).

mod explicit;
mod implicit;
mod step;
mod xpbd;

pub use implicit::CG_TOLERANCE;
pub(crate) use step::{Step, add_contact_work};
pub use xpbd::{ScopedThread, Spread};

use super::contact::Limits;
use super::model::ClothModel;
use super::settings::Integrator;

/// Every integrator's stepper. A stepper's scratch is sized and filled by [`Self::prepare`] when
/// its integrator is chosen (for [`Integrator::Auto`], XPBD's and Verlet's), never in a step.
#[derive(Debug, Clone, Default)]
pub(crate) struct Steppers {
    /// XPBD's.
    pub xpbd: xpbd::Xpbd,
    explicit: explicit::Explicit,
    implicit: implicit::Implicit,
}

impl Steppers {
    /// Readies the steppers `integrator` may run for `model` with per-spring `stiffness`, the
    /// particles' inverse masses (pins at 0), the tethers of `limits` (which XPBD projects
    /// itself) and, with `air`, the scratch of the air inside a closed cloth.
    pub fn prepare(
        &mut self,
        integrator: Integrator,
        model: &ClothModel,
        (stiffness, inv_mass): (&[f32], &[f32]),
        (limits, air): (&Limits, bool),
    ) {
        let auto = integrator == Integrator::Auto;
        if integrator == Integrator::ImplicitEuler {
            self.implicit
                .prepare(model.particle_count(), model.springs.len());
            self.implicit
                .air
                .prepare(air, &model.triangles, model.particle_count(), |i| i);
        }
        if integrator.is_explicit() || auto {
            self.explicit.prepare(model, stiffness);
            self.explicit
                .air
                .prepare(air, &model.triangles, model.particle_count(), |i| i);
        }
        if integrator == Integrator::Xpbd || auto {
            self.xpbd
                .prepare(model, (stiffness, inv_mass), (limits, air));
        }
    }

    /// One step of `dt` seconds in `substeps` substeps by `integrator` (not [`Integrator::Auto`],
    /// which `ClothSim` resolves first), prepared by [`Self::prepare`]. XPBD shares a large cloth
    /// with a thread from `spread`, if given.
    pub fn step(
        &mut self,
        integrator: Integrator,
        step: &mut Step,
        (dt, substeps): (f32, u32),
        spread: Option<&dyn Spread>,
    ) {
        match integrator {
            Integrator::Xpbd | Integrator::Auto => self.xpbd.step(step, dt, substeps, spread),
            Integrator::SymplecticEuler => self.explicit.step_symplectic_euler(step, dt, substeps),
            Integrator::Verlet => self.explicit.step_verlet(step, dt, substeps),
            Integrator::ImplicitEuler => self.implicit.step(step, dt, substeps),
        }
    }

    /// Conjugate-gradient iterations implicit Euler took in its last substep (0 before).
    pub fn cg_iterations(&self) -> u32 {
        self.implicit.last_iterations()
    }
}
