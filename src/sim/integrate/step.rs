//! What the steppers share: [`Step`], the cloth a step works on (everything but a stepper's own
//! scratch), and [`SoaState`], the coordinate arrays the vector steppers (XPBD, symplectic Euler,
//! Verlet) step in, with their contact response.

use glam::{Quat, Vec3, Vec3A};

use crate::sim::contact::{
    ContactState, Contacts, Near, Pose, Since, soa_clearances, soa_displaced, soa_ends, soa_since,
};
use crate::sim::forces::SpringSet;
use crate::sim::model::ClothModel;
use crate::sim::pressure::{Air, air_energy};
use crate::sim::settings::{Inertia, SolverSettings};
use crate::sim::soa::Soa;
use crate::sim::state::{Energy, Particles, PinState, pin_motion};
use crate::sim::wind::WindScratch;

/// The cloth a step works on, lent by `ClothSim` for one step: its model, settings, pins and
/// this step's wind (read only), and its particles and contacts (read and written).
pub(crate) struct Step<'a> {
    /// The topology.
    pub model: &'a ClothModel,
    /// The settings.
    pub settings: &'a SolverSettings,
    /// Per-spring stiffness `k`, N/m.
    pub stiffness: &'a [f32],
    /// The pins, with their targets at the start and end of the step.
    pub pins: &'a [PinState],
    /// The wind's forces over this step.
    pub wind: &'a WindScratch,
    /// The air inside a closed cloth, if it has any.
    pub air: Option<&'a Air>,
    /// The particle state, in the particles' own order.
    pub particles: &'a mut Particles,
    /// The colliders in reach this step, and contact scratch.
    pub contacts: &'a mut Contacts,
    /// Energy the contact responses added, J, when tracked (see `ClothSim::track_contact_work`).
    pub contact_work: &'a mut Option<f64>,
    /// The reference frame's poses at the step's start and end, and how much of its motion
    /// the cloth feels; `None` when it feels all of it (or the frame stands still).
    pub frame: Option<(Pose, Pose, Inertia)>,
}

impl Step<'_> {
    /// The springs with their stiffness, for the force kernels.
    pub fn springs(&self) -> SpringSet<'_> {
        SpringSet::new(&self.model.springs, self.stiffness)
    }

    /// The energy of the free particles (see [`Energy`]).
    pub fn energy(&self) -> Energy {
        let mut e = self.particles.energy(self.springs(), self.settings.gravity);
        e.elastic += air_energy(self.air, &self.model.triangles, &self.particles.positions);
        e
    }

    /// Adds to tracked contact work what a contact response gave the cloth (see
    /// [`add_contact_work`]).
    pub fn count_contact_work(&mut self, (before, after): (Energy, Energy), colliders: f64) {
        add_contact_work(self.contact_work, (before, after), colliders);
    }
}

/// Adds to tracked contact work `work` what a contact response that took the cloth's energy from
/// `before` to `after` gave it, J: the larger of the total energy's rise and the potential energy's
/// rise plus the colliders' work on the particles' motion (`colliders`, see
/// `Contacts::resolve_state`), when positive. The second counts the work of a moving collider that
/// presses the cloth against its springs: each response then takes away more kinetic energy (what
/// the springs put in since the last) than the collider's push adds.
pub(crate) fn add_contact_work(
    work: &mut Option<f64>,
    (before, after): (Energy, Energy),
    colliders: f64,
) {
    if let Some(work) = work {
        let potential = |e: &Energy| e.gravitational + e.elastic;
        let pushed = potential(&after) - potential(&before) + colliders;
        *work += (after.total() - before.total()).max(pushed).max(0.0);
    }
}

/// The part of the reference frame's motion over `[t0, t1]` (fractions of the step) that the
/// cloth does not feel (`frame`: see [`Step::frame`]). Each stepper carries its free particles
/// by it where, in its substep, they and the pins stand at the same time.
pub(crate) fn frame_shift(frame: Option<(Pose, Pose, Inertia)>, t0: f32, t1: f32) -> Option<Shift> {
    let (from, to, inertia) = frame?;
    // The frame turns at a constant rate (its rotation is slerped): over any part of the step,
    // by the same power of the step's turn, taken once from the step's two ends (a turn between
    // two slerped poses would carry their rounding, larger than a small substep's turn).
    let turn = (to.rotation * from.rotation.inverse()).normalize();
    let unfelt = (t1 - t0) * (1.0 - inertia.angular);
    Some(Shift {
        origin: from.translation.lerp(to.translation, t0),
        turn: Quat::IDENTITY.slerp(turn, unfelt).normalize(),
        translation: (1.0 - inertia.linear) * (t1 - t0) * (to.translation - from.translation),
    })
}

