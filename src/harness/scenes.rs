//! The accuracy benchmark scenes: three canonical grid cloths, each with fixed physical parameters,
//! pins and initial state, that `cloth_cli work-precision` and the accuracy tests run with any
//! integrator and compare against the f64 [`reference`](super::reference) solution. Also the error
//! measures: RMS and largest particle position difference at the end time divided by the cloth's
//! diagonal.
//!
//! Damping is off in every scene (the reference is the undamped ODE). Engine-free.

use glam::{DVec3, Vec3};

use crate::error::ClothError;
use crate::sim::{ClothModel, ClothSim, GridPlane, GridSpec, SolverSettings, Stiffness};

/// One of the accuracy benchmark scenes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AccuracyScene {
    /// A 16×16 cloth (5 cm spacing, 1 g particles, the default stiffness 5000/5000/50 N/m) lying
    /// flat, pinned at one corner, swinging down for 0.2 s.
    Swing,
    /// A stiff 24×24 cloth (4 cm spacing, 2 g particles, 20000/20000/20 N/m: 1000:1 stretch to
    /// bend) lying flat, pinned at the two corners of one edge, falling into a hang for 0.2 s.
    Stiff,
    /// A light 20×20 curtain (5 cm spacing, 500/500/5 N/m) hanging in the vertical plane from every
    /// fourth particle of its top row (and the last), its particle masses spread 100:1 (0.05 g to
    /// 5 g, log-uniformly by a golden-ratio sequence), hit by a 1 m/s gust (initial velocity along
    /// +z) and followed for 0.2 s.
    Curtain,
}

impl AccuracyScene {
    /// All scenes.
    pub const ALL: [AccuracyScene; 3] = [
        AccuracyScene::Swing,
        AccuracyScene::Stiff,
        AccuracyScene::Curtain,
    ];

    /// The frame time step every scene is run at, s.
    pub const FRAME_DT: f32 = 1.0 / 60.0;

    /// A short name (file names, table headings).
    pub fn name(self) -> &'static str {
        match self {
            AccuracyScene::Swing => "swing",
            AccuracyScene::Stiff => "stiff",
            AccuracyScene::Curtain => "curtain",
        }
    }

    /// A one-line description.
    pub fn description(self) -> &'static str {
        match self {
            AccuracyScene::Swing => "16×16 cloth pinned at one corner swinging down, 0.2 s",
            AccuracyScene::Stiff => {
                "stiff 24×24 cloth hanging from two corners, k 20000/20000/20 N/m, 0.2 s"
            }
            AccuracyScene::Curtain => {
                "light 20×20 curtain, masses 0.05–5 g (100:1), gust of 1 m/s, 0.2 s"
            }
        }
    }

    /// Number of frames of [`Self::FRAME_DT`] simulated: 12 (0.2 s) for every scene. Longer runs
    /// measure chaos rather than the integrator: compressed cloth with weak bending buckles, and
    /// all three motions amplify small perturbations strongly after about 0.25 s. Symplectic Euler
    /// at 512–1024 substeps errs about 1e-5 at 0.2 s (its f32 rounding floor), but 1e-4 at 0.33 s
    /// and 2e-3 at 0.5 s; by 0.75–1 s even the f64 reference at tolerances 1e-10 and 1e-11
    /// disagrees by 1e-5 to 1e-2 of the diagonal.
    pub fn frames(self) -> u32 {
        12
    }

    /// Simulated time, s (`frames · FRAME_DT`, in f64).
    pub fn duration(self) -> f64 {
        self.frames() as f64 * Self::FRAME_DT as f64
    }

    fn grid(self) -> GridSpec {
        match self {
            AccuracyScene::Swing => GridSpec::new(16, 16, 0.05),
            AccuracyScene::Stiff => GridSpec::new(24, 24, 0.04),
            AccuracyScene::Curtain => GridSpec::new(20, 20, 0.05).with_plane(GridPlane::Vertical),
        }
    }

    /// The distance between neighbouring particles at rest, m.
    pub fn spacing(self) -> f64 {
        self.grid().spacing as f64
    }

    /// Number of frames of [`Self::FRAME_DT`] in `seconds` (rounded).
    pub fn frames_in(seconds: f64) -> u32 {
        (seconds / Self::FRAME_DT as f64).round() as u32
    }

    /// Length of the cloth's diagonal at rest, m: the scale of the error measure.
    pub fn diagonal(self) -> f64 {
        let g = self.grid();
        let (w, h) = (
            (g.nx - 1) as f64 * g.spacing as f64,
            (g.ny - 1) as f64 * g.spacing as f64,
        );
        w.hypot(h)
    }

    /// The scene's physical parameters (stiffness, uniform mass, gravity, no damping, no
    /// sleeping) with the numerical ones (integrator, substeps, iterations, auto substeps) taken
    /// from `method`.
    pub fn settings(self, method: &SolverSettings) -> SolverSettings {
        let (stiffness, particle_mass) = match self {
            AccuracyScene::Swing => (Stiffness::default(), 0.001),
            AccuracyScene::Stiff => (
                Stiffness {
                    structural: 2.0e4,
                    shear: 2.0e4,
                    bend: 20.0,
                },
                0.002,
            ),
            AccuracyScene::Curtain => (
                Stiffness {
                    structural: 500.0,
                    shear: 500.0,
                    bend: 5.0,
                },
                0.0005,
            ),
        };
        SolverSettings {
            stiffness,
            particle_mass,
            damping: 0.0,
            gravity: Vec3::new(0.0, -9.81, 0.0),
            sleep_speed: 0.0,
            ..*method
        }
    }

    /// The per-particle masses of the curtain: `0.05 g · 100^u` with `u` the golden-ratio sequence
    /// rescaled to exactly `[0, 1]`.
    fn curtain_masses(count: usize) -> Vec<f32> {
        let phi = 0.618_033_988_749_895_f64;
        let u: Vec<f64> = (0..count).map(|i| (i as f64 * phi).fract()).collect();
        let (lo, hi) = u
            .iter()
            .fold((f64::MAX, f64::MIN), |(lo, hi), u| (lo.min(*u), hi.max(*u)));
        u.iter()
            .map(|u| (5.0e-5 * 100f64.powf((u - lo) / (hi - lo))) as f32)
            .collect()
    }

    /// Builds the scene at its initial state, ready to step at [`Self::FRAME_DT`], with the
    /// numerical settings of `method`.
    pub fn build(self, method: &SolverSettings) -> Result<ClothSim, ClothError> {
        let grid = self.grid();
        let mut model = ClothModel::grid(&grid)?;
        if self == AccuracyScene::Curtain {
            let masses = Self::curtain_masses(model.particle_count());
            model = model.with_particle_masses(masses)?;
        }
        let mut sim = ClothSim::new(model, self.settings(method), |p| p)?;
        let pins: Vec<u32> = match self {
            AccuracyScene::Swing => vec![0],
            AccuracyScene::Stiff => vec![0, grid.nx - 1],
            AccuracyScene::Curtain => (0..grid.nx)
                .filter(|i| i % 4 == 0 || *i == grid.nx - 1)
                .collect(),
        };
        let targets: Vec<(u32, Vec3)> = pins
            .iter()
            .map(|p| (*p, sim.positions()[*p as usize]))
            .collect();
        sim.set_pins(targets)?;
        if self == AccuracyScene::Curtain {
            sim.set_velocities(Vec3::new(0.0, 0.0, 1.0))?;
        }
        Ok(sim)
    }
}

