//! How `cloth_cli work-precision` describes runs in its report: errors, configurations, and
//! each tolerance-mode run against the fixed-substep runs of the same error or cost.

use super::*;

pub(super) fn fmt_error(m: &Measurement) -> String {
    match (&m.error, &m.max_error, &m.failure) {
        (Some(e), Some(max), _) => format!("{e:.2e} | {max:.2e}"),
        (_, _, Some(f)) => format!("**unstable** ({f}) | –"),
        _ => "? | ?".into(),
    }
}

/// One scene's reference at one horizon: its checks and cost.
pub(super) struct ReferenceInfo {
    pub(super) scene: AccuracyScene,
    /// Relative RMS difference to the reference at a tenth of the tolerance.
    pub(super) against_tighter: f64,
    /// Relative largest difference to the reference started 1e-7 of the spacing away.
    pub(super) sensitivity: f64,
    /// Relative largest difference between two f32 runs of Verlet, at its stability bound and at
    /// twice as many substeps: both err far less than this by truncation, so it is the
    /// positions' round-off, amplified by the scene.
    pub(super) rounding: f64,
    pub(super) steps: u64,
    pub(super) rejected: u64,
    pub(super) seconds: f64,
}

/// The tolerance check of one tolerance-mode run against the fixed runs of the same sweep.
pub(super) struct ToleranceCheck<'a> {
    pub(super) run: &'a Measurement,
    /// The cheapest fixed run whose largest error is at most this run's.
    pub(super) same_error: Option<&'a Measurement>,
    /// The cheapest fixed run whose largest error is within what the tolerance allows.
    pub(super) within: Option<&'a Measurement>,
    /// The error no run can be held to: the larger of the reference's sensitivity and the f32
    /// simulation's own (see [`ReferenceInfo`]).
    pub(super) floor: f64,
}

impl<'a> ToleranceCheck<'a> {
    pub(super) fn new(run: &'a Measurement, runs: &'a [Measurement], floor: f64) -> Self {
        let fixed = || {
            runs.iter()
                .filter(|m| m.tolerance.is_none() && m.max_error.is_some())
        };
        let cheapest = |limit: f64| {
            fixed()
                .filter(|m| m.max_error.is_some_and(|e| e <= limit))
                .min_by(|a, b| a.ms_per_frame.total_cmp(&b.ms_per_frame))
        };
        Self {
            run,
            same_error: run.max_error.and_then(cheapest),
            within: run.tolerance.and_then(|t| cheapest(allowed(t))),
            floor,
        }
    }

    /// Whether the tolerance can be met at all on this scene and horizon.
    pub(super) fn reachable(&self) -> bool {
        self.run.tolerance.is_some_and(|t| allowed(t) >= self.floor)
    }

    /// Whether the run met what its tolerance allows.
    pub(super) fn met(&self) -> bool {
        match (self.run.tolerance, self.run.max_error) {
            (Some(t), Some(e)) => e <= allowed(t),
            _ => false,
        }
    }

    /// Time of the run over that of a fixed run.
    pub(super) fn ratio(&self, other: Option<&Measurement>) -> Option<f64> {
        other.map(|o| self.run.ms_per_frame / o.ms_per_frame)
    }
}

pub(super) fn describe(m: &Measurement) -> String {
    match m.tolerance {
        Some(t) => format!("tolerance {t:.0e}"),
        None if m.integrator == Integrator::Auto => format!("auto ({})", m.method.name()),
        None => m.integrator.name().to_string(),
    }
}

pub(super) fn fmt_run(m: Option<&Measurement>) -> String {
    m.map_or("none".into(), |m| {
        format!(
            "{:.4} ({} × {}{})",
            m.ms_per_frame,
            describe(m),
            m.substeps,
            if m.method.is_explicit() {
                String::new()
            } else {
                format!(", {} it.", m.iterations)
            }
        )
    })
}

pub(super) fn fmt_ratio(r: Option<f64>) -> String {
    r.map_or("–".into(), |r| format!("{r:.2}"))
}
