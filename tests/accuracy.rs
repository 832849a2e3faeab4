//! Analytic accuracy tests of every integrator on the engine-free solver: a spring–mass oscillator
//! (period and amplitude), a hanging chain's static equilibrium against the exact discrete solution
//! (found by Newton's method in f64 here), free fall, energy conservation without damping, XPBD's
//! sag against its substep count, convergence orders against the f64 reference, and the reference
//! checked against itself at a 10× tighter tolerance.
//!
//! Every check runs every integrator and prints its numbers (`cargo test --test accuracy --
//! --nocapture`). XPBD and `Auto` (the default) are also held to their own measured values, with
//! [`MEASURED_MARGIN`], in the chain, energy and convergence checks (`Auto` in the chain, exact to
//! rounding there, to [`ROUNDING_EPSILONS`]). The thresholds are
//! asserted for the integrators listed with each check;
//! an integrator left out fails that threshold by construction, for the measured reason written
//! next to the list (and in docs/accuracy.md), and is asserted against its own analytic behaviour
//! where it has one. Thresholds are the issue's, not tuned to pass.

use bevy_cloth::harness::reference::{REFERENCE_TOLERANCE, ReferenceProblem};
use bevy_cloth::harness::scenes::{AccuracyScene, relative_max_error, relative_rms_error};
use bevy_cloth::sim::{
    Accuracy, ClothModel, ClothSim, GridSpec, Integrator, MAX_SUBSTEPS, SolverSettings, Stiffness,
};
use glam::{DVec3, Vec3};

const DT: f32 = 1.0 / 60.0;

/// How far XPBD and `Auto` (which runs XPBD at the default 20 substeps) may drift from their
/// measured accuracy before a test fails: half again the measured value, so that an accuracy
/// regression of 2× fails while run-to-run identity (the solver is deterministic) and small
/// deliberate changes pass. The measured values are named with each check.
const MEASURED_MARGIN: f64 = 1.5;

/// How far an integrator that is exact at rest may miss the exact f64 answer, in units of
/// `f32::EPSILON` times the scene's largest coordinate (one or two f32 ulps there each).
const ROUNDING_EPSILONS: f64 = 4.0;

/// The measured value of `integrator` in `table`, if it has one.
fn measured(table: &[(Integrator, f64)], integrator: Integrator) -> Option<f64> {
    table
        .iter()
        .find(|(i, _)| *i == integrator)
        .map(|(_, v)| *v)
}

/// The settings every test starts from for `integrator`: the defaults (default substeps), with a
/// conjugate-gradient cap of 100 for implicit Euler (its `iterations`; the default of 1 is meant for
/// XPBD), and sleeping off (these tests measure the integrators, not the sleep heuristic, which
/// freezes a cloth slightly before its exact rest).
fn method(integrator: Integrator) -> SolverSettings {
    SolverSettings {
        integrator,
        sleep_speed: 0.0,
        iterations: if integrator == Integrator::ImplicitEuler {
            100
        } else {
            SolverSettings::default().iterations
        },
        ..Default::default()
    }
}

/// A chain (or single spring): exactly one structural spring per consecutive pair, nothing else.
fn chain(points: &[Vec3]) -> ClothModel {
    let springs: Vec<_> = (0..points.len() as u32 - 1)
        .map(|i| (i, i + 1, bevy_cloth::sim::SpringKind::Structural))
        .collect();
    let model = ClothModel::from_springs(points, &springs).unwrap();
    assert_eq!(model.springs.len(), points.len() - 1);
    model
}

/// Integrators held to the oscillator's 1% amplitude threshold: the symplectic ones. XPBD (one
/// iteration) and implicit Euler both act as backward Euler on a single linear spring and lose
/// amplitude as `(1 + h²ω²)^(-n/2)` after `n` substeps: about 27% over 10 periods at 20 substeps of
/// 1/60 s. For them that predicted decay is asserted instead (within 1 percentage point).
const KEEPS_AMPLITUDE: [Integrator; 2] = [Integrator::SymplecticEuler, Integrator::Verlet];

