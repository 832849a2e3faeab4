//! The plan of a step: which integrator runs it ([`Integrator::Auto`]'s choice) and at how many
//! substeps (the explicit integrators' stability bound, or tolerance mode's count).

use super::{AccuracyReport, ClothSim};
use crate::error::ClothError;
#[cfg(doc)]
use crate::sim::settings::SolverSettings;
use crate::sim::settings::{
    AUTO_MAX_STRETCH, Integrator, MAX_SUBSTEPS, NONLINEAR_STABILITY_FRACTION, STABILITY_FRACTION,
};

impl ClothSim {
    /// Sets the level of detail of the cloth's steps: `detail` (in `(0, 1]`; 1, the default, is
    /// full quality) times its configured [`substeps`](SolverSettings::substeps), rounded up (the
    /// explicit integrators' stability bound still applies), or in tolerance mode its tolerance
    /// divided by `detail`. A value outside `(0, 1]` is [`ClothError::InvalidValue`] and changes
    /// nothing.
    pub fn set_detail(&mut self, detail: f32) -> Result<(), ClothError> {
        if !(detail > 0.0 && detail <= 1.0) {
            return Err(ClothError::InvalidValue {
                field: "detail",
                expected: "in (0, 1]",
                value: detail as f64,
            });
        }
        if let Some(a) = &mut self.adaptive {
            a.scale_tolerance(self.detail / detail);
        }
        self.detail = detail;
        Ok(())
    }

    /// The level of detail of the cloth's steps ([`Self::set_detail`]).
    pub fn detail(&self) -> f32 {
        self.detail
    }

    /// An upper bound on the highest angular frequency of the cloth's springs about rest, in rad/s
    /// (Gershgorin's bound from each free particle's springs and mass; pins count as infinite mass).
    /// Explicit integrators need a substep `h < 2/ω_max`. The air inside a closed cloth adds its
    /// own bound, taken at the start of each step, but for a cloth set to [`Integrator::Xpbd`]
    /// outside tolerance mode, which has no use for it (there it is the built cloth's).
    pub fn max_frequency(&self) -> f32 {
        self.omega_max
    }

    /// Number of substeps a step of `dt` seconds takes: `substeps`, raised to the stability bound
    /// for the explicit integrators when [`SolverSettings::auto_substeps`] is on, and at most
    /// [`MAX_SUBSTEPS`]. While a spring is stretched by more than [`AUTO_MAX_STRETCH`], the bound
    /// is taken at [`NONLINEAR_STABILITY_FRACTION`] instead.
    ///
    /// In tolerance mode ([`SolverSettings::accuracy`]), the count its controller chose for the
    /// next step.
    pub fn substeps_for(&self, dt: f32) -> u32 {
        match &self.adaptive {
            Some(a) => a.substeps(),
            None => self.substep_plan(dt).0,
        }
    }

    /// What tolerance mode ([`SolverSettings::accuracy`]) chose and estimated; `None` with fixed
    /// substeps.
    pub fn accuracy_report(&self) -> Option<AccuracyReport> {
        self.adaptive.as_ref().map(|a| a.report())
    }

    /// [`Self::substeps_for`], and the substeps the explicit integrators' bound asks for (the
    /// configured count for the others, or with `auto_substeps` off), which may exceed
    /// [`MAX_SUBSTEPS`].
    pub(super) fn substep_plan(&self, dt: f32) -> (u32, u32) {
        let n = self.settings.substeps;
        let n = if self.detail < 1.0 {
            ((n as f32 * self.detail).ceil() as u32).max(1)
        } else {
            n
        };
        let s = &self.settings;
        // Implicit Euler takes the air of a closed cloth explicitly, so its bound applies.
        let omega = match s.integrator {
            i if i.is_explicit() => self.omega_max,
            Integrator::ImplicitEuler if self.air_frequency > 0.0 => self.air_frequency,
            _ => return (n, n),
        };
        if !s.auto_substeps {
            return (n, n);
        }
        let fraction = if self.overstretched() {
            NONLINEAR_STABILITY_FRACTION
        } else {
            STABILITY_FRACTION
        };
        let wanted = n.max(substeps_within(dt, fraction, omega));
        (wanted.min(MAX_SUBSTEPS), wanted)
    }

    /// The fewest substeps per step of `dt` seconds at which the explicit integrators are within
    /// their stability bound, `h ≤ STABILITY_FRACTION · 2/ω_max` (see
    /// [`max_frequency`](Self::max_frequency)); `u32::MAX` if no count is.
    pub fn stable_substeps(&self, dt: f32) -> u32 {
        self.substeps_within(dt, STABILITY_FRACTION)
    }

    /// The fewest substeps per step of `dt` seconds with `h ≤ fraction · 2/ω_max`; `u32::MAX` if
    /// no count is.
    pub(super) fn substeps_within(&self, dt: f32, fraction: f32) -> u32 {
        substeps_within(dt, fraction, self.omega_max)
    }

    /// Sets the air's frequency bound for the cloth as it is now (the air's stiffness grows with
    /// its pressure and as a gas is compressed), and `omega_max` from it and the springs'.
    pub(super) fn refresh_air_frequency(&mut self) {
        self.air_frequency = self.air.as_ref().map_or(0.0, |air| {
            let p = &self.particles;
            let scratch = &mut self.air_bound;
            air.frequency(scratch, &self.model.triangles, (&p.positions, &p.inv_mass))
        });
        self.omega_max = self.spring_frequency.hypot(self.air_frequency);
    }

    /// The integrator the current (or last) step used: the configured one, or the one
    /// [`Integrator::Auto`] chose for it (before the first step, its choice for a step of 1/60 s).
    pub fn active_integrator(&self) -> Integrator {
        self.active
    }

    /// The method for a step of `dt`: the configured one, or [`Integrator::Auto`]'s choice.
    pub(super) fn choose_integrator(&self, dt: f32) -> Integrator {
        let s = &self.settings;
        if s.integrator != Integrator::Auto {
            return s.integrator;
        }
        if self.stable_substeps(dt) <= s.substeps && !self.needs_xpbd() {
            Integrator::Verlet
        } else {
            Integrator::Xpbd
        }
    }

    /// Whether the next step is one for XPBD whatever the substeps: a pin jumps farther than the
    /// cloth's longest spring, or a spring is overstretched.
    pub(super) fn needs_xpbd(&self) -> bool {
        self.pins
            .iter()
            .any(|p| p.from.distance(p.to) > self.longest_spring)
            || self.overstretched()
    }

    /// Whether a spring is stretched by more than [`AUTO_MAX_STRETCH`] of its rest length. A
    /// force-based integrator would release that elastic energy as motion (a teleported pin flings
    /// the cloth), so [`Integrator::Auto`] leaves such a state to XPBD until it has relaxed.
    pub(super) fn overstretched(&self) -> bool {
        let s = &self.model.springs;
        let x = &self.particles.positions;
        s.a.iter().zip(&s.b).zip(&s.rest).any(|((&a, &b), &rest)| {
            x[a as usize].distance_squared(x[b as usize])
                > (rest * (1.0 + AUTO_MAX_STRETCH)).powi(2)
        })
    }
}

/// The fewest substeps per step of `dt` seconds with `h ≤ fraction · 2/omega`; `u32::MAX` if no
/// count is.
fn substeps_within(dt: f32, fraction: f32, omega: f32) -> u32 {
    let needed = (dt * omega / (2.0 * fraction)).ceil();
    if needed.is_finite() && needed < u32::MAX as f32 {
        (needed as u32).max(1)
    } else {
        u32::MAX
    }
}
