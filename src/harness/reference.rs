//! The f64 reference integrator: the canonical model as an ODE, without damping or collisions and
//! with pinned particles fixed where they are, integrated by the Dormand–Prince 5(4) Runge–Kutta
//! pair (Dormand & Prince 1980) with local error control.
//!
//! Error control: a step is accepted when the RMS over all position and velocity components of the
//! embedded error estimate, each divided by `tol · (1 + max(|y|, |y_new|))`, is at most 1; the next
//! step is `h · clamp(0.9 err^{-1/5}, 0.2, 5)`. The global error is checked, not assumed: the tests
//! (and `cloth_cli work-precision`) compare a solution with one at a 10× tighter tolerance.
//!
//! Used by tests, benchmarks and the CLI; allocates freely (it is not a real-time path) and knows
//! nothing about ECS.

use glam::DVec3;

use crate::error::ClothError;
use crate::sim::ClothSim;

/// The tolerance the accuracy benchmark uses for its reference solutions.
pub const REFERENCE_TOLERANCE: f64 = 1e-10;

/// Most accepted plus rejected steps one [`ReferenceProblem::solve`] may take.
pub const MAX_REFERENCE_STEPS: u64 = 20_000_000;

/// The undamped mass-spring ODE `x' = v`, `v' = f(x)/m + g` of one cloth, in f64.
#[derive(Debug, Clone)]
pub struct ReferenceProblem {
    x0: Vec<DVec3>,
    v0: Vec<DVec3>,
    /// Inverse masses; 0 for pinned particles, which stay at their initial position.
    inv_mass: Vec<f64>,
    a: Vec<u32>,
    b: Vec<u32>,
    rest: Vec<f64>,
    k: Vec<f64>,
    gravity: DVec3,
}

/// The state of a [`ReferenceProblem`] at the end time, with the integrator's statistics.
#[derive(Debug, Clone)]
pub struct ReferenceSolution {
    /// Particle positions, m.
    pub positions: Vec<DVec3>,
    /// Particle velocities, m/s.
    pub velocities: Vec<DVec3>,
    /// Accepted steps.
    pub steps: u64,
    /// Rejected steps.
    pub rejected: u64,
}

impl ReferenceProblem {
    /// The ODE of `sim` from its current state: positions, velocities, masses, stiffness, gravity
    /// and springs (rest lengths as the f32 model stores them). Damping is ignored; pinned particles
    /// stay where they are now.
    pub fn from_sim(sim: &ClothSim) -> Self {
        let settings = sim.settings();
        let springs = &sim.model().springs;
        let mut inv_mass: Vec<f64> = sim.masses().iter().map(|m| 1.0 / *m as f64).collect();
        let mut v0: Vec<DVec3> = sim.velocities().iter().map(|v| v.as_dvec3()).collect();
        for p in sim.pinned() {
            inv_mass[p as usize] = 0.0;
            v0[p as usize] = DVec3::ZERO;
        }
        Self {
            x0: sim.positions().iter().map(|x| x.as_dvec3()).collect(),
            v0,
            inv_mass,
            a: springs.a.clone(),
            b: springs.b.clone(),
            rest: springs.rest.iter().map(|r| *r as f64).collect(),
            k: springs
                .kind
                .iter()
                .map(|kind| settings.stiffness.of(*kind) as f64)
                .collect(),
            gravity: settings.gravity.as_dvec3(),
        }
    }

    /// The same problem with each free particle's start moved by `distance` (m) in a direction
    /// of its own (a fixed, well-spread sequence of directions): solved to the same time, it
    /// shows how far the scene itself amplifies a perturbation of that size.
    pub fn perturbed(&self, distance: f64) -> Self {
        let mut p = self.clone();
        let golden = 0.618_033_988_749_895_f64;
        for (i, (x, w)) in p.x0.iter_mut().zip(&self.inv_mass).enumerate() {
            if *w > 0.0 {
                // Points spread evenly over the sphere (a Fibonacci lattice).
                let z = 1.0 - 2.0 * ((i as f64 + 0.5) * golden).fract();
                let phi = std::f64::consts::TAU * ((i as f64) * golden * golden).fract();
                let r = (1.0 - z * z).max(0.0).sqrt();
                *x += DVec3::new(r * phi.cos(), r * phi.sin(), z) * distance;
            }
        }
        p
    }

    /// Number of particles.
    pub fn particle_count(&self) -> usize {
        self.x0.len()
    }

    /// Initial positions.
    pub fn initial_positions(&self) -> &[DVec3] {
        &self.x0
    }

