//! The self-contacts' broad phase: when the candidates must be found again, and the search for
//! them through the pairs of patches that the normal cones leave (or through the spatial hash).

use glam::{Vec3, Vec3A};

use super::SelfContacts;
use super::cubes::BLOCK_CUBES;
use crate::sim::contact::narrow::ContactState;
use crate::sim::contact::pairs::{
    boxes_meet, boxes_meet_wide, closest_on_segments, largest_root, pair_key,
    point_triangle_distance, reorder,
};

/// At most this many candidate pairs per triangle of the cloth (of each kind): a cloth crushed
/// into a ball smaller than the margin would otherwise have every pair of its elements as a
/// candidate. A pile of cloth needs far fewer.
pub(super) const MAX_CANDIDATES_PER_TRIANGLE: usize = 16;

/// A search's cull: the widest culled cone for a shortest triangle altitude, and how far beyond
/// twice the margin to look for uncovered elements (see [`SelfContacts::find_candidates`]).
pub(super) type NormalConeCull = (fn(f32) -> f32, f32);

/// [`SelfContacts::find_candidates`] without culling.
pub(super) const NO_CULL: Option<NormalConeCull> = None;

/// Share of the limit on the edges' turn up to which the near bound stands in for the edges'
/// own bound (see [`ParticleCubes::edges_closing`](super::cubes::ParticleCubes::edges_closing)): the slack that a check leaves the next ones is
/// then at least the rest.
pub(super) const EDGES_NEAR_BOUND_SHARE: f32 = 0.25;

