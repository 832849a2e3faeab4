//! XPBD with substeps (Macklin et al. 2016, "XPBD"; Macklin et al. 2019, "Small Steps in Physics
//! Simulation"): each substep predicts the particles' motion, projects every spring once per
//! iteration by coloured Gauss-Seidel, and takes the velocity from the displacement.
//!
//! - `layout.rs` lays the springs out for the vector kernel ([`Projections`]),
//! - `kernel/` projects them ([`Sweep`]): the sweep in `mod.rs`, its columns in `columns.rs`, the
//!   lane arithmetic in `lanes.rs`,
//! - `team.rs` shares a large cloth's sweeps and particle passes with a second thread,
//! - `tethers.rs` projects the tethers after the sweeps ([`Tethered`]),
//! - this file drives the substeps: the particle passes, pins, wind and contacts.
//!
//! Nothing here allocates inside a step.

mod kernel;
mod layout;
mod team;
#[cfg(test)]
mod tests;
mod tethers;

use glam::{Vec3, Vec3A};

use super::step::{SoaState, Step, frame_shift};
use crate::sim::contact::{
    ContactState, Limits, Near, Since, soa_clearances, soa_displaced, soa_ends, soa_since,
};
use crate::sim::model::ClothModel;
use crate::sim::pressure::AirScratch;
use crate::sim::simd::{self, Build, Kernel};
use crate::sim::soa::Soa;
use crate::sim::state::{Energy, pin_motion};
use kernel::{Column, ReadColumn, SplitPositions, Sweep};
use layout::{LANES, Projections};
use team::{Lead, share};
pub use team::{ScopedThread, Spread};
use tethers::Tethered;

/// XPBD's stepper: the springs' layout and the step's scratch, in the layout's storage order.
#[derive(Debug, Clone, Default)]
pub(crate) struct Xpbd {
    layout: Projections,
    state: SoaState,
    /// The springs' multipliers in the current substep, per slot (used with more than one
    /// iteration).
    lambda: Vec<f32>,
    /// The wind's velocity change per substep (scratch).
    wind_dv: Soa,
    /// The tethers, projected after the sweeps of every substep.
    tethers: Tethered,
    /// The air's scratch in storage order (a closed cloth's volume is projected after the
    /// sweeps, before the tethers).
    air: AirScratch,
    /// The velocities contacts set in the current substep, by storage slot (at most one per
    /// particle; see [`AheadOfEnd`]), and where each slot's is in that list (1 + its place; 0 for
    /// none).
    contact_velocities: (Vec<(u32, Vec3)>, Vec<u32>),
    /// Test builds only: contacts are resolved after a separate end pass, on the end state, as
    /// the reference for the contacts resolved ahead of the fused pass.
    #[cfg(test)]
    pub contacts_after_end: bool,
}

impl Xpbd {
    /// Lays out `model`'s springs (if not done already) and sets their rest lengths,
    /// compliances `1/k`, the particles' inverse masses, the tethers of `limits` and, with `air`,
    /// the air's scratch.
    pub fn prepare(
        &mut self,
        model: &ClothModel,
        (stiffness, inv_mass): (&[f32], &[f32]),
        (limits, air): (&Limits, bool),
    ) {
        let (s, n) = (&model.springs, model.particle_count());
        if !self.layout.fits(s.len(), n) {
            self.layout = Projections::new(model);
            self.state = SoaState::new(n);
            self.wind_dv = Soa::new(n);
            self.contact_velocities = (Vec::with_capacity(n), vec![0; n]);
            self.lambda = vec![0.0; self.layout.slot_count()];
        }
        self.layout.set_constants(&s.rest, stiffness, inv_mass);
        self.tethers.set(limits.tethers(), self.layout.storage(), n);
        let layout = &self.layout;
        self.air
            .prepare(air, &model.triangles, n, |i| layout.stored(i));
    }

    /// Whether a step is worth sharing between two threads.
    pub fn worth_sharing(&self) -> bool {
        self.layout.worth_sharing()
    }