    /// Total energy (kinetic + gravitational + elastic) of the free particles in state `(x, v)`.
    pub fn energy(&self, x: &[DVec3], v: &[DVec3]) -> f64 {
        let mut e = 0.0;
        for i in 0..x.len() {
            if self.inv_mass[i] > 0.0 {
                let m = 1.0 / self.inv_mass[i];
                e += 0.5 * m * v[i].length_squared() - m * self.gravity.dot(x[i]);
            }
        }
        for s in 0..self.a.len() {
            let d = x[self.a[s] as usize].distance(x[self.b[s] as usize]) - self.rest[s];
            e += 0.5 * self.k[s] * d * d;
        }
        e
    }

    /// Writes the time derivative of the state `y = [x; v]` (`2n` entries) into `dy`.
    fn derivative(&self, y: &[DVec3], dy: &mut [DVec3]) {
        let n = self.x0.len();
        let (x, v) = y.split_at(n);
        let (dx, dv) = dy.split_at_mut(n);
        for i in 0..n {
            if self.inv_mass[i] > 0.0 {
                dx[i] = v[i];
                dv[i] = self.gravity / self.inv_mass[i];
            } else {
                dx[i] = DVec3::ZERO;
                dv[i] = DVec3::ZERO;
            }
        }
        for s in 0..self.a.len() {
            let (ia, ib) = (self.a[s] as usize, self.b[s] as usize);
            let d = x[ia] - x[ib];
            let len = d.length();
            if len > 1e-300 {
                let f = d * (self.k[s] * (len - self.rest[s]) / len);
                dv[ia] -= f;
                dv[ib] += f;
            }
        }
        for (dv, w) in dv.iter_mut().zip(&self.inv_mass) {
            *dv *= *w;
        }
    }