#[test]
fn spring_mass_oscillator_period_and_amplitude() {
    // A 0.1 kg particle on a 16 N/m spring below a pin, released at rest length: it oscillates about
    // y_eq = -(L + m g / k) with amplitude m g / k and period 2π √(m/k) ≈ 0.497 s.
    let (m, k, l, g) = (0.1f32, 16.0f32, 0.5f32, 9.81f32);
    let omega = (k / m).sqrt() as f64;
    let period = std::f64::consts::TAU / omega;
    let amplitude = (m * g / k) as f64;
    let y_eq = -(l as f64) - amplitude;
    let mut failures = Vec::new();
    for integrator in Integrator::ALL {
        let settings = SolverSettings {
            particle_mass: m,
            damping: 0.0,
            stiffness: Stiffness {
                structural: k,
                shear: 0.0,
                bend: 0.0,
            },
            ..method(integrator)
        };
        let model = chain(&[Vec3::ZERO, Vec3::new(0.0, -l, 0.0)]);
        let mut sim = ClothSim::new(model, settings, |p| p).unwrap();
        sim.set_pins([(0, Vec3::ZERO)]).unwrap();
        let frames = (10.0 * period / DT as f64).ceil() as usize + 2;
        let (mut crossings, mut amplitudes) = (Vec::new(), Vec::new());
        let mut prev = sim.positions()[1].y as f64 - y_eq;
        for f in 1..=frames {
            sim.step(DT).unwrap();
            let y = sim.positions()[1].y as f64 - y_eq;
            let v = sim.velocities()[1].y as f64;
            // Amplitude from position and velocity: exact for the continuous oscillator.
            amplitudes.push((y * y + (v / omega).powi(2)).sqrt());
            if prev < 0.0 && y >= 0.0 {
                let t = (f as f64 - 1.0 + prev / (prev - y)) * DT as f64;
                crossings.push(t);
            }
            prev = y;
        }
        let measured =
            (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as f64;
        let period_error = (measured - period).abs() / period;
        // Amplitude over the last period against the exact one, and against backward Euler's
        // decay (1 + h²ω²)^(-n/2) averaged over the same frames.
        let per = (period / DT as f64) as usize;
        let window = amplitudes.len() - per..amplitudes.len();
        let last = amplitudes[window.clone()].iter().sum::<f64>() / per as f64;
        let loss = (amplitude - last) / amplitude;
        let h_omega = omega * DT as f64 / sim.substeps_for(DT) as f64;
        let backward_euler = window
            .map(|f| {
                let n = ((f + 1) * sim.substeps_for(DT) as usize) as f64;
                (1.0 + h_omega * h_omega).powf(-n / 2.0)
            })
            .sum::<f64>()
            / per as f64;
        let predicted_loss = 1.0 - backward_euler;
        let held = KEEPS_AMPLITUDE.contains(&integrator);
        println!(
            "{:>16}: period error {:.3}%, amplitude loss {:.3}% ({} crossings){}",
            integrator.name(),
            100.0 * period_error,
            100.0 * loss,
            crossings.len(),
            if held {
                String::new()
            } else {
                format!(
                    ": fails the 1% amplitude check; backward Euler predicts {:.3}%",
                    100.0 * predicted_loss
                )
            }
        );
        if period_error > 0.005 {
            failures.push(format!(
                "{}: period error {:.3}%",
                integrator.name(),
                100.0 * period_error
            ));
        }
        if held && loss.abs() > 0.01 {
            failures.push(format!(
                "{}: amplitude change {:.3}%",
                integrator.name(),
                -100.0 * loss
            ));
        }
        if !held && (loss - predicted_loss).abs() > 0.01 {
            failures.push(format!(
                "{}: amplitude loss {:.3}%, backward Euler predicts {:.3}%",
                integrator.name(),
                100.0 * loss,
                100.0 * predicted_loss
            ));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Total energy and its gradient and Hessian for the free particles of a chain (f64, exact
/// Hessian), unknowns ordered `3 i + axis` over the free particles `1..n-1`.
fn chain_equilibrium(x0: &[DVec3], rest: &[f64], k: f64, m: f64, g: DVec3) -> Vec<DVec3> {
    let n = x0.len();
    let free = n - 2;
    let dim = 3 * free;
    let mut x = x0.to_vec();
    for _ in 0..100 {
        let mut grad = vec![0.0; dim];
        let mut hess = vec![0.0; dim * dim];
        for i in 1..n - 1 {
            for a in 0..3 {
                grad[3 * (i - 1) + a] -= m * g[a];
            }
        }
        for s in 0..n - 1 {
            let d = x[s] - x[s + 1];
            let len = d.length();
            let u = d / len;
            let f = k * (len - rest[s]);
            // Block for d/dx_a of the gradient: k u uᵀ + k (1 - L/len) (I - u uᵀ).
            let mut block = [[0.0; 3]; 3];
            for (r, row) in block.iter_mut().enumerate() {
                for (c, b) in row.iter_mut().enumerate() {
                    let id = if r == c { 1.0 } else { 0.0 };
                    *b = k * u[r] * u[c] + k * (1.0 - rest[s] / len) * (id - u[r] * u[c]);
                }
            }
            let ends = [(s, 1.0), (s + 1, -1.0)];
            for &(p, sign) in &ends {
                if p == 0 || p == n - 1 {
                    continue;
                }
                for a in 0..3 {
                    grad[3 * (p - 1) + a] += sign * f * u[a];
                }
                for &(q, sign_q) in &ends {
                    if q == 0 || q == n - 1 {
                        continue;
                    }
                    for r in 0..3 {
                        for c in 0..3 {
                            hess[(3 * (p - 1) + r) * dim + 3 * (q - 1) + c] +=
                                sign * sign_q * block[r][c];
                        }
                    }
                }
            }
        }
        let norm = grad.iter().map(|g| g * g).sum::<f64>().sqrt();
        if norm < 1e-13 {
            return x;
        }
        // Solve hess · step = -grad by Gaussian elimination with partial pivoting.
        let mut rhs: Vec<f64> = grad.iter().map(|g| -g).collect();
        for col in 0..dim {
            let pivot = (col..dim)
                .max_by(|a, b| {
                    hess[a * dim + col]
                        .abs()
                        .total_cmp(&hess[b * dim + col].abs())
                })
                .unwrap();
            for c in 0..dim {
                hess.swap(col * dim + c, pivot * dim + c);
            }
            rhs.swap(col, pivot);
            for r in col + 1..dim {
                let factor = hess[r * dim + col] / hess[col * dim + col];
                for c in col..dim {
                    hess[r * dim + c] -= factor * hess[col * dim + c];
                }
                rhs[r] -= factor * rhs[col];
            }
        }
        let mut step = vec![0.0; dim];
        for r in (0..dim).rev() {
            let mut acc = rhs[r];
            for c in r + 1..dim {
                acc -= hess[r * dim + c] * step[c];
            }
            step[r] = acc / hess[r * dim + r];
        }
        for i in 1..n - 1 {
            for a in 0..3 {
                x[i][a] += step[3 * (i - 1) + a];
            }
        }
    }
    panic!("Newton did not converge");
}

/// Integrators held to the chain's 0.1 mm threshold: those whose rest state is exactly `f = 0`.
/// XPBD with one Gauss-Seidel iteration per substep settles where one sweep of its constraint
/// projection balances one substep of gravity, which is not exactly the force balance: it hangs
/// 0.15 mm (0.05% of the sag) off the exact equilibrium.
const EXACT_AT_REST: [Integrator; 3] = [
    Integrator::SymplecticEuler,
    Integrator::Verlet,
    Integrator::ImplicitEuler,
];

#[test]
fn hanging_chain_reaches_the_exact_discrete_equilibrium() {
    // 11 particles, 10 springs of rest length 0.1 m laid out as a V whose ends are 0.8 m apart,
    // both ends pinned: the chain sags into an elastic discrete catenary.
    let (k, m) = (100.0f32, 0.01f32);
    let n = 11;
    let (cos, sin) = (0.8f32, 0.6f32);
    let points: Vec<Vec3> = (0..n)
        .map(|i| {
            let down = if i <= 5 { i } else { 10 - i } as f32;
            Vec3::new(i as f32 * 0.1 * cos, -down * 0.1 * sin, 0.0)
        })
        .collect();
    let model = chain(&points);
    // The model's springs are coloured; re-order rest lengths by the first particle index.
    let springs = &model.springs;
    let mut rest_by_index = vec![0.0; n - 1];
    for ((a, b), rest) in springs.a.iter().zip(&springs.b).zip(&springs.rest) {
        rest_by_index[*a.min(b) as usize] = *rest as f64;
    }
    let gravity = Vec3::new(0.0, -9.81, 0.0);
    let mut settled = Vec::new();
    for integrator in Integrator::CHOICES {
        let settings = SolverSettings {
            particle_mass: m,
            damping: 2.0,
            gravity,
            stiffness: Stiffness {
                structural: k,
                shear: 0.0,
                bend: 0.0,
            },
            ..method(integrator)
        };
        let mut sim = ClothSim::new(chain(&points), settings, |p| p).unwrap();
        sim.set_pins([(0, points[0]), (n as u32 - 1, points[n - 1])])
            .unwrap();
        for _ in 0..1200 {
            sim.step(DT).unwrap();
        }
        settled.push((integrator, sim.positions().to_vec()));
    }
    // Newton's method (exact Hessian, f64) from the symplectic Euler result: the V start is far
    // from equilibrium, with compressed springs, where the Hessian is indefinite. Newton converges
    // to the equilibrium nearest its start, which is the only one in reach of a hanging chain.
    let start: Vec<DVec3> = settled[2].1.iter().map(|p| p.as_dvec3()).collect();
    let exact = chain_equilibrium(
        &start,
        &rest_by_index,
        k as f64,
        m as f64,
        gravity.as_dvec3(),
    );
    let sag = -exact[5].y;
    let span = exact
        .iter()
        .map(|p| p.abs().max_element())
        .fold(0.0, f64::max);
    let rounding = span * f32::EPSILON as f64;
    let mut failures = Vec::new();
    for (integrator, positions) in &settled {
        let err = positions
            .iter()
            .zip(&exact)
            .map(|(p, e)| p.as_dvec3().distance(*e))
            .fold(0.0, f64::max);
        println!(
            "{:>16}: max distance to the exact equilibrium {err:.2e} m (chain length 1 m, sag {sag:.4} m)",
            integrator.name()
        );
        // 0.1 mm on a 1 m chain.
        if err > 1e-4 && EXACT_AT_REST.contains(integrator) {
            failures.push(format!("{}: {err:.2e} m", integrator.name()));
        }
        // Measured 2026-11-23: XPBD's one iteration per substep leaves a residual stretch.
        let xpbd = 1.16e-4;
        if *integrator == Integrator::Xpbd && err > xpbd * MEASURED_MARGIN {
            failures.push(format!("XPBD: {err:.2e} m, measured {xpbd:.2e}"));
        }
        // `Auto` settles on Verlet (within its bound here), exact to rounding: held to a rounding
        // bound, not to a measured value, since any change in the order of the arithmetic moves
        // a rounding-level error by an ulp or two.
        if *integrator == Integrator::Auto && err > ROUNDING_EPSILONS * rounding {
            failures.push(format!(
                "auto: {err:.2e} m, more than {ROUNDING_EPSILONS} × {rounding:.2e} m"
            ));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn free_fall_follows_the_parabola() {
    let mut failures = Vec::new();
    for integrator in Integrator::ALL {
        let settings = SolverSettings {
            damping: 0.0,
            ..method(integrator)
        };
        let model = ClothModel::grid(&GridSpec::new(3, 3, 0.1)).unwrap();
        let mut sim = ClothSim::new(model, settings, |p| p + Vec3::new(0.0, 10.0, 0.0)).unwrap();
        let v0 = Vec3::new(1.0, 2.0, 0.5);
        sim.set_velocities(v0).unwrap();
        let x0 = sim.positions()[4];
        for _ in 0..60 {
            sim.step(DT).unwrap();
        }
        let exact = x0.as_dvec3() + v0.as_dvec3() + 0.5 * settings.gravity.as_dvec3();
        let err = sim.positions()[4].as_dvec3().distance(exact);
        // First-order methods err by g t h / 2 (h the substep); Verlet is exact for constant
        // acceleration. On top, f32 rounding: a random walk of √(2 × substeps) roundings of
        // positions of about 10 m.
        let substeps = 60 * sim.substeps_for(DT) as usize;
        let rounding = ((2 * substeps) as f64).sqrt() * f32::EPSILON as f64 * 10.0;
        let h = DT as f64 / sim.substeps_for(DT) as f64;
        let bound = if integrator == Integrator::Verlet {
            rounding
        } else {
            0.5 * 9.81 * h * 1.01 + rounding
        };
        println!(
            "{:>16}: error {err:.2e} m (bound {bound:.2e})",
            integrator.name()
        );
        if err > bound {
            failures.push(format!("{}: {err:.2e} m > {bound:.2e}", integrator.name()));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Integrators held to the 0.1% energy-growth threshold. Left out, measured at the default
/// settings: symplectic Euler at the stability-bound substep count (84 here) oscillates about the
/// true energy by about 1% of the kinetic energy (its error is O(hω), and the automatic substeps put
/// hω near its limit); XPBD with one iteration gains up to about 5% transiently before losing
/// most of it (it is not an energy-consistent method).
const ENERGY_STABLE: [Integrator; 2] = [Integrator::Verlet, Integrator::ImplicitEuler];

#[test]
fn undamped_energy_does_not_grow() {
    // An 8×8 cloth with the default stiffness and mass (5 cm spacing) swinging from one corner for
    // 10 s, no damping. Energy growth is measured against the peak kinetic energy of the run (the
    // energy that is actually in motion; the total depends on where gravity's zero is).
    let mut failures = Vec::new();
    for integrator in Integrator::CHOICES {
        let settings = SolverSettings {
            damping: 0.0,
            ..method(integrator)
        };
        let model = ClothModel::grid(&GridSpec::new(8, 8, 0.05)).unwrap();
        let mut sim = ClothSim::new(model, settings, |p| p).unwrap();
        sim.set_pins([(0, sim.positions()[0])]).unwrap();
        let e0 = sim.energy().total();
        let (mut peak_kinetic, mut max_growth) = (0.0f64, f64::MIN);
        for _ in 0..600 {
            sim.step(DT).unwrap();
            let e = sim.energy();
            peak_kinetic = peak_kinetic.max(e.kinetic);
            max_growth = max_growth.max(e.total() - e0);
        }
        let growth = max_growth / peak_kinetic;
        println!(
            "{:>16}: max energy growth {:.4}% of the peak kinetic energy {peak_kinetic:.3e} J, \
             final energy change {:.2}%",
            integrator.name(),
            100.0 * growth,
            100.0 * (sim.energy().total() - e0) / peak_kinetic
        );
        if growth > 1e-3 && ENERGY_STABLE.contains(&integrator) {
            failures.push(format!(
                "{}: grew {:.4}%",
                integrator.name(),
                100.0 * growth
            ));
        }
        // XPBD's transient gain, measured 9.44% of the peak kinetic energy (2026-11-23); `Auto`
        // runs XPBD here (20 substeps are below Verlet's bound).
        let table = [(Integrator::Xpbd, 0.0944), (Integrator::Auto, 0.0944)];
        if let Some(m) = measured(&table, integrator)
            && growth > m * MEASURED_MARGIN
        {
            failures.push(format!(
                "{}: grew {:.4}%, measured {:.2}%",
                integrator.name(),
                100.0 * growth,
                100.0 * m
            ));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn xpbd_sag_hardly_depends_on_substeps() {
    // A 16×16 cloth (5 cm) hanging from two corners settles; its sag (lowest point below the pins)
    // at 10 and 40 substeps, same compliance, one iteration.
    let sag = |substeps: u32| {
        let settings = SolverSettings {
            integrator: Integrator::Xpbd,
            substeps,
            iterations: 1,
            damping: 2.0,
            ..Default::default()
        };
        let model = ClothModel::grid(&GridSpec::new(16, 16, 0.05)).unwrap();
        let mut sim = ClothSim::new(model, settings, |p| p).unwrap();
        sim.set_pins([(0, sim.positions()[0]), (15, sim.positions()[15])])
            .unwrap();
        for _ in 0..900 {
            sim.step(DT).unwrap();
        }
        -sim.positions().iter().map(|p| p.y).fold(f32::MAX, f32::min)
    };
    let (s10, s40) = (sag(10), sag(40));
    let change = (s10 - s40).abs() / s40;
    println!(
        "sag {s10:.5} m at 10 substeps, {s40:.5} m at 40: {:.3}%",
        100.0 * change
    );
    assert!(change <= 0.01, "sag changed by {:.3}%", 100.0 * change);
}

#[test]
fn integrators_converge_at_their_order() {
    // The soft cloth of DESIGN.md (8×8, 10 cm, 10 g, 500/500/50 N/m, two corners pinned), 0.5 s:
    // doubling the substeps halves the error of the first-order methods and quarters Verlet's.
    let soft = |integrator: Integrator, substeps: u32| SolverSettings {
        integrator,
        substeps,
        // A converged implicit solve; XPBD (also as `Auto`'s choice) as it runs by default.
        iterations: if integrator == Integrator::ImplicitEuler {
            200
        } else {
            1
        },
        auto_substeps: false,
        particle_mass: 0.01,
        damping: 0.0,
        stiffness: Stiffness {
            structural: 500.0,
            shear: 500.0,
            bend: 50.0,
        },
        ..Default::default()
    };
    let build = |settings: SolverSettings| {
        let model = ClothModel::grid(&GridSpec::new(8, 8, 0.1)).unwrap();
        let mut sim = ClothSim::new(model, settings, |p| p).unwrap();
        sim.set_pins([(0, sim.positions()[0]), (7, sim.positions()[7])])
            .unwrap();
        sim
    };
    let reference = ReferenceProblem::from_sim(&build(soft(Integrator::Xpbd, 1)))
        .solve(0.5, 1e-9)
        .unwrap();
    let diagonal = 0.7 * 2f64.sqrt();
    let mut failures = Vec::new();
    // Orders, and for XPBD and `Auto` the errors measured 2026-11-23 at the coarse and fine
    // substep counts. `Auto` switches between XPBD and Verlet from step to step here, so it has
    // no single order.
    for (integrator, order, errors) in [
        (Integrator::Xpbd, Some(1.0), Some((7.73e-3, 4.08e-3))),
        (Integrator::SymplecticEuler, Some(1.0), None),
        (Integrator::Verlet, Some(2.0), None),
        (Integrator::ImplicitEuler, Some(1.0), None),
        (Integrator::Auto, None, Some((4.34e-4, 1.80e-4))),
    ] {
        let error = |substeps| {
            let mut sim = build(soft(integrator, substeps));
            for _ in 0..30 {
                sim.step(DT).unwrap();
            }
            relative_rms_error(sim.positions(), &reference.positions, diagonal)
        };
        let (coarse, fine) = if integrator == Integrator::Verlet {
            (10, 20)
        } else {
            (20, 40)
        };
        let (e1, e2) = (error(coarse), error(fine));
        let observed = (e1 / e2).log2();
        println!(
            "{:>16}: error {e1:.2e} at {coarse} substeps, {e2:.2e} at {fine}: order {observed:.2}",
            integrator.name()
        );
        if order.is_some_and(|order: f64| (observed - order).abs() > 0.3) {
            failures.push(format!("{}: order {observed:.2}", integrator.name()));
        }
        if let Some((m1, m2)) = errors
            && (e1 > m1 * MEASURED_MARGIN || e2 > m2 * MEASURED_MARGIN)
        {
            failures.push(format!(
                "{}: errors {e1:.2e}, {e2:.2e}, measured {m1:.2e}, {m2:.2e}",
                integrator.name()
            ));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn reference_agrees_with_itself_at_a_tighter_tolerance() {
    // The swing scene's reference at the benchmark's tolerance against one at a tenth of it.
    let scene = AccuracyScene::Swing;
    let problem = ReferenceProblem::from_sim(&scene.build(&SolverSettings::default()).unwrap());
    let t = scene.duration();
    let a = problem.solve(t, REFERENCE_TOLERANCE).unwrap();
    let b = problem.solve(t, REFERENCE_TOLERANCE / 10.0).unwrap();
    let diff = (a
        .positions
        .iter()
        .zip(&b.positions)
        .map(|(a, b)| a.distance_squared(*b))
        .sum::<f64>()
        / a.positions.len() as f64)
        .sqrt()
        / scene.diagonal();
    println!(
        "reference: {} steps ({} rejected) at {REFERENCE_TOLERANCE:e}, {} at a tenth; difference \
         {diff:.2e} of the diagonal",
        a.steps, a.rejected, b.steps
    );
    // The reference must be far more accurate than anything f32 can resolve (~1e-7).
    assert!(diff < 1e-8, "reference error estimate {diff:.2e}");
    // And it conserves energy.
    let e0 = problem.energy(
        problem.initial_positions(),
        &vec![DVec3::ZERO; problem.particle_count()],
    );
    let e1 = problem.energy(&a.positions, &a.velocities);
    let kinetic: f64 = a
        .velocities
        .iter()
        .map(|v| 0.5 * 0.001 * v.length_squared())
        .sum();
    assert!(
        (e1 - e0).abs() < 1e-6 * kinetic,
        "energy drift {:.2e} J of kinetic {kinetic:.2e} J",
        e1 - e0
    );
}

#[path = "accuracy/tolerance.rs"]
mod tolerance;
