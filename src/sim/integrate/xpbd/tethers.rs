//! Tethers inside XPBD's solve. After each substep's spring sweeps, every tethered particle
//! farther than its tether's length from its anchor (a pinned particle, already on its target
//! for the substep's end) is projected back onto that sphere: a one-sided distance constraint
//! whose anchor does not move. As for the springs, the velocity follows from the displacement.
//!
//! Projected every substep, tethers carry a pin's pull down the whole cloth at once, which one
//! Gauss-Seidel sweep per substep does only a few particles at a time: a cloth hanging from its
//! pins stretches then by the tethers' slack at most, not by what the sweeps leave unconverged.

use crate::sim::integrate::step::Order;
use crate::sim::simd::{self, Build, Kernel};
use crate::sim::soa::Soa;

/// A cloth's tethers by storage slot, with each slot's anchor position in the current substep.
/// The kernel reads the anchors' positions from arrays of their own, one value per slot, so that
/// it runs in whole vectors without gathers; they are filled again only when an anchor has moved
/// (never for still pins), run by run of slots that share an anchor.
#[derive(Debug, Clone, Default)]
pub(super) struct Tethered {
    /// Per slot: its tether's length, m (infinite where it has none).
    length: Vec<f32>,
    /// The anchors' slots.
    anchors: Vec<u32>,
    /// Runs of consecutive slots with the same anchor (a place in `anchors`): `(start, end,
    /// place)`. A slot without a tether joins the run before it (or the first).
    runs: Vec<(u32, u32, u32)>,
    /// The anchors' positions the slots' arrays were last filled with (NaN before the first).
    filled: Soa,
    /// Per slot: its anchor's position in the current substep, one array per coordinate.
    at: Soa,
}

impl Tethered {
    /// Lays out `tethers` (particle, anchor particle, length) for `n` particles stored in
    /// `order`. Tethers whose particle or anchor is not among the `n` are left out.
    pub fn set(&mut self, tethers: impl Iterator<Item = (u32, u32, f32)>, order: &Order, n: usize) {
        self.length.clear();
        self.length.resize(n, f32::INFINITY);
        self.anchors.clear();
        let mut place_of_slot = vec![u32::MAX; n];
        let mut place = std::collections::HashMap::new();
        for (particle, anchor, length) in tethers {
            if particle as usize >= n || anchor as usize >= n {
                continue;
            }
            let (slot, anchor) = (order.stored(particle), order.stored(anchor));
            let next = self.anchors.len() as u32;
            let k = *place.entry(anchor).or_insert(next);
            if k == next {
                self.anchors.push(anchor);
            }
            place_of_slot[slot as usize] = k;
            self.length[slot as usize] = length;
        }
        self.runs.clear();
        for (slot, &p) in place_of_slot.iter().enumerate() {
            match self.runs.last_mut() {
                Some(run) if p == u32::MAX || p == run.2 => run.1 = slot as u32 + 1,
                // Leading slots without a tether join the first run.
                Some(run) if run.2 == u32::MAX => *run = (run.0, slot as u32 + 1, p),
                _ => self.runs.push((slot as u32, slot as u32 + 1, p)),
            }
        }
        if self.anchors.is_empty() {
            self.runs.clear();
        }
        self.filled = Soa::new(self.anchors.len());
        self.filled.x.fill(f32::NAN);
        self.at = Soa::new(n);
    }

    /// Whether there is no tether.
    pub fn is_empty(&self) -> bool {
        self.anchors.is_empty()
    }

    /// Projects every tethered particle that ends the substep (at `x + d`) past its tether back
    /// onto it, by changing its `d`.
    pub fn project(&mut self, x: &Soa, d: &mut Soa) {
        self.project_as(None, x, d);
    }