    /// One XPBD step of `dt` seconds in `n` substeps. With `spread`, a large cloth's colours are
    /// projected by two threads; the result is bit-identical.
    pub fn step(&mut self, s: &mut Step, dt: f32, n: u32, spread: Option<&dyn Spread>) {
        match spread.filter(|_| self.worth_sharing()) {
            Some(spread) => share(spread, |lead| self.substeps(s, dt, n, lead)),
            None => self.substeps(s, dt, n, None),
        }
    }

    /// The substeps of [`Self::step`], with the sweeps shared with `lead`'s helper if given.
    fn substeps(&mut self, s: &mut Step, dt: f32, n: u32, lead: Option<&Lead>) {
        let h = dt / n as f32;
        let inv_h = 1.0 / h;
        let inv_h2 = inv_h * inv_h;
        let motion = Motion {
            h,
            inv_h,
            keep: (-s.settings.damping * h).exp(),
            gravity: (s.settings.gravity * h).to_array(),
        };
        let accumulate = s.settings.iterations > 1;
        if !accumulate {
            self.layout.set_weights(inv_h2);
        }
        self.state.load(s.particles, self.layout.storage());
        self.tethers
            .begin_step(s.pins, &self.state.x, self.layout.storage());
        // Wind forces are held over the step (see `wind.rs`): their velocity change per substep,
        // in storage order.
        let wind = s.wind.active;
        if wind {
            let forces = s.wind.particle_forces();
            let order = self.layout.storage().order();
            let dv = self.wind_dv.iter_mut();
            for ((k, w), (x, y, z)) in self.layout.inv_mass.iter().enumerate().zip(dv) {
                let f = forces[order.get(k).map_or(k, |&i| i as usize)] * (*w * h);
                (*x, *y, *z) = (f.x, f.y, f.z);
            }
        }
        // Nothing happens to the state between the end of one substep and the start of the next
        // but the pins' drive, so the two particle passes are one: contacts are resolved just
        // before it, on the state the substep ends in (`AheadOfEnd`).
        let contacts = s.contacts.is_active();
        // Tests compare this with contacts resolved after a separate end pass, on the end state.
        let after = contacts && self.contacts_after_end();
        let ahead = contacts && !after;
        for sub in 0..n {
            if sub == 0 || after {
                self.advance::<false, true>(&motion, wind, lead);
            }
            let (t0, t1) = (sub as f32 / n as f32, (sub + 1) as f32 / n as f32);
            if let Some(shift) = frame_shift(s.frame, t0, t1) {
                self.state.carry(&shift, &self.layout.inv_mass, true);
            }
            // Pinned particles are given the displacement to their targets.
            for pin in s.pins {
                let i = self.layout.stored(pin.particle) as usize;
                let (target, _) = pin_motion(pin, t0, t1, inv_h);
                self.state.d.set(i, target - self.state.x.get(i));
            }
            // λ starts at 0 each substep, so one iteration needs no multiplier storage.
            if accumulate {
                self.lambda.fill(0.0);
            }
            self.sweeps(s.settings.iterations, accumulate, inv_h2, lead);
            if let Some(air) = s.air {
                let inv_mass = &self.layout.inv_mass;
                let (x, d) = (&self.state.x, &mut self.state.d);
                air.project(&mut self.air, inv_mass, (x, d), h);
            }
            self.tethers.project(t1, &self.state.x, &mut self.state.d);
            // Contacts last, so every substep ends outside the colliders; their push-out is not
            // turned into velocity (see `contact`).
            if ahead {
                self.resolve_contacts_ahead(s, (t0, t1, h));
            }
            let begin = !after && sub + 1 < n;
            if begin {
                self.advance::<true, true>(&motion, wind, lead);
            } else {
                self.advance::<true, false>(&motion, wind, lead);
            }
            if ahead {
                self.apply_contact_velocities(&motion, wind, begin);
            }
            // Pinned particles end on their targets, at the velocity that takes them there.
            self.state
                .drive_pins(s.pins, self.layout.storage(), (t0, t1), inv_h);
            if after {
                let layout = &self.layout;
                self.state.resolve_contacts(
                    s,
                    (layout.storage(), Some(&layout.inv_mass), true),
                    (sub, n, h),
                    false,
                );
            }
        }
        self.state.store(s.particles, self.layout.storage());
    }

