//! Contacts between cloths: a cloth keeps its vertices, edges and triangles at least the mean of
//! two cloths' thicknesses from another cloth's, with the narrow phase and response of its contacts
//! with itself (`self_contact`), in the same substeps.
//!
//! Each cloth steps on its own. The others are handed to its step as their triangles and their
//! particles' positions at the step's start and end ([`OtherCloth`]), and move in straight lines
//! between the two during it: surfaces this cloth reads and never writes, so each push moves this
//! cloth alone. A cloth that has not stepped yet is given where it is (start and end the same):
//! the earlier of two cloths keeps clear of where the later one is, and the later one, meeting
//! the earlier one's actual motion, keeps clear of that. Whatever the order, neither ends a step
//! through the other; a fixed order (the caller's) makes the result deterministic. A prediction
//! of the later cloth's motion is not used: it ignores the contacts that will stop that cloth, and
//! a cloth pushed out of a predicted surface ploughing through a pile is pushed through the pile.
//!
//! # Pipeline
//! 1. **Broad phase, per step** ([`ClothContacts::begin_step`]): the other cloths whose boxes,
//!    swept over the step and grown by the pair's thickness, meet this cloth's box grown by how
//!    far its particles can move in the step are copied in; the others cost nothing more.
//! 2. **Candidates, when needed**: the pairs (a vertex of this cloth and a triangle of another, a
//!    vertex of another and a triangle of this one, an edge of each) closer than the thickness
//!    plus twice a reach, found with spatial hashes. They hold every pair that can come within
//!    the thickness while no particle on either side has moved farther than the reach, relative
//!    to this cloth's mean motion, since they were found; past that they are found again, within
//!    a step if need be. Cloths falling or swinging together keep their candidates, and so does a
//!    cloth lying on another from step to step while the same cloths are copied in.
//! 3. **Narrow phase and response, where the cloths may have come closer**: at the step's last
//!    substep, and at others once a pair can have come [`DEFER_CLOSING`] of its kept distance closer
//!    since the last resolution (this cloth's particles measured as for self-contacts, the
//!    others' by how far they move along their paths), so a cloth resting on another is resolved
//!    every few substeps. As for self-contacts (sides taken from the start of the substep, pushes
//!    to the thickness, two edges a little less, the approaching velocity removed, friction), on
//!    the candidates whose distance when found, less how far their particles have moved since,
//!    may have closed to the thickness.

use glam::Vec3;

use super::narrow::ContactState;
use super::pairs::{
    DEFER_CLOSING, GapBands, GatheredParticles, LastResolution, LayerSpacing, SpatialHash,
    closest_on_segments, edge_table, later_passes, map_four, max_or_infinite,
    point_triangle_distance, reorder, storage_order_changed,
};
use super::vectors::Vectors;
use crate::error::{ClothError, indices_in_range, non_negative, positive};
use crate::sim::settings::MAX_THICKNESS_PER_EDGE;
use joined::JoinedState;

mod joined;
#[cfg(test)]
mod tests;

/// At most this many candidates per vertex or edge of the search, of each kind: enough for
/// several layers within the margin, not for a crushed ball of cloth.
const MAX_CANDIDATES_PER_ELEMENT: usize = 32;

/// Another cloth as one cloth's step sees it (see
/// [`Environment::cloths`](crate::sim::Environment::cloths)): its triangles and where its
/// particles are at the start and the end of the step.
#[derive(Debug, Clone, Copy)]
pub struct OtherCloth<'a> {
    /// Triangles, three particle indices each.
    pub triangles: &'a [u32],
    /// Its particles' positions at the start of the step.
    pub start: &'a [Vec3],
    /// Their positions at the end of the step: the other cloth's result if it has stepped, else
    /// the same as `start`.
    pub end: &'a [Vec3],
    /// Its thickness, m: two cloths keep the mean of their thicknesses apart.
    pub thickness: f32,
    /// Its friction: two cloths' layers slide with the mean of theirs.
    pub friction: f32,
}

