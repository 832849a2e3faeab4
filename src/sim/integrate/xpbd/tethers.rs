//! Tethers inside XPBD's solve. After each substep's spring sweeps, every tethered particle
//! farther than its tether's length from its anchor (a pinned particle, on its target for the
//! substep's end) is projected back onto that sphere: a one-sided distance constraint whose
//! anchor does not move. As for the springs, the velocity follows from the displacement.
//!
//! Projected every substep, tethers carry a pin's pull down the whole cloth at once, which one
//! Gauss-Seidel sweep per substep does only a few particles at a time: a cloth hanging from its
//! pins stretches then by the tethers' slack at most, not by what the sweeps leave unconverged.

use glam::Vec3;

use crate::sim::integrate::step::Order;
use crate::sim::simd::{self, Build, Kernel};
use crate::sim::soa::Soa;
use crate::sim::state::{PinState, between_coordinate};

/// A cloth's tethers by storage slot, with each slot's anchor's targets over the step. The kernel
/// reads the anchors' targets from arrays of their own, one value per slot, so that it runs in
/// whole vectors without gathers; they are filled again only in a step whose pins' targets
/// changed (never while the pins stand still).
#[derive(Debug, Clone, Default)]
pub(super) struct Tethered {
    /// Per slot: its tether's length, m (infinite where it has none).
    length: Vec<f32>,
    /// Per slot: the place of its anchor in `anchors` (`u32::MAX` where it has no tether).
    place: Vec<u32>,
    /// The anchors (particles).
    anchors: Vec<u32>,
    /// Per particle: its place in `anchors` (`u32::MAX` for none).
    anchor_place: Vec<u32>,
    /// Each anchor's targets at the start and end of the step the slots' arrays were filled for
    /// (NaN before the first), and the coming step's (scratch).
    filled: Vec<(Vec3, Vec3)>,
    ends: Vec<(Vec3, Vec3)>,
    /// Per slot: its anchor's target at the start of the step and at its end, one array per
    /// coordinate.
    from: Soa,
    to: Soa,
}

impl Tethered {
    /// Lays out `tethers` (particle, anchor particle, length) for `n` particles stored in
    /// `order`. Tethers whose particle or anchor is not among the `n` are left out.
    pub fn set(&mut self, tethers: impl Iterator<Item = (u32, u32, f32)>, order: &Order, n: usize) {
        self.length.clear();
        self.length.resize(n, f32::INFINITY);
        self.place.clear();
        self.place.resize(n, u32::MAX);
        self.anchors.clear();
        self.anchor_place.clear();
        self.anchor_place.resize(n, u32::MAX);
        for (particle, anchor, length) in tethers {
            if particle as usize >= n || anchor as usize >= n {
                continue;
            }
            let k = &mut self.anchor_place[anchor as usize];
            if *k == u32::MAX {
                *k = self.anchors.len() as u32;
                self.anchors.push(anchor);
            }
            let slot = order.stored(particle) as usize;
            self.place[slot] = *k;
            self.length[slot] = length;
        }
        self.filled = vec![(Vec3::NAN, Vec3::NAN); self.anchors.len()];
        self.ends = self.filled.clone();
        self.from = Soa::new(n);
        self.to = Soa::new(n);
    }

    /// Whether there is no tether.
    pub fn is_empty(&self) -> bool {
        self.anchors.is_empty()
    }

    /// Takes the anchors' targets over the coming step from `pins` (an anchor without a pin
    /// stays where it is in `x`, in storage `order`).
    pub fn begin_step(&mut self, pins: &[PinState], x: &Soa, order: &Order) {
        if self.is_empty() {
            return;
        }
        for (end, &a) in self.ends.iter_mut().zip(&self.anchors) {
            let at = x.get(order.stored(a) as usize);
            *end = (at, at);
        }
        for pin in pins {
            if let Some(&k) = self.anchor_place.get(pin.particle as usize)
                && let Some(end) = self.ends.get_mut(k as usize)
            {
                *end = (pin.from, pin.to);
            }
        }
        let bits = |(a, b): (Vec3, Vec3)| {
            (
                a.to_array().map(f32::to_bits),
                b.to_array().map(f32::to_bits),
            )
        };
        if self
            .ends
            .iter()
            .zip(&self.filled)
            .all(|(&e, &f)| bits(e) == bits(f))
        {
            return;
        }
        std::mem::swap(&mut self.filled, &mut self.ends);
        for (slot, &k) in self.place.iter().enumerate() {
            if let Some(&(from, to)) = self.filled.get(k as usize) {
                self.from.set(slot, from);
                self.to.set(slot, to);
            }
        }
    }

