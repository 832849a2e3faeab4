//! Drawing a case from the suite's seed and the case's index: a small seeded generator and
//! [`draw_case`], the only place the suite's randomness comes from.

use std::f32::consts::TAU;

use bevy::math::primitives::{Capsule3d, Cuboid, InfinitePlane3d, Sphere};
use glam::{Quat, Vec3};

use super::case::{StressAir, StressCase, StressCollider, StressLimits, corner_pins};
use crate::hash::{GOLDEN_GAMMA, mix64};
use crate::sim::{
    ColliderShape, Cut, Integrator, SolverSettings, Stiffness, TearSprings, Tearing, Tethers,
};

/// SplitMix64: a small, fast, well-mixed generator; enough for drawing cases reproducibly.
#[derive(Debug, Clone)]
struct SplitMix64(u64);

impl SplitMix64 {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(GOLDEN_GAMMA);
        mix64(self.0)
    }

    /// Uniform in `[0, 1)`.
    fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }

    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit()
    }

    /// Log-uniform in `[lo, hi]`.
    fn log_range(&mut self, lo: f32, hi: f32) -> f32 {
        (lo.ln() + (hi.ln() - lo.ln()) * self.unit()).exp()
    }

    fn chance(&mut self, p: f32) -> bool {
        self.unit() < p
    }

    fn direction(&mut self) -> Vec3 {
        let z = self.range(-1.0, 1.0);
        let a = self.range(0.0, TAU);
        let r = (1.0 - z * z).sqrt();
        Vec3::new(r * a.cos(), z, r * a.sin())
    }

    fn pick<T: Copy>(&mut self, items: &[T]) -> T {
        items[(self.next() % items.len() as u64) as usize]
    }
}

/// Draws case `index` of the suite `seed`, with an integrator from `integrators`.
pub fn draw_case(
    seed: u64,
    index: u64,
    integrators: &[Integrator],
    limits: &StressLimits,
) -> StressCase {
    let mut rng = SplitMix64(seed ^ index.wrapping_mul(0xD1B5_4A32_D192_ED03));
    rng.next();
    let integrator = rng.pick(if integrators.is_empty() {
        &Integrator::CHOICES
    } else {
        integrators
    });
    let dt = rng.log_range(1.0 / 240.0, 1.0 / 15.0);
    let substeps = rng.log_range(1.0, 64.99).floor() as u32;
    let structural = rng.log_range(1.0, 1e9);
    let stiffness = Stiffness {
        structural,
        shear: structural * rng.range(0.1, 1.0),
        bend: structural * rng.log_range(1e-3, 1.0),
    };
    let mut settings = SolverSettings {
        integrator,
        substeps,
        iterations: if integrator == Integrator::ImplicitEuler {
            50
        } else {
            rng.log_range(1.0, 4.99).floor() as u32
        },
        stiffness,
        particle_mass: rng.log_range(1e-4, 0.1),
        damping: if rng.chance(0.3) {
            0.0
        } else {
            rng.range(0.0, 2.0)
        },
        // Sleeping would hide steps from the checks.
        sleep_speed: 0.0,
        ..Default::default()
    };
    let steps = ((limits.duration / dt).ceil() as u32).clamp(4, 240);
    let side = rng.log_range(2.0, limits.max_side as f32 + 0.99).floor() as u32;
    let size = rng.log_range(0.2, 2.0);
    let mass_ratio = if rng.chance(0.5) {
        rng.log_range(1.0, 1000.0)
    } else {
        1.0
    };
    let pins = corner_pins(side, (rng.next() % 5) as usize);
    let pin_speed = if !pins.is_empty() && rng.chance(0.5) {
        rng.log_range(0.1, 20.0)
    } else {
        0.0
    };
    let collider = rng.chance(0.6).then(|| {
        let radius = rng.log_range(0.02, 0.5);
        let (shape, thickness) = match rng.next() % 4 {
            0 => (ColliderShape::Sphere(Sphere::new(radius)), 2.0 * radius),
            1 => (
                ColliderShape::Capsule(Capsule3d::new(radius, rng.range(0.0, 1.0))),
                2.0 * radius,
            ),
            2 => {
                let half = Vec3::new(
                    rng.log_range(0.02, 0.5),
                    rng.log_range(0.02, 0.5),
                    rng.log_range(0.02, 0.5),
                );
                (
                    ColliderShape::Cuboid(Cuboid::from_size(2.0 * half)),
                    2.0 * half.min_element(),
                )
            }
            _ => (ColliderShape::HalfSpace(InfinitePlane3d::new(Vec3::Y)), 1.0),
        };
        let half_space = matches!(shape, ColliderShape::HalfSpace(_));
        let h = dt / substeps as f32;
        // Up to half the thickness per substep (a floor rises at most 2 m/s).
        let limit = if half_space { 2.0 } else { 0.5 * thickness / h };
        let speed = if rng.chance(0.5) {
            0.0
        } else {
            rng.range(0.0, limit)
        };
        // Radius of a ball around the collider's centre that holds it.
        let extent = match shape {
            ColliderShape::Sphere(s) => s.radius,
            ColliderShape::Capsule(c) => c.radius + c.half_length,
            ColliderShape::Cuboid(b) => b.half_size.length(),
            ColliderShape::HalfSpace(_) => 0.0,
        };
        let (start, direction) = if half_space {
            (Vec3::new(0.0, rng.range(-1.0, 0.9), 0.0), Vec3::Y)
        } else if speed == 0.0 {
            // Below the cloth, which falls onto it.
            (
                Vec3::new(0.0, 0.95 - extent - rng.range(0.0, 0.5), 0.0),
                Vec3::Y,
            )
        } else {
            // Clear of the cloth at the start, heading through its middle.
            let d = rng.direction();
            let travel = speed * dt * steps as f32;
            let back = 0.5 * travel.min(3.0) + extent + 0.05;
            (Vec3::new(0.0, 1.0, 0.0) - d * back, d)
        };
        StressCollider {
            shape,
            start,
            velocity: direction * speed,
            rotation: if half_space {
                Quat::IDENTITY
            } else {
                Quat::from_axis_angle(rng.direction(), rng.range(0.0, TAU))
            },
        }
    });
    let (wind, gusts) = if rng.chance(0.5) {
        (rng.direction() * rng.log_range(0.5, 50.0), rng.chance(0.5))
    } else {
        (Vec3::ZERO, false)
    };
    // Tethers in a quarter of the cases, a third of those without slack (drawn last, so that
    // every other draw stays what it was).
    if rng.chance(0.25) {
        settings.tethers = Tethers {
            enabled: true,
            slack: if rng.chance(1.0 / 3.0) {
                0.0
            } else {
                rng.log_range(1e-3, 0.2)
            },
        };
    }
    StressCase {
        seed,
        index,
        settings,
        side,
        size,
        dt,
        steps,
        mass_ratio,
        pins,
        pin_speed,
        collider,
        wind,
        gusts,
        air: None,
        cut: None,
    }
}