impl OtherCloth<'_> {
    /// Checks that `start` and `end` have one entry per particle, every triangle's indices are in
    /// range, the positions are finite, the thickness finite and positive and the friction finite
    /// and not negative.
    pub fn validate(&self) -> Result<(), ClothError> {
        let count = self.start.len();
        if self.end.len() != count {
            return Err(ClothError::InvalidMesh {
                what: format!(
                    "another cloth has {count} start positions and {} end positions: they must \
                     match",
                    self.end.len()
                ),
            });
        }
        if !self.triangles.len().is_multiple_of(3) {
            return Err(ClothError::InvalidMesh {
                what: format!(
                    "another cloth's triangle list has {} indices, not a multiple of 3",
                    self.triangles.len()
                ),
            });
        }
        indices_in_range(self.triangles, count)?;
        if !self.start.iter().chain(self.end).all(|p| p.is_finite()) {
            return Err(ClothError::InvalidMesh {
                what: "another cloth has a position that is not finite".into(),
            });
        }
        positive("other cloth thickness", self.thickness)?;
        non_negative("other cloth friction", self.friction)
    }
}

/// A cloth's contacts with the other cloths of its step: their copies and this step's candidate
/// pairs. Nothing allocates once the lists have grown to the largest step's size.
#[derive(Debug, Clone, Default)]
pub(crate) struct ClothContacts {
    /// The other cloths of this step, one after another: positions at the step's start and end
    /// and triangles (indices into these lists).
    start: Vec<Vec3>,
    end: Vec<Vec3>,
    tris: Vec<[u32; 3]>,
    /// The copied triangles' edge table (see `edge_table`; found again only when the copied
    /// triangles change): an edge shared by two triangles is owned by one, so a search meets
    /// it once. The last step's triangles, to tell, and the table's scratch.
    tri_edges: Vec<[u32; 3]>,
    other_edges: Vec<[u32; 2]>,
    last_tris: Vec<[u32; 3]>,
    keyed: Vec<(u64, usize)>,
    /// The spacing of each copied cloth with this one, and the copied cloth of each particle.
    spacing: Vec<LayerSpacing>,
    owner: Vec<u32>,
    /// 1 / the step's length.
    inv_dt: f32,
    /// This cloth's triangles and unique edges (found once).
    own_tris: Vec<[u32; 3]>,
    edges: Vec<[u32; 2]>,
    /// The most reach a search is given, m.
    reach_cap: f32,
    /// The reach the candidates were found with, m.
    reach: f32,
    /// The candidates and each one's distance when found, m, in the search's order.
    pairs: Vec<(ClothPair, f32)>,
    /// The same ready for the substeps, ordered into `bands` of that distance.
    prepared: Vec<SubstepCandidate>,
    bands: GapBands,
    /// Scratch of the ordering into bands.
    order: Vec<u32>,
    reordered: Vec<SubstepCandidate>,
    /// Where each of this cloth's model particles is stored in the state being resolved.
    slot: Vec<u32>,
    /// Positions when the candidates were found: this cloth's (by model particle), the others'.
    found_own: Vec<Vec3>,
    found_other: Vec<Vec3>,
    /// Whether the candidates must be found again before the next resolution.
    stale: bool,
    /// Whether the next resolution is a step's first (whose stepper may store this cloth's
    /// particles in another order than the last step's).
    new_step: bool,
    /// The last step's copies of the others' positions at its end (scratch, to tell whether
    /// this step's start is where they were).
    last_end: Vec<Vec3>,
    /// The farthest any copied particle moves over the step, m.
    motion: f32,
    /// When the pairs were last resolved in this step (a fraction of it; 0 at its start).
    resolved_at: f32,
    /// Where this cloth was then, which lets substeps defer the next resolution (see
    /// [`LastResolution`]).
    last_resolution: LastResolution,
    /// Searches run so far.
    searches: u64,
    /// Substeps whose pairs were resolved so far.
    resolutions: u64,
    /// Spatial hashes of the others' triangles and of this cloth's.
    other_hash: SpatialHash,
    own_hash: SpatialHash,
    /// Scratch: each stored particle's drift (this cloth's, then the others'), and the candidates
    /// that acted in a substep's first pass.
    drift: Vec<f32>,
    acting: Vec<u32>,
    /// The joined slots in a candidate pair, each once, sorted.
    involved: Vec<u32>,
    /// Scratch of the narrow phase: the particles of `involved` copied out of the state, their
    /// drifts, and the ones it moved.
    gathered: GatheredParticles,
    local_drift: Vec<f32>,
    moved: Vec<u32>,
}