    /// `iterations` Gauss-Seidel sweeps over every spring, colour by colour in two shares when
    /// `lead` lends a helper.
    fn sweeps(&mut self, iterations: u32, accumulate: bool, inv_h2: f32, lead: Option<&Lead>) {
        let (start, delta) = (&self.state.x, &mut self.state.d);
        let [dx, dy, dz] = [&mut delta.x, &mut delta.y, &mut delta.z];
        let sweep = Sweep {
            p: &self.layout,
            x: SplitPositions {
                start: [
                    ReadColumn::new(&start.x),
                    ReadColumn::new(&start.y),
                    ReadColumn::new(&start.z),
                ],
                delta: [Column::new(dx), Column::new(dy), Column::new(dz)],
            },
            lambda: Column::new(&mut self.lambda),
            inv_h2,
        };
        for _ in 0..iterations {
            match lead {
                Some(lead) => {
                    for c in 0..sweep.p.color_count() {
                        // SAFETY: the two shares of a colour touch disjoint particles and slots
                        // (`Projections::cut` makes them so from a proper colouring, which
                        // `ClothSim::new` validates; `Projections::check` proves it in tests and
                        // debug builds), and the team runs each share on one thread.
                        lead.run(&|k| unsafe { sweep.run(sweep.p.share(c, k), accumulate) });
                    }
                }
                // Share by share, as two threads would: the kernel pairs batches within a share.
                None => {
                    for c in 0..sweep.p.color_count() {
                        for k in 0..2 {
                            // SAFETY: one thread, and the columns are used by nothing else
                            // meanwhile.
                            unsafe { sweep.run(sweep.p.share(c, k), accumulate) };
                        }
                    }
                }
            }
        }
    }

    /// Whether contacts are resolved after the end pass (a test-only reference path; see
    /// `contacts_after_end`).
    fn contacts_after_end(&self) -> bool {
        #[cfg(test)]
        return self.contacts_after_end;
        #[cfg(not(test))]
        false
    }

    /// The contact response for substep `[t0, t1]` of length `h`, ahead of the end pass
    /// ([`AheadOfEnd`]); with contact work tracked, the energy it adds is counted.
    fn resolve_contacts_ahead(&mut self, s: &mut Step, t: (f32, f32, f32)) {
        let before = s.contact_work.map(|_| self.energy_ahead(s, 1.0 / t.2));
        let (touched, entry) = &mut self.contact_velocities;
        let mut state = AheadOfEnd {
            x: &self.state.x,
            d: &mut self.state.d,
            inv_h: 1.0 / t.2,
            layout: &self.layout,
            touched,
            entry,
        };
        let work = s.contacts.resolve_state(t, &s.model.triangles, &mut state);
        if let Some(before) = before {
            let after = self.energy_ahead(s, 1.0 / t.2);
            s.count_contact_work((before, after), work);
        }
    }

    /// The energy of the state [`AheadOfEnd`] describes (`inv_h` = 1/substep), through the
    /// particles, which the step rewrites at its end anyway (only for tracked contact work).
    fn energy_ahead(&self, s: &mut Step, inv_h: f32) -> Energy {
        let (touched, entry) = &self.contact_velocities;
        let order = self.layout.storage().order();
        for (k, &e) in entry.iter().enumerate().take(self.state.x.len()) {
            let (x, d) = (self.state.x.get(k), self.state.d.get(k));
            let v = match e {
                0 => d * inv_h,
                e => touched[e as usize - 1].1,
            };
            let p = order.get(k).map_or(k, |&p| p as usize);
            let particles = &mut *s.particles;
            (particles.positions[p], particles.velocities[p]) = (x + d, v);
        }
        s.energy()
    }

    /// After the end pass, the velocities the contacts set replace the displacement's: in the
    /// next substep's start (`begin`, the same formula as [`Self::advance`]'s) or, at the step's
    /// end, in the velocities.
    fn apply_contact_velocities(&mut self, m: &Motion, wind: bool, begin: bool) {
        let (touched, entry) = &mut self.contact_velocities;
        let g = Vec3::from_array(m.gravity);
        for &(i, v) in touched.iter() {
            let i = i as usize;
            entry[i] = 0;
            if !begin {
                self.state.v.set(i, v);
                continue;
            }
            let a = if wind {
                self.wind_dv.get(i)
            } else {
                Vec3::ZERO
            };
            self.state.d.set(i, ((v + g + a) * m.keep) * m.h);
        }
        touched.clear();
    }

