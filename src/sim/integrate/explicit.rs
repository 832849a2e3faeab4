//! The explicit force-based integrators: symplectic (semi-implicit) Euler and position Verlet, on the
//! shared spring-force kernel. Both are symplectic (energy oscillates instead of drifting) and stable
//! only for substeps `h < 2/ω_max`; [`SolverSettings::auto_substeps`](crate::sim::SolverSettings::auto_substeps) keeps
//! them there.
//!
//! Same model and semantics as every integrator: Hookean springs, per-particle mass, gravity, pinned
//! particles following their interpolated targets, velocities decaying as `exp(-damping t)`.
//! Nothing here allocates.

use super::step::{Order, SoaState, Step, frame_shift};
use crate::sim::forces::{ForceRuns, add_spring_forces};
use crate::sim::model::ClothModel;
use crate::sim::pressure::AirScratch;
use crate::sim::soa::Soa;
use crate::sim::state::between;

/// The explicit integrators' scratch: the springs grouped for the vector force kernel, the force
/// sums and the coordinate arrays they step in (in the particles' own order).
#[derive(Debug, Clone, Default)]
pub(crate) struct Explicit {
    runs: ForceRuns,
    forces: Soa,
    state: SoaState,
    /// The air's scratch, in the particles' own order.
    pub air: AirScratch,
}

impl Explicit {
    /// Sizes the scratch for `model` (if it is not already) and copies in the springs' stiffness.
    pub fn prepare(&mut self, model: &ClothModel, stiffness: &[f32]) {
        let (s, n) = (&model.springs, model.particle_count());
        if !self.runs.fits(s.len()) || self.forces.len() != n {
            self.runs = ForceRuns::new(&s.a, &s.b);
            self.forces = Soa::new(n);
            self.state = SoaState::new(n);
        }
        self.runs.set_stiffness(&s.rest, stiffness);
    }

    /// Sets `forces` to gravity plus wind plus the spring forces, plus the air's in a closed
    /// cloth (for a substep of `h`), at the positions `state.x`.
    fn compute_forces(&mut self, s: &Step, h: f32) {
        let g = s.settings.gravity;
        for ((x, y, z), m) in self.forces.iter_mut().zip(&s.particles.mass) {
            (*x, *y, *z) = (*m * g.x, *m * g.y, *m * g.z);
        }
        if s.wind.active {
            for ((x, y, z), f) in self.forces.iter_mut().zip(s.wind.particle_forces()) {
                (*x, *y, *z) = (*x + f.x, *y + f.y, *z + f.z);
            }
        }
        add_spring_forces(&mut self.runs, s.springs(), &self.state.x, &mut self.forces);
        if let Some(air) = s.air {
            let (x, f) = (&self.state.x, &mut self.forces);
            let weights = (&s.particles.inv_mass[..], h);
            air.forces(
                &mut self.air,
                |i| x.get(i),
                weights,
                |i, g| f.set(i, f.get(i) + g),
            );
        }
    }

    /// [`kick_drift`] for all three coordinates, with the forces in `forces`.
    fn kick_drift_all(&mut self, w: &[f32], h: f32, keep: f32, tau: f32) {
        let (x, v, f) = (&mut self.state.x, &mut self.state.v, &self.forces);
        kick_drift(&mut x.x, &mut v.x, &f.x, w, h, keep, tau);
        kick_drift(&mut x.y, &mut v.y, &f.y, w, h, keep, tau);
        kick_drift(&mut x.z, &mut v.z, &f.z, w, h, keep, tau);
    }

    /// The contact response at the end of substep `sub` of `n` (length `h`).
    fn resolve_contacts(&mut self, s: &mut Step, sub: u32, n: u32, h: f32) {
        self.state
            .resolve_contacts(s, (&Order::default(), None, false), (sub, n, h), true);
    }

