//! Implicit (backward) Euler after Baraff & Witkin 1998, "Large Steps in Cloth Simulation": per
//! substep of length `h`, one Newton step of backward Euler on the linearised springs,
//!
//! `(M + h² K) Δv = h (f(x) - h K v)`,   `v ← e^{-c h} (v + Δv)`,   `x ← x + h v`,
//!
//! with `K = -∂f/∂x` the spring stiffness matrix (its geometric term clamped to keep it positive
//! semi-definite, see `forces.rs`), solved matrix-free by Jacobi-preconditioned conjugate gradients.
//! Pinned particles are handled by filtering, as in the paper's modified CG: their `Δv` is prescribed
//! (the velocity that takes them to their target), their rows are removed from the residual and the
//! search directions, and their columns enter the right-hand side. Particles a collider pushed in
//! the previous substep are held the same way along the contact normal only (the paper's
//! one-dimensional constraints): their normal velocity becomes the collider surface's, while the
//! solve moves them freely along the surface. Solved without that, the linearised springs would
//! pull them into the collider, and the response would push them back out, each substep, against
//! springs stiff enough to give the cloth energy that way. A held particle ends the substep on
//! the margin, not within it, so unless something pushes it in again it is free in the next one.
//! Far from the linear regime the Newton step is checked against the incremental potential that
//! backward Euler minimises, and shortened until it is no worse than standing still
//! (`Cg::limit_to_descent`).
//!
//! All vectors are sized when the integrator is selected; nothing here allocates.

use glam::Vec3;

use super::step::{Step, add_contact_work, frame_shift};
use crate::sim::contact::Touch;
use crate::sim::forces::{
    SpringJacobians, SpringSet, add_spring_forces_and_jacobians, add_stiffness_product,
    spring_energy,
};
use crate::sim::pressure::{AirScratch, air_energy};
use crate::sim::state::{Particles, between, drive_pins, energy_of};

/// Conjugate gradients stops when the filtered residual is below this fraction of the larger of the
/// right-hand side and the substep's gravity impulse `h m g` (both as Euclidean norms).
pub const CG_TOLERANCE: f32 = 1e-5;

/// The smallest fraction of a substep's end velocities [`Cg::limit_to_descent`] tries before it
/// stops the free particles.
const MIN_DESCENT_SCALE: f32 = 1e-3;

/// A particle moving off a collider's surface faster than this (m/s, relative to the surface) is
/// not held against it in the next solve.
const SEPARATING_SPEED: f32 = 1e-6;

/// Implicit Euler's scratch: the force sums, the linearised springs and the conjugate-gradient
/// vectors.
#[derive(Debug, Clone, Default)]
pub(crate) struct Implicit {
    /// Force accumulator.
    forces: Vec<Vec3>,
    cg: Cg,
    /// The air's scratch, in the particles' own order.
    pub air: AirScratch,
}

/// The linearised springs and the conjugate-gradient vectors.
#[derive(Debug, Clone, Default)]
struct Cg {
    jacobians: SpringJacobians,
    /// Right-hand side `h (f - h K v)`.
    rhs: Vec<Vec3>,
    /// The unknown `Δv` (kept between substeps as the next initial guess).
    dv: Vec<Vec3>,
    /// Residual.
    r: Vec<Vec3>,
    /// Preconditioned residual.
    z: Vec<Vec3>,
    /// Search direction.
    p: Vec<Vec3>,
    /// `A p`.
    ap: Vec<Vec3>,
    /// Inverse of the diagonal of `A`, per coordinate.
    inv_diag: Vec<Vec3>,
    /// CG iterations taken in the last substep.
    last_iterations: u32,
    /// The colliders' contacts in the last substep's response, per particle.
    touches: Vec<Touch>,
    /// Whether `touches` may hold any contact.
    touched: bool,
    /// Per particle, the contact normal this substep's solve holds (zero: not held).
    held: Vec<Vec3>,
    /// The substep's external forces (gravity and wind), for [`Cg::limit_to_descent`].
    external: Vec<Vec3>,
    /// Where a trial end of the substep puts the particles (scratch of the same).
    trial: Vec<Vec3>,
}

