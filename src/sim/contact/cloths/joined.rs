//! A cloth's state joined with the other cloths' particles, so that the pair response moves this
//! cloth's particles against the others' paths.

use glam::Vec3;

use crate::sim::contact::narrow::ContactState;
use crate::sim::contact::shapes::Near;

/// This cloth's state joined with the other cloths' particles, stored after this cloth's: they
/// move in straight lines over the step, are read at the substep's ends and never written.
pub(super) struct JoinedState<'a, S> {
    pub(super) own: &'a mut S,
    /// Where the others' particles begin (this cloth's stored length).
    pub(super) n: usize,
    pub(super) start: &'a [Vec3],
    pub(super) end: &'a [Vec3],
    /// The substep, as fractions of the step.
    pub(super) t: (f32, f32),
    pub(super) inv_dt: f32,
}

impl<S: ContactState> ContactState for JoinedState<'_, S> {
    fn len(&self) -> usize {
        self.n + self.start.len()
    }
    fn inv_mass(&self, i: usize) -> f32 {
        match i.checked_sub(self.n) {
            None => self.own.inv_mass(i),
            // Never moved by this cloth's pushes.
            Some(_) => 0.0,
        }
    }
    fn slot(&self, p: u32) -> usize {
        self.own.slot(p)
    }
    fn start(&self, i: usize) -> Vec3 {
        match i.checked_sub(self.n) {
            None => self.own.start(i),
            Some(j) => self.start[j].lerp(self.end[j], self.t.0),
        }
    }
    fn position(&self, i: usize) -> Vec3 {
        match i.checked_sub(self.n) {
            None => self.own.position(i),
            Some(j) => self.start[j].lerp(self.end[j], self.t.1),
        }
    }
    fn velocity(&self, i: usize) -> Vec3 {
        match i.checked_sub(self.n) {
            None => self.own.velocity(i),
            Some(j) => (self.end[j] - self.start[j]) * self.inv_dt,
        }
    }
    fn set(&mut self, i: usize, x: Vec3, v: Vec3) {
        if i < self.n {
            self.own.set(i, x, v);
        }
    }
    fn clearances(&self, near: Near, within: f32, out: &mut [f32]) {
        // Not used by the pair responses; the others' particles are always near.
        let n = self.n.min(out.len());
        self.own.clearances(near, within, &mut out[..n]);
        out[n..].fill(f32::NEG_INFINITY);
    }
}
