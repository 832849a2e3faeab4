//! The explicit force-based integrators: symplectic (semi-implicit) Euler and position Verlet, on the
//! shared spring-force kernel. Both are symplectic (energy oscillates instead of drifting) and stable
//! only for substeps `h < 2/ω_max`; [`SolverSettings::auto_substeps`](super::SolverSettings) keeps
//! them there.
//!
//! Same model and semantics as every integrator: Hookean springs, per-particle mass, gravity, pinned
//! particles following their interpolated targets, velocities decaying as `exp(-damping t)`.
//! Nothing here allocates.

use super::forces::{Soa, SpringSet, add_spring_forces};
use super::solver::{ClothSim, PinState, pin_motion};

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

/// The state the explicit integrators step: positions in `sim.soa` and velocities in
/// `sim.velocity_soa` for the whole step (one array per coordinate, so the particle loops are
/// vector code), copied back to `sim.positions` and `sim.velocities` at the end and around the
/// contact response (which works on the vectors).
fn load_state(sim: &mut ClothSim) {
    sim.soa.load(&sim.positions);
    sim.velocity_soa.load(&sim.velocities);
}

fn store_state(sim: &mut ClothSim) {
    sim.soa.write_to(&mut sim.positions);
    sim.velocity_soa.write_to(&mut sim.velocities);
}

/// The contact response of substep `sub` of `n`, on the vectors (nothing without a collider in
/// reach).
fn resolve_contacts(sim: &mut ClothSim, sub: u32, n: u32, h: f32) {
    if sim.contacts.is_active() {
        store_state(sim);
        sim.resolve_contacts(sub, n, h);
        load_state(sim);
    }
}

/// Where a substep begins, for the contact response's swept tests.
fn begin_substep(sim: &mut ClothSim) {
    if sim.contacts.is_active() {
        sim.soa.write_to(&mut sim.positions);
        sim.contacts.begin_substep(&sim.positions);
    }
}

/// Moves the pinned particles to their targets at the end of substep `[t0, t1]` (fractions of the
/// step), with the velocity of that motion.
fn drive_pins(pins: &[PinState], t0: f32, t1: f32, inv_h: f32, x: &mut Soa, v: &mut Soa) {
    for pin in pins {
        let (target, velocity) = pin_motion(pin, t0, t1, inv_h);
        x.set(pin.particle as usize, target);
        v.set(pin.particle as usize, velocity);
    }
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
    load_state(sim);
    for sub in 0..n {
        begin_substep(sim);
        compute_forces(sim);
        kick_drift_all(sim, h, keep, h);
        let (t0, t1) = (sub as f32 / n as f32, (sub + 1) as f32 / n as f32);
        drive_pins(
            &sim.pins,
            t0,
            t1,
            inv_h,
            &mut sim.soa,
            &mut sim.velocity_soa,
        );
        resolve_contacts(sim, sub, n, h);
    }
    store_state(sim);
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
    load_state(sim);
    let (x, v, w) = (&mut sim.soa, &sim.velocity_soa, &sim.inv_mass);
    for (coord, vel) in [(&mut x.x, &v.x), (&mut x.y, &v.y), (&mut x.z, &v.z)] {
        for ((x, v), w) in coord.iter_mut().zip(vel).zip(w) {
            *x += if *w > 0.0 { *v * half } else { 0.0 };
        }
    }
    for sub in 0..n {
        begin_substep(sim);
        let mid = (sub as f32 + 0.5) / n as f32;
        for pin in &sim.pins {
            sim.soa
                .set(pin.particle as usize, pin.from.lerp(pin.to, mid));
        }
        compute_forces(sim);
        let last = sub + 1 == n;
        // Close this substep's drift and (unless it is the last) open the next one's.
        kick_drift_all(sim, h, keep, if last { half } else { h });
        if last {
            let (t0, t1) = (sub as f32 / n as f32, (sub + 1) as f32 / n as f32);
            drive_pins(
                &sim.pins,
                t0,
                t1,
                inv_h,
                &mut sim.soa,
                &mut sim.velocity_soa,
            );
        }
        resolve_contacts(sim, sub, n, h);
    }
    store_state(sim);
}