impl Implicit {
    /// Sizes the scratch for `particles` particles and `springs` springs, if it is not already.
    pub fn prepare(&mut self, particles: usize, springs: usize) {
        if self.fits(particles, springs) {
            return;
        }
        let v = || vec![Vec3::ZERO; particles];
        *self = Self {
            forces: v(),
            cg: Cg {
                jacobians: SpringJacobians::new(springs),
                rhs: v(),
                dv: v(),
                r: v(),
                z: v(),
                p: v(),
                ap: v(),
                inv_diag: v(),
                last_iterations: 0,
                touches: vec![Touch::default(); particles],
                touched: false,
                held: v(),
                external: v(),
                trial: v(),
            },
            air: AirScratch::default(),
        };
    }

    /// Whether the buffers are sized for this cloth.
    fn fits(&self, particles: usize, springs: usize) -> bool {
        self.cg.rhs.len() == particles && self.cg.jacobians.fits(springs)
    }

    /// Conjugate-gradient iterations taken in the last substep (0 before the first).
    pub fn last_iterations(&self) -> u32 {
        self.cg.last_iterations
    }
}

/// The rows CG solves for: a pinned particle's (inverse mass 0) are prescribed whole, a held
/// contact's along its normal (`held`, when any particle is held).
#[derive(Clone, Copy)]
struct Rows<'a> {
    inv_mass: &'a [f32],
    held: Option<&'a [Vec3]>,
}

impl Rows<'_> {
    /// The filter `S`: zeroes the prescribed part of every row.
    fn filter(&self, v: &mut [Vec3]) {
        for (v, w) in v.iter_mut().zip(self.inv_mass) {
            if *w == 0.0 {
                *v = Vec3::ZERO;
            }
        }
        if let Some(held) = self.held {
            for (v, n) in v.iter_mut().zip(held) {
                *v -= *n * n.dot(*v);
            }
        }
    }

    /// The prescribed part of `v`, the rest zeroed (`v - S v`).
    fn prescribed(&self, v: &[Vec3], out: &mut [Vec3]) {
        out.copy_from_slice(v);
        self.filter(out);
        for (o, v) in out.iter_mut().zip(v) {
            *o = *v - *o;
        }
    }
}