impl ClothContacts {
    /// The broad phase of a step of `dt` seconds for a cloth of `thickness` and `friction` whose
    /// box at the start is `bounds`, whose particles move at most `reach` in the step, and whose
    /// longest and mean edges at rest are `max_edge` and `mean_edge` long: copies the valid
    /// `others` in reach (see the module docs). The distance kept from each, the mean of the two
    /// thicknesses, is at most [`MAX_THICKNESS_PER_EDGE`] times `mean_edge`.
    pub fn begin_step(
        &mut self,
        others: &[OtherCloth],
        (thickness, friction): (f32, f32),
        (bounds, reach): ((Vec3, Vec3), f32),
        (max_edge, mean_edge): (f32, f32),
        dt: f32,
    ) {
        self.start.clear();
        std::mem::swap(&mut self.end, &mut self.last_end);
        self.end.clear();
        std::mem::swap(&mut self.tris, &mut self.last_tris);
        self.tris.clear();
        self.spacing.clear();
        self.owner.clear();
        self.new_step = true;
        self.inv_dt = if dt > 0.0 { 1.0 / dt } else { 0.0 };
        let reach = if reach.is_finite() { reach } else { f32::MAX };
        for other in others {
            if other.validate().is_err() || other.triangles.is_empty() {
                continue;
            }
            // The distance kept is at most MAX_THICKNESS_PER_EDGE times this cloth's mean edge:
            // the pairs a search meets grow with its square.
            let spacing = LayerSpacing {
                thickness: (0.5 * (thickness + other.thickness))
                    .min(MAX_THICKNESS_PER_EDGE * mean_edge),
                friction: 0.5 * (friction + other.friction),
            };
            let (a0, a1) = super::bounds(other.start);
            let (b0, b1) = super::bounds(other.end);
            let grow = Vec3::splat(spacing.thickness + reach);
            let (lo, hi) = (a0.min(b0) - grow, a1.max(b1) + grow);
            if !(lo.cmple(bounds.1).all() && hi.cmpge(bounds.0).all()) {
                continue;
            }
            let offset = self.start.len() as u32;
            let index = self.spacing.len() as u32;
            self.spacing.push(spacing);
            self.start.extend_from_slice(other.start);
            self.end.extend_from_slice(other.end);
            self.owner.extend(other.start.iter().map(|_| index));
            self.tris.extend(
                other
                    .triangles
                    .chunks_exact(3)
                    .map(|t| [t[0] + offset, t[1] + offset, t[2] + offset]),
            );
        }
        // A resolution can be deferred past the step's start only if the others start it where
        // the last step's ended.
        let same_tris = same_triangles(&self.tris, &self.last_tris);
        if !same_tris || self.start != self.last_end {
            self.last_resolution.forget();
        }
        self.resolved_at = 0.0;
        self.motion = (self.start.iter().zip(&self.end))
            .map(|(a, b)| a.distance(*b))
            .fold(0.0, max_or_infinite);
        // Candidates found in an earlier step hold while the same cloths are copied in the same
        // order (the joined indices they name are the same) and their particles stay within reach.
        if !same_tris {
            self.stale = true;
            edge_table(
                &self.tris,
                &mut self.keyed,
                &mut self.other_edges,
                &mut self.tri_edges,
            );
        }
        let thickest = self.spacing.iter().map(|s| s.thickness).fold(0.0, f32::max);
        self.reach_cap = (0.1 * max_edge).max(thickest);
    }