impl SelfContacts {
    /// Finds the candidates at the step's first resolution, or again when a particle has moved
    /// farther than the reach since they were found. Returns the particles' mean displacement
    /// since then, at the start and at the end of the substep.
    pub(super) fn refresh_candidates<S: ContactState>(&mut self, state: &S) -> (Vec3, Vec3) {
        let n = state.len();
        // The order of the stored particles was checked at this step's first resolution.
        let new_step = std::mem::take(&mut self.new_step);
        if !self.stale {
            if let Some(mean) = self.last_check.unchanged(state) {
                self.cubes.skip();
                return mean;
            }
            let turn_limit = 2.0 * self.reach;
            // The near bound stands in for the edges' own up to `EDGES_NEAR_BOUND_SHARE` of twice the
            // reach: worked out pair by pair above that.
            let limits = (EDGES_NEAR_BOUND_SHARE * turn_limit, self.far_limit);
            let closing = self.cubes.closing(state, &self.found, limits);
            if closing.slack >= 0.0
                && closing.mid <= self.far_limit
                && closing.far <= self.wide_limit
            {
                // An edge's ends lie in the same or neighbouring cubes: within the near bound.
                // The edges' own bound is much smaller where the cloth bends: worked out unless
                // the near bound leaves most of the limit to spare for the next checks.
                let turning = if closing.near <= EDGES_NEAR_BOUND_SHARE * turn_limit {
                    closing.near
                } else {
                    self.cubes.edges_closing(&self.edge_slots)
                };
                if turning <= turn_limit {
                    let slack = closing
                        .slack
                        .min(self.far_limit - closing.mid)
                        .min(self.wide_limit - closing.far)
                        .min(turn_limit - turning);
                    self.last_check.take(state, slack, closing.mean);
                    return closing.mean;
                }
            }
            // A full list holds an arbitrary share of the close pairs (a cloth crushed into a
            // ball): searching again within the step would only pick another share, at the
            // cost of a search per substep. The next step's first substep searches.
            if self.full() && !new_step {
                self.last_check.valid = false;
                return closing.mean;
            }
        }
        self.last_check.valid = false;
        self.slot.clear();
        self.slot
            .extend((0..n as u32).map(|p| state.slot(p) as u32));
        // The substep's paths, as stored, read in one pass.
        let (starts, steps) = (&mut self.path_starts, &mut self.path_steps);
        starts.resize(n, Vec3::ZERO);
        steps.resize(n, Vec3::ZERO);
        state.paths(|i, start, end| {
            starts[i] = start;
            steps[i] = end - start;
        });
        self.found_at.clear();
        self.found_at
            .extend(self.slot.iter().map(|&s| self.path_starts[s as usize]));
        // Found at the substep's start, the candidates must also cover where it ends. A cloth
        // whose parts moved farther apart than the cap within this one substep gets its
        // candidates where the substep ends instead: the pairs within the thickness there, on
        // the wrong side or not, are still found and put right; a pair that passed through
        // each other and far beyond within one substep is not (that needs a continuous test).
        let moved = spread_about_mean(n, |p| self.path_steps[self.slot[p] as usize]);
        if moved <= self.reach_cap {
            self.reach = self.step_reach.max(moved);
        } else {
            self.reach = self.reach_cap;
            for (x, &s) in self.found_at.iter_mut().zip(&self.slot) {
                *x = state.position(s as usize);
            }
        }
        let positions = std::mem::take(&mut self.found_at);
        let cap = self.cap();
        self.searches += 1;
        let longest = largest_root(self.edges.len(), |k| {
            let [a, b] = self.edges[k];
            positions[a as usize].distance_squared(positions[b as usize])
        });
        // Two elements' particles lie within a side of their closest points each: two particles
        // that were not in neighbouring cubes (at least the cubes' size apart) belong to
        // elements that were at least that less two sides apart.
        self.far_limit = self.cubes.size - 2.0 * longest - self.thickness;
        self.wide_limit = BLOCK_CUBES as f32 * self.cubes.size - 2.0 * longest - self.thickness;
        let margin = self.thickness + 2.0 * self.reach;
        // Uncovered elements farther apart than the far limit allows are of no use to the near
        // limit: the far bound, which is at least the near one, would ask for a search first.
        let out = self.far_limit + self.thickness - 2.0 * margin;
        self.find_candidates(&positions, margin, cap, Some((self.cull(), out)));
        self.edge_slots.clear();
        self.edge_slots
            .extend(self.edges.iter().map(|e| e.map(|p| self.slot[p as usize])));
        self.cubes.assign(&positions, &self.slot);
        // Two elements the search did not pair may come closer by twice the reach where they
        // are in patches searched together (every cube holding a corner of a patch that takes
        // part in the search is held to that), and by their distance less the thickness where
        // they are in patches left uncovered: at least either patch's clear distance (which is
        // at least the margin, so more than twice the reach). With a vertex in no triangle,
        // every patch takes part.
        let (turn_limit, patches) = (2.0 * self.reach, &self.patches);
        self.patch_limit.clear();
        self.patch_limit.extend((0..patches.len() as u32).map(|p| {
            if self.loose || patches.live(p) {
                turn_limit
            } else {
                (patches.clear_of(p) - self.thickness).max(turn_limit)
            }
        }));
        let limits = &self.patch_limit;
        self.cubes.limit(&self.slot, |p| {
            patches.least_around(p as u32, limits).unwrap_or(turn_limit)
        });
        self.found.clear();
        self.found.resize(n, Vec3::ZERO);
        for (&s, x) in self.slot.iter().zip(&positions) {
            self.found[s as usize] = *x;
        }
        self.found_at = positions;
        self.stale = false;
        self.order_by_gap(self.thickness + 2.0 * self.reach);
        self.list_involved();
        let (mut m0, mut m1) = (Vec3::ZERO, Vec3::ZERO);
        let found = &self.found;
        state.paths(|i, start, end| {
            m0 += start - found[i];
            m1 += end - found[i];
        });
        (m0 / n as f32, m1 / n as f32)
    }

    /// Lists the stored particles that are in a candidate pair, and each candidate's four
    /// particles' places among them.
    pub(super) fn list_involved(&mut self) {
        let slot = |p: u32| self.slot[p as usize];
        self.quads.clear();
        for &(p, t) in &self.vt {
            let [a, b, c] = self.tris[t as usize];
            self.quads.push([p, a, b, c].map(slot));
        }
        for &(e, f) in &self.ee {
            let ([a, b], [c, d]) = (self.edges[e as usize], self.edges[f as usize]);
            self.quads.push([a, b, c, d].map(slot));
        }
        // Marked, then listed in storage order.
        self.place.clear();
        self.place.resize(self.slot.len(), u32::MAX);
        for &s in self.quads.iter().flatten() {
            self.place[s as usize] = 0;
        }
        self.involved.clear();
        for (s, place) in self.place.iter_mut().enumerate() {
            if *place == 0 {
                *place = self.involved.len() as u32;
                self.involved.push(s as u32);
            }
        }
        for quad in &mut self.quads {
            *quad = quad.map(|s| self.place[s as usize]);
        }
    }