/// A rigid motion the free particles are carried along by, unfelt (no force, no change of their
/// velocity relative to it): a turn about `origin`, then a translation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Shift {
    origin: Vec3,
    turn: Quat,
    translation: Vec3,
}

impl Shift {
    /// Where the motion takes point `x`.
    #[inline]
    pub fn point(&self, x: Vec3) -> Vec3 {
        self.origin + self.turn * (x - self.origin) + self.translation
    }

    /// Where the motion turns vector `v` (a velocity or a displacement).
    #[inline]
    pub fn vector(&self, v: Vec3) -> Vec3 {
        self.turn * v
    }

    /// Carries the free particles (`inv_mass > 0`) at positions `x` along, turning their
    /// velocities `v`.
    pub fn carry(&self, inv_mass: &[f32], x: &mut [Vec3], v: &mut [Vec3]) {
        for ((x, v), w) in x.iter_mut().zip(v.iter_mut()).zip(inv_mass) {
            if *w > 0.0 {
                (*x, *v) = (self.point(*x), self.vector(*v));
            }
        }
    }
}

/// Where each particle is stored in a stepper's coordinate arrays: `order()[s]` is the particle
/// stored at `s`; empty for the particles' own order.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Order {
    order: Vec<u32>,
    slot: Vec<u32>,
}

impl Order {
    /// The order `order`, a permutation of the particles (empty: their own order).
    pub fn new(order: Vec<u32>) -> Self {
        let mut slot = vec![0; order.len()];
        for (s, &i) in order.iter().enumerate() {
            slot[i as usize] = s as u32;
        }
        Self { order, slot }
    }

    /// Where particle `i` is stored.
    #[inline]
    pub fn stored(&self, i: u32) -> u32 {
        self.slot.get(i as usize).copied().unwrap_or(i)
    }

    /// The particle stored at each place (empty: the particles' own order).
    pub fn order(&self) -> &[u32] {
        &self.order
    }
}

/// A vector stepper's state during a step, one array per coordinate in its storage [`Order`]:
/// positions `x`, velocities `v`, and `d`, which holds each particle's displacement over the
/// substep (XPBD) or its position at the substep's start (the explicit integrators, see
/// [`Self::begin_substep`]).
#[derive(Debug, Clone, Default)]
pub(crate) struct SoaState {
    pub x: Soa,
    pub v: Soa,
    pub d: Soa,
}

impl SoaState {
    /// Arrays for `n` particles.
    pub fn new(n: usize) -> Self {
        Self {
            x: Soa::spread(n, 0),
            v: Soa::spread(n, 1),
            d: Soa::spread(n, 2),
        }
    }

    /// Copies the particles' positions and velocities in, in storage order `order`.
    pub fn load(&mut self, particles: &Particles, order: &Order) {
        self.x.load_ordered(&particles.positions, order.order());
        self.v.load_ordered(&particles.velocities, order.order());
    }

    /// Copies the positions and velocities back out to the particles (see [`Self::load`]).
    pub fn store(&self, particles: &mut Particles, order: &Order) {
        self.x
            .write_ordered(&mut particles.positions, order.order());
        self.v
            .write_ordered(&mut particles.velocities, order.order());
    }

    /// Carries the free particles (`inv_mass > 0`, in storage order) along by `shift`: their
    /// positions `x`, and their velocities, held in `v` or (`velocity_in_d`, XPBD's predicted
    /// displacement) in `d`.
    pub fn carry(&mut self, shift: &Shift, inv_mass: &[f32], velocity_in_d: bool) {
        let velocity = if velocity_in_d {
            &mut self.d
        } else {
            &mut self.v
        };
        for (i, w) in inv_mass.iter().enumerate().take(self.x.len()) {
            if *w > 0.0 {
                self.x.set(i, shift.point(self.x.get(i)));
                velocity.set(i, shift.vector(velocity.get(i)));
            }
        }
    }

    /// Records where a substep begins, in `d`, for the contact response's swept tests (only with
    /// a collider in reach).
    pub fn begin_substep(&mut self, contacts: &Contacts) {
        if contacts.is_active() {
            self.d.copy_from(&self.x);
        }
    }

    /// Carries the free particles' recorded substep starts (see [`Self::begin_substep`]) along
    /// by `shift`, as [`Self::carry`] carries their positions.
    pub fn carry_starts(&mut self, shift: &Shift, inv_mass: &[f32], contacts: &Contacts) {
        if !contacts.is_active() {
            return;
        }
        for (i, w) in inv_mass.iter().enumerate().take(self.d.len()) {
            if *w > 0.0 {
                self.d.set(i, shift.point(self.d.get(i)));
            }
        }
    }

