//! The explicit force-based integrators: symplectic (semi-implicit) Euler and position Verlet, on the
//! shared spring-force kernel. Both are symplectic (energy oscillates instead of drifting) and stable
//! only for substeps `h < 2/ω_max`; [`SolverSettings::auto_substeps`](super::SolverSettings) keeps
//! them there.
//!
//! Same model and semantics as every integrator: Hookean springs, per-particle mass, gravity, pinned
//! particles following their interpolated targets, velocities decaying as `exp(-damping t)`.
//! Nothing here allocates.

use glam::Vec3;

use super::forces::add_spring_forces;
use super::solver::{ClothSim, drive_pins};

/// Sets `sim.forces` to gravity plus wind plus the spring forces at the current state.
pub(super) fn compute_forces(sim: &mut ClothSim) {
    let g = sim.settings.gravity;
    for (f, m) in sim.forces.iter_mut().zip(&sim.mass) {
        *f = *m * g;
    }
    sim.wind.add_forces(&mut sim.forces);
    let springs = super::forces::SpringSet {
        a: &sim.model.springs.a,
        b: &sim.model.springs.b,
        rest: &sim.model.springs.rest,
        k: &sim.stiffness,
    };
    add_spring_forces(springs, &sim.positions, &mut sim.forces);
}

/// Symplectic Euler, `n` substeps of `h = dt/n`: `v ← e^{-c h} (v + h f(x)/m)`, then `x ← x + h v`.
pub(super) fn step_symplectic_euler(sim: &mut ClothSim, dt: f32, n: u32) {
    let h = dt / n as f32;
    let inv_h = 1.0 / h;
    let keep = (-sim.settings.damping * h).exp();
    for sub in 0..n {
        sim.contacts.begin_substep(&sim.positions);
        compute_forces(sim);
        for ((x, v), (f, w)) in sim
            .positions
            .iter_mut()
            .zip(sim.velocities.iter_mut())
            .zip(sim.forces.iter().zip(&sim.inv_mass))
        {
            if *w > 0.0 {
                *v = (*v + *f * (*w * h)) * keep;
                *x += *v * h;
            }
        }
        let (t0, t1) = (sub as f32 / n as f32, (sub + 1) as f32 / n as f32);
        drive_pins(
            &sim.pins,
            t0,
            t1,
            inv_h,
            &mut sim.positions,
            &mut sim.velocities,
        );
        sim.resolve_contacts(sub, n, h);
    }
}

/// Position Verlet (drift-kick-drift), `n` substeps of `h = dt/n`: `x ← x + h/2 v`,
/// `v ← e^{-c h} (v + h f(x)/m)`, `x ← x + h/2 v`. Pinned particles sit at their target of the
/// half step while the forces are evaluated. The closing half drift of one substep and the opening
/// half drift of the next are fused into one pass (the same arithmetic, in one sweep).
pub(super) fn step_verlet(sim: &mut ClothSim, dt: f32, n: u32) {
    let h = dt / n as f32;
    let half = 0.5 * h;
    let inv_h = 1.0 / h;
    let keep = (-sim.settings.damping * h).exp();
    drift(&mut sim.positions, &sim.velocities, &sim.inv_mass, half);
    for sub in 0..n {
        sim.contacts.begin_substep(&sim.positions);
        let mid = (sub as f32 + 0.5) / n as f32;
        for pin in &sim.pins {
            sim.positions[pin.particle as usize] = pin.from.lerp(pin.to, mid);
        }
        compute_forces(sim);
        let last = sub + 1 == n;
        for ((x, v), (f, w)) in sim
            .positions
            .iter_mut()
            .zip(sim.velocities.iter_mut())
            .zip(sim.forces.iter().zip(&sim.inv_mass))
        {
            if *w > 0.0 {
                *v = (*v + *f * (*w * h)) * keep;
                // Close this substep's drift, then (unless it is the last) open the next one's.
                *x += *v * half;
                if !last {
                    *x += *v * half;
                }
            }
        }
        let (t0, t1) = (sub as f32 / n as f32, (sub + 1) as f32 / n as f32);
        if last {
            drive_pins(
                &sim.pins,
                t0,
                t1,
                inv_h,
                &mut sim.positions,
                &mut sim.velocities,
            );
        }
        sim.resolve_contacts(sub, n, h);
    }
}

/// `x ← x + τ v` for the free particles.
fn drift(x: &mut [Vec3], v: &[Vec3], inv_mass: &[f32], tau: f32) {
    for ((x, v), w) in x.iter_mut().zip(v).zip(inv_mass) {
        if *w > 0.0 {
            *x += *v * tau;
        }
    }
}