    /// Symplectic Euler, `n` substeps of `h = dt/n`: `v ← e^{-c h} (v + h f(x)/m)`, then
    /// `x ← x + h v`.
    pub fn step_symplectic_euler(&mut self, s: &mut Step, dt: f32, n: u32) {
        let h = dt / n as f32;
        let inv_h = 1.0 / h;
        let keep = (-s.settings.damping * h).exp();
        self.state.load(s.particles, &Order::default());
        for sub in 0..n {
            let (t0, t1) = (sub as f32 / n as f32, (sub + 1) as f32 / n as f32);
            self.state.begin_substep(s.contacts);
            self.compute_forces(s, h);
            self.kick_drift_all(&s.particles.inv_mass, h, keep, h);
            // The frame's unfelt motion over the substep, so that the next forces see the free
            // particles and the pins at the same time. The substep's start goes with it: the
            // contacts' sweeps and friction leave that motion out.
            if let Some(shift) = frame_shift(s.frame, t0, t1) {
                self.state.carry(&shift, &s.particles.inv_mass, false);
                self.state
                    .carry_starts(&shift, &s.particles.inv_mass, s.contacts);
            }
            self.state
                .drive_pins(s.pins, &Order::default(), (t0, t1), inv_h);
            self.resolve_contacts(s, sub, n, h);
        }
        self.state.store(s.particles, &Order::default());
    }

    /// Position Verlet (drift-kick-drift), `n` substeps of `h = dt/n`: `x ← x + h/2 v`,
    /// `v ← e^{-c h} (v + h f(x)/m)`, `x ← x + h/2 v`. Pinned particles sit at their target of
    /// the half step while the forces are evaluated. The closing half drift of one substep and
    /// the opening half drift of the next are fused into one drift by `h`.
    pub fn step_verlet(&mut self, s: &mut Step, dt: f32, n: u32) {
        let h = dt / n as f32;
        let half = 0.5 * h;
        let inv_h = 1.0 / h;
        let keep = (-s.settings.damping * h).exp();
        self.state.load(s.particles, &Order::default());
        // The first substep's contacts sweep from where the step starts, through the opening
        // half-drift: a thin collider crossed in that half would otherwise go unseen.
        self.state.begin_substep(s.contacts);
        let (x, v, w) = (&mut self.state.x, &self.state.v, &s.particles.inv_mass);
        for (coord, vel) in [(&mut x.x, &v.x), (&mut x.y, &v.y), (&mut x.z, &v.z)] {
            for ((x, v), w) in coord.iter_mut().zip(vel).zip(w) {
                *x += if *w > 0.0 { *v * half } else { 0.0 };
            }
        }
        let mut carried_to = 0.0;
        for sub in 0..n {
            let (t0, t1) = (sub as f32 / n as f32, (sub + 1) as f32 / n as f32);
            let mid = (sub as f32 + 0.5) / n as f32;
            // The free particles stand at the substep's middle, where the pins are put: carried
            // along by the frame's unfelt motion up to there.
            if let Some(shift) = frame_shift(s.frame, carried_to, mid) {
                self.state.carry(&shift, &s.particles.inv_mass, false);
                if sub == 0 {
                    // The sweeps leave the frame's motion out: the start goes with it.
                    self.state
                        .carry_starts(&shift, &s.particles.inv_mass, s.contacts);
                }
            }
            carried_to = mid;
            if sub > 0 {
                self.state.begin_substep(s.contacts);
            }
            for pin in s.pins {
                self.state
                    .x
                    .set(pin.particle as usize, between(pin.from, pin.to, mid));
            }
            self.compute_forces(s, h);
            let last = sub + 1 == n;
            // Close this substep's drift and (unless it is the last) open the next one's.
            self.kick_drift_all(&s.particles.inv_mass, h, keep, if last { half } else { h });
            if last {
                if let Some(shift) = frame_shift(s.frame, mid, 1.0) {
                    // As above, the start with the particles.
                    self.state.carry(&shift, &s.particles.inv_mass, false);
                    self.state
                        .carry_starts(&shift, &s.particles.inv_mass, s.contacts);
                }
                self.state
                    .drive_pins(s.pins, &Order::default(), (t0, t1), inv_h);
            }
            self.resolve_contacts(s, sub, n, h);
        }
        self.state.store(s.particles, &Order::default());
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