    /// Moves the pinned particles to their targets at the end of substep `[t0, t1]` (fractions
    /// of the step) of length `1/inv_h`, with the velocity of that motion.
    pub fn drive_pins(&mut self, pins: &[PinState], order: &Order, t: (f32, f32), inv_h: f32) {
        for pin in pins {
            let (target, velocity) = pin_motion(pin, t.0, t.1, inv_h);
            let i = order.stored(pin.particle) as usize;
            self.x.set(i, target);
            self.v.set(i, velocity);
        }
    }

    /// Contacts at the end of substep `sub` of `n` (length `h`), on the final positions and
    /// velocities of the substep, in place ([`SoaContacts`]). `d` holds each particle's
    /// displacement over the substep, or with `d_is_start` the start [`Self::begin_substep`]
    /// recorded (turned into the displacement here). `inv_mass` is in storage order (`None`: the
    /// particles', for their own order).
    pub fn resolve_contacts(
        &mut self,
        step: &mut Step,
        (order, inv_mass, tethered): (&Order, Option<&[f32]>, bool),
        (sub, n, h): (u32, u32, f32),
        d_is_start: bool,
    ) {
        if !step.contacts.is_active() {
            return;
        }
        if d_is_start {
            let (x, d) = (&self.x, &mut self.d);
            for (x, d) in [(&x.x, &mut d.x), (&x.y, &mut d.y), (&x.z, &mut d.z)] {
                for (x, d) in x.iter().zip(d.iter_mut()) {
                    *d = *x - *d;
                }
            }
        }
        let energy = |state: &Self, step: &mut Step| {
            step.contact_work.map(|_| {
                state.store(step.particles, order);
                step.energy()
            })
        };
        let before = energy(self, step);
        let mut state = SoaContacts {
            state: self,
            inv_mass: inv_mass.unwrap_or(&step.particles.inv_mass),
            order,
            tethered,
        };
        let (t0, t1) = (sub as f32 / n as f32, (sub + 1) as f32 / n as f32);
        let work = step
            .contacts
            .resolve_state((t0, t1, h), &step.model.triangles, &mut state);
        if let (Some(before), Some(after)) = (before, energy(self, step)) {
            step.count_contact_work((before, after), work);
        }
    }
}

/// A [`SoaState`] at the end of a substep as the contact response's state: positions `x`,
/// velocities `v` and displacements `d` over the substep, so a particle started at `x − d`.
/// Moving a particle moves its displacement with it, so its start stays put.
struct SoaContacts<'a> {
    state: &'a mut SoaState,
    /// Inverse masses in storage order.
    inv_mass: &'a [f32],
    order: &'a Order,
    /// Whether the stepper projected the tethers itself ([`ContactState::projects_tethers`]).
    tethered: bool,
}