    /// The per-particle work around the projections. With `END`, the end of a substep: the
    /// velocity `v = Δ/h` from the displacement itself, which holds every correction in full
    /// (added to the position, corrections below its f32 resolution would vanish, and the lost
    /// ones bias the dynamics: a cloth can gain energy), and the position `x += Δ`, rounded once.
    /// With `BEGIN`, the start of the next: the unconstrained symplectic Euler move
    /// `v ← (v + g h + a) e^{-c h}`, `Δ = v h`, where `a` is the wind's velocity change (with
    /// `wind`); that velocity is not stored (the end of the substep replaces it).
    ///
    /// A vector [`Kernel`] ([`simd`]). With `lead`, the two threads each take half of the
    /// particles, the halves the colours' shares mostly keep to.
    fn advance<const END: bool, const BEGIN: bool>(
        &mut self,
        m: &Motion,
        wind: bool,
        lead: Option<&Lead>,
    ) {
        let wind_dv = wind.then_some(&self.wind_dv);
        let SoaState { x, v, d } = &mut self.state;
        let Some(lead) = lead else {
            return simd::run(Advance::<END, BEGIN> {
                x: [&mut x.x, &mut x.y, &mut x.z],
                v: [&mut v.x, &mut v.y, &mut v.z],
                d: [&mut d.x, &mut d.y, &mut d.z],
                wind_dv: wind_dv.map(|w| [&w.x[..], &w.y[..], &w.z[..]]),
                m,
            });
        };
        let n = x.len();
        let mid = (n / 2).next_multiple_of(2 * LANES).min(n);
        let cols = [
            [&mut x.x, &mut x.y, &mut x.z].map(|a| Column::new(a)),
            [&mut v.x, &mut v.y, &mut v.z].map(|a| Column::new(a)),
            [&mut d.x, &mut d.y, &mut d.z].map(|a| Column::new(a)),
        ];
        lead.run(&|share| {
            let range = if share == 0 { 0..mid } else { mid..n };
            // SAFETY: the two shares' ranges are disjoint, the team runs each share on one
            // thread, and nothing else uses the arrays until `run` returns.
            let [x, v, d] = cols.map(|c| c.map(|c| unsafe { c.slice_mut(range.clone()) }));
            let wind = wind_dv.map(|w| {
                [
                    &w.x[range.clone()],
                    &w.y[range.clone()],
                    &w.z[range.clone()],
                ]
            });
            simd::run(Advance::<END, BEGIN> {
                x,
                v,
                d,
                wind_dv: wind,
                m,
            });
        });
    }
}

/// XPBD's arrays between a substep's projections and its end pass, as the contact response's
/// state: each particle starts the substep at `x` and ends it at `x + d`, moving at `d / h`
/// unless a contact has set its velocity (listed in `touched`, for
/// [`Xpbd::apply_contact_velocities`]; `entry[i]` is 1 + its place there, 0 for none). Moving a
/// particle changes its `d`.
struct AheadOfEnd<'a> {
    x: &'a Soa,
    d: &'a mut Soa,
    inv_h: f32,
    layout: &'a Projections,
    touched: &'a mut Vec<(u32, Vec3)>,
    entry: &'a mut [u32],
}

