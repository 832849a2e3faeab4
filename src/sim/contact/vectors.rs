//! A state as plain arrays of vectors in the particles' own order, and what a collider's contact
//! reports for one particle.

use glam::Vec3;

use super::narrow::ContactState;
use super::shapes::Near;

/// The state as three arrays of vectors in the particles' own order.
pub(super) struct Vectors<'a> {
    pub(super) x: &'a mut [Vec3],
    pub(super) v: &'a mut [Vec3],
    pub(super) start: &'a [Vec3],
    pub(super) inv_mass: &'a [f32],
    /// Where given, each touched particle's [`Touch`].
    pub(super) touches: Option<&'a mut [Touch]>,
}

/// A collider's contact with one particle in a substep, as
/// [`Contacts::resolve`](super::Contacts::resolve) reports it: the outward normal (zero: no
/// contact) and the velocity of the collider's surface there.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Touch {
    /// Outward unit normal; zero for a particle no collider touched.
    pub normal: Vec3,
    /// Velocity of the collider's surface at the contact, m/s.
    pub surface: Vec3,
}

impl ContactState for Vectors<'_> {
    fn len(&self) -> usize {
        self.x.len()
    }
    #[inline(always)]
    fn inv_mass(&self, i: usize) -> f32 {
        self.inv_mass[i]
    }
    fn slot(&self, p: u32) -> usize {
        p as usize
    }
    #[inline(always)]
    fn start(&self, i: usize) -> Vec3 {
        self.start[i]
    }
    #[inline(always)]
    fn position(&self, i: usize) -> Vec3 {
        self.x[i]
    }
    #[inline(always)]
    fn velocity(&self, i: usize) -> Vec3 {
        self.v[i]
    }
    #[inline(always)]
    fn set(&mut self, i: usize, x: Vec3, v: Vec3) {
        (self.x[i], self.v[i]) = (x, v);
    }
    fn touched(&mut self, i: usize, normal: Vec3, surface: Vec3) {
        if let Some(touches) = self.touches.as_deref_mut() {
            touches[i] = Touch { normal, surface };
        }
    }
    fn clearances(&self, near: Near, within: f32, out: &mut [f32]) {
        for ((o, x), s) in out.iter_mut().zip(&*self.x).zip(self.start) {
            *o = near.distance(*x) - x.distance(*s) - within;
        }
    }
}