    /// Orders the candidates of each kind into bands of distance (see [`GapBands`](crate::sim::contact::pairs::GapBands)), the distances
    /// found being below `margin`.
    pub(super) fn order_by_gap(&mut self, margin: f32) {
        let split = self.vt.len();
        let mut order = std::mem::take(&mut self.order);
        order.clear();
        let spacing = self.spacing();
        let pair = |k: usize| (self.gap[k], spacing.kept(k < split));
        let [vt, ee] = &mut self.bands;
        vt.order(0..split, margin, pair, &mut order);
        ee.order(split..self.gap.len(), margin, pair, &mut order);
        reorder(
            &mut self.gap,
            &mut self.reordered_gaps,
            order.iter().map(|&k| k as usize),
        );
        reorder(
            &mut self.vt,
            &mut self.reordered_pairs,
            order[..split].iter().map(|&k| k as usize),
        );
        reorder(
            &mut self.ee,
            &mut self.reordered_pairs,
            order[split..].iter().map(|&k| k as usize - split),
        );
        self.order = order;
    }

    /// This search's cull: for a patch whose shortest triangle altitude is `h`, [`cull_angle`]
    /// of `h` or the shortest at rest, whichever is less (a compressed patch's triangles are
    /// thinner).
    pub(super) fn cull(&self) -> impl Fn(f32) -> f32 + use<> {
        let (reach, rest) = (self.reach, self.altitude);
        move |h| cull_angle(reach, rest.min(h))
    }

    /// The broad phase on `x` (by model particle): every vertex–triangle and edge–edge pair that
    /// shares no vertex, is not exempt, and is closer than `margin`, up to `cap` of each kind;
    /// with `cull` (`flat`, `out`), none between patches within one direction by the angle `flat`
    /// gives for their shortest triangle altitude at `x` (see [`patches`](super::patches)), the patches' uncovered
    /// distance being looked for up to `out` beyond twice the margin (`Patches::clear_of`).
    pub(super) fn find_candidates(
        &mut self,
        x: &[Vec3],
        margin: f32,
        cap: usize,
        cull: Option<(impl Fn(f32) -> f32, f32)>,
    ) {
        self.vt.clear();
        self.ee.clear();
        self.gap.clear();
        let grow = Vec3::splat(margin);
        self.hash.triangle_boxes(&self.tris, x, grow);
        let culls = cull.is_some();
        if let Some((flat, out)) = cull {
            self.patches
                .update(x, &self.tris, &self.hash.boxes, (flat, margin, out));
        }
        if culls && !self.loose {
            if self.hash.finite() {
                self.pair_patches(x, margin, cap);
            }
            return;
        }
        let patches = &self.patches;
        let live = |patch: u32| !culls || patches.live(patch);
        let culled = |a: u32, b: u32| culls && patches.culled(a, b);
        if !self.hash.build(|t| live(patches.of_triangle(t))) {
            return;
        }
        let hash = &self.hash;
        for (p, &at) in x.iter().enumerate() {
            if self.vt.len() >= cap {
                break;
            }
            let p = p as u32;
            let patch = patches.of_vertex(p);
            if !live(patch) {
                continue;
            }
            hash.visit(at, at, |t| {
                let tri = self.tris[t as usize];
                if tri.contains(&p)
                    || culled(patch, patches.of_triangle(t))
                    || is_listed(&self.exempt_vt, pair_key(p, t))
                {
                    return;
                }
                let [a, b, c] = tri.map(|i| x[i as usize]);
                let gap = point_triangle_distance(at, a, b, c);
                if gap < margin {
                    self.vt.push((p, t));
                    self.gap.push(gap);
                }
            });
        }
        for (e, &[a, b]) in self.edges.iter().enumerate() {
            if self.ee.len() >= cap {
                break;
            }
            let e = e as u32;
            let patch = self.edge_patch[e as usize];
            if !live(patch) {
                continue;
            }
            let (lo, hi) = (
                x[a as usize].min(x[b as usize]),
                x[a as usize].max(x[b as usize]),
            );
            hash.visit(lo, hi, |t| {
                if culled(patch, patches.of_triangle(t)) {
                    return;
                }
                for &f in &self.tri_edges[t as usize] {
                    if f <= e || f == u32::MAX {
                        continue;
                    }
                    let [c, d] = self.edges[f as usize];
                    if c == a || c == b || d == a || d == b {
                        continue;
                    }
                    let [pa, pb, pc, pd] = [a, b, c, d].map(|i| x[i as usize]);
                    let (flo, fhi) = (pc.min(pd), pc.max(pd));
                    if !boxes_meet((flo - grow, fhi + grow), (lo, hi))
                        || is_listed(&self.exempt_ee, pair_key(e, f))
                    {
                        continue;
                    }
                    let (s, t) = closest_on_segments(pa, pb, pc, pd);
                    let gap = pa.lerp(pb, s).distance(pc.lerp(pd, t));
                    if gap < margin {
                        self.ee.push((e, f));
                        self.gap.push(gap);
                    }
                }
            });
        }
    }