    /// Projects every tethered particle that ends the substep (at `x + d`) past its tether back
    /// onto it, by changing its `d`; the substep ends at fraction `t1` of the step.
    pub fn project(&self, t1: f32, x: &Soa, d: &mut Soa) {
        if let Some(kernel) = self.kernel(t1, x, d) {
            simd::run(kernel);
        }
    }

    /// [`Self::project`] in `build`; returns whether it ran.
    #[cfg(test)]
    fn project_as(&self, build: Build, t1: f32, x: &Soa, d: &mut Soa) -> bool {
        self.kernel(t1, x, d)
            .is_none_or(|kernel| simd::run_as(build, kernel))
    }

    /// The projection's kernel, if there is a tether.
    fn kernel<'a>(&'a self, t1: f32, x: &'a Soa, d: &'a mut Soa) -> Option<Project<'a>> {
        (!self.is_empty()).then(|| Project {
            length: &self.length,
            from: [&self.from.x, &self.from.y, &self.from.z],
            to: [&self.to.x, &self.to.y, &self.to.z],
            t1,
            x: [&x.x, &x.y, &x.z],
            d: [&mut d.x, &mut d.y, &mut d.z],
        })
    }
}

/// [`Tethered::project`]'s arguments, as a [`Kernel`].
struct Project<'a> {
    length: &'a [f32],
    from: [&'a [f32]; 3],
    to: [&'a [f32]; 3],
    t1: f32,
    x: [&'a [f32]; 3],
    d: [&'a mut [f32]; 3],
}

impl Kernel for Project<'_> {
    const WIDEST: Build = Build::Avx512;

    #[inline(always)]
    fn body<const WIDE: bool>(self) {
        let Self {
            length,
            from,
            to,
            t1,
            x,
            d,
        } = self;
        let n = length.len();
        let [f0, f1, f2] = from.map(|c| &c[..n]);
        let [g0, g1, g2] = to.map(|c| &c[..n]);
        let [x0, x1, x2] = x.map(|c| &c[..n]);
        let [d0, d1, d2] = d.map(|c| &mut c[..n]);
        // The pin's target at the substep's end, as the pin computes it (`state::between`).
        let between = |f: f32, g: f32| between_coordinate(f, g, t1);
        for k in 0..n {
            let (ax, ay, az) = (
                between(f0[k], g0[k]),
                between(f1[k], g1[k]),
                between(f2[k], g2[k]),
            );
            // The way from the anchor, in f64: its difference of f32 positions is exact there,
            // and the move back onto the sphere, a small part of it, keeps its precision. In f32
            // from the end position `x + d`, the move would be rounded to the position's
            // resolution, a velocity error of that over the substep, which lends a swinging
            // particle energy (the more, the more substeps).
            let way = |x: f32, d: f32, a: f32| (f64::from(x) - f64::from(a)) + f64::from(d);
            let (ex, ey, ez) = (
                way(x0[k], d0[k], ax),
                way(x1[k], d1[k], ay),
                way(x2[k], d2[k], az),
            );
            let len2 = ex * ex + ey * ey + ez * ez;
            let limit = f64::from(length[k]);
            // Untethered slots have an infinite length; a non-finite position is left alone.
            // Selected, not branched on, so that the loop runs in vectors.
            let past = len2 > limit * limit;
            let back = limit / len2.sqrt() - 1.0;
            let moved = |d: f32, e: f64| if past { d + (e * back) as f32 } else { d };
            (d0[k], d1[k], d2[k]) = (moved(d0[k], ex), moved(d1[k], ey), moved(d2[k], ez));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The anchors, every seventh particle and the last two have no tether.
    fn untethered(p: u32) -> bool {
        p.is_multiple_of(7) || p >= 68 || p == 29 || p == 40
    }

    fn anchor_of(p: u32) -> u32 {
        if p < 35 { 29 } else { 40 }
    }

    /// The substep ends at this fraction of the step.
    const T1: f32 = 0.25;

    /// 70 particles stored in reverse order, tied to particle 29 or 40 (pins moving over the
    /// step): some tethered past their length, some within it, some untethered.
    fn case() -> (Tethered, Soa, Soa, Vec<PinState>) {
        let n = 70;
        let order = Order::new((0..n as u32).rev().collect());
        let mut x = Soa::new(n);
        let mut d = Soa::new(n);
        for k in 0..n {
            let f = k as f32;
            x.set(k, Vec3::new(0.1 * f, -0.05 * f, 0.02 * (f * 0.7).sin()));
            d.set(k, Vec3::new(0.01 * (f * 1.3).cos(), -0.003 * f, 0.001));
        }
        let tethers = (0..n as u32)
            .filter(|&p| !untethered(p))
            .map(|p| (p, anchor_of(p), 0.04 * (p % 11) as f32));
        let mut t = Tethered::default();
        t.set(tethers, &order, n);
        let pins: Vec<PinState> = [29u32, 40, 3]
            .map(|p| {
                let at = x.get(order.stored(p) as usize);
                PinState {
                    particle: p,
                    from: at,
                    to: at + Vec3::new(0.2, 0.1, -0.3),
                }
            })
            .to_vec();
        t.begin_step(&pins, &x, &order);
        (t, x, d, pins)
    }

    #[test]
    fn tethered_particles_end_within_their_tethers_and_the_others_stay() {
        let (t, x, mut d, pins) = case();
        let order = Order::new((0..x.len() as u32).rev().collect());
        let before = d.clone();
        t.project(T1, &x, &mut d);
        let (mut moved, mut kept) = (0, 0);
        for p in 0..x.len() as u32 {
            let k = order.stored(p) as usize;
            let end = x.get(k) + d.get(k);
            let was = x.get(k) + before.get(k);
            if untethered(p) {
                assert_eq!(d.get(k), before.get(k), "untethered particle {p} moved");
                continue;
            }
            let pin = pins.iter().find(|q| q.particle == anchor_of(p)).unwrap();
            let anchor = crate::sim::state::between(pin.from, pin.to, T1);
            let length = 0.04 * (p % 11) as f32;
            if was.distance(anchor) <= length {
                assert_eq!(
                    d.get(k),
                    before.get(k),
                    "particle {p} within its tether moved"
                );
                kept += 1;
            } else {
                assert!(
                    (end.distance(anchor) - length).abs() <= 1e-5,
                    "particle {p} ends {} from its anchor, tether {length}",
                    end.distance(anchor)
                );
                // Straight back towards the anchor (onto it, for a tether of length 0).
                if length > 0.0 {
                    let (to, from) = ((end - anchor).normalize(), (was - anchor).normalize());
                    assert!(to.dot(from) > 1.0 - 1e-5, "particle {p} moved sideways");
                }
                moved += 1;
            }
        }
        assert!(moved > 10 && kept > 3, "{moved} projected, {kept} within");
    }

    #[test]
    fn the_anchors_targets_are_taken_again_only_when_the_pins_move() {
        let (mut t, x, _, mut pins) = case();
        let order = Order::new((0..x.len() as u32).rev().collect());
        let slot = order.stored(10) as usize;
        assert_eq!(t.to.get(slot), pins[0].to);
        // The same targets: nothing to fill (a stale array would show it).
        t.to.set(slot, Vec3::ZERO);
        t.begin_step(&pins, &x, &order);
        assert_eq!(t.to.get(slot), Vec3::ZERO);
        // A pin moved: every slot tied to it follows.
        pins[0].to += Vec3::X;
        t.begin_step(&pins, &x, &order);
        assert_eq!(t.to.get(slot), pins[0].to);
        assert_eq!(t.from.get(slot), pins[0].from);
    }

    #[test]
    fn every_build_projects_the_same() {
        let (t, x, d, _) = case();
        let mut plain = d.clone();
        assert!(t.project_as(Build::Plain, T1, &x, &mut plain));
        for build in [Build::Avx2, Build::Avx512] {
            let mut wide = d.clone();
            if t.project_as(build, T1, &x, &mut wide) {
                for k in 0..x.len() {
                    assert_eq!(
                        wide.get(k).to_array().map(f32::to_bits),
                        plain.get(k).to_array().map(f32::to_bits),
                        "{build:?}, slot {k}"
                    );
                }
            }
        }
    }
}