    /// Whether another cloth is near this step.
    pub fn is_active(&self) -> bool {
        !self.tris.is_empty()
    }

    /// Whether another cloth near this step moves during it.
    pub fn any_moving(&self) -> bool {
        self.start != self.end
    }

    /// Searches run so far.
    pub fn searches(&self) -> u64 {
        self.searches
    }

    /// Substeps whose pairs were resolved so far (the others deferred theirs).
    pub fn resolutions(&self) -> u64 {
        self.resolutions
    }

    /// The narrow phase and response at the end of the substep `[t0, t1]` (fractions of the
    /// step) of length `h`, for a cloth of `triangles` whose particles are in `state`, or nothing
    /// while no pair can have come [`DEFER_CLOSING`] of its kept distance closer since the last
    /// resolution, unless the substep is the step's last (`t1 = 1`). Returns whether any particle
    /// moved.
    pub fn resolve<S: ContactState>(
        &mut self,
        (t0, t1, h): (f32, f32, f32),
        triangles: &[u32],
        state: &mut S,
    ) -> bool {
        if self.tris.is_empty() || triangles.is_empty() {
            return false;
        }
        if self.own_tris.len() * 3 != triangles.len() {
            self.own_tris = triangles
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect();
            edge_table(
                &self.own_tris,
                &mut self.keyed,
                &mut self.edges,
                &mut Vec::new(),
            );
        }
        let n = state.len();
        // A stepper may store this cloth's particles in another order from one step to the next.
        if std::mem::take(&mut self.new_step) && storage_order_changed(state, &self.slot) {
            self.stale = true;
            self.last_resolution.forget();
        }
        // Between this cloth and a copied particle: this cloth's bound plus how far the copy
        // moved since (along its straight path over the step).
        let others = self.motion * (t1 - self.resolved_at);
        let slack = DEFER_CLOSING
            * self
                .spacing
                .iter()
                .map(|s| s.thickness)
                .fold(f32::MAX, f32::min);
        if t1 < 1.0
            && !self.stale
            && (self.last_resolution).holds(state, |r, c| r + c.length() + others <= slack)
        {
            return false;
        }
        self.resolutions += 1;
        let h = h * (self.last_resolution.deferred + 1) as f32;
        self.last_resolution.forget();
        self.resolved_at = t1;
        let mut drift = std::mem::take(&mut self.drift);
        let mut acting = std::mem::take(&mut self.acting);
        let within = !self.stale && self.measure_drift(state, (t0, t1), &mut drift) <= self.reach;
        if !within {
            self.search(state, (t0, t1), &mut drift);
        }
        let inv_h = if h > 0.0 { 1.0 / h } else { 0.0 };
        let mut joined = JoinedState {
            own: state,
            n,
            start: &self.start,
            end: &self.end,
            t: (t0, t1),
            inv_dt: self.inv_dt,
        };
        // As for the self-contacts: the pairs' particles copied out once, the moved ones set
        // back (the others' are never moved).
        let mut gathered = std::mem::take(&mut self.gathered);
        gathered.read(&joined, &self.involved);
        let mut local = std::mem::take(&mut self.local_drift);
        local.clear();
        local.extend(self.involved.iter().map(|&s| drift[s as usize]));
        let mut copies = gathered.state();
        acting.clear();
        let closing = 2.0 * local.iter().copied().fold(0.0, max_or_infinite);
        self.bands.visit(closing, |k| {
            if !(self.may_touch(k, &local) && self.pair(&mut copies, k, inv_h, &mut local) > 0.0) {
                return 0.0;
            }
            acting.push(k as u32);
            let [a, b, c, d] = map_four(self.prepared[k].slots, |i| local[i as usize]);
            a.max(b).max(c).max(d)
        });
        later_passes(&acting, |k| self.pair(&mut copies, k, inv_h, &mut local));
        let any = !acting.is_empty();
        if any {
            gathered.write(&mut joined, &self.involved, &mut self.moved);
        }
        self.gathered = gathered;
        self.local_drift = local;
        self.drift = drift;
        self.last_resolution.due = !self.prepared.is_empty();
        self.acting = acting;
        any
    }