    /// Integrates from the initial state to `t_end` seconds at tolerance `tolerance` (see the module
    /// docs for its meaning). Errors: a bad `t_end` or `tolerance`, a non-finite state, or more than
    /// [`MAX_REFERENCE_STEPS`] steps.
    pub fn solve(&self, t_end: f64, tolerance: f64) -> Result<ReferenceSolution, ClothError> {
        if !(t_end.is_finite() && t_end >= 0.0) {
            return Err(ClothError::InvalidValue {
                field: "t_end",
                expected: "finite and >= 0",
                value: t_end,
            });
        }
        if !(tolerance.is_finite() && (1e-14..=1e-1).contains(&tolerance)) {
            return Err(ClothError::InvalidValue {
                field: "tolerance",
                expected: "in 1e-14..=0.1",
                value: tolerance,
            });
        }
        // Dormand–Prince 5(4) (an autonomous ODE, so the nodes c are not needed): matrix a, whose
        // last row is the 5th-order weights b (first same as last), and e = b - b̂ with b̂ the
        // embedded 4th-order weights.
        const A: [&[f64]; 6] = [
            &[1.0 / 5.0],
            &[3.0 / 40.0, 9.0 / 40.0],
            &[44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0],
            &[
                19372.0 / 6561.0,
                -25360.0 / 2187.0,
                64448.0 / 6561.0,
                -212.0 / 729.0,
            ],
            &[
                9017.0 / 3168.0,
                -355.0 / 33.0,
                46732.0 / 5247.0,
                49.0 / 176.0,
                -5103.0 / 18656.0,
            ],
            &[
                35.0 / 384.0,
                0.0,
                500.0 / 1113.0,
                125.0 / 192.0,
                -2187.0 / 6784.0,
                11.0 / 84.0,
            ],
        ];
        const E: [f64; 7] = [
            71.0 / 57600.0,
            0.0,
            -71.0 / 16695.0,
            71.0 / 1920.0,
            -17253.0 / 339200.0,
            22.0 / 525.0,
            -1.0 / 40.0,
        ];
        let n2 = 2 * self.x0.len();
        let mut y: Vec<DVec3> = self.x0.iter().chain(&self.v0).copied().collect();
        let mut k: Vec<Vec<DVec3>> = vec![vec![DVec3::ZERO; n2]; 7];
        let mut stage = vec![DVec3::ZERO; n2];
        let mut y_new = vec![DVec3::ZERO; n2];
        self.derivative(&y, &mut k[0]);
        let (mut t, mut h) = (0.0, (1e-4f64).min(t_end));
        let (mut steps, mut rejected) = (0u64, 0u64);
        let mut last_rejected = false;
        while t < t_end {
            if steps + rejected >= MAX_REFERENCE_STEPS {
                return Err(ClothError::Reference {
                    what: format!("needed more than {MAX_REFERENCE_STEPS} steps by t = {t} s"),
                });
            }
            let last = t + h >= t_end;
            if last {
                h = t_end - t;
            }
            for (s, row) in A.iter().enumerate() {
                for i in 0..n2 {
                    let mut acc = DVec3::ZERO;
                    for (j, a) in row.iter().enumerate() {
                        acc += k[j][i] * *a;
                    }
                    stage[i] = y[i] + acc * h;
                }
                let (_, rest) = k.split_at_mut(s + 1);
                self.derivative(&stage, &mut rest[0]);
            }
            // The last stage was evaluated at y_new (FSAL): stage holds y_new.
            y_new.copy_from_slice(&stage);
            let mut sum = 0.0;
            for i in 0..n2 {
                let mut e = DVec3::ZERO;
                for (j, w) in E.iter().enumerate() {
                    e += k[j][i] * *w;
                }
                let scale = tolerance * (DVec3::ONE + y[i].abs().max(y_new[i].abs()));
                sum += (e * h / scale).length_squared();
            }
            let err = (sum / (3 * n2) as f64).sqrt();
            if !err.is_finite() {
                return Err(ClothError::Reference {
                    what: format!("the state became non-finite at t = {t} s"),
                });
            }
            if err <= 1.0 {
                t = if last { t_end } else { t + h };
                std::mem::swap(&mut y, &mut y_new);
                k.swap(0, 6);
                steps += 1;
                let grow = if last_rejected { 1.0 } else { 5.0 };
                h *= (0.9 * err.max(1e-10).powf(-0.2)).clamp(0.2, grow);
                last_rejected = false;
            } else {
                rejected += 1;
                h *= (0.9 * err.powf(-0.2)).clamp(0.2, 1.0);
                last_rejected = true;
            }
            if h <= 1e-14 * t_end.max(1.0) {
                return Err(ClothError::Reference {
                    what: format!("step size underflow at t = {t} s"),
                });
            }
        }
        let velocities = y.split_off(self.x0.len());
        Ok(ReferenceSolution {
            positions: y,
            velocities,
            steps,
            rejected,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::{ClothModel, SolverSettings};
    use glam::Vec3;

    /// One free particle of 0.25 kg on a 100 N/m spring of rest length 1 to a pinned particle, no
    /// gravity, stretched by 0.1 m: x(t) = 1 + 0.1 cos(20 t).
    fn oscillator() -> ClothSim {
        let p = [
            Vec3::ZERO,
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
        ];
        // A triangle gives three structural springs; the third vertex is pinned too.
        let model = ClothModel::from_mesh(&p, None, &[0, 1, 2], 3).unwrap();
        let settings = SolverSettings {
            particle_mass: 0.25,
            gravity: Vec3::ZERO,
            stiffness: crate::sim::Stiffness {
                structural: 100.0,
                shear: 0.0,
                bend: 0.0,
            },
            ..Default::default()
        };
        let mut sim = ClothSim::new(model, settings, |p| p).unwrap();
        sim.set_pins([(0, p[0]), (2, p[2])]).unwrap();
        sim
    }

    #[test]
    fn harmonic_oscillator_to_tolerance() {
        let mut problem = ReferenceProblem::from_sim(&oscillator());
        // Stretch the free particle 0.1 m along its spring to the pin at the origin; the spring to
        // the other pin is then off-axis, so use only the first spring.
        problem.x0[1] = DVec3::new(1.1, 0.0, 0.0);
        problem.k = problem
            .a
            .iter()
            .zip(&problem.b)
            .map(|(a, b)| {
                if (*a, *b) == (0, 1) || (*a, *b) == (1, 0) {
                    100.0
                } else {
                    0.0
                }
            })
            .collect();
        let t = 3.0;
        let sol = problem.solve(t, 1e-10).unwrap();
        let exact = 1.0 + 0.1 * (20.0f64 * t).cos();
        let err = (sol.positions[1].x - exact).abs();
        assert!(err < 1e-8, "error {err} after {} steps", sol.steps);
        assert!(sol.positions[0] == DVec3::ZERO);
    }

    #[test]
    fn bad_arguments_are_errors() {
        let problem = ReferenceProblem::from_sim(&oscillator());
        assert!(problem.solve(f64::NAN, 1e-8).is_err());
        assert!(problem.solve(1.0, 0.0).is_err());
        assert!(problem.solve(1.0, 1.0).is_err());
        let sol = problem.solve(0.0, 1e-8).unwrap();
        assert_eq!(sol.steps, 0);
    }
}