/// `out = M p + h² K p`, then filtered (`S A p`).
fn apply_system(
    springs: SpringSet<'_>,
    jacobians: &SpringJacobians,
    (mass, rows): (&[f32], Rows<'_>),
    h2: f32,
    p: &[Vec3],
    out: &mut [Vec3],
) {
    for ((o, p), m) in out.iter_mut().zip(p).zip(mass) {
        *o = *p * *m;
    }
    add_stiffness_product(springs.a, springs.b, jacobians, h2, p, out);
    rows.filter(out);
}

impl Cg {
    /// Backward Euler's end of a substep minimises the incremental potential
    /// `Φ(x₁) = ½ Σ m |(x₁ - x)/h - v - h f_ext/m|² + U(x₁)`; the solve's one linearised Newton
    /// step only approximates that. Far from the linear regime (springs turned through a
    /// sizeable angle within the substep, stiff enough that `h ω` is in the thousands) the step
    /// can land where `Φ` is far above its value at the particles' start, `Φ(x)`: the springs
    /// there hold energy the cloth never had. Staying put bounds the
    /// minimum, and `Φ(x₁) ≤ Φ(x)` bounds the elastic energy after the substep by the kinetic and
    /// elastic energy before it (plus the external forces' impulse), so the free particles'
    /// end velocities `v + Δv` are scaled back, halving, until the end is no worse than the start
    /// (within a round-off tolerance), or to zero. Pinned particles keep their prescribed ends.
    /// Within the linear regime the full step passes at once; the check costs two energy passes
    /// over the springs.
    fn limit_to_descent(
        &mut self,
        springs: SpringSet<'_>,
        (mass, inv_mass): (&[f32], &[f32]),
        h: f32,
        (x, v): (&[Vec3], &[Vec3]),
    ) {
        let potential = |scale: f32, trial: &mut [Vec3], dv: &[Vec3], external: &[Vec3]| {
            let mut inertia = 0.0;
            for i in 0..x.len() {
                let end = v[i] + dv[i];
                if inv_mass[i] > 0.0 {
                    let m = f64::from(mass[i]);
                    let miss = (end * scale - v[i] - external[i] * (h * inv_mass[i])).as_dvec3();
                    inertia += 0.5 * m * miss.length_squared();
                    trial[i] = x[i] + end * (scale * h);
                } else {
                    trial[i] = x[i] + end * h;
                }
            }
            inertia + spring_energy(springs, trial)
        };
        let start = potential(0.0, &mut self.trial, &self.dv, &self.external);
        let tolerance = 1e-3 * start.abs() + 1e-12;
        let mut scale = 1.0;
        while potential(scale, &mut self.trial, &self.dv, &self.external) > start + tolerance {
            scale *= 0.5;
            if scale < MIN_DESCENT_SCALE {
                scale = 0.0;
                break;
            }
        }
        if scale < 1.0 {
            for ((dv, v), w) in self.dv.iter_mut().zip(v).zip(inv_mass) {
                if *w > 0.0 {
                    *dv = (*v + *dv) * scale - *v;
                }
            }
        }
    }
}

fn dot(a: &[Vec3], b: &[Vec3]) -> f32 {
    a.iter().zip(b).map(|(a, b)| a.dot(*b)).sum()
}

impl Implicit {
    /// Implicit Euler, `n` substeps of `h = dt/n`, each one linearised Newton step solved by CG
    /// with at most `settings.iterations` iterations.
    pub fn step(&mut self, st: &mut Step, dt: f32, n: u32) {
        let Step {
            model,
            settings,
            stiffness,
            pins,
            wind,
            air,
            particles,
            contacts,
            contact_work,
            frame,
        } = st;
        let Particles {
            positions: x,
            velocities: v,
            mass,
            inv_mass,
        } = &mut **particles;
        debug_assert!(
            self.fits(x.len(), model.springs.len()),
            "implicit Euler's scratch is sized when the integrator is chosen"
        );
        let springs = SpringSet::new(&model.springs, stiffness);
        let (forces, s) = (&mut self.forces, &mut self.cg);
        let h = dt / n as f32;
        let h2 = h * h;
        let inv_h = 1.0 / h;
        let keep = (-settings.damping * h).exp();
        let g = settings.gravity;
        let max_iterations = settings.iterations;
        // The size of the substep's gravity impulse, the floor of the CG tolerance.
        let mut weight2 = 0.0;
        for (m, w) in mass.iter().zip(inv_mass.iter()) {
            if *w > 0.0 {
                weight2 += (h * m * g).length_squared();
            }
        }
        if !contacts.is_active() && s.touched {
            // No collider in reach: none of the last contacts is held when one comes back.
            s.touches.fill(Touch::default());
            s.touched = false;
        }
        for sub in 0..n {
            let (t0, t1) = (sub as f32 / n as f32, (sub + 1) as f32 / n as f32);
            let shift = frame_shift(*frame, t0, t1);
            contacts.begin_substep(x);
            // Forces and their linearisation at the start of the substep.
            for (f, m) in forces.iter_mut().zip(mass.iter()) {
                *f = *m * g;
            }
            // Wind and the air inside a closed cloth enter explicitly (not linearised).
            wind.add_forces(forces);
            if let Some(air) = air {
                let weights = (&inv_mass[..], h);
                air.forces(&mut self.air, |i| x[i], weights, |i, f| forces[i] += f);
            }
            s.external.copy_from_slice(forces);
            add_spring_forces_and_jacobians(springs, x, forces, &mut s.jacobians);
            // rhs = h f - h² K v.
            for (b, f) in s.rhs.iter_mut().zip(forces.iter()) {
                *b = *f * h;
            }
            // The free particles are carried along by the frame's unfelt motion at the substep's
            // end (below): relative to them, the pins move that much less (their velocity and
            // target here; `drive_pins` sets both afterwards).
            if let Some(shift) = &shift {
                for pin in pins.iter() {
                    let i = pin.particle as usize;
                    v[i] -= (shift.point(x[i]) - x[i]) * inv_h;
                }
            }
            add_stiffness_product(springs.a, springs.b, &s.jacobians, -h2, v, &mut s.rhs);
            // Jacobi preconditioner: the diagonal of M + h² K.
            for (d, m) in s.inv_diag.iter_mut().zip(mass.iter()) {
                *d = Vec3::splat(*m);
            }
            for k in 0..springs.a.len() {
                let dk = s.jacobians.diagonal(k) * h2;
                s.inv_diag[springs.a[k] as usize] += dk;
                s.inv_diag[springs.b[k] as usize] += dk;
            }
            for d in s.inv_diag.iter_mut() {
                *d = d.recip();
            }
            // Prescribed Δv of the pinned particles; free ones start from the last substep's Δv.
            for pin in pins.iter() {
                let i = pin.particle as usize;
                let mut target = between(pin.from, pin.to, t1);
                if let Some(shift) = &shift {
                    target -= shift.point(x[i]) - x[i];
                }
                s.dv[i] = (target - x[i]) * inv_h - v[i];
            }
            // Particles a collider pushed in the last substep and not moving off it are held:
            // their normal velocity is prescribed to become the surface's.
            let mut any_held = false;
            if contacts.is_active() {
                for (i, (t, held)) in s.touches.iter_mut().zip(s.held.iter_mut()).enumerate() {
                    let n = t.normal;
                    let hold = inv_mass[i] > 0.0
                        && n != Vec3::ZERO
                        && (v[i] - t.surface).dot(n) <= SEPARATING_SPEED;
                    *held = if hold {
                        let dv = s.dv[i];
                        s.dv[i] = dv + n * ((t.surface - v[i]).dot(n) - n.dot(dv));
                        n
                    } else {
                        Vec3::ZERO
                    };
                    any_held |= hold;
                    // This substep's response records its own.
                    *t = Touch::default();
                }
            }
            let rows = Rows {
                inv_mass,
                held: any_held.then_some(&s.held[..]),
            };
            rows.filter(&mut s.rhs);
            let tolerance2 = CG_TOLERANCE * CG_TOLERANCE * dot(&s.rhs, &s.rhs).max(weight2);
            // r = S (b - A Δv).
            apply_system(springs, &s.jacobians, (mass, rows), h2, &s.dv, &mut s.r);
            for (r, b) in s.r.iter_mut().zip(&s.rhs) {
                *r = *b - *r;
            }
            // CG minimises φ(Δv) = ½ Δvᵀ A Δv - bᵀ Δv over the free rows, the prescribed parts
            // (`Δv₀`) held at their values (the A-norm of the error, up to a constant), from its
            // start. Stopped early, a start worse than `Δv₀` (φ > φ(Δv₀)) leaves stale velocity
            // changes in the stiff modes, which then gain energy step after step (found by the
            // stress suite): it restarts from `Δv₀` instead. With e = Δv - Δv₀ (free), r = S (b -
            // A Δv) and c = S A Δv₀, φ(Δv) - φ(Δv₀) = -½ eᵀ (b + r - c).
            let prescribed = !pins.is_empty() || any_held;
            if prescribed {
                rows.prescribed(&s.dv, &mut s.z);
                apply_system(springs, &s.jacobians, (mass, rows), h2, &s.z, &mut s.ap);
            }
            let mut phi = 0.0;
            for (i, (dv, w)) in s.dv.iter().zip(inv_mass.iter()).enumerate() {
                if *w > 0.0 {
                    let (c, e) = if prescribed {
                        (s.ap[i], *dv - s.z[i])
                    } else {
                        (Vec3::ZERO, *dv)
                    };
                    phi -= 0.5 * e.dot(s.rhs[i] + s.r[i] - c);
                }
            }
            if phi > 0.0 {
                // From Δv₀ the residual is b - c (both filtered).
                for (i, (dv, w)) in s.dv.iter_mut().zip(inv_mass.iter()).enumerate() {
                    let c = if prescribed { s.ap[i] } else { Vec3::ZERO };
                    if *w > 0.0 {
                        *dv = if prescribed { s.z[i] } else { Vec3::ZERO };
                    }
                    s.r[i] = s.rhs[i] - c;
                }
            }
            // For the prescribed parts, A Δv was filtered away and rhs is 0, so r is 0 there.
            for ((z, r), d) in s.z.iter_mut().zip(&s.r).zip(&s.inv_diag) {
                *z = *r * *d;
            }
            if any_held {
                rows.filter(&mut s.z);
            }
            s.p.copy_from_slice(&s.z);
            let mut rz = dot(&s.r, &s.z);
            let mut iterations = 0;
            while iterations < max_iterations && dot(&s.r, &s.r) > tolerance2 {
                apply_system(springs, &s.jacobians, (mass, rows), h2, &s.p, &mut s.ap);
                let pap = dot(&s.p, &s.ap);
                if pap.is_nan() || pap <= 0.0 {
                    break;
                }
                let alpha = rz / pap;
                for ((dv, r), (p, ap)) in
                    s.dv.iter_mut()
                        .zip(s.r.iter_mut())
                        .zip(s.p.iter().zip(&s.ap))
                {
                    *dv += *p * alpha;
                    *r -= *ap * alpha;
                }
                for ((z, r), d) in s.z.iter_mut().zip(&s.r).zip(&s.inv_diag) {
                    *z = *r * *d;
                }
                if any_held {
                    rows.filter(&mut s.z);
                }
                let rz_new = dot(&s.r, &s.z);
                let beta = rz_new / rz;
                rz = rz_new;
                for (p, z) in s.p.iter_mut().zip(&s.z) {
                    *p = *z + *p * beta;
                }
                iterations += 1;
            }
            s.last_iterations = iterations;
            s.limit_to_descent(springs, (mass, inv_mass), h, (x, v));
            for ((x, v), (dv, w)) in x
                .iter_mut()
                .zip(v.iter_mut())
                .zip(s.dv.iter().zip(inv_mass.iter()))
            {
                if *w > 0.0 {
                    *v = (*v + *dv) * keep;
                    *x += *v * h;
                }
            }
            if let Some(shift) = shift {
                shift.carry(inv_mass, x, v);
                contacts.carry_starts(inv_mass, |p| shift.point(p));
                // The next substep's first guess turns with the velocities.
                for (dv, w) in s.dv.iter_mut().zip(inv_mass.iter()) {
                    if *w > 0.0 {
                        *dv = shift.vector(*dv);
                    }
                }
            }
            drive_pins(pins, t0, t1, inv_h, x, v);
            if contacts.is_active() {
                let energy = |x: &[Vec3], v: &[Vec3]| {
                    let mut e = energy_of(springs, (mass, inv_mass), g, x, v);
                    e.elastic += air_energy(*air, &model.triangles, x);
                    e
                };
                let before = contact_work.map(|_| energy(x, v));
                let touches = Some(&mut s.touches[..]);
                let work = contacts.resolve(t0, t1, h, &model.triangles, inv_mass, (x, v), touches);
                s.touched = true;
                if let Some(before) = before {
                    add_contact_work(contact_work, (before, energy(x, v)), work);
                }
            }
        }
    }
}