impl StressCase {
    /// The same case on a closed cloth with air inside ([`StressAir`], drawn from the case's seed
    /// and index): an icosphere the cloth's size across, of about the grid's particle count,
    /// pinned at as many of its first particles as the grid had corners pinned, its collider
    /// moved back by the ball's radius. Half the cases keep a volume (0.6–1.4 of the built one,
    /// bulk modulus 10²–10⁸ Pa), half hold a gas (−50 kPa to +100 kPa about the air outside at
    /// the built volume).
    pub fn with_air(mut self) -> Self {
        let mut rng = SplitMix64(self.seed ^ self.index.wrapping_mul(0xA076_1D64_78BD_642F));
        rng.next();
        self.air = Some(if rng.chance(0.5) {
            StressAir::Volume {
                scale: rng.range(0.6, 1.4),
                bulk_modulus: rng.log_range(1e2, 1e8),
            }
        } else if rng.chance(0.25) {
            StressAir::Gas {
                gauge: -rng.log_range(10.0, 5e4),
            }
        } else {
            StressAir::Gas {
                gauge: rng.log_range(10.0, 1e5),
            }
        });
        self.pins = self.pins_for(self.side, self.pins.len());
        // The ball is centred where the grid lay: its collider starts as far again from the
        // grid's plane (below it, or back along its path), so as to start clear of the ball.
        let radius = 0.5 * self.size;
        if let Some(c) = &mut self.collider {
            let along = c.velocity.normalize_or_zero();
            if along == Vec3::ZERO || matches!(c.shape, ColliderShape::HalfSpace(_)) {
                c.start.y -= radius;
            } else {
                c.start -= along * radius;
            }
        }
        self
    }
}

impl StressCase {
    /// The same case torn (drawn from the case's seed and index): in three cases of four,
    /// tearing under strain at a stretch of 0.5%–100% (at most 1–64 splits a step, of the
    /// structural springs or of all), and in three of four a cut at a random step, through the
    /// cloth's starting centre: a plane, a blade's segment across the whole cloth, or a ray's
    /// hole of up to half the cloth's size. The drawn wind (half the cases, up to 50 m/s, gusty
    /// in half of those) is the gale.
    pub fn with_tearing(mut self) -> Self {
        let mut rng = SplitMix64(self.seed ^ self.index.wrapping_mul(0xE703_7ED1_A0B4_28DB));
        rng.next();
        if rng.chance(0.75) {
            self.settings.tearing = Tearing {
                enabled: true,
                max_stretch: rng.log_range(0.005, 1.0),
                max_per_step: rng.log_range(1.0, 64.99).floor() as u32,
                springs: if rng.chance(0.5) {
                    TearSprings::Structural
                } else {
                    TearSprings::All
                },
            };
        }
        // The cloth starts centred 1 m up (see `StressCase::build`).
        let centre = Vec3::Y;
        self.cut = rng.chance(0.75).then(|| {
            let step = (rng.next() % self.steps.max(1) as u64) as u32;
            let d = rng.direction();
            let cut = match rng.next() % 3 {
                0 => Cut::Plane {
                    point: centre,
                    normal: d,
                },
                1 => Cut::Segment {
                    start: centre - d * self.size,
                    end: centre + d * self.size,
                    radius: rng.log_range(0.01, 0.5) * self.size,
                },
                _ => Cut::Ray {
                    origin: centre - d * self.size,
                    direction: d,
                    radius: rng.log_range(0.01, 0.5) * self.size,
                },
            };
            (step, cut)
        });
        self
    }
}