    /// The candidates within `margin` (up to `cap` of each kind) among the pairs of patches that
    /// take part in the search (`Patches::pairs`): each pair's vertices against its triangles
    /// and its edges against its edges, by box, then by distance. The same candidates as the
    /// hash finds (every close pair that is not culled lies in one of the patch pairs), cheaply
    /// when few patches take part.
    pub(super) fn pair_patches(&mut self, x: &[Vec3], margin: f32, cap: usize) {
        let grow = Vec3A::splat(margin);
        // The boxes patch by patch, so that a pair's inner loop reads them in order; only those
        // of the patches in a pair (a hanging cloth's search has few), the others left as they
        // were.
        let unset = (Vec3A::NAN, Vec3A::NAN);
        self.triangle_boxes
            .resize(self.patch_triangles.items.len(), unset);
        self.edge_boxes.resize(self.patch_edges.items.len(), unset);
        self.boxed.clear();
        self.boxed.resize(self.patches.len(), false);
        for &p in self.patches.pairs().iter().flat_map(|(a, b)| [a, b]) {
            if std::mem::replace(&mut self.boxed[p as usize], true) {
                continue;
            }
            let range = self.patch_triangles.range(p);
            for (out, &t) in self.triangle_boxes[range.clone()]
                .iter_mut()
                .zip(&self.patch_triangles.items[range])
            {
                let (lo, hi) = self.hash.boxes[t as usize];
                *out = (lo.into(), hi.into());
            }
            let range = self.patch_edges.range(p);
            for (out, &e) in self.edge_boxes[range.clone()]
                .iter_mut()
                .zip(&self.patch_edges.items[range])
            {
                let [a, b] = self.edges[e as usize].map(|i| Vec3A::from(x[i as usize]));
                *out = (a.min(b), a.max(b));
            }
        }
        // Once a kind's list is full, nothing more of it is looked at (a cloth crushed into a
        // ball has every pair of patches in the search).
        'vt: for &(a, b) in self.patches.pairs() {
            let sides: &[(u32, u32)] = if a == b { &[(a, a)] } else { &[(a, b), (b, a)] };
            for &(v, w) in sides {
                // An element outside the other patch's box meets none of its triangles' boxes.
                let (wlo, whi) = self.patches.bounds(w);
                let bounds = (wlo.into(), whi.into());
                let range = self.patch_triangles.range(w);
                let (triangles, boxes) = (
                    &self.patch_triangles.items[range.clone()],
                    &self.triangle_boxes[range],
                );
                for &p in self.patch_vertices.of(v) {
                    if self.vt.len() >= cap {
                        break 'vt;
                    }
                    let at = Vec3A::from(x[p as usize]);
                    if !boxes_meet_wide(bounds, (at, at)) {
                        continue;
                    }
                    for (&t, &(lo, hi)) in triangles.iter().zip(boxes) {
                        if !boxes_meet_wide((lo, hi), (at, at)) {
                            continue;
                        }
                        let tri = self.tris[t as usize];
                        if tri.contains(&p) || is_listed(&self.exempt_vt, pair_key(p, t)) {
                            continue;
                        }
                        let [ta, tb, tc] = tri.map(|i| x[i as usize]);
                        let gap = point_triangle_distance(at.into(), ta, tb, tc);
                        if gap < margin && self.vt.len() < cap {
                            self.vt.push((p, t));
                            self.gap.push(gap);
                        }
                    }
                }
            }
        }
        'ee: for &(a, b) in self.patches.pairs() {
            let (blo, bhi) = self.patches.bounds(b);
            let bounds = (blo.into(), bhi.into());
            let (ra, rb) = (self.patch_edges.range(a), self.patch_edges.range(b));
            let (others, boxes) = (&self.patch_edges.items[rb.clone()], &self.edge_boxes[rb]);
            for (&e, &(elo, ehi)) in self.patch_edges.items[ra.clone()]
                .iter()
                .zip(&self.edge_boxes[ra])
            {
                if self.ee.len() >= cap {
                    break 'ee;
                }
                if !boxes_meet_wide((elo, ehi), bounds) {
                    continue;
                }
                let (lo, hi) = (elo - grow, ehi + grow);
                for (&f, &(flo, fhi)) in others.iter().zip(boxes) {
                    if !boxes_meet_wide((flo, fhi), (lo, hi)) || (a == b && f <= e) {
                        continue;
                    }
                    let ([ea, eb], [fc, fd]) = (self.edges[e as usize], self.edges[f as usize]);
                    let key = pair_key(e.min(f), e.max(f));
                    if fc == ea
                        || fc == eb
                        || fd == ea
                        || fd == eb
                        || is_listed(&self.exempt_ee, key)
                    {
                        continue;
                    }
                    let [pa, pb, pc, pd] = [ea, eb, fc, fd].map(|i| x[i as usize]);
                    let (s, t) = closest_on_segments(pa, pb, pc, pd);
                    let gap = pa.lerp(pb, s).distance(pc.lerp(pd, t));
                    if gap < margin && self.ee.len() < cap {
                        self.ee.push((e.min(f), e.max(f)));
                        self.gap.push(gap);
                    }
                }
            }
        }
    }
}