impl ContactState for AheadOfEnd<'_> {
    fn len(&self) -> usize {
        self.x.len()
    }
    #[inline(always)]
    fn inv_mass(&self, i: usize) -> f32 {
        self.layout.inv_mass[i]
    }
    fn slot(&self, p: u32) -> usize {
        self.layout.stored(p) as usize
    }
    fn projects_tethers(&self) -> bool {
        true
    }
    #[inline(always)]
    fn start(&self, i: usize) -> Vec3 {
        self.x.get(i)
    }
    #[inline(always)]
    fn position(&self, i: usize) -> Vec3 {
        // The end pass's `x += d`, coordinate by coordinate.
        self.x.get(i) + self.d.get(i)
    }
    #[inline(always)]
    fn velocity(&self, i: usize) -> Vec3 {
        match self.entry[i] {
            0 => self.d.get(i) * self.inv_h,
            k => self.touched[k as usize - 1].1,
        }
    }
    #[inline(always)]
    fn set(&mut self, i: usize, x: Vec3, v: Vec3) {
        self.d.set(i, x - self.x.get(i));
        match self.entry[i] {
            0 => {
                // At most one entry per particle, within the capacity reserved for all of them.
                self.touched.push((i as u32, v));
                self.entry[i] = self.touched.len() as u32;
            }
            k => self.touched[k as usize - 1].1 = v,
        }
    }
    fn clearances(&self, near: Near, within: f32, out: &mut [f32]) {
        soa_clearances::<true>(self.x, self.d, (near, within), out);
    }
    // Inlined, so that the caller's running sums stay in registers.
    #[inline(always)]
    fn paths(&self, mut f: impl FnMut(usize, Vec3, Vec3)) {
        for (i, (x, d)) in self.x.iter().zip(self.d.iter()).enumerate() {
            // The end pass's `x += d`, coordinate by coordinate.
            f(i, x, x + d);
        }
    }
    fn displaced(&self, found: &[Vec3], moved: &mut [Vec3A]) -> (Vec3A, Vec3A) {
        soa_displaced::<true>(self.x, self.d, found, moved)
    }
    fn since(&self, at: &Soa, guess: Vec3) -> Since {
        soa_since::<true>(self.x, self.d, at, guess)
    }
    fn ends(&self, out: &mut Soa) {
        soa_ends::<true>(self.x, self.d, out);
    }
}

/// The constants of a step's particle passes: substep `h`, `1/h`, the velocity kept over a
/// substep `e^{-c h}` and gravity's velocity change `g h`.
struct Motion {
    h: f32,
    inv_h: f32,
    keep: f32,
    gravity: [f32; 3],
}

/// [`Xpbd::advance`]'s arguments for a range of particles, as a [`Kernel`].
struct Advance<'a, const END: bool, const BEGIN: bool> {
    x: [&'a mut [f32]; 3],
    v: [&'a mut [f32]; 3],
    d: [&'a mut [f32]; 3],
    wind_dv: Option<[&'a [f32]; 3]>,
    m: &'a Motion,
}

impl<const END: bool, const BEGIN: bool> Kernel for Advance<'_, END, BEGIN> {
    const WIDEST: Build = Build::Avx2;

    #[inline(always)]
    fn body<const WIDE: bool>(self) {
        let Self {
            x,
            v,
            d,
            wind_dv,
            m,
        } = self;
        let [x0, x1, x2] = x;
        let [v0, v1, v2] = v;
        let [d0, d1, d2] = d;
        let w = wind_dv.map(|w| w.map(Some)).unwrap_or([None; 3]);
        let coords = [(x0, v0, d0, w[0]), (x1, v1, d1, w[1]), (x2, v2, d2, w[2])];
        for (c, (x, v, d, wind)) in coords.into_iter().enumerate() {
            let (g, keep, h, inv_h) = (m.gravity[c], m.keep, m.h, m.inv_h);
            // The velocity a substep starts with is only read by that start, so it is stored only
            // where a substep ends without the next one starting (the step's last, or before contacts).
            let step = |x: &mut f32, v: &mut f32, d: &mut f32, a: f32| {
                let mut u = *v;
                if END {
                    u = *d * inv_h;
                    *x += *d;
                }
                if BEGIN {
                    *d = ((u + g + a) * keep) * h;
                } else {
                    *v = u;
                }
            };
            match wind {
                Some(wind) => {
                    for (((x, v), d), a) in
                        x.iter_mut().zip(v.iter_mut()).zip(d.iter_mut()).zip(wind)
                    {
                        step(x, v, d, *a);
                    }
                }
                None => {
                    for ((x, v), d) in x.iter_mut().zip(v.iter_mut()).zip(d.iter_mut()) {
                        step(x, v, d, 0.0);
                    }
                }
            }
        }
    }
}