impl ContactState for SoaContacts<'_> {
    fn len(&self) -> usize {
        self.state.x.len()
    }
    #[inline(always)]
    fn inv_mass(&self, i: usize) -> f32 {
        self.inv_mass[i]
    }
    fn slot(&self, p: u32) -> usize {
        self.order.stored(p) as usize
    }
    fn projects_tethers(&self) -> bool {
        self.tethered
    }
    #[inline(always)]
    fn start(&self, i: usize) -> Vec3 {
        self.state.x.get(i) - self.state.d.get(i)
    }
    #[inline(always)]
    fn position(&self, i: usize) -> Vec3 {
        self.state.x.get(i)
    }
    #[inline(always)]
    fn velocity(&self, i: usize) -> Vec3 {
        self.state.v.get(i)
    }
    #[inline(always)]
    fn set(&mut self, i: usize, x: Vec3, v: Vec3) {
        let s = &mut self.state;
        s.d.set(i, s.d.get(i) + (x - s.x.get(i)));
        s.x.set(i, x);
        s.v.set(i, v);
    }
    fn clearances(&self, near: Near, within: f32, out: &mut [f32]) {
        soa_clearances::<false>(&self.state.x, &self.state.d, (near, within), out);
    }
    // Inlined, so that the caller's running sums stay in registers.
    #[inline(always)]
    fn paths(&self, mut f: impl FnMut(usize, Vec3, Vec3)) {
        for (i, (x, d)) in self.state.x.iter().zip(self.state.d.iter()).enumerate() {
            f(i, x - d, x);
        }
    }
    fn displaced(&self, found: &[Vec3], moved: &mut [Vec3A]) -> (Vec3A, Vec3A) {
        soa_displaced::<false>(&self.state.x, &self.state.d, found, moved)
    }
    fn since(&self, at: &Soa, guess: Vec3) -> Since {
        soa_since::<false>(&self.state.x, &self.state.d, at, guess)
    }
    fn ends(&self, out: &mut Soa) {
        soa_ends::<false>(&self.state.x, &self.state.d, out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::contact::bounds;
    use crate::sim::{Collider, ColliderShape, Friction, GridSpec, Pose};
    use bevy::math::primitives::Sphere;

    #[test]
    fn contacts_on_the_coordinate_arrays_match_contacts_on_vectors() {
        // A 40×12 grid (stored in XPBD's grid order), jostled, against a sphere smaller than its
        // edges (so triangles are tested too) and a large one, with every tenth particle pinned.
        let model = ClothModel::grid(&GridSpec::new(40, 12, 0.05)).unwrap();
        let n = model.particle_count();
        // Each row's columns grouped by residue mod 4, as XPBD stores a grid.
        let layout = Order::new(
            (0..12)
                .flat_map(|j| (0..4).flat_map(move |r| (r..40).step_by(4).map(move |i| j * 40 + i)))
                .collect(),
        );
        let wobble = |i: usize, k: usize| ((i * 7 + k * 13) % 17) as f32 / 17.0 - 0.5;
        let start: Vec<Vec3> = model.rest_positions.clone();
        let end: Vec<Vec3> = (0..n)
            .map(|i| start[i] + 0.02 * Vec3::new(wobble(i, 0), wobble(i, 1) - 0.6, wobble(i, 2)))
            .collect();
        let velocity: Vec<Vec3> = (0..n).map(|i| Vec3::new(wobble(i, 3), -1.0, 0.0)).collect();
        let inv_mass: Vec<f32> = (0..n)
            .map(|i| if i % 10 == 0 { 0.0 } else { 2.0 })
            .collect();
        let (lo, hi) = bounds(&start);
        let centre = 0.5 * (lo + hi);
        let sphere = |r: f32, at: Vec3| {
            Collider::fixed(
                ColliderShape::Sphere(Sphere::new(r)),
                Pose::from_translation(at),
                Friction::new(0.3),
                0.005,
            )
        };
        let colliders = [
            sphere(0.02, centre - 0.012 * Vec3::Y),
            sphere(0.3, centre + Vec3::new(0.6, -0.27, 0.0)),
        ];
        let mut contacts = Contacts::new(n, (model.max_edge_length(), model.mean_edge_length()));
        contacts.begin_step(&colliders, (u32::MAX, false), (lo, hi), 0.1, 1.0 / 60.0);
        assert_eq!(contacts.active_count(), 2);
        let t = (0.0, 0.05, 1.0 / 1200.0);

        let (mut x, mut v) = (end.clone(), velocity.clone());
        contacts.begin_substep(&start);
        contacts.resolve(
            t.0,
            t.1,
            t.2,
            &model.triangles,
            &inv_mass,
            (&mut x, &mut v),
            None,
        );

        let order = layout.order();
        let mut soa = [Soa::new(n), Soa::new(n), Soa::new(n)];
        soa[0].load_ordered(&end, order);
        soa[1].load_ordered(&velocity, order);
        let moved: Vec<Vec3> = (0..n).map(|i| end[i] - start[i]).collect();
        soa[2].load_ordered(&moved, order);
        let stored_mass: Vec<f32> = order.iter().map(|&i| inv_mass[i as usize]).collect();
        let [xs, vs, ds] = &mut soa;
        let mut soa_state = SoaState {
            x: std::mem::take(xs),
            v: std::mem::take(vs),
            d: std::mem::take(ds),
        };
        let mut state = SoaContacts {
            state: &mut soa_state,
            inv_mass: &stored_mass,
            order: &layout,
            tethered: false,
        };
        contacts.resolve_state(t, &model.triangles, &mut state);
        let soa = [soa_state.x, soa_state.v, soa_state.d];

        let mut touched = 0;
        for p in 0..n {
            let s = layout.stored(p as u32) as usize;
            let close = |a: Vec3, b: Vec3| (a - b).length() <= 1e-5 * b.length().max(1.0);
            assert!(close(soa[0].get(s), x[p]), "position of {p}");
            assert!(close(soa[1].get(s), v[p]), "velocity of {p}");
            assert!(
                close(soa[0].get(s) - soa[2].get(s), start[p]),
                "start of {p}"
            );
            touched += usize::from(x[p] != end[p]);
        }
        assert!(touched > 20, "{touched} particles in contact");
    }
}