    /// Ends a substep's contacts: after a resolution, once the colliders have had their last
    /// word, keeps the positions that the next substeps' motion is measured from.
    pub fn end_substep<S: ContactState>(&mut self, state: &S) {
        if std::mem::take(&mut self.last_resolution.due) {
            self.last_resolution.take(state);
        }
    }

    /// Fills `drift` (by joined slot) with each particle's largest distance, at the start or the
    /// end of the substep, from where it was at the search, this cloth's mean displacement since
    /// taken off (as for self-contacts). Returns the largest.
    fn measure_drift<S: ContactState>(
        &self,
        state: &S,
        (t0, t1): (f32, f32),
        drift: &mut Vec<f32>,
    ) -> f32 {
        let n = state.len();
        drift.clear();
        drift.resize(n + self.start.len(), f32::INFINITY);
        let count = self.slot.len();
        if count == 0 {
            return f32::INFINITY;
        }
        let (mut m0, mut m1) = (Vec3::ZERO, Vec3::ZERO);
        for (&s, x) in self.slot.iter().zip(&self.found_own) {
            m0 += state.start(s as usize) - *x;
            m1 += state.position(s as usize) - *x;
        }
        let (m0, m1) = (m0 / count as f32, m1 / count as f32);
        let mut worst = 0.0f32;
        let mut record = |slot: usize, d0: Vec3, d1: Vec3| {
            let d = (d0 - m0).length().max((d1 - m1).length());
            // NaN stays infinite: such a particle is always tested and forces a search.
            let d = if d.is_nan() { f32::INFINITY } else { d };
            drift[slot] = d;
            worst = max_or_infinite(worst, d);
        };
        for (&s, x) in self.slot.iter().zip(&self.found_own) {
            let s = s as usize;
            record(s, state.start(s) - *x, state.position(s) - *x);
        }
        for (i, x) in self.found_other.iter().enumerate() {
            let (a, b) = (self.start[i], self.end[i]);
            record(n + i, a.lerp(b, t0) - *x, a.lerp(b, t1) - *x);
        }
        worst
    }

    /// Finds the candidates from where the particles are at the start of the substep `[t0, t1]`,
    /// with a reach that covers the substep itself; leaves the substep's drift in `drift`.
    fn search<S: ContactState>(&mut self, state: &S, (t0, t1): (f32, f32), drift: &mut Vec<f32>) {
        self.searches += 1;
        self.stale = false;
        let n = state.len();
        self.slot.clear();
        self.slot
            .extend((0..n as u32).map(|p| state.slot(p) as u32));
        self.found_own.clear();
        self.found_own
            .extend(self.slot.iter().map(|&s| state.start(s as usize)));
        self.found_other.clear();
        self.found_other.extend(
            self.start
                .iter()
                .zip(&self.end)
                .map(|(a, b)| a.lerp(*b, t0)),
        );
        // The substep's own motion, measured as the drift is.
        let moved = self.measure_drift(state, (t0, t1), drift);
        self.reach = if moved.is_finite() {
            self.reach_cap.max(moved)
        } else {
            self.reach_cap
        };
        self.find_candidates();
        self.prepare(n);
    }