    /// [`Self::project`] in `build` (`None`: the widest the CPU has); returns whether it ran.
    fn project_as(&mut self, build: Option<Build>, x: &Soa, d: &mut Soa) -> bool {
        if self.is_empty() {
            return true;
        }
        let bits = |v: glam::Vec3| v.to_array().map(f32::to_bits);
        let moved = self.anchors.iter().enumerate().any(|(k, &a)| {
            let a = a as usize;
            bits(x.get(a) + d.get(a)) != bits(self.filled.get(k))
        });
        if moved {
            for k in 0..self.anchors.len() {
                let a = self.anchors[k] as usize;
                self.filled.set(k, x.get(a) + d.get(a));
            }
            for &(start, end, place) in &self.runs {
                let p = self.filled.get(place as usize);
                let range = start as usize..end as usize;
                self.at.x[range.clone()].fill(p.x);
                self.at.y[range.clone()].fill(p.y);
                self.at.z[range].fill(p.z);
            }
        }
        let kernel = Project {
            length: &self.length,
            at: [&self.at.x, &self.at.y, &self.at.z],
            x: [&x.x, &x.y, &x.z],
            d: [&mut d.x, &mut d.y, &mut d.z],
        };
        match build {
            None => {
                simd::run(kernel);
                true
            }
            #[cfg(test)]
            Some(build) => simd::run_as(build, kernel),
            #[cfg(not(test))]
            Some(_) => unreachable!("builds are chosen by tests only"),
        }
    }
}

/// [`Tethered::project`]'s arguments, as a [`Kernel`].
struct Project<'a> {
    length: &'a [f32],
    at: [&'a [f32]; 3],
    x: [&'a [f32]; 3],
    d: [&'a mut [f32]; 3],
}

impl Kernel for Project<'_> {
    const WIDEST: Build = Build::Avx512;

    #[inline(always)]
    fn body<const WIDE: bool>(self) {
        let Self { length, at, x, d } = self;
        let n = length.len();
        let [a0, a1, a2] = at.map(|c| &c[..n]);
        let [x0, x1, x2] = x.map(|c| &c[..n]);
        let [d0, d1, d2] = d.map(|c| &mut c[..n]);
        for k in 0..n {
            let (ax, ay, az) = (a0[k], a1[k], a2[k]);
            let (ex, ey, ez) = (x0[k] + d0[k] - ax, x1[k] + d1[k] - ay, x2[k] + d2[k] - az);
            let len2 = ex * ex + ey * ey + ez * ez;
            let limit = length[k];
            // Untethered slots have an infinite length; a non-finite position is left alone.
            // Selected, not branched on, so that the loop runs in vectors.
            let past = len2 > limit * limit;
            let s = limit / len2.sqrt();
            d0[k] = if past { (ax + ex * s) - x0[k] } else { d0[k] };
            d1[k] = if past { (ay + ey * s) - x1[k] } else { d1[k] };
            d2[k] = if past { (az + ez * s) - x2[k] } else { d2[k] };
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;

    fn untethered(p: u32) -> bool {
        p % 7 == 0 || p >= 68 || p == 29 || p == 40
    }

    /// Particle 67, in the first tethered slot, is tied to another anchor than the slot after it.
    fn anchor_of(p: u32) -> u32 {
        if p < 35 || p == 67 { 29 } else { 40 }
    }

    /// 70 particles stored in reverse order, tied to particle 29 or 40: some tethered past
    /// their length, some within it, some untethered (the anchors, and the first two slots).

    fn case() -> (Tethered, Soa, Soa, Order) {
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
        (t, x, d, order)
    }

    #[test]
    fn tethered_particles_end_within_their_tethers_and_the_others_stay() {
        let (mut t, x, mut d, order) = case();
        let before = d.clone();
        t.project(&x, &mut d);
        let (mut moved, mut kept) = (0, 0);
        for p in 0..x.len() as u32 {
            let k = order.stored(p) as usize;
            let end = x.get(k) + d.get(k);
            let was = x.get(k) + before.get(k);
            if untethered(p) {
                assert_eq!(d.get(k), before.get(k), "untethered particle {p} moved");
                continue;
            }
            let a = order.stored(anchor_of(p)) as usize;
            let anchor = x.get(a) + d.get(a);
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
    fn every_build_projects_the_same() {
        let (mut t, x, d, _) = case();
        let mut plain = d.clone();
        assert!(t.project_as(Some(Build::Plain), &x, &mut plain));
        for build in [Build::Avx2, Build::Avx512] {
            let mut wide = d.clone();
            if t.project_as(Some(build), &x, &mut wide) {
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