/// RMS distance between `positions` and `reference` (same particle order), divided by `diagonal`.
/// Returns infinity when any position is non-finite or the lengths differ.
pub fn relative_rms_error(positions: &[Vec3], reference: &[DVec3], diagonal: f64) -> f64 {
    if positions.len() != reference.len() || positions.is_empty() {
        return f64::INFINITY;
    }
    let sum: f64 = positions
        .iter()
        .zip(reference)
        .map(|(p, r)| p.as_dvec3().distance_squared(*r))
        .sum();
    let e = (sum / positions.len() as f64).sqrt() / diagonal;
    if e.is_finite() { e } else { f64::INFINITY }
}

/// The largest distance between `positions` and `reference` (same particle order), divided by
/// `diagonal`. Returns infinity when any position is non-finite or the lengths differ.
pub fn relative_max_error(positions: &[Vec3], reference: &[DVec3], diagonal: f64) -> f64 {
    if positions.len() != reference.len() || positions.is_empty() {
        return f64::INFINITY;
    }
    let e = positions
        .iter()
        .zip(reference)
        .map(|(p, r)| p.as_dvec3().distance(*r))
        .fold(
            0.0,
            |a: f64, d| if d.is_nan() { f64::NAN } else { a.max(d) },
        )
        / diagonal;
    if e.is_finite() { e } else { f64::INFINITY }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn curtain_masses_span_100_to_1() {
        let m = AccuracyScene::curtain_masses(400);
        let (lo, hi) = m
            .iter()
            .fold((f32::MAX, f32::MIN), |(lo, hi), m| (lo.min(*m), hi.max(*m)));
        assert!((hi / lo - 100.0).abs() < 1e-3, "{lo} {hi}");
    }

    #[test]
    fn scenes_build_with_their_pins() {
        for scene in AccuracyScene::ALL {
            let sim = scene.build(&SolverSettings::default()).unwrap();
            assert!(sim.pinned().count() >= 1);
            assert_eq!(sim.settings().damping, 0.0);
        }
        assert!((AccuracyScene::Swing.diagonal() - 0.75 * 2f64.sqrt()).abs() < 1e-6);
    }
}
