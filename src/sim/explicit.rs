//! The explicit force-based integrators: symplectic (semi-implicit) Euler and position Verlet, on the
//! shared spring-force kernel. Both are symplectic (energy oscillates instead of drifting) and stable
//! only for substeps `h < 2/ω_max`; [`SolverSettings::auto_substeps`](super::SolverSettings) keeps
//! them there.
//!
//! Same model and semantics as every integrator: Hookean springs, per-particle mass, gravity, pinned
//! particles following their interpolated targets, velocities decaying as `exp(-damping t)`.
//! Nothing here allocates.

use super::forces::{SpringSet, add_spring_forces};
use super::solver::ClothSim;

/// Sets `sim.force_sums` to gravity plus wind plus the spring forces at the positions `sim.soa`.
fn compute_forces(sim: &mut ClothSim) {
    let g = sim.settings.gravity;
    for ((x, y, z), m) in sim.force_sums.iter_mut().zip(&sim.mass) {
        (*x, *y, *z) = (*m * g.x, *m * g.y, *m * g.z);
    }
    if sim.wind.active {
        for ((x, y, z), f) in sim.force_sums.iter_mut().zip(sim.wind.particle_forces()) {
            (*x, *y, *z) = (*x + f.x, *y + f.y, *z + f.z);
        }
    }
    let springs = SpringSet {
        a: &sim.model.springs.a,
        b: &sim.model.springs.b,
        rest: &sim.model.springs.rest,
        k: &sim.stiffness,
    };
    add_spring_forces(&mut sim.force_runs, springs, &sim.soa, &mut sim.force_sums);
}

/// For every free particle (inverse mass `w > 0`), one coordinate: the kick
/// `v ← e^{-c h} (v + h w f)`, then the drift `x ← x + τ v`. Pinned particles are left alone.
fn kick_drift(x: &mut [f32], v: &mut [f32], f: &[f32], w: &[f32], h: f32, keep: f32, tau: f32) {
    for (((x, v), f), w) in x.iter_mut().zip(v.iter_mut()).zip(f).zip(w) {
        let kicked = (*v + *f * (*w * h)) * keep;
        let free = *w > 0.0;
        *v = if free { kicked } else { *v };
        *x += if free { kicked * tau } else { 0.0 };
    }
}

/// [`kick_drift`] for all three coordinates, with the forces in `sim.force_sums`.
fn kick_drift_all(sim: &mut ClothSim, h: f32, keep: f32, tau: f32) {
    let (x, v, f, w) = (
        &mut sim.soa,
        &mut sim.velocity_soa,
        &sim.force_sums,
        &sim.inv_mass,
    );
    kick_drift(&mut x.x, &mut v.x, &f.x, w, h, keep, tau);
    kick_drift(&mut x.y, &mut v.y, &f.y, w, h, keep, tau);
    kick_drift(&mut x.z, &mut v.z, &f.z, w, h, keep, tau);
}

/// Symplectic Euler, `n` substeps of `h = dt/n`: `v ← e^{-c h} (v + h f(x)/m)`, then `x ← x + h v`.
pub(super) fn step_symplectic_euler(sim: &mut ClothSim, dt: f32, n: u32) {
    let h = dt / n as f32;
    let inv_h = 1.0 / h;
    let keep = (-sim.settings.damping * h).exp();
    sim.load_soa_state();
    for sub in 0..n {
        sim.begin_soa_substep();
        compute_forces(sim);
        kick_drift_all(sim, h, keep, h);
        let (t0, t1) = (sub as f32 / n as f32, (sub + 1) as f32 / n as f32);
        sim.drive_soa_pins(t0, t1, inv_h);
        sim.resolve_soa_contacts(sub, n, h);
    }
    sim.store_soa_state();
}

/// Position Verlet (drift-kick-drift), `n` substeps of `h = dt/n`: `x ← x + h/2 v`,
/// `v ← e^{-c h} (v + h f(x)/m)`, `x ← x + h/2 v`. Pinned particles sit at their target of the
/// half step while the forces are evaluated. The closing half drift of one substep and the opening
/// half drift of the next are fused into one drift by `h`.
pub(super) fn step_verlet(sim: &mut ClothSim, dt: f32, n: u32) {
    let h = dt / n as f32;
    let half = 0.5 * h;
    let inv_h = 1.0 / h;
    let keep = (-sim.settings.damping * h).exp();
    sim.load_soa_state();
    let (x, v, w) = (&mut sim.soa, &sim.velocity_soa, &sim.inv_mass);
    for (coord, vel) in [(&mut x.x, &v.x), (&mut x.y, &v.y), (&mut x.z, &v.z)] {
        for ((x, v), w) in coord.iter_mut().zip(vel).zip(w) {
            *x += if *w > 0.0 { *v * half } else { 0.0 };
        }
    }
    for sub in 0..n {
        sim.begin_soa_substep();
        let mid = (sub as f32 + 0.5) / n as f32;
        for pin in &sim.pins {
            let i = sim.soa_index(pin.particle);
            sim.soa.set(i, pin.from.lerp(pin.to, mid));
        }
        compute_forces(sim);
        let last = sub + 1 == n;
        // Close this substep's drift and (unless it is the last) open the next one's.
        kick_drift_all(sim, h, keep, if last { half } else { h });
        if last {
            let (t0, t1) = (sub as f32 / n as f32, (sub + 1) as f32 / n as f32);
            sim.drive_soa_pins(t0, t1, inv_h);
        }
        sim.resolve_soa_contacts(sub, n, h);
    }
    sim.store_soa_state();
}
