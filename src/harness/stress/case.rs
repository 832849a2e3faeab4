//! What a stress case is: its limits ([`StressLimits`]), its drawn parameters ([`StressCase`],
//! [`StressCollider`]), its variants, and how it becomes a cloth (shrunk to the work budget) and
//! drives it (pins, collider). Drawing the parameters is `draw`; stepping and checking is `run`.

use glam::{Quat, Vec3};

use crate::error::ClothError;
use crate::sim::{
    Accuracy, ClothModel, ClothSim, Collider, ColliderShape, Cut, Friction, GridSpec, Pose,
    Pressure, SelfCollision, SolverSettings,
};

/// How big the cases may get.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StressLimits {
    /// Largest grid side, particles.
    pub max_side: u32,
    /// Most particle-substeps per case (particles × substeps × steps, the cap's substeps in
    /// tolerance mode); larger cases are shrunk.
    pub max_work: f64,
    /// Simulated time per case, s.
    pub duration: f32,
}

impl Default for StressLimits {
    /// Up to 128×128 particles and 10⁷ particle-substeps (tens of milliseconds in a release
    /// build for XPBD), half a second each.
    fn default() -> Self {
        Self {
            max_side: 128,
            max_work: 1e7,
            duration: 0.5,
        }
    }
}

/// A collider of a case and how it moves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StressCollider {
    /// Its shape.
    pub shape: ColliderShape,
    /// Position at the start, m.
    pub start: Vec3,
    /// Constant velocity, m/s.
    pub velocity: Vec3,
    /// Rotation (fixed).
    pub rotation: Quat,
}

/// The air inside a closed case ([`StressCase::with_air`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StressAir {
    /// [`Pressure::Volume`]: this fraction of the built volume kept at this bulk modulus, Pa.
    Volume {
        /// Kept over built volume.
        scale: f32,
        /// Bulk modulus, Pa.
        bulk_modulus: f32,
    },
    /// [`Pressure::gas`]: an ideal gas this many Pa above the standard atmosphere at the built
    /// volume (below it when negative).
    Gas {
        /// Gauge pressure at the built volume, Pa.
        gauge: f32,
    },
}

/// One drawn case (everything needed to rerun it).
#[derive(Debug, Clone, PartialEq)]
pub struct StressCase {
    /// Seed of the suite.
    pub seed: u64,
    /// Index of the case within the suite.
    pub index: u64,
    /// Solver settings (integrator, substeps, stiffness, mass, damping).
    pub settings: SolverSettings,
    /// Particles along each side of the square grid.
    pub side: u32,
    /// Side length of the cloth, m.
    pub size: f32,
    /// Fixed time step, s.
    pub dt: f32,
    /// Number of steps.
    pub steps: u32,
    /// Largest ratio of neighbouring particle masses.
    pub mass_ratio: f32,
    /// Pinned corners (0 to 4).
    pub pins: Vec<u32>,
    /// Peak speed of the pins' oscillation, m/s (0: fixed pins).
    pub pin_speed: f32,
    /// The collider, if any.
    pub collider: Option<StressCollider>,
    /// Mean wind, m/s (zero: no air at all).
    pub wind: Vec3,
    /// Whether the wind is gusty.
    pub gusts: bool,
    /// With air, the cloth is a closed one: an icosphere of about `side`² particles, `size`
    /// across, instead of the grid.
    pub air: Option<StressAir>,
    /// A cut made after the step of this index ([`StressCase::with_tearing`]).
    pub cut: Option<(u32, Cut)>,
}

/// The first `count` (at most 4) corners of a `side`×`side` grid, as pinned particles.
pub(super) fn corner_pins(side: u32, count: usize) -> Vec<u32> {
    [0, side - 1, side * (side - 1), side * side - 1]
        .into_iter()
        .take(count)
        .collect()
}

impl StressCase {
    /// Where a pin that started at `start` should be at time `t`: all pins oscillate together
    /// (a rigid motion the cloth can follow) with peak speed `pin_speed`, amplitude 0.2 m, along
    /// a diagonal.
    pub(super) fn pin_target(&self, start: Vec3, t: f32) -> Vec3 {
        if self.pin_speed <= 0.0 {
            return start;
        }
        let amplitude = 0.2;
        let omega = self.pin_speed / amplitude;
        start + Vec3::new(1.0, 1.0, 0.5).normalize() * amplitude * (omega * t).sin()
    }