    /// The broad phase proper on `found_own` and `found_other`: every pair closer than its
    /// spacing's thickness plus twice the reach, up to the cap per element of each kind.
    fn find_candidates(&mut self) {
        self.pairs.clear();
        let reach2 = 2.0 * self.reach;
        let thickest = self.spacing.iter().map(|s| s.thickness).fold(0.0, f32::max);
        let grow = Vec3::splat(thickest + reach2);
        let (x, y) = (&self.found_own, &self.found_other);
        let corners = |t: &[u32; 3], p: &[Vec3]| t.map(|i| p[i as usize]);
        let limit =
            |other: u32| self.spacing[self.owner[other as usize] as usize].thickness + reach2;
        let cap = |elements: usize| MAX_CANDIDATES_PER_ELEMENT * elements;
        let pairs = &mut self.pairs;
        let mut count = [0usize; 3];
        self.other_hash.triangle_boxes(&self.tris, y, grow);
        if self.other_hash.build(|_| true) {
            let hash = &self.other_hash;
            for (p, &at) in x.iter().enumerate() {
                if count[0] >= cap(x.len()) {
                    break;
                }
                hash.visit(at, at, |t| {
                    let tri = self.tris[t as usize];
                    let [a, b, c] = corners(&tri, y);
                    let gap = point_triangle_distance(at, a, b, c);
                    if gap < limit(tri[0]) {
                        pairs.push((ClothPair::OwnVertex(p as u32, t), gap));
                        count[0] += 1;
                    }
                });
            }
            for (e, &[a, b]) in self.edges.iter().enumerate() {
                if count[1] >= cap(self.edges.len()) {
                    break;
                }
                let (pa, pb) = (x[a as usize], x[b as usize]);
                hash.visit(pa.min(pb), pa.max(pb), |t| {
                    let tri = self.tris[t as usize];
                    for k in (0..3).filter(|&k| self.tri_edges[t as usize][k] != u32::MAX) {
                        let (c, d) = (tri[k], tri[(k + 1) % 3]);
                        let (pc, pd) = (y[c as usize], y[d as usize]);
                        let (s, u) = closest_on_segments(pa, pb, pc, pd);
                        let gap = pa.lerp(pb, s).distance(pc.lerp(pd, u));
                        if gap < limit(c) {
                            pairs.push((ClothPair::Edges(e as u32, [c.min(d), c.max(d)]), gap));
                            count[1] += 1;
                        }
                    }
                });
            }
        }
        self.own_hash.triangle_boxes(&self.own_tris, x, grow);
        if self.own_hash.build(|_| true) {
            let hash = &self.own_hash;
            for (p, &at) in y.iter().enumerate() {
                if count[2] >= cap(y.len()) {
                    break;
                }
                hash.visit(at, at, |t| {
                    let [a, b, c] = corners(&self.own_tris[t as usize], x);
                    let gap = point_triangle_distance(at, a, b, c);
                    if gap < limit(p as u32) {
                        pairs.push((ClothPair::OtherVertex(p as u32, t), gap));
                        count[2] += 1;
                    }
                });
            }
        }
    }

    /// The joined slots of candidate `pair`'s four particles (this cloth's stored where `slot`
    /// says, the others' after this cloth's `n`), the weight of the first in the pair's
    /// combination being 1, and the other cloth it meets.
    fn slots(&self, pair: ClothPair, n: usize) -> ([usize; 4], u32) {
        let own = |p: u32| self.slot[p as usize] as usize;
        let other = |p: u32| n + p as usize;
        match pair {
            ClothPair::OwnVertex(p, t) => {
                let [a, b, c] = self.tris[t as usize];
                ([own(p), other(a), other(b), other(c)], a)
            }
            ClothPair::OtherVertex(p, t) => {
                let [a, b, c] = self.own_tris[t as usize];
                ([other(p), own(a), own(b), own(c)], p)
            }
            ClothPair::Edges(e, [c, d]) => {
                let [a, b] = self.edges[e as usize];
                ([own(a), own(b), other(c), other(d)], c)
            }
        }
    }