/// How far the `n` displacements `d(0..n)` spread about their mean: the largest distance of one
/// from the mean (infinite if one is not finite). Moving every particle by the same vector
/// changes no distance between them, so only this part of the motion can bring a pair together:
/// two elements move closer by at most twice it.
pub(super) fn spread_about_mean(n: usize, d: impl Fn(usize) -> Vec3) -> f32 {
    if n == 0 {
        return 0.0;
    }
    let mean = (0..n).map(&d).sum::<Vec3>() / n as f32;
    largest_root(n, |p| d(p).distance_squared(mean))
}

/// The widest normal cone (half-angle, radians) of patches whose elements are not paired in a
/// search of this `reach`, for triangles whose shortest altitude is `altitude`: a right angle
/// (beyond which a surface can fold onto itself) less the most a triangle can turn while the
/// candidates are kept, and a tenth of a radian to spare. Its vertices' relative displacements
/// stay within twice the reach, `d`; a vertex moved by `d` turns a triangle of altitude `h` by at
/// most `asin(d / h)` (the tangent from the opposite side to the ball the vertex stays in), and at
/// `d ≥ h` the triangle can fold flat.
pub(super) fn cull_angle(reach: f32, altitude: f32) -> f32 {
    // A ratio that is NaN (no triangles, or a degenerate one) counts as 1 (`min` drops NaN): a
    // negative angle, which culls nothing.
    let turn = (2.0 * reach / altitude).min(1.0).asin();
    std::f32::consts::FRAC_PI_2 - turn - 0.1
}

/// Whether pair `key` is in the sorted list `pairs` (the exempt pairs, or those parting).
pub(super) fn is_listed(pairs: &[u64], key: u64) -> bool {
    !pairs.is_empty() && pairs.binary_search(&key).is_ok()
}