    pub(super) fn collider_at(&self, t0: f32, t1: f32) -> Option<Collider> {
        self.collider.map(|c| Collider {
            start: Pose {
                rotation: c.rotation,
                translation: c.start + c.velocity * t0,
            },
            end: Pose {
                rotation: c.rotation,
                translation: c.start + c.velocity * t1,
            },
            ..Collider::fixed(
                c.shape,
                Pose::from_translation(Vec3::ZERO),
                Friction::default(),
                0.005,
            )
        })
    }

    /// The same case with self-collision on, its thickness a quarter of the drawn grid's
    /// spacing (a cloth shrunk to the work budget is coarser, so its thickness stays below that).
    pub fn with_self_collision(mut self) -> Self {
        let spacing = self.size / (self.side.max(2) - 1) as f32;
        self.settings.self_collision = SelfCollision {
            enabled: true,
            thickness: 0.25 * spacing,
            ..Default::default()
        };
        self
    }

    /// The same case in tolerance mode ([`Accuracy`]): `tolerance` relative to the cloth's size
    /// per second, at most the default cap of substeps; the drawn integrator and substeps are
    /// then only where the controller starts.
    pub fn with_tolerance(mut self, tolerance: f32) -> Self {
        self.settings.accuracy = Accuracy {
            tolerance: Some(tolerance),
            ..Default::default()
        };
        self
    }

    /// The pinned particles of a cloth of `side` with `count` pins: the grid's first corners, or
    /// a closed cloth's first particles (an icosphere's first twelve are its icosahedron's
    /// corners, spread over it).
    pub(super) fn pins_for(&self, side: u32, count: usize) -> Vec<u32> {
        match self.air {
            None => corner_pins(side, count),
            Some(_) => (0..count.min(4) as u32).collect(),
        }
    }

    pub(super) fn isolated(&self) -> bool {
        self.pin_speed == 0.0
            && self.wind == Vec3::ZERO
            && self.collider.is_none_or(|c| c.velocity == Vec3::ZERO)
    }

    /// The cloth, shrunk (fewer particles) until it fits the work budget.
    pub(super) fn build(
        &self,
        limits: &StressLimits,
    ) -> Result<(ClothSim, StressCase), ClothError> {
        let mut case = self.clone();
        loop {
            let sim = self.build_side(case.side)?;
            // In tolerance mode the controller may take up to its cap of substeps per step.
            let substeps = match self.settings.accuracy.tolerance {
                Some(_) => self.settings.accuracy.max_substeps,
                None => sim.substeps_for(case.dt),
            };
            let particles = sim.positions().len() as f64;
            let work = particles * substeps as f64 * case.steps as f64;
            if work <= limits.max_work || case.side <= 2 {
                return Ok((sim, case));
            }
            let shrink = (limits.max_work / work).sqrt();
            case.side = ((case.side as f64 * shrink).floor() as u32).clamp(2, case.side - 1);
            case.pins = self.pins_for(case.side, self.pins.len());
        }
    }

    fn build_side(&self, side: u32) -> Result<ClothSim, ClothError> {
        let mut model = match self.air {
            None => ClothModel::grid(&GridSpec::new(side, side, self.size / (side - 1) as f32))?,
            // The most subdivisions with at most `side`² particles, at least none.
            Some(_) => {
                let fits = |s: u32| {
                    ClothModel::icosphere_particle_count(s)
                        .is_ok_and(|n| n <= (side as usize).pow(2))
                };
                let subdivisions = (1..).take_while(|&s| fits(s)).last().unwrap_or(0);
                ClothModel::icosphere(0.5 * self.size, subdivisions)?
            }
        };
        if self.mass_ratio > 1.0 {
            // Alternating heavy and light particles (a checkerboard on the grid), with smooth
            // variation on top: neighbours differ by up to `mass_ratio`.
            let m = self.settings.particle_mass;
            let masses = (0..model.particle_count() as u32)
                .map(|i| {
                    let heavy = match self.air {
                        None => (i % side + i / side).is_multiple_of(2),
                        Some(_) => i.is_multiple_of(2),
                    };
                    if heavy { m * self.mass_ratio } else { m }
                })
                .collect();
            model = model.with_particle_masses(masses)?;
        }
        let mut settings = self.settings;
        settings.pressure = match self.air {
            None => settings.pressure,
            Some(StressAir::Volume {
                scale,
                bulk_modulus,
            }) => Pressure::Volume {
                scale,
                bulk_modulus,
            },
            Some(StressAir::Gas { gauge }) => Pressure::gas(model.check_closed()?, gauge),
        };
        ClothSim::new(model, settings, |p| p + Vec3::new(0.0, 1.0, 0.0))
    }
}