    /// Each candidate's slots, kind and spacing, for the substeps (after a search, for a state of
    /// `n` stored particles).
    fn prepare(&mut self, n: usize) {
        let mut prepared = std::mem::take(&mut self.prepared);
        prepared.clear();
        prepared.extend(self.pairs.iter().map(|&(pair, gap)| {
            let (slots, other) = self.slots(pair, n);
            SubstepCandidate {
                slots: slots.map(|s| s as u32),
                vertex: !matches!(pair, ClothPair::Edges(..)),
                spacing: self.owner[other as usize],
                gap,
            }
        }));
        // The joined slots in a pair, each once; then each pair's places among them.
        self.involved.clear();
        self.involved.extend(prepared.iter().flat_map(|c| c.slots));
        self.involved.sort_unstable();
        self.involved.dedup();
        for c in &mut prepared {
            c.slots = c.slots.map(|s| {
                // Every slot of a pair is in the list.
                self.involved.binary_search(&s).unwrap_or_default() as u32
            });
        }
        let thickest = self.spacing.iter().map(|s| s.thickness).fold(0.0, f32::max);
        let mut order = std::mem::take(&mut self.order);
        order.clear();
        let pair = |k: usize| {
            let c: &SubstepCandidate = &prepared[k];
            (c.gap, self.spacing[c.spacing as usize].kept(c.vertex))
        };
        let margin = thickest + 2.0 * self.reach;
        self.bands
            .order(0..prepared.len(), margin, pair, &mut order);
        reorder(
            &mut prepared,
            &mut self.reordered,
            order.iter().map(|&k| k as usize),
        );
        self.order = order;
        self.prepared = prepared;
    }

    /// Whether candidate `k` may have come within its kept distance since it was found: its gap
    /// then less the most its two elements' particles have drifted.
    fn may_touch(&self, k: usize, drift: &[f32]) -> bool {
        let c = &self.prepared[k];
        let d = map_four(c.slots, |i| drift[i as usize]);
        let closing = if c.vertex {
            d[0] + d[1].max(d[2]).max(d[3])
        } else {
            d[0].max(d[1]) + d[2].max(d[3])
        };
        c.gap - closing <= self.spacing[c.spacing as usize].kept(c.vertex)
    }

    /// Resolves candidate `k` on the copies of the joined state's pair particles (see
    /// [`LayerSpacing`]). Returns how far it pushed the pair out, as a fraction of its kept distance
    /// (0: nothing moved); adds what it moved each particle to `drift`.
    fn pair(&self, state: &mut Vectors, k: usize, inv_h: f32, drift: &mut [f32]) -> f32 {
        let c = &self.prepared[k];
        let spacing = self.spacing[c.spacing as usize];
        let s = map_four(c.slots, |i| i as usize);
        if c.vertex {
            spacing.vertex_triangle(state, s, inv_h, drift)
        } else {
            spacing.edge_edge(state, s, inv_h, drift)
        }
    }
}

/// A candidate as the substeps use it: its four particles' places in `involved` (the vertex first
/// in a vertex–triangle pair), its kind, the copied cloth it meets and its distance when found.
#[derive(Debug, Clone, Copy)]
struct SubstepCandidate {
    slots: [u32; 4],
    vertex: bool,
    spacing: u32,
    gap: f32,
}

/// A candidate pair between this cloth and another.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ClothPair {
    /// This cloth's vertex and another's triangle (an index into the copied triangles).
    OwnVertex(u32, u32),
    /// Another cloth's vertex (an index into the copied particles) and this cloth's triangle.
    OtherVertex(u32, u32),
    /// This cloth's edge and another's, as its two copied particles (lower first).
    Edges(u32, [u32; 2]),
}

/// Whether `a` and `b` list the same triangles. Two empty lists (a cloth with no other near,
/// every step) are answered without comparing: a slice comparison calls `memcmp` even for zero
/// bytes, at an empty `Vec`'s dangling address, and glibc's AVX-512 `memcmp` is slow there (its
/// masked load of nothing at an unmapped page takes a microcode assist).
fn same_triangles(a: &[[u32; 3]], b: &[[u32; 3]]) -> bool {
    a.len() == b.len() && (a.is_empty() || a == b)
}
