//! Self-contact: the cloth's own vertices, edges and triangles kept at least a thickness apart.
//!
//! # Pipeline
//! 1. **Topology, once** ([`SelfContacts::new`]): the triangles, their unique edges, and the
//!    vertex–triangle and edge–edge pairs that share no vertex but are closer than the thickness
//!    at rest (neighbours along the mesh of a fine cloth). Those are exempt for good.
//! 2. **Broad phase, when needed** ([`SelfContacts::begin_step`]): every triangle's bounding
//!    box is grown by the thickness and twice a reach (the step's relative motion, capped below
//!    what a flat grid's non-neighbours allow). Parts of the cloth too flat to fold onto
//!    themselves are not searched (normal cones of patches, see [`patches`]); the pairs of
//!    patches that are, vertices against triangles and edges against edges by their boxes, give
//!    the candidates: the pairs closer than the thickness plus twice the reach (at most
//!    `MAX_CANDIDATES_PER_TRIANGLE` per triangle). So a hanging or gently curved cloth's search
//!    is one pass over its triangles. (A mesh with a vertex in no triangle is searched through a
//!    spatial hash of the boxes instead.) Two elements farther apart than that cannot come
//!    within the thickness until their displacements since differ by twice the reach, and those
//!    of patches neither culled nor searched together (farther apart still, see
//!    `Patches::clear_of`) until they differ by that distance less the thickness, which each cube
//!    of the cloth keeps for the patches it holds (`Regions::limit`); a culled patch
//!    keeps its cone while each of its triangles' edges' ends move within twice the reach of each
//!    other. Each substep bounds the displacements cube by cube and block by block of cubes
//!    (`Regions`), and edge by edge where the cubes' bound exceeds twice the reach: a cloth moving
//!    as a whole keeps its candidates; one whose parts move relative to each other searches
//!    again, within a step if need be. A cloth at rest searches once, and while its particles
//!    stay within the slack the last check left, it is not checked either: one vector pass over
//!    the particles (`Watch`) shows they did.
//! 3. **Narrow phase and response, at every substep where the layers may have come closer** (at the
//!    step's last substep always; at others only once any two particles can have come [`DEFER`] of
//!    the thickness closer since the last one, so a resting fold or pile is resolved every few
//!    substeps, see `Settled`), on whatever layout the stepper keeps its particles in
//!    ([`ContactState`]): for each candidate whose distance at the broad phase, less how far its
//!    particles have since moved relative to the cloth, may have fallen to the thickness (a pile's
//!    candidates mostly have not; they are ordered by that distance, so the pass stops where none
//!    further can have, see [`Bands`]), and that a quick test does not find clear, the signed
//!    distance at the end of the substep along the pair's normal (the triangle's, for a vertex over
//!    a triangle's interior; the line between the closest points, for two edges), with its sign
//!    taken from the start of the substep. A pair closer than the thickness (two edges:
//!    [`EDGES_APART`] of it), or on the other side of each other than at the start (it passed
//!    through within the substep), is pushed apart to that distance on its starting side, each
//!    particle moved in proportion to its inverse mass and its weight in the pair (momentum is
//!    kept). Then the relative velocity's approaching normal part is removed and Coulomb friction
//!    acts on its tangential part, bounded by `friction` times the normal change (the velocity
//!    removed plus the push-out over the time since the last resolution). Passes repeat
//!    (Gauss-Seidel) over the pairs that acted in the first until none is pushed by more than
//!    [`SETTLED`] of its kept distance, at most [`PASSES`] times in all.
//!
//! Deciding the side from the start of each substep is what keeps a pile from passing through
//! itself: a proximity test alone pushes a particle that has already crossed further through. A
//! deferred resolution keeps that sound: no pair can cross while it closes by less than its kept
//! distance, and deferring stops at a share of it. Not covered: two elements that pass through each
//! other and beyond within a single substep (faster than the thickness per substep relative to each
//! other; that needs a continuous test), and more candidate pairs than the cap (a cloth crushed
//! into a ball: the search stops when a list is full, and is not run again until the next step).

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use glam::{Vec3, Vec3A};

use super::Vectors;
use super::narrow::ContactState;
use crate::sim::soa::Soa;
use patches::Patches;

mod patches;

/// Gauss-Seidel passes over the candidate pairs per substep (stopping early once no pair is
/// pushed by more than [`SETTLED`] of its kept distance).
pub(super) const PASSES: u32 = 4;

/// A later pass that pushes no pair out by more than this fraction of its kept distance is the
/// last: what is left is far below anything a crossing could come from.
pub(super) const SETTLED: f32 = 1e-3;

/// The passes after a substep's first, over the candidates `acting` that acted in it, until
/// `pair(k)` (resolving candidate `k`: how far it pushed the pair out, as a fraction of its kept
/// distance) pushes none by more than [`SETTLED`], at most [`PASSES`] in all.
pub(super) fn later_passes(acting: &[u32], mut pair: impl FnMut(usize) -> f32) {
    for _ in 1..PASSES {
        let mut moved = false;
        for &k in acting {
            moved |= pair(k as usize) > SETTLED;
        }
        if !moved {
            break;
        }
    }
}

/// The share of the thickness that two edges are kept apart. Resting layers are held the
/// thickness apart by their vertex–triangle pairs, which puts the edges of one layer that
/// thickness from the other's too: kept a little less apart, those edge pairs do not act and
/// are mostly not tested, while edges that come closer (where no vertex is over a triangle) are
/// still kept from passing through each other.
pub(super) const EDGES_APART: f32 = 0.9;

/// How much closer than at their last resolution, as a share of the thickness, any two of the
/// cloth's particles may have come before its pairs are resolved again (see [`Settled`]): a
/// resting fold or pile, whose layers approach each other by micrometres a substep, is resolved
/// every few substeps instead of every one, and no layer sinks more than this into another
/// meanwhile. Far below what a crossing needs (a pair closing by its whole kept distance).
pub(super) const DEFER: f32 = 0.25;

/// At most this many candidate pairs per triangle of the cloth (of each kind): a cloth crushed
/// into a ball smaller than the margin would otherwise have every pair of its elements as a
/// candidate. A pile of cloth needs far fewer.
pub(super) const MAX_CANDIDATES_PER_TRIANGLE: usize = 16;

/// A search's cull: the widest culled cone for a shortest triangle altitude, and how far beyond
/// twice the margin to look for uncovered elements (see [`SelfContacts::find_candidates`]).
type Cull = (fn(f32) -> f32, f32);

/// [`SelfContacts::find_candidates`] without culling.
const NO_CULL: Option<Cull> = None;

/// Share of the limit on the edges' turn up to which the near bound stands in for the edges'
/// own bound (see [`Regions::edges_closing`]): the slack that a check leaves the next ones is
/// then at least the rest.
const EDGES_SPARED: f32 = 0.25;

/// Cubes along each side of a block of `Regions`.
const BLOCK: i32 = 3;

/// Bands of distance a search's candidates are ordered into (see [`Bands`]).
const BANDS: usize = 32;

/// A vertex counts as over a triangle's interior when none of its barycentric coordinates is
/// below this (a vertex just past an edge is caught by the edge–edge pairs of that edge).
const INSIDE: f32 = -1e-3;

/// A cloth's self-contacts: its topology and exempt pairs (built once), this step's candidate
/// pairs and the scratch of the broad phase. Nothing allocates once the candidate lists have
/// grown to the largest step's size.
#[derive(Debug, Clone, Default)]
pub(crate) struct SelfContacts {
    /// Distance kept between layers, m.
    thickness: f32,
    /// Coulomb friction between layers.
    friction: f32,
    /// Triangles, by model particle.
    tris: Vec<[u32; 3]>,
    /// The unique edges, by model particle.
    edges: Vec<[u32; 2]>,
    /// The edges each triangle owns (indices into `edges`; `u32::MAX` for one owned by the
    /// triangle before it that shares it). An edge lies inside its owner's box, so the broad
    /// phase meets each edge once, through its owner.
    tri_edges: Vec<[u32; 3]>,
    /// Vertex–triangle pairs exempt (closer than the thickness at rest), as `vertex << 32 |
    /// triangle`, sorted.
    exempt_vt: Vec<u64>,
    /// Edge–edge pairs exempt, as `low << 32 | high` edge index, sorted.
    exempt_ee: Vec<u64>,
    /// The triangles in patches, whose normal cones cull the search.
    patches: Patches,
    /// Patch of each edge (that of the triangle owning it).
    edge_patch: Vec<u32>,
    /// The vertices of each patch (see `Patches::of_vertex`), its triangles and its edges.
    patch_vertices: Grouped,
    patch_triangles: Grouped,
    patch_edges: Grouped,
    /// The triangles' grown boxes in `patch_triangles`' order, and the edges' own boxes in
    /// `patch_edges`' order (scratch of the search through patch pairs).
    triangle_boxes: Vec<(Vec3A, Vec3A)>,
    edge_boxes: Vec<(Vec3A, Vec3A)>,
    /// Per patch: whether its boxes are in `triangle_boxes` and `edge_boxes` (scratch).
    boxed: Vec<bool>,
    /// Whether some vertex is in no triangle (then every search goes through the hash).
    loose: bool,
    /// The shortest altitude of a triangle at rest, m.
    altitude: f32,
    /// The spatial hash of the triangles' grown boxes.
    hash: Hash,
    /// This step's vertex–triangle candidates: (vertex, triangle).
    vt: Vec<(u32, u32)>,
    /// This step's edge–edge candidates: (edge, edge).
    ee: Vec<(u32, u32)>,
    /// Each candidate's distance when found (vertex–triangle ones, then edge–edge ones), m.
    gap: Vec<f32>,
    /// Per particle in a candidate pair (in `involved`'s order): how far it may have moved,
    /// relative to the cloth's mean motion, since the candidates were found (an upper bound;
    /// scratch of each resolution).
    drift: Vec<f32>,
    /// The stored particles that are in a candidate pair, each once, in storage order.
    involved: Vec<u32>,
    /// Per stored particle: its place in `involved` (`u32::MAX` if it is in no candidate pair;
    /// scratch of the search).
    place: Vec<u32>,
    /// Per candidate (vertex–triangle ones, then edge–edge ones): its four particles' places in
    /// `involved` (the vertex and the triangle's corners; the two edges' ends).
    quads: Vec<[u32; 4]>,
    /// The candidates of each kind (vertex–triangle, edge–edge) in bands of growing distance at
    /// the search.
    bands: [Bands; 2],
    /// Scratch of the ordering into bands: the new order, and the lists being reordered.
    order: Vec<u32>,
    reordered_pairs: Vec<(u32, u32)>,
    reordered_gaps: Vec<f32>,
    /// The particles of `involved`, copied out of the state for the narrow phase and written
    /// back after it (scratch).
    gathered: Gathered,
    /// The stored particles the last resolution moved.
    moved: Vec<u32>,
    /// Where each model particle is stored in the state being resolved.
    slot: Vec<u32>,
    /// Positions (by model particle) when the candidates were found; scratch of the search.
    found_at: Vec<Vec3>,
    /// Positions (by stored particle) when the candidates were found.
    found: Vec<Vec3>,
    /// The reach the candidates were found with, m: they hold every pair that can come within the
    /// thickness while any two particles' displacements since `found` differ by at most twice
    /// this.
    reach: f32,
    /// The reach the step was begun with.
    step_reach: f32,
    /// The edges by stored particle, as stored at the last broad phase.
    edge_slots: Vec<[u32; 2]>,
    /// The most reach a broad phase is given (see `reach_cap`).
    reach_cap: f32,
    /// Whether the candidates must be found again before the next resolution.
    stale: bool,
    /// Broad phases run so far.
    searches: u64,
    /// Substeps whose pairs were resolved so far (the others deferred theirs).
    resolutions: u64,
    /// How much closer particles in cubes of `regions` that are not neighbours (in the same or
    /// neighbouring blocks) may come before a search is due: they were at least the cubes' size
    /// apart, so the elements they belong to were at least that less twice the longest edge apart
    /// (less one edge for a vertex and a triangle).
    far_limit: f32,
    /// How much closer particles in blocks of `regions` that are not neighbours may come: as
    /// `far_limit`, for particles at least the blocks' size apart.
    wide_limit: f32,
    /// Per patch: how much closer the particles of its elements may come to those of neighbouring
    /// cubes (scratch of the search, see `Regions::limit`).
    patch_limit: Vec<f32>,
    /// The particles' patches at the last broad phase, whose motion since tells when to search
    /// again.
    regions: Regions,
    /// Where the particles were at the last check of `regions`, which lets substeps skip it.
    watch: Watch,
    /// Where the particles were at the last resolution, which lets substeps defer the next.
    settled: Settled,
    /// The candidates that acted in a substep's first pass (scratch).
    acting: Vec<u32>,
    /// Whether the next resolution is a step's first (whose stepper may store the particles in
    /// another order than the last step's).
    new_step: bool,
}

impl SelfContacts {
    /// Self-contacts of a cloth with triangles `triangles` (three model particles each) whose
    /// particles rest at `rest`, `thickness` apart with `friction` between layers.
    pub fn new(triangles: &[u32], rest: &[Vec3], thickness: f32, friction: f32) -> Self {
        let tris: Vec<[u32; 3]> = triangles
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect();
        let (mut keyed, mut edges, mut tri_edges) = (Vec::new(), Vec::new(), Vec::new());
        edge_table(&tris, &mut keyed, &mut edges, &mut tri_edges);
        let lengths = || {
            edges
                .iter()
                .map(|&[a, b]| rest[a as usize].distance(rest[b as usize]))
        };
        let shortest = lengths().fold(f32::INFINITY, f32::min);
        let longest = lengths().fold(0.0, f32::max);
        let cap = reach_cap(shortest, thickness);
        let patches = Patches::new(&tris, rest, &keyed);
        let mut edge_patch = vec![0; edges.len()];
        for (t, owned) in tri_edges.iter().enumerate() {
            for &e in owned.iter().filter(|&&e| e != u32::MAX) {
                edge_patch[e as usize] = patches.of_triangle(t as u32);
            }
        }
        let groups = patches.len();
        let patch_vertices =
            Grouped::new(groups, (0..rest.len() as u32).map(|p| patches.of_vertex(p)));
        let loose = (0..rest.len() as u32).any(|p| patches.of_vertex(p) as usize >= groups);
        let patch_edges = Grouped::new(groups, edge_patch.iter().copied());
        let patch_triangles = Grouped::new(
            groups,
            (0..tris.len() as u32).map(|t| patches.of_triangle(t)),
        );
        let altitude = tris
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| rest[i as usize]);
                let longest = a.distance(b).max(b.distance(c)).max(c.distance(a));
                (b - a).cross(c - a).length() / longest
            })
            .fold(f32::INFINITY, f32::min);
        let mut contacts = Self {
            patches,
            edge_patch,
            patch_vertices,
            patch_triangles,
            patch_edges,
            loose,
            altitude,
            thickness,
            friction,
            tris,
            edges,
            tri_edges,
            stale: true,
            reach_cap: cap,
            // Eight margins of the widest search, and at least enough that the far limit (the
            // size less two edges and the thickness) is an edge at rest: a mesh whose edges differ
            // much in length (a disc's spokes and hem) would otherwise search every substep.
            regions: Regions {
                size: (8.0 * (thickness + 2.0 * cap)).max(3.0 * longest + thickness),
                ..Regions::default()
            },
            ..Self::default()
        };
        // The pairs within the thickness at rest are exactly the candidates of a broad phase on
        // the rest positions with no motion.
        contacts.find_candidates(rest, thickness, usize::MAX, NO_CULL);
        contacts.exempt_vt = contacts.vt.iter().map(|&(p, t)| pair_key(p, t)).collect();
        contacts.exempt_ee = contacts.ee.iter().map(|&(e, f)| pair_key(e, f)).collect();
        contacts.exempt_vt.sort_unstable();
        contacts.exempt_ee.sort_unstable();
        contacts.vt.clear();
        contacts.ee.clear();
        contacts.gap.clear();
        contacts
    }

    /// The thickness and friction these contacts were built with.
    pub fn settings(&self) -> (f32, f32) {
        (self.thickness, self.friction)
    }

    /// Number of vertex–triangle and edge–edge pairs exempt because they are closer than the
    /// thickness at rest.
    #[cfg(test)]
    pub fn exempt_count(&self) -> usize {
        self.exempt_vt.len() + self.exempt_ee.len()
    }

    /// Number of candidate pairs (vertex–triangle, edge–edge) the last broad phase found.
    pub fn candidate_count(&self) -> (usize, usize) {
        (self.vt.len(), self.ee.len())
    }

    /// The stored particles the last [`Self::resolve`] moved.
    pub fn moved(&self) -> &[u32] {
        &self.moved
    }

    /// Number of broad phases run so far.
    pub fn searches(&self) -> u64 {
        self.searches
    }

    /// Number of substeps whose pairs were resolved so far (see [`DEFER`]).
    pub fn resolutions(&self) -> u64 {
        self.resolutions
    }

    /// The most candidates a search lists of each kind.
    fn cap(&self) -> usize {
        MAX_CANDIDATES_PER_TRIANGLE * self.tris.len()
    }

    /// Whether the last search filled a list to its cap.
    fn full(&self) -> bool {
        let cap = self.cap();
        self.vt.len() >= cap || self.ee.len() >= cap
    }

    /// The layers' spacing and friction.
    fn spacing(&self) -> Spacing {
        Spacing {
            thickness: self.thickness,
            friction: self.friction,
        }
    }

    /// Starts a step in which no particle is expected to move farther than `reach` (m) relative to
    /// the cloth's mean motion: candidates found in this step get that reach, at most
    /// `reach_cap`'s (a fast cloth finds them again within the step rather than gathering every
    /// pair in reach of a whole step's motion). Candidates found in an earlier step are kept as
    /// long as the particles stay within their reach, so a cloth at rest finds them only once.
    pub fn begin_step(&mut self, reach: f32) {
        self.step_reach = if reach.is_finite() {
            reach.clamp(0.0, self.reach_cap)
        } else {
            self.reach_cap
        };
        self.new_step = true;
        self.settled.order_checked = false;
    }

    /// The narrow phase and response at the end of a substep of length `h` (see the module docs),
    /// or nothing while no two particles can have come [`DEFER`] of the thickness closer since
    /// the last resolution, unless the substep is the step's `last` (every step ends resolved).
    /// Returns whether any particle moved.
    pub fn resolve<S: ContactState>(&mut self, (h, last): (f32, bool), state: &mut S) -> bool {
        self.moved.clear();
        if self.tris.is_empty() {
            return false;
        }
        if self.new_step && !self.settled.order_checked {
            // A stepper may store the particles in another order from one step to the next.
            self.settled.order_checked = true;
            if order_changed(state, &self.slot) {
                self.stale = true;
                self.settled.forget();
            }
        }
        let deferred = self.settled.deferred;
        let slack = DEFER * self.thickness;
        if !last && self.settled.holds(state, |r, _| 2.0 * r <= slack) {
            self.regions.skip();
            return false;
        }
        self.resolutions += 1;
        let any = self.resolve_now(h * (deferred + 1) as f32, state);
        self.settled.forget();
        // A cloth with no candidates (hanging, or flat) has nothing to defer.
        self.settled.due = !(self.vt.is_empty() && self.ee.is_empty());
        any
    }

    /// Ends a substep's contacts: after a resolution, once the colliders have had their last
    /// word, keeps the positions that the next substeps' motion is measured from (taken before
    /// the colliders, a layer pushed into the floor and back would count as motion).
    pub fn end_substep<S: ContactState>(&mut self, state: &S) {
        if std::mem::take(&mut self.settled.due) {
            self.settled.take(state);
        }
    }

    /// [`Self::resolve`] at this substep of length `h`: every candidate that may have come within
    /// its kept distance.
    fn resolve_now<S: ContactState>(&mut self, h: f32, state: &mut S) -> bool {
        let mean = self.refresh_candidates(state);
        if self.vt.is_empty() && self.ee.is_empty() {
            return false;
        }
        let inv_h = if h > 0.0 { 1.0 / h } else { 0.0 };
        let mut drift = std::mem::take(&mut self.drift);
        let mut gathered = std::mem::take(&mut self.gathered);
        gathered.read(state, &self.involved);
        self.measure_drift(&gathered, mean, &mut drift);
        // The narrow phase reads and writes the pairs' particles in one place (they are few and
        // each is in many pairs), then the ones it moved go back.
        let mut local = gathered.state();
        // The first pass tests the candidates that may have come within the thickness since they
        // were found; the later ones only those that acted in it (in a pile most candidates are
        // near but never act).
        let mut acting = std::mem::take(&mut self.acting);
        acting.clear();
        // A candidate's elements came closer by at most twice the largest drift.
        let mut closing = 2.0 * drift.iter().copied().fold(0.0, max_or_infinite);
        for bands in &self.bands {
            closing = bands.visit(closing, |k| {
                if !(self.may_touch(k, &drift) && self.pair(&mut local, k, inv_h, &mut drift) > 0.0)
                {
                    return 0.0;
                }
                acting.push(k as u32);
                let [a, b, c, d] = four(self.quads[k], |i| drift[i as usize]);
                a.max(b).max(c).max(d)
            });
        }
        later_passes(&acting, |k| self.pair(&mut local, k, inv_h, &mut drift));
        let any = !acting.is_empty();
        if any {
            gathered.write(state, &self.involved, &mut self.moved);
        }
        self.gathered = gathered;
        self.acting = acting;
        self.drift = drift;
        any
    }

    /// Fills `drift` (in `involved`'s order) with each particle's largest distance, at the start
    /// or the end of the substep, from where it was when the candidates were found, the cloth's
    /// mean displacement `(start, end)` of the substep taken off. Along the substep's straight
    /// paths no particle is farther than that, so two elements have come closer than at the
    /// broad phase by at most the sum of their particles' largest drifts.
    fn measure_drift(&self, gathered: &Gathered, (m0, m1): (Vec3, Vec3), drift: &mut Vec<f32>) {
        drift.clear();
        drift.extend(
            (self.involved.iter().zip(&gathered.start).zip(&gathered.x)).map(|((&s, x0), x1)| {
                let found = self.found[s as usize];
                let d0 = (*x0 - found - m0).length();
                let d1 = (*x1 - found - m1).length();
                // NaN stays infinite: such a particle is always tested.
                if d0.is_nan() || d1.is_nan() {
                    f32::INFINITY
                } else {
                    d0.max(d1)
                }
            }),
        );
    }

    /// Whether candidate `k`'s elements may have come within their kept distance since they were
    /// found: its distance then less the most its two elements' particles have drifted.
    fn may_touch(&self, k: usize, drift: &[f32]) -> bool {
        let [a, b, c, d] = four(self.quads[k], |i| drift[i as usize]);
        let closing = if k < self.vt.len() {
            a + b.max(c).max(d)
        } else {
            a.max(b) + c.max(d)
        };
        self.gap[k] - closing <= self.spacing().kept(k < self.vt.len())
    }

    /// Resolves candidate `k` on the gathered particles `state`: vertex–triangle pairs first, then
    /// edge–edge pairs. Returns how far it pushed the pair out, as a fraction of its kept
    /// distance (0: nothing moved); adds what it moved each particle to `drift`.
    fn pair(&self, state: &mut Vectors, k: usize, inv_h: f32, drift: &mut [f32]) -> f32 {
        let quad = four(self.quads[k], |i| i as usize);
        if k < self.vt.len() {
            self.spacing().vertex_triangle(state, quad, inv_h, drift)
        } else {
            self.spacing().edge_edge(state, quad, inv_h, drift)
        }
    }

    /// Finds the candidates at the step's first resolution, or again when a particle has moved
    /// farther than the reach since they were found. Returns the particles' mean displacement
    /// since then, at the start and at the end of the substep.
    fn refresh_candidates<S: ContactState>(&mut self, state: &S) -> (Vec3, Vec3) {
        let n = state.len();
        // The order of the stored particles was checked at this step's first resolution.
        let new_step = std::mem::take(&mut self.new_step);
        if !self.stale {
            if let Some(mean) = self.watch.unchanged(state) {
                self.regions.skip();
                return mean;
            }
            let turn_limit = 2.0 * self.reach;
            // The near bound stands in for the edges' own up to `EDGES_SPARED` of twice the
            // reach: worked out pair by pair above that.
            let limits = (EDGES_SPARED * turn_limit, self.far_limit);
            let closing = self.regions.closing(state, &self.found, limits);
            if closing.slack >= 0.0
                && closing.mid <= self.far_limit
                && closing.far <= self.wide_limit
            {
                // An edge's ends lie in the same or neighbouring cubes: within the near bound.
                // The edges' own bound is much smaller where the cloth bends: worked out unless
                // the near bound leaves most of the limit to spare for the next checks.
                let turning = if closing.near <= EDGES_SPARED * turn_limit {
                    closing.near
                } else {
                    self.regions.edges_closing(&self.edge_slots)
                };
                if turning <= turn_limit {
                    let slack = closing
                        .slack
                        .min(self.far_limit - closing.mid)
                        .min(self.wide_limit - closing.far)
                        .min(turn_limit - turning);
                    self.watch.take(state, slack, closing.mean);
                    return closing.mean;
                }
            }
            // A full list holds an arbitrary share of the close pairs (a cloth crushed into a
            // ball): searching again within the step would only pick another share, at the
            // cost of a search per substep. The next step's first substep searches.
            if self.full() && !new_step {
                self.watch.valid = false;
                return closing.mean;
            }
        }
        self.watch.valid = false;
        self.slot.clear();
        self.slot
            .extend((0..n as u32).map(|p| state.slot(p) as u32));
        self.found_at.clear();
        self.found_at
            .extend(self.slot.iter().map(|&s| state.start(s as usize)));
        // Found at the substep's start, the candidates must also cover where it ends. A cloth
        // whose parts moved farther apart than the cap within this one substep gets its
        // candidates where the substep ends instead: the pairs within the thickness there, on
        // the wrong side or not, are still found and put right; a pair that passed through
        // each other and far beyond within one substep is not (that needs a continuous test).
        let moved = spread(n, |p| {
            state.position(self.slot[p] as usize) - self.found_at[p]
        });
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
        let longest = self
            .edges
            .iter()
            .map(|&[a, b]| positions[a as usize].distance(positions[b as usize]))
            .fold(0.0, max_or_infinite);
        // Two elements' particles lie within a side of their closest points each: two particles
        // that were not in neighbouring cubes (at least the cubes' size apart) belong to
        // elements that were at least that less two sides apart.
        self.far_limit = self.regions.size - 2.0 * longest - self.thickness;
        self.wide_limit = BLOCK as f32 * self.regions.size - 2.0 * longest - self.thickness;
        let margin = self.thickness + 2.0 * self.reach;
        // Uncovered elements farther apart than the far limit allows are of no use to the near
        // limit: the far bound, which is at least the near one, would ask for a search first.
        let out = self.far_limit + self.thickness - 2.0 * margin;
        self.find_candidates(&positions, margin, cap, Some((self.cull(), out)));
        self.edge_slots.clear();
        self.edge_slots
            .extend(self.edges.iter().map(|e| e.map(|p| self.slot[p as usize])));
        self.regions.assign(&positions, &self.slot);
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
        self.regions.limit(&self.slot, |p| {
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
    fn list_involved(&mut self) {
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

    /// Orders the candidates of each kind into bands of distance (see [`Bands`]), the distances
    /// found being below `margin`.
    fn order_by_gap(&mut self, margin: f32) {
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
    fn cull(&self) -> impl Fn(f32) -> f32 + use<> {
        let (reach, rest) = (self.reach, self.altitude);
        move |h| cull_angle(reach, rest.min(h))
    }

    /// The broad phase on `x` (by model particle): every vertex–triangle and edge–edge pair that
    /// shares no vertex, is not exempt, and is closer than `margin`, up to `cap` of each kind;
    /// with `cull` (`flat`, `out`), none between patches within one direction by the angle `flat`
    /// gives for their shortest triangle altitude at `x` (see [`patches`]), the patches' uncovered
    /// distance being looked for up to `out` beyond twice the margin (`Patches::clear_of`).
    fn find_candidates(
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
                    || is_exempt(&self.exempt_vt, pair_key(p, t))
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
                        || is_exempt(&self.exempt_ee, pair_key(e, f))
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
    fn pair_patches(&mut self, x: &[Vec3], margin: f32, cap: usize) {
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
                        if tri.contains(&p) || is_exempt(&self.exempt_vt, pair_key(p, t)) {
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
                        || is_exempt(&self.exempt_ee, key)
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

/// Items grouped by patch: those of patch `p` are `items[start[p]..start[p + 1]]`.
#[derive(Debug, Clone, Default)]
struct Grouped {
    start: Vec<u32>,
    items: Vec<u32>,
}

impl Grouped {
    /// Items `0..` grouped by `group` (of each item in order; one not below `groups` in none).
    fn new(groups: usize, group: impl Iterator<Item = u32> + Clone) -> Self {
        let mut grouped = Self::default();
        grouped.regroup(groups, group);
        grouped
    }

    /// [`Self::new`] in place, keeping the allocations.
    fn regroup(&mut self, groups: usize, group: impl Iterator<Item = u32> + Clone) {
        let (start, items) = (&mut self.start, &mut self.items);
        start.clear();
        start.resize(groups + 1, 0);
        for g in group.clone().filter(|&g| (g as usize) < groups) {
            start[g as usize + 1] += 1;
        }
        for g in 0..groups {
            start[g + 1] += start[g];
        }
        items.clear();
        items.resize(start[groups] as usize, 0);
        // Each group's start moves on as its items are placed, ending where the next begins;
        // then every start goes back one group.
        for (i, g) in group.enumerate().filter(|&(_, g)| (g as usize) < groups) {
            items[start[g as usize] as usize] = i as u32;
            start[g as usize] += 1;
        }
        start.copy_within(0..groups, 1);
        start[0] = 0;
    }

    /// The items of group `g`.
    fn of(&self, g: u32) -> &[u32] {
        &self.items[self.range(g)]
    }

    /// Where group `g`'s items are in `items`.
    fn range(&self, g: u32) -> std::ops::Range<usize> {
        self.start[g as usize] as usize..self.start[g as usize + 1] as usize
    }
}

/// How far apart a pair of layers is kept and the friction between them: the response to one
/// vertex–triangle or edge–edge pair, shared by a cloth's contacts with itself and with other
/// cloths.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Spacing {
    /// Distance kept between the layers, m.
    pub thickness: f32,
    /// Coulomb friction between them.
    pub friction: f32,
}

impl Spacing {
    /// How far apart a pair is kept, m: a vertex from a triangle (`vertex`) the thickness, two
    /// edges [`EDGES_APART`] of it.
    #[inline(always)]
    pub(super) fn kept(&self, vertex: bool) -> f32 {
        if vertex {
            self.thickness
        } else {
            EDGES_APART * self.thickness
        }
    }

    /// Whether edge–edge pair `s` is clear on a quick test (most tested pairs are): edges on
    /// lines at least their kept distance ([`Self::kept`]) apart (not nearly parallel, where that
    /// distance is lost to rounding), or with boxes that far apart, are at least that apart; if
    /// their ends also moved less than half of it in the substep, the gap between their closest
    /// points differs from its start by less than its length, so it did not turn, and
    /// [`Self::edge_edge`] leaves them alone. Decided without the closest points.
    #[inline(always)]
    fn edge_edge_clear<S: ContactState>(&self, state: &S, s: [usize; 4]) -> bool {
        let [a, b, c, d] = four(s, |i| state.position(i));
        let [a0, b0, c0, d0] = four(s, |i| state.start(i));
        let kept = self.kept(false);
        let kept2 = kept * kept;
        let (ab, cd) = (b - a, d - c);
        let across = ab.cross(cd);
        let apart = (a - c).dot(across);
        let [ma, mb, mc, md] = four([a - a0, b - b0, c - c0, d - d0], Vec3::length_squared);
        let moved = ma.max(mb).max(mc).max(md);
        let across2 = across.length_squared();
        let lines_apart = across2 > 1e-4 * ab.length_squared() * cd.length_squared()
            && apart * apart >= kept2 * across2;
        // The distance between the edges' boxes is a lower bound too.
        let boxes = (c.min(d) - a.max(b))
            .max(a.min(b) - c.max(d))
            .max(Vec3::ZERO);
        (lines_apart || boxes.length_squared() >= kept2) && 4.0 * moved < kept2
    }

    /// Keeps vertex `s[0]` at least the thickness from triangle `s[1..]` on the side it started
    /// the substep on, when it is over the triangle's interior. Returns how far it pushed the
    /// pair out, as a fraction of the thickness (0: nothing moved).
    pub(super) fn vertex_triangle<S: ContactState>(
        &self,
        state: &mut S,
        s: [usize; 4],
        inv_h: f32,
        drift: &mut [f32],
    ) -> f32 {
        let over = Over::of(state, s);
        if over.clear(self.thickness) {
            return 0.0;
        }
        let w = four(s, |i| state.inv_mass(i));
        if w == [0.0; 4] || !(over.area2 > 0.0 && over.area2.is_finite()) {
            return 0.0;
        }
        // Not clear, so over the interior: the coordinates are all at least `INSIDE`.
        let inv_length = over.area2.sqrt().recip();
        let (n, dist) = (over.area * inv_length, over.above * inv_length);
        let [u, v, t] = over.scaled;
        let [u, v, t] = [u / over.area2, v / over.area2, t / over.area2];
        // The side it started on: that of the start's plane, through the start triangle (a
        // degenerate one has none; then the side it ends on).
        let side = if over.area0_2 > 0.0 {
            if over.above0 >= 0.0 { 1.0 } else { -1.0 }
        } else {
            dist.signum()
        };
        let weights = [1.0, -u, -v, -t];
        let apart = (side * n, side * dist, self.kept(true));
        self.separate(state, s, (w, weights), apart, inv_h, drift)
    }

    /// Keeps edge `s[0..2]` at least [`EDGES_APART`] of the thickness from edge `s[2..]` on the
    /// side it started the substep on. Returns how far it pushed the pair out, as a fraction of
    /// that distance (0: nothing moved).
    pub(super) fn edge_edge<S: ContactState>(
        &self,
        state: &mut S,
        s: [usize; 4],
        inv_h: f32,
        drift: &mut [f32],
    ) -> f32 {
        if self.edge_edge_clear(state, s) {
            return 0.0;
        }
        let w = four(s, |i| state.inv_mass(i));
        if w == [0.0; 4] {
            return 0.0;
        }
        let [a, b, c, d] = four(s, |i| state.position(i));
        let [a0, b0, c0, d0] = four(s, |i| state.start(i));
        let kept = self.kept(false);
        let (u, t) = closest_on_segments(a, b, c, d);
        let gap = a.lerp(b, u) - c.lerp(d, t);
        let gap0 = a0.lerp(b0, u) - c0.lerp(d0, t);
        // Otherwise clear pairs are decided without the square root.
        if gap.length_squared() >= kept * kept && gap.dot(gap0) >= 0.0 {
            return 0.0;
        }
        let length = gap.length();
        // The direction apart: the gap's, turned to the starting side; the start's if the gap
        // has closed to nothing.
        let (n, dist) = if length > 1e-9 {
            let side = if gap.dot(gap0) >= 0.0 { 1.0 } else { -1.0 };
            (gap * (side / length), side * length)
        } else {
            match gap0.try_normalize() {
                Some(n0) => (n0, gap.dot(n0)),
                None => return 0.0,
            }
        };
        let weights = [1.0 - u, u, t - 1.0, -t];
        let apart = (n, dist, kept);
        self.separate(state, s, (w, weights), apart, inv_h, drift)
    }

    /// The response to one pair: the combination `Σ weights[k] x[s[k]]` is `dist` along `n`;
    /// pushes it out to `kept`, then removes its approaching velocity along `n` and applies
    /// friction to its tangential velocity. `w` are the particles' inverse masses. Returns the
    /// push as a fraction of `kept` (0: nothing moved).
    fn separate<S: ContactState>(
        &self,
        state: &mut S,
        s: [usize; 4],
        (w, weights): ([f32; 4], [f32; 4]),
        (n, dist, kept): (Vec3, f32, f32),
        inv_h: f32,
        drift: &mut [f32],
    ) -> f32 {
        let depth = kept - dist;
        if depth.is_nan() || depth <= 0.0 {
            return 0.0;
        }
        let effective: f32 = (0..4).map(|k| weights[k] * weights[k] * w[k]).sum();
        if effective.is_nan() || effective <= 1e-12 {
            return 0.0;
        }
        let push = depth / effective;
        let v = four(s, |i| state.velocity(i));
        let relative: Vec3 = (0..4).map(|k| weights[k] * v[k]).sum();
        let normal = relative.dot(n);
        // The normal change in velocity units: the approach removed plus the push-out per substep.
        let removed = (-normal).max(0.0);
        let normal_change = removed + depth * inv_h;
        let tangential = relative - normal * n;
        let slide = tangential.length();
        let stop = if slide > 0.0 {
            (self.friction * normal_change).min(slide) / slide
        } else {
            0.0
        };
        // Velocity change of the pair's combination, spread like the push.
        let dv = removed * n - stop * tangential;
        let x = four(s, |i| state.position(i));
        for k in 0..4 {
            let g = weights[k] * w[k];
            if g == 0.0 {
                continue;
            }
            let scale = g / effective;
            state.set(s[k], x[k] + (push * g) * n, v[k] + scale * dv);
            drift[s[k]] += (push * g).abs();
        }
        depth / kept
    }
}

/// A vertex over a triangle (a vertex–triangle pair) at the end and the start of a substep,
/// nothing normalised: the triangle's area vector (its normal times twice its area), the
/// vertex's height over its plane times that area, and its barycentric coordinates in the plane
/// times the squared area.
struct Over {
    area: Vec3,
    area2: f32,
    above: f32,
    scaled: [f32; 3],
    /// The same at the start (the area vector's squared length, the height).
    area0_2: f32,
    above0: f32,
}

impl Over {
    /// Pair `s` (the vertex, then the triangle's corners) of `state`.
    #[inline(always)]
    fn of<S: ContactState>(state: &S, s: [usize; 4]) -> Self {
        let [p, a, b, c] = four(s, |i| state.position(i));
        let [p0, a0, b0, c0] = four(s, |i| state.start(i));
        let area = (b - a).cross(c - a);
        let area0 = (b0 - a0).cross(c0 - a0);
        Self {
            area,
            area2: area.length_squared(),
            above: (p - a).dot(area),
            scaled: [
                (c - b).cross(p - b).dot(area),
                (a - c).cross(p - c).dot(area),
                (b - a).cross(p - a).dot(area),
            ],
            area0_2: area0.length_squared(),
            above0: (p0 - a0).dot(area0),
        }
    }

    /// Whether the vertex is clear of the triangle at `thickness`: not over its interior, or at
    /// least the thickness from its plane on the side it started the substep on (the side of
    /// the start's plane, on which every point of the start triangle lies).
    #[inline(always)]
    fn clear(&self, thickness: f32) -> bool {
        let outside = INSIDE * self.area2;
        let [u, v, t] = self.scaled;
        (self.above * self.above0 > 0.0
            && self.above * self.above >= thickness * thickness * self.area2)
            || u < outside
            || v < outside
            || t < outside
    }
}

/// Copies of some particles of a [`ContactState`] (each one's start, position, velocity and
/// inverse mass), for a narrow phase that visits each many times.
#[derive(Debug, Clone, Default)]
pub(super) struct Gathered {
    start: Vec<Vec3>,
    x: Vec<Vec3>,
    v: Vec<Vec3>,
    inv_mass: Vec<f32>,
}

impl Gathered {
    /// Copies the stored particles `which` out of `state`.
    pub(super) fn read<S: ContactState>(&mut self, state: &S, which: &[u32]) {
        let at = which.iter().map(|&s| s as usize);
        self.start.clear();
        self.start.extend(at.clone().map(|s| state.start(s)));
        self.x.clear();
        self.x.extend(at.clone().map(|s| state.position(s)));
        self.v.clear();
        self.v.extend(at.clone().map(|s| state.velocity(s)));
        self.inv_mass.clear();
        self.inv_mass.extend(at.map(|s| state.inv_mass(s)));
    }

    /// The copies as a state of their own (particle `k` is `which[k]` of [`Self::read`]).
    pub(super) fn state(&mut self) -> Vectors<'_> {
        Vectors {
            x: &mut self.x,
            v: &mut self.v,
            start: &self.start,
            inv_mass: &self.inv_mass,
            touches: None,
        }
    }

    /// Writes back into `state` the particles of `which` (as read) whose copies changed, and lists
    /// them in `moved`.
    pub(super) fn write<S: ContactState>(
        &self,
        state: &mut S,
        which: &[u32],
        moved: &mut Vec<u32>,
    ) {
        moved.clear();
        for ((&s, x), v) in which.iter().zip(&self.x).zip(&self.v) {
            let s = s as usize;
            // Bit for bit, so that a particle that is not a number is not written back.
            let same =
                |a: Vec3, b: Vec3| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits);
            if !same(*x, state.position(s)) || !same(*v, state.velocity(s)) {
                state.set(s, *x, *v);
                moved.push(s as u32);
            }
        }
    }
}

/// Where the particles were at the last check of the cubes ([`Regions::closing`]) that found the
/// candidates still good, and how much closer two particles could still come then. Two particles'
/// displacements since then differ by at most twice the largest distance of one from any common
/// vector, so while that stays within the slack the check would still pass and is skipped: one
/// vector pass over the particles instead of the cubes' gather and scatter. A cloth at rest pays
/// only that pass.
#[derive(Debug, Clone, Default)]
struct Watch {
    /// Each stored particle's position at the check.
    at: Soa,
    /// The particles' mean displacement since the broad phase, at the check.
    mean: Vec3,
    /// How much closer particles could still come, at the check, before a search is due.
    slack: f32,
    /// The common displacement since the check expected at the next substep (any vector keeps
    /// the bound valid; this one keeps it small).
    guess: Vec3,
    /// Whether `at` holds a check's positions that the candidates are still good for.
    valid: bool,
}

impl Watch {
    /// Keeps `state`'s positions after a check that passed with `slack` to spare, when the
    /// particles' mean displacement since the broad phase was `mean` (at the substep's start, at
    /// its end).
    fn take<S: ContactState>(&mut self, state: &S, slack: f32, (m0, m1): (Vec3, Vec3)) {
        state.ends(&mut self.at);
        self.mean = m1;
        self.slack = slack;
        self.guess = m1 - m0;
        self.valid = true;
    }

    /// The particles' mean displacement since the broad phase, at the substep's start and end, if
    /// no two particles can have come closer since the check than its slack allows.
    fn unchanged<S: ContactState>(&mut self, state: &S) -> Option<(Vec3, Vec3)> {
        let n = state.len();
        if !self.valid || self.at.len() != n || n == 0 {
            return None;
        }
        let since = state.since(&self.at, self.guess);
        let (moved, step) = (since.moved / n as f32, since.step / n as f32);
        // The next substep is expected to move like this one.
        self.guess = moved + step;
        // False for NaN (`worst` is infinite then).
        if 2.0 * since.worst.sqrt() <= self.slack {
            let m1 = self.mean + moved;
            Some((m1 - step, m1))
        } else {
            self.valid = false;
            None
        }
    }
}

/// Whether `state` stores the particles in another order than `slot` (where each was stored).
pub(super) fn order_changed<S: ContactState>(state: &S, slot: &[u32]) -> bool {
    slot.len() != state.len()
        || (slot.iter().enumerate()).any(|(p, &s)| state.slot(p as u32) != s as usize)
}

/// Where a cloth's particles were when its pairs were last resolved (each then at least its kept
/// distance apart, or being pushed there), and the substeps deferred since: while no pair can have
/// crossed or come more than [`DEFER`] of its kept distance closer since, a substep's resolution
/// is deferred, for one vector pass over the particles. Every displacement since lies within a
/// distance `r` of a common vector `c`, so two of the cloth's particles have come at most `2 r`
/// closer, and one of them and a point that moved by `e` at most `r + |c| + e`.
#[derive(Debug, Clone, Default)]
pub(super) struct Settled {
    /// Each stored particle's position at the last resolution.
    at: Soa,
    /// The common displacement since then expected at the next substep.
    guess: Vec3,
    /// Whether `at` holds the last resolution's positions in the state's current order.
    valid: bool,
    /// Whether this step's storage order has been compared with the last one's.
    order_checked: bool,
    /// Substeps deferred since the last resolution.
    pub deferred: u32,
    /// Whether this substep resolved the pairs and its end is to be taken.
    pub due: bool,
}

impl Settled {
    /// Keeps `state`'s positions after a resolution.
    pub fn take<S: ContactState>(&mut self, state: &S) {
        state.ends(&mut self.at);
        self.guess = Vec3::ZERO;
        self.valid = true;
        self.deferred = 0;
    }

    /// No resolution to defer from.
    pub fn forget(&mut self) {
        self.valid = false;
        self.deferred = 0;
    }

    /// Whether `within(r, c)` holds for the particles of `state` since the last resolution (see
    /// the type's docs); then the substep is counted as deferred. False without a snapshot, or
    /// if a displacement is not finite.
    pub fn holds<S: ContactState>(
        &mut self,
        state: &S,
        within: impl FnOnce(f32, Vec3) -> bool,
    ) -> bool {
        let n = state.len();
        if !self.valid || self.at.len() != n || n == 0 {
            return false;
        }
        let c = self.guess;
        let since = state.since(&self.at, c);
        // The next substep is expected to move like this one.
        self.guess = (since.moved + since.step) / n as f32;
        // `worst` is infinite for a displacement that is not finite.
        let holds = since.worst.is_finite() && within(since.worst.sqrt(), c);
        if holds {
            self.deferred += 1;
        }
        holds
    }
}

/// The particles grouped into cubes of side `size` by where they were at the last broad phase, and
/// the cubes into blocks of [`BLOCK`]³ cubes. Two particles that were closer than `size` then lie
/// in the same or neighbouring cubes, and two closer than `BLOCK` times that in the same or
/// neighbouring blocks; the displacements since then, compared cube by cube and block by block,
/// bound how much closer any two elements can have come: a cloth that swings or falls as a whole,
/// however fast, moves little within and between neighbouring cubes and need not search again.
#[derive(Debug, Clone, Default)]
struct Regions {
    /// Side of the cubes, m (at least the broad phase's margin).
    size: f32,
    /// Each stored particle's cube.
    of: Vec<u32>,
    /// Particles per cube.
    count: Vec<u32>,
    /// Pairs of neighbouring cubes (a cube with itself too), `a <= b`.
    pairs: Vec<(u32, u32)>,
    /// Per cube: how much closer one of its particles and one of a neighbouring cube may come
    /// before a search is due (a pair of cubes takes the larger of their two limits; set after
    /// [`Self::assign`], see [`Self::limit`]).
    limit: Vec<f32>,
    /// The least and the largest of `limit`.
    least: f32,
    most: f32,
    /// Cube index of each occupied cell.
    index: HashMap<[i32; 3], u32, BuildHasherDefault<CellHasher>>,
    /// Each cube's cell.
    cell: Vec<[i32; 3]>,
    /// Each cube's block.
    block: Vec<u32>,
    /// The cubes of each block.
    block_cubes: Grouped,
    /// Scratch of [`neighbours`].
    dense: Vec<u32>,
    /// Pairs of neighbouring blocks (a block with itself too), `a <= b`.
    block_pairs: Vec<(u32, u32)>,
    /// Block index of each occupied block cell (scratch of [`Self::assign`]).
    block_index: HashMap<[i32; 3], u32, BuildHasherDefault<CellHasher>>,
    /// Per block: a displacement (the mean of its cubes' references) and the largest distance
    /// of one of its particles' displacements from it (scratch).
    block_reference: Vec<(Vec3, u32)>,
    block_deviation: Vec<f32>,
    /// Per cube: the displacement its particles' displacements are measured from (any point
    /// would do; the cube's mean displacement extrapolated from the last two
    /// [`Self::closing`]s keeps the deviations small).
    reference: Vec<Vec3>,
    /// Per cube: its mean displacement at the last [`Self::closing`].
    last_mean: Vec<Vec3>,
    /// Whether no [`Self::closing`] has run since [`Self::assign`] (the references are unknown).
    fresh: bool,
    /// Substeps skipped since the last [`Self::closing`] (see [`Self::skip`]).
    skipped: u32,
    /// Per cube: sum of displacements (scratch).
    sum: Vec<Vec3A>,
    /// Per cube: largest distance of a displacement from the cube's reference (scratch).
    deviation: Vec<f32>,
    /// Per stored particle: its displacement since [`Self::assign`] at the last
    /// [`Self::closing`].
    moved: Vec<Vec3A>,
}

/// What [`Regions::closing`] found.
struct Closing {
    /// How much closer two particles of the same or neighbouring cubes can have come.
    near: f32,
    /// How much closer still two such particles may come before their cubes' limit (see
    /// [`Regions::limit`]); negative once one pair has passed it.
    slack: f32,
    /// How much closer two particles of cubes that are not neighbours, in the same or
    /// neighbouring blocks, can have come, less a cube's side for each cube between them beyond
    /// the first (they were farther apart by as much).
    mid: f32,
    /// How much closer any two particles can have come.
    far: f32,
    /// The particles' mean displacement at the start and at the end of the substep.
    mean: (Vec3, Vec3),
}

impl Regions {
    /// Groups the particles at `x` (by model particle, stored at `slot`) into cubes.
    fn assign(&mut self, x: &[Vec3], slot: &[u32]) {
        let inv = 1.0 / self.size;
        self.index.clear();
        self.of.clear();
        self.of.resize(x.len(), 0);
        self.count.clear();
        // Neighbours along the mesh mostly share a cube: the last one is looked up first.
        let mut last: Option<([i32; 3], u32)> = None;
        for (p, &s) in x.iter().zip(slot) {
            let cell = cell_of(*p, inv);
            let r = match last {
                Some((c, r)) if c == cell => r,
                _ => {
                    let next = self.index.len() as u32;
                    let r = *self.index.entry(cell).or_insert(next);
                    if r == next {
                        self.count.push(0);
                    }
                    last = Some((cell, r));
                    r
                }
            };
            self.count[r as usize] += 1;
            self.of[s as usize] = r;
        }
        neighbours(&self.index, &mut self.pairs, &mut self.dense);
        let cubes = self.count.len();
        self.limit.clear();
        self.limit.resize(cubes, 0.0);
        (self.least, self.most) = (0.0, 0.0);
        self.block_index.clear();
        self.block.clear();
        self.block.resize(cubes, 0);
        self.cell.resize(cubes, [0; 3]);
        for (cell, &a) in &self.index {
            let next = self.block_index.len() as u32;
            let block = cell.map(|c| c.div_euclid(BLOCK));
            self.block[a as usize] = *self.block_index.entry(block).or_insert(next);
            self.cell[a as usize] = *cell;
        }
        self.block_cubes
            .regroup(self.block_index.len(), self.block.iter().copied());
        neighbours(&self.block_index, &mut self.block_pairs, &mut self.dense);
        self.block_reference
            .resize(self.block_index.len(), (Vec3::ZERO, 0));
        self.block_deviation.resize(self.block_index.len(), 0.0);
        self.reference.resize(cubes, Vec3::ZERO);
        self.last_mean.resize(cubes, Vec3::ZERO);
        self.fresh = true;
        self.skipped = 0;
        self.sum.resize(cubes, Vec3A::ZERO);
        self.deviation.resize(cubes, 0.0);
    }

    /// Sets each cube's limit to the least `of_particle(p)` of the model particles `p` (stored at
    /// `slot`) in it. Where that is the least limit of the patches with a triangle corner at `p`
    /// (see [`SelfContacts::refresh_candidates`]), two particles of neighbouring cubes may come
    /// closer by the larger of their cubes' limits: an element with a particle in a cube belongs
    /// to one of those patches, and the pair of elements is within both limits.
    fn limit(&mut self, slot: &[u32], of_particle: impl Fn(usize) -> f32) {
        self.limit.clear();
        self.limit.resize(self.count.len(), f32::INFINITY);
        for (p, &s) in slot.iter().enumerate() {
            let cube = &mut self.limit[self.of[s as usize] as usize];
            *cube = cube.min(of_particle(p));
        }
        let (least, most) =
            (self.limit.iter()).fold((f32::INFINITY, 0.0f32), |(l, m), &c| (l.min(c), m.max(c)));
        (self.least, self.most) = (least, most);
    }

    /// The bound of [`Closing::mid`] from each pair of cubes in the same or neighbouring blocks
    /// that are not neighbours.
    fn cubes_apart(&self) -> f32 {
        let (cubes, cell) = (&self.block_cubes, &self.cell);
        let mut worst = 0.0;
        for &(ba, bb) in &self.block_pairs {
            for &a in cubes.of(ba) {
                let (ra, da, ca) = (
                    self.reference[a as usize],
                    self.deviation[a as usize],
                    cell[a as usize],
                );
                for &b in cubes.of(bb).iter().filter(|&&b| ba != bb || b > a) {
                    let cb = cell[b as usize];
                    let cells = (0..3).map(|k| (ca[k] - cb[k]).abs()).max().unwrap_or(0);
                    if cells <= 1 {
                        continue;
                    }
                    // Particles `cells` cubes apart were more than `cells - 1` sides apart: the
                    // limit for two cubes apart is exceeded where the bound less the sides
                    // beyond those exceeds it.
                    let beyond = (cells - 2) as f32 * self.size;
                    let bound =
                        da + self.deviation[b as usize] + ra.distance(self.reference[b as usize])
                            - beyond;
                    worst = max_or_infinite(worst, bound);
                }
            }
        }
        worst
    }

    /// Each cube's sum of [`Self::moved`] and the largest distance of one from its reference (a
    /// NaN is lost to the maximum but kept by the sum).
    fn scatter(&mut self) {
        self.sum.fill(Vec3A::ZERO);
        self.deviation.fill(0.0);
        let (sum, deviation, reference) = (&mut self.sum, &mut self.deviation, &self.reference);
        for (d, &r) in self.moved.iter().zip(&self.of) {
            let r = r as usize;
            sum[r] += *d;
            let w = d.distance_squared(reference[r].into());
            deviation[r] = if w > deviation[r] { w } else { deviation[r] };
        }
        for dev in deviation {
            *dev = dev.sqrt();
        }
    }

    /// Notes a substep without [`Self::closing`], so that the next one extrapolates the
    /// references over the substeps between.
    fn skip(&mut self) {
        self.skipped = self.skipped.saturating_add(1);
    }

    /// How much closer particles of `state` can have come since [`Self::assign`], when they were
    /// at `found` (by stored particle, as many as `state` holds and as were assigned): one pass
    /// over the particles. Infinite if a displacement is not finite. Pairs of neighbouring blocks
    /// are looked at only if the far bound exceeds every limit, pairs of neighbouring cubes only
    /// if the blocks' bound exceeds the least of the cubes' limits or `spare` (below which the
    /// near bound is close enough), and pairs of cubes that are not neighbours, within
    /// neighbouring blocks, only if it exceeds `mid_limit`.
    fn closing<S: ContactState>(
        &mut self,
        state: &S,
        found: &[Vec3],
        (spare, mid_limit): (f32, f32),
    ) -> Closing {
        let n = self.of.len();
        if n == 0 {
            return Closing {
                near: 0.0,
                slack: self.least,
                mid: 0.0,
                far: 0.0,
                mean: (Vec3::ZERO, Vec3::ZERO),
            };
        }
        if std::mem::take(&mut self.fresh) {
            // The first time, an extra pass for the cubes' mean displacements and their mean
            // motion over this substep, so that the next reference is extrapolated too.
            self.sum.fill(Vec3A::ZERO);
            self.last_mean.fill(Vec3::ZERO);
            let (of, sum, step) = (&self.of, &mut self.sum, &mut self.last_mean);
            state.paths(|i, start, end| {
                sum[of[i] as usize] += Vec3A::from(end - found[i]);
                step[of[i] as usize] += end - start;
            });
            for (((r, last), s), &c) in (self.reference.iter_mut().zip(&mut self.last_mean))
                .zip(&self.sum)
                .zip(&self.count)
            {
                *r = Vec3::from(*s) / c as f32;
                *last = *r - *last / c as f32;
            }
        }
        // The references were extrapolated by one substep; after more, by as many.
        let steps = std::mem::take(&mut self.skipped) as f32 + 1.0;
        if steps > 1.0 {
            for (r, last) in self.reference.iter_mut().zip(&self.last_mean) {
                *r = *last + (*r - *last) * steps;
            }
        }
        self.moved.resize(n, Vec3A::ZERO);
        // A NaN displacement is lost to the cubes' maxima but not to the mean `m1`, which makes
        // the far bound infinite.
        let (m0, m1) = state.displaced(&found[..n], &mut self.moved[..n]);
        self.scatter();
        let (m0, m1) = (Vec3::from(m0) / n as f32, Vec3::from(m1) / n as f32);
        // Any two particles: |d_p − d_q| ≤ |d_p − m1| + |d_q − m1|.
        let far = 2.0
            * self
                .reference
                .iter()
                .zip(&self.deviation)
                .map(|(r, dev)| r.distance(m1) + dev)
                .fold(0.0, max_or_infinite);
        // Two particles of blocks (or cubes) a and b: |d_p − d_q| ≤ dev_a + |ref_a − ref_b| +
        // dev_b, which is at most `far`, and for cubes at most the blocks' bound: the pairs need
        // looking at only where the cloth's parts moved apart more than the limits allow.
        let blocks = if far <= self.most.max(mid_limit) {
            far
        } else {
            self.block_reference.fill((Vec3::ZERO, 0));
            self.block_deviation.fill(0.0);
            for (&b, r) in self.block.iter().zip(&self.reference) {
                let (sum, count) = &mut self.block_reference[b as usize];
                *sum += *r;
                *count += 1;
            }
            for (sum, count) in &mut self.block_reference {
                *sum /= *count as f32;
            }
            for ((&b, r), dev) in self.block.iter().zip(&self.reference).zip(&self.deviation) {
                let d = &mut self.block_deviation[b as usize];
                *d = max_or_infinite(*d, r.distance(self.block_reference[b as usize].0) + dev);
            }
            self.block_pairs
                .iter()
                .map(|&(a, b)| {
                    let (a, b) = (a as usize, b as usize);
                    self.block_deviation[a]
                        + self.block_deviation[b]
                        + self.block_reference[a]
                            .0
                            .distance(self.block_reference[b].0)
                })
                .fold(0.0, max_or_infinite)
                .min(far)
        };
        let mid = if blocks <= mid_limit {
            blocks
        } else {
            self.cubes_apart().min(blocks)
        };
        let (near, slack) = if blocks <= self.least.min(spare) {
            (blocks, self.least - blocks)
        } else {
            // (A NaN displacement has made `far` infinite: the check fails whatever the slack.)
            let (mut near, mut slack) = (0.0, f32::INFINITY);
            for &(a, b) in &self.pairs {
                let (a, b) = (a as usize, b as usize);
                let bound = (self.deviation[a]
                    + self.deviation[b]
                    + self.reference[a].distance(self.reference[b]))
                .min(blocks);
                near = max_or_infinite(near, bound);
                slack = slack.min(self.limit[a].max(self.limit[b]) - bound);
            }
            (near, slack)
        };
        for (((r, last), s), &c) in (self.reference.iter_mut().zip(&mut self.last_mean))
            .zip(&self.sum)
            .zip(&self.count)
        {
            let mean = Vec3::from(*s) / c as f32;
            *r = if steps > 1.0 {
                mean + (mean - *last) / steps
            } else {
                2.0 * mean - *last
            };
            *last = mean;
        }
        Closing {
            near,
            slack,
            mid,
            far,
            mean: (m0, m1),
        }
    }
}

impl Regions {
    /// How much closer the ends of `edges` (by stored particle) came, at most, by the last
    /// [`Self::closing`] (infinite if a displacement is not finite).
    fn edges_closing(&self, edges: &[[u32; 2]]) -> f32 {
        let moved = &self.moved;
        // Four edges at a time, each into running values of its own, so that one edge's sum
        // does not wait on the last.
        let (mut worst, mut total) = ([0.0f32; 4], [0.0f32; 4]);
        let mut add = |k: usize, [a, b]: [u32; 2]| {
            let d = moved[a as usize].distance_squared(moved[b as usize]);
            worst[k] = if d > worst[k] { d } else { worst[k] };
            total[k] += d;
        };
        let mut fours = edges.chunks_exact(4);
        for four in &mut fours {
            for (k, &edge) in four.iter().enumerate() {
                add(k, edge);
            }
        }
        for (k, &edge) in fours.remainder().iter().enumerate() {
            add(k, edge);
        }
        let worst = worst.into_iter().fold(0.0f32, f32::max);
        let total: f32 = total.into_iter().sum();
        // The comparison drops a NaN, which the sum keeps (a sum too large counts as one).
        if total.is_finite() {
            worst.sqrt()
        } else {
            f32::INFINITY
        }
    }
}

/// Fills `pairs` with the pairs `(a, b)`, `a <= b`, of the cells of `index` (each to its index)
/// that are the same or neighbours (`dense` is scratch).
fn neighbours(
    index: &HashMap<[i32; 3], u32, BuildHasherDefault<CellHasher>>,
    pairs: &mut Vec<(u32, u32)>,
    dense: &mut Vec<u32>,
) {
    pairs.clear();
    let mut each = |lookup: &dyn Fn([i32; 3]) -> Option<u32>| {
        for (cell, &a) in index {
            let (lo, hi) = (
                cell.map(|c| c.saturating_sub(1)),
                cell.map(|c| c.saturating_add(1)),
            );
            for_cells(lo, hi, |c| {
                if let Some(b) = lookup(c)
                    && a <= b
                {
                    pairs.push((a, b));
                }
            });
        }
    };
    // Where the occupied cells fill a good share of their bounding box (a cloth's cubes do), a
    // dense array of it answers the lookups instead of the hash map; the pairs are the same and
    // in the same order.
    let (mut lo, mut hi) = ([i64::MAX; 3], [i64::MIN; 3]);
    for cell in index.keys() {
        for k in 0..3 {
            lo[k] = lo[k].min(cell[k] as i64);
            hi[k] = hi[k].max(cell[k] as i64);
        }
    }
    // Saturating: no cells leave the bounds inverted (`lo` above `hi`).
    let size = [0, 1, 2].map(|k| hi[k].saturating_sub(lo[k]).saturating_add(1).max(0));
    let volume = size.iter().try_fold(1i64, |v, &s| v.checked_mul(s));
    match volume {
        Some(volume) if !index.is_empty() && volume <= 8 * index.len() as i64 + 4096 => {
            let place = |c: [i32; 3]| -> Option<usize> {
                let mut at = 0;
                for k in 0..3 {
                    let i = c[k] as i64 - lo[k];
                    if !(0..size[k]).contains(&i) {
                        return None;
                    }
                    at = at * size[k] + i;
                }
                Some(at as usize)
            };
            dense.clear();
            dense.resize(volume as usize, u32::MAX);
            for (cell, &a) in index {
                if let Some(i) = place(*cell) {
                    dense[i] = a;
                }
            }
            each(&|c| place(c).map(|i| dense[i]).filter(|&b| b != u32::MAX));
        }
        _ => each(&|c| index.get(&c).copied()),
    }
}

/// How far the `n` displacements `d(0..n)` spread about their mean: the largest distance of one
/// from the mean (infinite if one is not finite). Moving every particle by the same vector
/// changes no distance between them, so only this part of the motion can bring a pair together:
/// two elements move closer by at most twice it.
fn spread(n: usize, d: impl Fn(usize) -> Vec3) -> f32 {
    if n == 0 {
        return 0.0;
    }
    let mean = (0..n).map(&d).sum::<Vec3>() / n as f32;
    let worst = (0..n)
        .map(|p| d(p).distance_squared(mean))
        .fold(0.0, max_or_infinite);
    worst.sqrt()
}

/// The widest normal cone (half-angle, radians) of patches whose elements are not paired in a
/// search of this `reach`, for triangles whose shortest altitude is `altitude`: a right angle
/// (beyond which a surface can fold onto itself) less the most a triangle can turn while the
/// candidates are kept, and a tenth of a radian to spare. Its vertices' relative displacements
/// stay within twice the reach, `d`; a vertex moved by `d` turns a triangle of altitude `h` by at
/// most `asin(d / h)` (the tangent from the opposite side to the ball the vertex stays in), and at
/// `d ≥ h` the triangle can fold flat.
fn cull_angle(reach: f32, altitude: f32) -> f32 {
    // A ratio that is NaN (no triangles, or a degenerate one) counts as 1 (`min` drops NaN): a
    // negative angle, which culls nothing.
    let turn = (2.0 * reach / altitude).min(1.0).asin();
    std::f32::consts::FRAC_PI_2 - turn - 0.1
}

/// The most reach a broad phase is given for a cloth whose shortest edge is `edge` long and which
/// is `thickness` thick: small enough that a flat grid's non-neighbouring elements (at least
/// `edge/√2` apart) stay out of the margin `thickness + 2 reach`, so a cloth that cannot touch
/// itself has no candidates; a cloth moving faster finds its candidates again more often within
/// a step. (0 without edges: a cloth without triangles has no self-contacts.)
fn reach_cap(edge: f32, thickness: f32) -> f32 {
    if !edge.is_finite() {
        return 0.0;
    }
    (0.45 * (0.7 * edge - thickness)).max(0.1 * edge)
}

/// Candidates of a search in bands of growing distance at the search: a substep's first pass
/// over them ([`Self::visit`]) stops at the first band none of whose candidates can have come
/// within their thickness since, and so do the farther bands after it. A resting pile's pass
/// visits only the candidates that were about touching.
#[derive(Debug, Clone, Default)]
pub(super) struct Bands {
    /// The first candidate (its index in the ordered list).
    start: u32,
    /// The bands in order.
    list: Vec<Band>,
}

/// One of [`Bands`].
#[derive(Debug, Clone, Copy)]
struct Band {
    /// The end of the band's candidates (exclusive).
    end: u32,
    /// The least distance at the search among them, m.
    least: f32,
    /// The largest thickness among them, m.
    thickness: f32,
}

impl Bands {
    /// Orders the candidates `range` into [`BANDS`] bands of their distance at the search below
    /// `margin` (`pair(k)`: candidate `k`'s distance and thickness; those past the margin go to
    /// the last band), each band keeping their order: appends them to `order` in their new order
    /// and lists the bands.
    pub(super) fn order(
        &mut self,
        range: std::ops::Range<usize>,
        margin: f32,
        pair: impl Fn(usize) -> (f32, f32),
        order: &mut Vec<u32>,
    ) {
        let width = margin / BANDS as f32;
        // NaN and negative distances go to the first band.
        let band = |gap: f32| ((gap / width) as usize).min(BANDS - 1);
        let mut count = [0u32; BANDS];
        let mut list = [(f32::INFINITY, 0.0f32); BANDS];
        for k in range.clone() {
            let (gap, thickness) = pair(k);
            let b = band(gap);
            count[b] += 1;
            // A NaN distance is passed over: such a candidate never passes the filter.
            list[b] = (list[b].0.min(gap), list[b].1.max(thickness));
        }
        self.start = order.len() as u32;
        self.list.clear();
        let mut next = [0u32; BANDS];
        let mut end = self.start;
        for b in 0..BANDS {
            next[b] = end;
            end += count[b];
            if count[b] > 0 {
                let (least, thickness) = list[b];
                self.list.push(Band {
                    end,
                    least,
                    thickness,
                });
            }
        }
        order.resize(end as usize, 0);
        for k in range {
            let b = band(pair(k).0);
            order[next[b] as usize] = k as u32;
            next[b] += 1;
        }
    }

    /// Calls `f(k)` for the candidates in order, band by band, while a band may hold one that
    /// came within its thickness: particles of a candidate came closer by at most `closing` (m)
    /// since the search, and after `f(k)` by at most twice what it returns (the largest drift
    /// among its particles after it acted, or 0). Returns the bound at the end.
    pub(super) fn visit(&self, mut closing: f32, mut f: impl FnMut(usize) -> f32) -> f32 {
        let mut k = self.start as usize;
        for band in &self.list {
            if band.least - closing > band.thickness {
                break;
            }
            for k in k..band.end as usize {
                // Most candidates do not act (0): the bound is left alone rather than carried
                // through a `max` per candidate.
                let drift = f(k);
                if drift != 0.0 {
                    closing = max_or_infinite(closing, 2.0 * drift);
                }
            }
            k = band.end as usize;
        }
        closing
    }
}

/// Replaces `v` by its elements at `order`, building it in `scratch` (which keeps the old list).
pub(super) fn reorder<T: Copy>(
    v: &mut Vec<T>,
    scratch: &mut Vec<T>,
    order: impl Iterator<Item = usize>,
) {
    scratch.clear();
    scratch.extend(order.map(|k| v[k]));
    std::mem::swap(v, scratch);
}

/// `s.map(f)` for the four particles of a pair, written out: in the narrow phase's hot loop the
/// library's `map` was left as a call.
#[inline(always)]
pub(super) fn four<T: Copy, U>(s: [T; 4], f: impl Fn(T) -> U) -> [U; 4] {
    [f(s[0]), f(s[1]), f(s[2]), f(s[3])]
}

/// The larger of `a` and `b`, infinite if `b` is NaN (a non-finite displacement must force a new
/// search, not vanish in a comparison).
pub(super) fn max_or_infinite(a: f32, b: f32) -> f32 {
    if b.is_nan() { f32::INFINITY } else { a.max(b) }
}

/// The unique edges of triangles `tris` (lower particle first, sorted) into `edges`, and for each
/// triangle the edge from each of its corners to the next (an index into `edges`; `u32::MAX` where
/// an earlier triangle that shares it owns it) into `tri_edges`; `keyed` is left holding each
/// triangle side's edge key and place (`3 × triangle + corner`), sorted by key.
pub(super) fn edge_table(
    tris: &[[u32; 3]],
    keyed: &mut Vec<(u64, usize)>,
    edges: &mut Vec<[u32; 2]>,
    tri_edges: &mut Vec<[u32; 3]>,
) {
    keyed.clear();
    for (t, tri) in tris.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            keyed.push((pair_key(a.min(b), a.max(b)), 3 * t + k));
        }
    }
    keyed.sort_unstable();
    edges.clear();
    tri_edges.clear();
    tri_edges.resize(tris.len(), [u32::MAX; 3]);
    for (i, &(key, at)) in keyed.iter().enumerate() {
        if i == 0 || keyed[i - 1].0 != key {
            edges.push([(key >> 32) as u32, key as u32]);
            tri_edges[at / 3][at % 3] = (edges.len() - 1) as u32;
        }
    }
}

/// The key of pair `(a, b)` in the exemption lists.
fn pair_key(a: u32, b: u32) -> u64 {
    (a as u64) << 32 | b as u64
}

/// Whether `key` is in the sorted `exempt` list.
fn is_exempt(exempt: &[u64], key: u64) -> bool {
    !exempt.is_empty() && exempt.binary_search(&key).is_ok()
}

/// The unit normal of triangle `abc` (`None` for a degenerate one).
fn unit_normal(a: Vec3, b: Vec3, c: Vec3) -> Option<Vec3> {
    (b - a).cross(c - a).try_normalize()
}

/// Barycentric coordinates of `q` (in the plane of `abc`) with respect to `a`, `b`, `c`.
fn barycentric(q: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Option<[f32; 3]> {
    let (e1, e2, r) = (b - a, c - a, q - a);
    let (d00, d01, d11) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (d20, d21) = (r.dot(e1), r.dot(e2));
    let denom = d00 * d11 - d01 * d01;
    if denom.is_nan() || denom <= 0.0 {
        return None;
    }
    let v = (d11 * d20 - d01 * d21) / denom;
    let w = (d00 * d21 - d01 * d20) / denom;
    Some([1.0 - v - w, v, w])
}

/// Distance from `p` to triangle `abc` (to its nearest edge or vertex when `p` is not over it).
pub(super) fn point_triangle_distance(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> f32 {
    if let Some(n) = unit_normal(a, b, c) {
        let dist = (p - a).dot(n);
        if let Some([u, v, w]) = barycentric(p - dist * n, a, b, c)
            && u >= 0.0
            && v >= 0.0
            && w >= 0.0
        {
            return dist.abs();
        }
    }
    [(a, b), (b, c), (c, a)]
        .into_iter()
        .map(|(e0, e1)| {
            let d = e1 - e0;
            let t = if d.length_squared() > 0.0 {
                ((p - e0).dot(d) / d.length_squared()).clamp(0.0, 1.0)
            } else {
                0.0
            };
            p.distance(e0 + t * d)
        })
        .fold(f32::INFINITY, f32::min)
}

/// The parameters `(s, t)` of the closest points `a + s (b − a)` and `c + t (d − c)` of segments
/// `ab` and `cd`, both in `0..=1`.
pub(super) fn closest_on_segments(a: Vec3, b: Vec3, c: Vec3, d: Vec3) -> (f32, f32) {
    let (d1, d2, r) = (b - a, d - c, a - c);
    let (aa, ee, f) = (d1.dot(d1), d2.dot(d2), d2.dot(r));
    const TINY: f32 = 1e-20;
    if aa <= TINY && ee <= TINY {
        return (0.0, 0.0);
    }
    if aa <= TINY {
        return (0.0, (f / ee).clamp(0.0, 1.0));
    }
    let cc = d1.dot(r);
    if ee <= TINY {
        return ((-cc / aa).clamp(0.0, 1.0), 0.0);
    }
    let bb = d1.dot(d2);
    let denom = aa * ee - bb * bb;
    // The reciprocals are independent of each other, so their divisions overlap rather than
    // queue behind `s`.
    let (inv_aa, inv_ee) = (1.0 / aa, 1.0 / ee);
    let mut s = if denom > TINY * aa * ee {
        ((bb * f - cc * ee) / denom).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let mut t = (bb * s + f) * inv_ee;
    if t < 0.0 {
        t = 0.0;
        s = (-cc * inv_aa).clamp(0.0, 1.0);
    } else if t > 1.0 {
        t = 1.0;
        s = ((bb - cc) * inv_aa).clamp(0.0, 1.0);
    }
    (s, t)
}

/// A spatial hash of boxes no larger than its cells: each box is listed in every cell it meets
/// (at most two per axis), bucketed by a hash of the cell (counting sort, no per-build
/// allocation once grown).
#[derive(Debug, Clone, Default)]
pub(super) struct Hash {
    /// The boxes, filled by the caller before [`Self::build`].
    pub(super) boxes: Vec<(Vec3, Vec3)>,
    /// 1 / cell size.
    inv_cell: f32,
    /// Buckets − 1 (a power of two less one).
    mask: u32,
    /// Where each bucket's entries begin in `entries` (one more than the buckets).
    start: Vec<u32>,
    /// (box, cell) per listing, grouped by bucket.
    entries: Vec<(u32, [i32; 3])>,
    /// The cell of each box's low corner.
    low: Vec<[i32; 3]>,
}

impl Hash {
    /// Lists the boxes `i` for which `include(i)` holds in their cells. Returns `false` (and lists
    /// nothing) if a box is not finite.
    pub(super) fn build(&mut self, include: impl Fn(u32) -> bool) -> bool {
        if !self.finite() {
            self.entries.clear();
            return false;
        }
        let mut extent = 0.0f32;
        for (i, (lo, hi)) in self.boxes.iter().enumerate() {
            if include(i as u32) {
                extent = extent.max((*hi - *lo).max_element());
            }
        }
        self.inv_cell = 1.0 / extent.max(1e-6);
        let inv = self.inv_cell;
        // Low corners' cells (only those of listed boxes are read), then twice as many buckets
        // as entries, so that few cells share a bucket.
        self.low.clear();
        self.low.resize(self.boxes.len(), [0; 3]);
        let mut count = 0usize;
        for (i, (lo, hi)) in self.boxes.iter().enumerate() {
            if include(i as u32) {
                let (a, b) = (cell_of(*lo, inv), cell_of(*hi, inv));
                self.low[i] = a;
                count += (0..3)
                    .map(|k| (b[k] - a[k] + 1) as usize)
                    .product::<usize>();
            }
        }
        let buckets = (2 * count).next_power_of_two().max(16);
        self.mask = (buckets - 1) as u32;
        self.start.clear();
        self.start.resize(buckets + 1, 0);
        for (i, (_, hi)) in self.boxes.iter().enumerate() {
            if include(i as u32) {
                for_cells(self.low[i], self.cell(*hi), |c| {
                    self.start[bucket(c, self.mask) + 1] += 1;
                });
            }
        }
        for b in 0..buckets {
            self.start[b + 1] += self.start[b];
        }
        self.entries.clear();
        self.entries.resize(count, (0, [0; 3]));
        // `start[b]` serves as bucket b's cursor while filling, then is restored.
        for (i, (_, hi)) in self.boxes.iter().enumerate() {
            if include(i as u32) {
                for_cells(self.low[i], self.cell(*hi), |c| {
                    let b = bucket(c, self.mask);
                    self.entries[self.start[b] as usize] = (i as u32, c);
                    self.start[b] += 1;
                });
            }
        }
        for b in (1..=buckets).rev() {
            self.start[b] = self.start[b - 1];
        }
        self.start[0] = 0;
        true
    }

    /// Whether every box is finite (a search on non-finite positions pairs nothing).
    pub(super) fn finite(&self) -> bool {
        self.boxes
            .iter()
            .all(|(lo, hi)| lo.is_finite() && hi.is_finite())
    }

    /// Sets the boxes to those of triangles `tris` over positions `x`, grown by `grow`.
    pub(super) fn triangle_boxes(&mut self, tris: &[[u32; 3]], x: &[Vec3], grow: Vec3) {
        self.boxes.clear();
        self.boxes.extend(tris.iter().map(|t| {
            let [a, b, c] = t.map(|i| x[i as usize]);
            (a.min(b).min(c) - grow, a.max(b).max(c) + grow)
        }));
    }

    /// The cell of point `p`.
    fn cell(&self, p: Vec3) -> [i32; 3] {
        cell_of(p, self.inv_cell)
    }

    /// Calls `f(box)` once for every box that meets box `lo..hi`, which must be no larger
    /// than a cell (in the one cell that holds the low corner of the two boxes' overlap).
    pub(super) fn visit(&self, lo: Vec3, hi: Vec3, mut f: impl FnMut(u32)) {
        if self.entries.is_empty() {
            return;
        }
        let from = self.cell(lo);
        for_cells(from, self.cell(hi), |c| {
            let b = bucket(c, self.mask);
            for &(i, cell) in &self.entries[self.start[b] as usize..self.start[b + 1] as usize] {
                if cell != c {
                    continue;
                }
                let (blo, bhi) = self.boxes[i as usize];
                // The overlap's low corner is the larger of the two low corners, and the cell
                // of a point is monotonic in it.
                let low = self.low[i as usize];
                let first = [0, 1, 2].map(|k| low[k].max(from[k]));
                if boxes_meet((blo, bhi), (lo, hi)) && first == c {
                    f(i);
                }
            }
        });
    }
}

/// A hasher for integer cell coordinates: far cheaper than the standard library's keyed one, and
/// the same in every process (the cubes' pairs come out in one order).
#[derive(Debug, Clone, Copy, Default)]
struct CellHasher(u64);

impl Hasher for CellHasher {
    fn finish(&self) -> u64 {
        crate::hash::mix64(self.0)
    }
    fn write(&mut self, bytes: &[u8]) {
        // A slice of integers arrives as its bytes: four at a time.
        for chunk in bytes.chunks(4) {
            let mut word = [0; 4];
            word[..chunk.len()].copy_from_slice(chunk);
            self.write_u32(u32::from_le_bytes(word));
        }
    }
    fn write_u32(&mut self, i: u32) {
        self.0 = (self.0 ^ u64::from(i)).wrapping_mul(crate::hash::GOLDEN_GAMMA);
    }
    fn write_i32(&mut self, i: i32) {
        self.write_u32(i as u32);
    }
}

/// Calls `f` for every cell from `lo` to `hi` (inclusive).
fn for_cells(lo: [i32; 3], hi: [i32; 3], mut f: impl FnMut([i32; 3])) {
    for x in lo[0]..=hi[0] {
        for y in lo[1]..=hi[1] {
            for z in lo[2]..=hi[2] {
                f([x, y, z]);
            }
        }
    }
}

/// Whether boxes `a` and `b` (low and high corners) meet; false if a corner is NaN.
fn boxes_meet((alo, ahi): (Vec3, Vec3), (blo, bhi): (Vec3, Vec3)) -> bool {
    alo.cmple(bhi).all() && ahi.cmpge(blo).all()
}

/// [`boxes_meet`] in whole vector registers, without a branch per axis (the inner loops of the
/// patch pairs' search, where most boxes do not meet and which axis tells is hard to predict).
fn boxes_meet_wide((alo, ahi): (Vec3A, Vec3A), (blo, bhi): (Vec3A, Vec3A)) -> bool {
    (alo.cmple(bhi) & ahi.cmpge(blo)).all()
}

/// The cell of point `p` in a grid of cells `1 / inv` wide.
fn cell_of(p: Vec3, inv: f32) -> [i32; 3] {
    // `floor` without a library call where the target lacks a rounding instruction: truncate,
    // then step down where that rounded up (negative non-integers). Saturating as `floor` and
    // `as` would, and 0 for NaN.
    (p * inv).to_array().map(|x| {
        let t = x as i32;
        t.saturating_sub(i32::from((t as f32) > x))
    })
}

/// The bucket of cell `c`.
fn bucket(c: [i32; 3], mask: u32) -> usize {
    let h = (c[0] as u32).wrapping_mul(0x8da6_b343)
        ^ (c[1] as u32).wrapping_mul(0xd816_3841)
        ^ (c[2] as u32).wrapping_mul(0xcb1a_b31f);
    (h & mask) as usize
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hash::{mix64, unit_interval};
    use crate::sim::contact::Vectors;
    use crate::sim::{ClothModel, GridSpec};

    /// Resolves one substep of `contacts` from `start` to `x` with velocities `v`.
    fn resolve(
        contacts: &mut SelfContacts,
        start: &[Vec3],
        x: &mut [Vec3],
        v: &mut [Vec3],
        w: &[f32],
    ) {
        resolve_within(contacts, 0.0, start, x, v, w);
    }

    /// [`resolve`] in a step whose particles may move `reach` relative to each other.
    fn resolve_within(
        contacts: &mut SelfContacts,
        reach: f32,
        start: &[Vec3],
        x: &mut [Vec3],
        v: &mut [Vec3],
        w: &[f32],
    ) {
        contacts.begin_step(reach);
        substep(contacts, (1.0 / 1200.0, true), start, (x, v), w);
    }

    /// One substep of `contacts` of length `h` (the step's `last` or not) for particles of
    /// inverse masses `w` that moved from `start` to `x` (velocities `v`).
    fn substep(
        contacts: &mut SelfContacts,
        (h, last): (f32, bool),
        start: &[Vec3],
        (x, v): (&mut [Vec3], &mut [Vec3]),
        w: &[f32],
    ) {
        let mut state = Vectors {
            x,
            v,
            start,
            inv_mass: w,
            touches: None,
        };
        contacts.resolve((h, last), &mut state);
        contacts.end_substep(&state);
    }

    /// `Regions::closing` for particles found at `found` and now at `x` (started at `found`).
    fn closing_of(regions: &mut Regions, found: &[Vec3], x: &mut [Vec3], limit: f32) -> Closing {
        closing_from(regions, found, found, x, limit)
    }

    /// `Regions::closing` for particles found at `found` that moved from `start` to `x`, with
    /// every cube's limit and the far one at `limit`.
    fn closing_from(
        regions: &mut Regions,
        found: &[Vec3],
        start: &[Vec3],
        x: &mut [Vec3],
        limit: f32,
    ) -> Closing {
        regions.limit.fill(limit);
        (regions.least, regions.most) = (limit, limit);
        closing_within(regions, (found, start), x, limit)
    }

    /// `Regions::closing` for particles found at `found` that moved from `start` to `x`, with the
    /// cubes' limits as they are and the far limit at `mid_limit`.
    fn closing_within(
        regions: &mut Regions,
        (found, start): (&[Vec3], &[Vec3]),
        x: &mut [Vec3],
        mid_limit: f32,
    ) -> Closing {
        let (mut v, w) = (vec![Vec3::ZERO; x.len()], vec![1.0; x.len()]);
        let state = Vectors {
            x,
            v: &mut v,
            start,
            inv_mass: &w,
            touches: None,
        };
        regions.closing(&state, found, (mid_limit, mid_limit))
    }

    #[test]
    fn cubes_and_blocks_bound_every_pair_that_was_within_their_reach() {
        // Particles strewn over a cube of 1.5 m, a few in each cube of 20 cm and across more than
        // two blocks; one in fifty displaced by up to 9 cm, more than its cube's mean.
        let h = |k: usize| unit_interval(mix64(k as u64));
        let n = 1500;
        let found: Vec<Vec3> = (0..n)
            .map(|i| 1.5 * Vec3::new(h(3 * i), h(3 * i + 1), h(3 * i + 2)))
            .collect();
        let slot: Vec<u32> = (0..n as u32).collect();
        let mut regions = Regions {
            size: 0.2,
            ..Regions::default()
        };
        regions.assign(&found, &slot);
        let mut x: Vec<Vec3> = (found.iter().enumerate())
            .map(|(i, p)| {
                let k = 10_000 + 3 * i;
                let d = 0.1 * (Vec3::new(h(k), h(k + 1), h(k + 2)) - 0.5);
                if i % 50 == 0 { *p + d } else { *p }
            })
            .collect();
        // No limit: every bound is worked out.
        let c = closing_of(&mut regions, &found, &mut x, 0.0);
        assert!(
            c.near <= c.far && c.mid <= c.far,
            "{} {} {}",
            c.near,
            c.mid,
            c.far
        );
        let cell = |p: Vec3| cell_of(p, 1.0 / regions.size);
        let neighbours = |a: [i32; 3], b: [i32; 3]| (0..3).all(|k| (a[k] - b[k]).abs() <= 1);
        let block = |c: [i32; 3]| c.map(|c| c.div_euclid(BLOCK));
        let mut counted = [0; 3];
        for p in 0..n {
            for q in p + 1..n {
                let closer = (x[p] - found[p]).distance(x[q] - found[q]);
                let (a, b) = (cell(found[p]), cell(found[q]));
                let (bound, kind) = if neighbours(a, b) {
                    (c.near, 0)
                } else if neighbours(block(a), block(b)) {
                    // Plus a side for each cube between them beyond the first.
                    let cells = (0..3).map(|k| (a[k] - b[k]).abs()).max().unwrap();
                    (c.mid + (cells - 2) as f32 * regions.size, 1)
                } else {
                    (c.far, 2)
                };
                assert!(closer <= bound + 1e-6, "{p}, {q}: {closer} > {bound}");
                counted[kind] += 1;
            }
        }
        assert!(counted.iter().all(|&k| k > 0), "{counted:?}");
    }

    #[test]
    fn cubes_that_are_not_neighbours_bound_their_particles_in_one_block_or_in_two() {
        // Cubes of 0.2 m along x: cells 0, 1 and 2 make block 0, cell 3 begins block 1. The
        // particle in cell 2 moves 5 cm toward the one in cell 0 (same block), then the one in
        // cell 3 toward it (neighbouring blocks); nothing else moves.
        let found: Vec<Vec3> = [0.1, 0.3, 0.5, 0.7]
            .map(|x| Vec3::new(x, 0.1, 0.1))
            .to_vec();
        let slot: Vec<u32> = (0..4).collect();
        for (moved, by) in [(2, -0.05), (3, -0.05), (0, 0.05)] {
            let mut regions = Regions {
                size: 0.2,
                ..Regions::default()
            };
            regions.assign(&found, &slot);
            let mut x = found.clone();
            x[moved].x += by;
            let c = closing_of(&mut regions, &found, &mut x, 0.0);
            assert!(c.mid >= 0.05 - 1e-6, "particle {moved}: mid {}", c.mid);
            assert!(
                c.mid <= c.far + 1e-6,
                "particle {moved}: {} {}",
                c.mid,
                c.far
            );
        }
    }

    #[test]
    fn cubes_farther_apart_may_come_closer_by_a_side_for_each_cube_between() {
        // Cubes of 0.2 m along x: particles in cells 0 and 3 (neighbouring blocks), 0.6 m apart,
        // the second moved 0.25 m toward the first: against the limit of cubes two apart, that
        // counts as 0.05 m.
        let found: Vec<Vec3> = [0.1, 0.7].map(|x| Vec3::new(x, 0.1, 0.1)).to_vec();
        let mut regions = Regions {
            size: 0.2,
            ..Regions::default()
        };
        regions.assign(&found, &[0, 1]);
        let mut x = found.clone();
        x[1].x -= 0.25;
        let c = closing_of(&mut regions, &found, &mut x, 0.0);
        assert!((c.mid - 0.05).abs() < 1e-6, "mid {}", c.mid);
        assert!(c.far >= 0.25 - 1e-6, "far {}", c.far);
    }

    #[test]
    fn a_cube_takes_the_least_limit_of_its_particles() {
        // Cubes of 0.2 m along x: particles 0, 2 and 4 in cell 0, 1 and 3 in cell 1, stored in
        // reverse; each particle's limit is its index plus one.
        let found: Vec<Vec3> = [0.05, 0.25, 0.1, 0.3, 0.15]
            .map(|x| Vec3::new(x, 0.1, 0.1))
            .to_vec();
        let slot: Vec<u32> = (0..5).rev().collect();
        let mut regions = Regions {
            size: 0.2,
            ..Regions::default()
        };
        regions.assign(&found, &slot);
        regions.limit(&slot, |p| p as f32 + 1.0);
        let cube = |p: usize| regions.of[slot[p] as usize] as usize;
        assert_eq!(regions.limit[cube(0)], 1.0);
        assert_eq!(regions.limit[cube(1)], 2.0);
        assert_eq!((regions.least, regions.most), (1.0, 2.0));
    }

    #[test]
    fn neighbouring_cubes_may_come_closer_by_the_larger_of_their_limits() {
        // Cubes of 0.2 m along x, one particle in each of cells 0, 1 and 2 (one block); the
        // middle one moves 3 cm toward the last.
        let found: Vec<Vec3> = [0.1, 0.3, 0.5].map(|x| Vec3::new(x, 0.1, 0.1)).to_vec();
        for (limits, slack) in [([0.01, 0.05, 0.01], 0.01), ([0.01, 0.01, 0.05], -0.02)] {
            let mut regions = Regions {
                size: 0.2,
                ..Regions::default()
            };
            regions.assign(&found, &[0, 1, 2]);
            regions.limit = limits.to_vec();
            (regions.least, regions.most) = (0.01, 0.05);
            let mut x = found.clone();
            x[1].x += 0.03;
            let c = closing_within(&mut regions, (&found, &found), &mut x, 1.0);
            assert!((c.near - 0.03).abs() < 1e-6, "{limits:?}: near {}", c.near);
            assert!(
                (c.slack - slack).abs() < 1e-6,
                "{limits:?}: slack {}",
                c.slack
            );
        }
    }

    #[test]
    fn neighbouring_cells_are_paired_once_whether_looked_up_densely_or_hashed() {
        // A compact cluster (looked up in a dense array) and the same cells with one far away
        // (the hash map), against every pair of cells tried.
        let h = |k: usize| unit_interval(mix64(k as u64));
        let cluster: Vec<[i32; 3]> = (0..300)
            .map(|i| [0, 1, 2].map(|k| (8.0 * h(3 * i + k)) as i32 - 3))
            .collect();
        // One scratch for all: a dense lookup after another, larger one finds no stale cells.
        let mut scratch = Vec::new();
        let far = Some([1 << 20, -(1 << 20), 7]);
        for (shift, far) in [(0, None), (2, None), (0, far), (-1, None)] {
            let mut index = HashMap::default();
            let shifted = (cluster.iter()).map(|c| [(c[0] + shift).min(3), c[1] + shift, c[2]]);
            for c in shifted.chain(far) {
                let next = index.len() as u32;
                index.entry(c).or_insert(next);
            }
            let mut pairs = Vec::new();
            neighbours(&index, &mut pairs, &mut scratch);
            let mut expected = Vec::new();
            for (a, &i) in &index {
                for (b, &j) in &index {
                    if i <= j && (0..3).all(|k| (a[k] - b[k]).abs() <= 1) {
                        expected.push((i, j));
                    }
                }
            }
            let mut found = pairs.clone();
            found.sort_unstable();
            expected.sort_unstable();
            assert_eq!(found, expected, "far: {far:?}");
        }
        let mut pairs = vec![(0, 0)];
        neighbours(&HashMap::default(), &mut pairs, &mut Vec::new());
        assert!(pairs.is_empty());
    }

    #[test]
    fn edges_close_by_their_ends_relative_displacement_and_infinitely_when_not_finite() {
        let mut regions = Regions {
            moved: vec![
                Vec3A::ZERO,
                Vec3A::X,
                Vec3A::new(0.0, 0.5, 0.0),
                Vec3A::ZERO,
            ],
            ..Regions::default()
        };
        let edges = [[0, 1], [1, 2], [2, 3]];
        let closing = regions.edges_closing(&edges);
        assert!((closing - 1.25f32.sqrt()).abs() < 1e-6, "{closing}");
        // The edge that turned most, wherever it is in a list of any length.
        let one_among = |n: usize, k: usize, edge: [u32; 2], rest: [u32; 2]| {
            let mut edges = vec![rest; n];
            edges[k] = edge;
            edges
        };
        for n in 1..10 {
            for k in 0..n {
                let closing = regions.edges_closing(&one_among(n, k, [1, 2], [0, 3]));
                assert!(
                    (closing - 1.25f32.sqrt()).abs() < 1e-6,
                    "{n}, {k}: {closing}"
                );
            }
        }
        for bad in [f32::NAN, f32::INFINITY, 1e30] {
            regions.moved[3] = Vec3A::splat(bad);
            assert_eq!(regions.edges_closing(&edges), f32::INFINITY, "{bad}");
            for n in 1..10 {
                for k in 0..n {
                    let edges = one_among(n, k, [2, 3], [0, 1]);
                    assert_eq!(
                        regions.edges_closing(&edges),
                        f32::INFINITY,
                        "{bad} {n} {k}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_triangle_turning_beyond_the_cull_is_searched_again_though_the_cubes_allow_it() {
        // A flat 12×12 grid (3 cm): its patches are culled, and elements it leaves uncovered are
        // far apart, so the cubes allow more than twice the reach; a vertex lifted by more than
        // that turns its triangles further than the cull allowed for.
        let model = ClothModel::grid(&GridSpec::new(12, 12, 0.03)).unwrap();
        let rest = &model.rest_positions;
        let mut c = SelfContacts::new(&model.triangles, rest, 0.005, 0.0);
        let w = vec![1.0; rest.len()];
        let mut x = rest.clone();
        let mut v = vec![Vec3::ZERO; x.len()];
        resolve_within(&mut c, 1.0, rest, &mut x, &mut v, &w);
        assert_eq!(c.searches(), 1);
        let lift = 1.4 * c.reach;
        assert!(
            c.regions.least > 2.0 * lift,
            "least limit {}, reach {}",
            c.regions.least,
            c.reach
        );
        let [a, b, d] = [0, 1, 12].map(|i| rest[i]);
        let normal = (b - a).cross(d - a).normalize();
        let start = x.clone();
        x[5 * 12 + 5] += normal * 2.0 * lift;
        resolve_within(&mut c, 1.0, &start, &mut x, &mut v, &w);
        assert_eq!(c.searches(), 2, "the turned triangles are searched again");
    }

    /// A flat grid at `rest` (in the plane y = 0) folded back over itself along the line x =
    /// `bend`, over a radius `r` (x being the arc length).
    fn folded(rest: &[Vec3], bend: f32, r: f32) -> Vec<Vec3> {
        let arc = std::f32::consts::PI * r;
        (rest.iter())
            .map(|p| {
                let s = p.x;
                if s < bend {
                    Vec3::new(s, 0.0, p.z)
                } else if s < bend + arc {
                    let a = (s - bend) / r;
                    Vec3::new(bend + r * a.sin(), r - r * a.cos(), p.z)
                } else {
                    Vec3::new(bend - (s - bend - arc), 2.0 * r, p.z)
                }
            })
            .collect()
    }

    #[test]
    fn the_elements_of_patches_searched_together_lie_in_tight_cubes() {
        // A 16×16 grid (3 cm) with its last 9 cm folded back over a 1 cm radius: the layers are
        // searched together, the flat part beyond them is not.
        let model = ClothModel::grid(&GridSpec::new(16, 16, 0.03)).unwrap();
        let rest = &model.rest_positions;
        let mut c = SelfContacts::new(&model.triangles, rest, 0.005, 0.0);
        let mut x = folded(rest, 0.12, 0.01);
        let (start, w) = (x.clone(), vec![1.0; x.len()]);
        let mut v = vec![Vec3::ZERO; x.len()];
        resolve_within(&mut c, 0.01, &start, &mut x, &mut v, &w);
        assert!(!c.patches.pairs().is_empty());
        let tight = |p: u32| {
            c.regions.limit[c.regions.of[c.slot[p as usize] as usize] as usize] <= 2.0 * c.reach
        };
        for &patch in c.patches.pairs().iter().flat_map(|(a, b)| [a, b]) {
            for &t in c.patch_triangles.of(patch) {
                assert!(c.tris[t as usize].iter().all(|&p| tight(p)), "{t}");
            }
        }
        assert!(
            (0..x.len() as u32).any(|p| !tight(p)),
            "the flat part is not tight"
        );
        // Every other cube is held to what the patches with a corner in it allow.
        for (t, tri) in c.tris.iter().enumerate() {
            let clear = c.patches.clear_of(c.patches.of_triangle(t as u32));
            for &p in tri {
                let limit = c.regions.limit[c.regions.of[c.slot[p as usize] as usize] as usize];
                assert!(
                    limit <= (clear - c.thickness).max(2.0 * c.reach),
                    "{t}: {limit}"
                );
            }
        }
    }

    #[test]
    fn a_vertex_takes_the_least_value_of_the_patches_of_its_triangles() {
        // A 20×20 grid: its patches meet along their borders, where a vertex is a corner of
        // triangles of two to four patches.
        let model = ClothModel::grid(&GridSpec::new(20, 20, 0.03)).unwrap();
        let c = SelfContacts::new(&model.triangles, &model.rest_positions, 0.005, 0.0);
        let h = |k: usize| unit_interval(mix64(k as u64));
        let value: Vec<f32> = (0..c.patches.len()).map(h).collect();
        let mut shared = 0;
        for p in 0..model.rest_positions.len() as u32 {
            let of: Vec<u32> = (c.tris.iter().enumerate())
                .filter(|(_, tri)| tri.contains(&p))
                .map(|(t, _)| c.patches.of_triangle(t as u32))
                .collect();
            let least = of.iter().map(|&a| value[a as usize]).reduce(f32::min);
            assert_eq!(c.patches.least_around(p, &value), least, "vertex {p}");
            shared += usize::from(of.iter().any(|&a| a != of[0]));
        }
        assert!(shared > 20, "{shared} vertices on patch borders");
    }

    #[test]
    fn elements_left_uncovered_are_at_least_the_clear_distance_apart() {
        // A 14×14 grid (3 cm) rippled along x: its patches' cones are within a wide cull, but
        // patches farther along the mesh are neither culled nor searched together.
        let model = ClothModel::grid(&GridSpec::new(14, 14, 0.03)).unwrap();
        let mut c = SelfContacts::new(&model.triangles, &model.rest_positions, 0.005, 0.0);
        let x: Vec<Vec3> = (model.rest_positions.iter())
            .map(|p| *p + Vec3::new(0.0, 0.0, 0.03 * (p.x / 0.06).sin()))
            .collect();
        let margin = 0.012;
        c.find_candidates(&x, margin, usize::MAX, Some((move |_| 1.2, 0.2)));
        let patches = &c.patches;
        let clear = (0..patches.len() as u32)
            .map(|p| patches.clear_of(p))
            .fold(f32::INFINITY, f32::min);
        assert!(clear > margin, "{clear}");
        let covered = |a: u32, b: u32| {
            patches.culled(a, b) || patches.pairs().contains(&(a.min(b), a.max(b)))
        };
        // Each at least either patch's own clear distance apart, which is more than the least
        // for some.
        let clear_of = |a: u32, b: u32| patches.clear_of(a).max(patches.clear_of(b));
        let widest = (0..patches.len() as u32)
            .map(|p| patches.clear_of(p))
            .fold(0.0, f32::max);
        assert!(widest > clear + 0.01, "{widest} {clear}");
        let mut uncovered = 0;
        for (p, &at) in x.iter().enumerate() {
            for (t, tri) in c.tris.iter().enumerate() {
                let (a, b) = (patches.of_vertex(p as u32), patches.of_triangle(t as u32));
                if tri.contains(&(p as u32)) || covered(a, b) {
                    continue;
                }
                let [ta, tb, tc] = tri.map(|i| x[i as usize]);
                let gap = point_triangle_distance(at, ta, tb, tc);
                let clear = clear_of(a, b);
                assert!(gap >= clear - 1e-6, "{p} and {t}: {gap} < {clear}");
                uncovered += 1;
            }
        }
        for (e, &[a, b]) in c.edges.iter().enumerate() {
            for (f, &[p, q]) in c.edges.iter().enumerate() {
                let (ea, fb) = (c.edge_patch[e], c.edge_patch[f]);
                if [a, b].iter().any(|i| [p, q].contains(i)) || covered(ea, fb) {
                    continue;
                }
                let [a, b, p, q] = [a, b, p, q].map(|i| x[i as usize]);
                let (s, t) = closest_on_segments(a, b, p, q);
                let gap = a.lerp(b, s).distance(p.lerp(q, t));
                let clear = clear_of(ea, fb);
                assert!(gap >= clear - 1e-6, "edges {e} and {f}: {gap} < {clear}");
            }
        }
        assert!(uncovered > 0);
    }

    #[test]
    fn the_cubes_bound_how_much_closer_particles_came() {
        // A row of particles 0.1 m apart along x, in cubes of 0.25 m.
        let found: Vec<Vec3> = (0..20)
            .map(|i| Vec3::new(0.1 * i as f32, 0.0, 0.0))
            .collect();
        let slot: Vec<u32> = (0..20).collect();
        let fresh = || {
            let mut r = Regions {
                size: 0.25,
                ..Regions::default()
            };
            r.assign(&found, &slot);
            r
        };
        // A rigid translation, however large, brings nothing closer.
        let mut x: Vec<Vec3> = found.iter().map(|p| *p + Vec3::splat(3.0)).collect();
        let c = closing_of(&mut fresh(), &found, &mut x, 0.01);
        assert!(c.near < 1e-5 && c.far < 1e-5, "{} {}", c.near, c.far);
        assert!((c.mean.1 - Vec3::splat(3.0)).length() < 1e-5);
        // One particle moved 5 cm toward its neighbour: neighbouring cubes see it, whether or not
        // the pairs are looked at, and wherever it is stored among its cube's particles (5, 6 and
        // 7 share one).
        for (limit, p) in [0.0, 1.0].into_iter().flat_map(|l| [(l, 5), (l, 7)]) {
            let mut x = found.clone();
            x[p].x -= 0.05;
            let c = closing_of(&mut fresh(), &found, &mut x, limit);
            assert!(
                c.near >= 0.05 - 1e-6 && c.far >= c.near,
                "{p}: {} {}",
                c.near,
                c.far
            );
        }
        // Particles moving on as they moved over the first substep checked: every cube's
        // reference follows them, so the next check sees nothing come closer.
        let mut regions = fresh();
        let step = Vec3::new(0.03, -0.01, 0.02);
        let start: Vec<Vec3> = found.iter().map(|p| *p + step).collect();
        let mut x = start.clone();
        closing_of(&mut regions, &found, &mut x, 0.01);
        let mut x: Vec<Vec3> = start.iter().map(|p| *p + step).collect();
        let c = closing_from(&mut regions, &found, &start, &mut x, 1.0);
        assert!(c.near < 1e-5, "{}", c.near);
        // The same after three substeps without a check: the references are extrapolated over
        // all four, and the next one from the motion over those four.
        let mut regions = fresh();
        let at = |k: f32| -> Vec<Vec3> { found.iter().map(|p| *p + step * k).collect() };
        closing_from(&mut regions, &found, &found, &mut at(1.0), 0.01);
        for _ in 0..3 {
            regions.skip();
        }
        for k in [5.0, 6.0] {
            let c = closing_from(&mut regions, &found, &at(k - 1.0), &mut at(k), 1.0);
            assert!(c.near < 1e-5, "substep {k}: {}", c.near);
        }
        // A position that is not a number makes both bounds infinite.
        let mut x = found.clone();
        x[3] = Vec3::NAN;
        let c = closing_of(&mut fresh(), &found, &mut x, 0.01);
        assert!(c.near == f32::INFINITY && c.far == f32::INFINITY);
    }

    #[test]
    fn neighbours_closer_than_the_thickness_at_rest_are_exempt() {
        let coarse = ClothModel::grid(&GridSpec::new(8, 8, 0.03)).unwrap();
        let c = SelfContacts::new(&coarse.triangles, &coarse.rest_positions, 0.005, 0.0);
        assert_eq!(c.exempt_count(), 0);
        // At 2 mm spacing a 5 mm thickness reaches the next ring of triangles and edges.
        let fine = ClothModel::grid(&GridSpec::new(8, 8, 0.002)).unwrap();
        let mut c = SelfContacts::new(&fine.triangles, &fine.rest_positions, 0.005, 0.0);
        assert!(c.exempt_count() > 100, "{}", c.exempt_count());
        // So the flat cloth at rest has no candidate pairs and nothing moves.
        let start = fine.rest_positions.clone();
        let (mut x, mut v) = (start.clone(), vec![Vec3::ZERO; start.len()]);
        resolve(&mut c, &start, &mut x, &mut v, &vec![1.0; start.len()]);
        assert_eq!(c.candidate_count(), (0, 0));
        assert_eq!(x, start);
    }

    /// The most the normal of the triangle with a right angle at the origin and legs `(u, 0, 0)`
    /// and `(0, 0, w)` turns as its right-angle vertex moves by `d` any way.
    fn most_turn(u: f32, w: f32, d: f32) -> f32 {
        let [a, b] = [Vec3::new(u, 0.0, 0.0), Vec3::new(0.0, 0.0, w)];
        let normal = |p: Vec3| (b - a).cross(p - a).normalize();
        let mut most = 0.0f32;
        for i in 0..=200 {
            let polar = std::f32::consts::PI * i as f32 / 200.0;
            for j in 0..40 {
                let azimuth = std::f32::consts::TAU * j as f32 / 40.0;
                let dir = Vec3::new(
                    polar.sin() * azimuth.cos(),
                    polar.cos(),
                    polar.sin() * azimuth.sin(),
                );
                most = most.max(normal(Vec3::ZERO).angle_between(normal(d * dir)));
            }
        }
        most
    }

    #[test]
    fn a_culled_patch_cannot_fold_while_its_vertices_stay_within_the_reach() {
        // A thin cloth, so that the reach is most of a triangle's altitude.
        let e = 1.0 / 63.0;
        let grid = ClothModel::grid(&GridSpec::new(8, 8, e)).unwrap();
        let mut c = SelfContacts::new(&grid.triangles, &grid.rest_positions, 0.001, 0.0);
        c.reach = c.reach_cap;
        let flat = cull_angle(c.reach, c.altitude);
        assert!(flat > 0.0, "the thin cloth culls at {flat} rad");
        // A degenerate triangle (no altitude, with or without a reach) culls nothing.
        for reach in [0.0, c.reach] {
            assert!(cull_angle(reach, 0.0) < 0.0, "degenerate, reach {reach}");
        }
        // A triangle of the grid whose right-angle vertex moves by twice the reach relative to
        // the other two, every way: its normal may not turn past the right angle that the
        // culled patches' cones leave.
        let most = most_turn(e, e, 2.0 * c.reach);
        assert!(
            flat + most < std::f32::consts::FRAC_PI_2,
            "cones of {flat} rad culled, a triangle turned {most} rad"
        );
        // The same cloth compressed to 0.8 of its width at the search: thinner triangles turn
        // further, and the search culls less.
        let x: Vec<Vec3> = grid
            .rest_positions
            .iter()
            .map(|p| p * Vec3::new(0.8, 1.0, 1.0))
            .collect();
        let margin = c.thickness + 2.0 * c.reach;
        c.find_candidates(&x, margin, usize::MAX, Some((c.cull(), 0.0)));
        let flat = c.patches.flat();
        let most = most_turn(0.8 * e, e, 2.0 * c.reach);
        assert!(
            flat + most < std::f32::consts::FRAC_PI_2,
            "compressed: cones of {flat} rad culled, a triangle turned {most} rad"
        );
    }

    /// Two triangles: a fixed one in y = 0 and a free one above it, whose first vertex dips to
    /// `dip` below the first triangle's interior over the substep.
    fn falling_vertex(dip: f32) -> (SelfContacts, Vec<Vec3>, Vec<Vec3>) {
        let start = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.25, 0.02, 0.25),
            Vec3::new(2.0, 0.5, 2.0),
            Vec3::new(3.0, 0.5, 2.0),
        ];
        let mut end = start.clone();
        end[3].y = -dip;
        let contacts = SelfContacts::new(&[0, 1, 2, 3, 4, 5], &start, 0.005, 0.0);
        (contacts, start, end)
    }

    #[test]
    fn a_resting_layer_is_resolved_every_few_substeps_and_sinks_at_most_the_slack() {
        // A free sheet lying the thickness above a fixed one, pulled down by gravity: between
        // resolutions it falls, and each resolution puts it back.
        // The top sheet's vertices lie over the centres of the bottom sheet's cells.
        let thickness = 0.005;
        let bottom = ClothModel::grid(&GridSpec::new(4, 4, 0.1)).unwrap();
        let top = ClothModel::grid(&GridSpec::new(3, 3, 0.1)).unwrap();
        let mut tris = bottom.triangles.clone();
        tris.extend(top.triangles.iter().map(|&i| i + 16));
        let rest: Vec<Vec3> = (bottom.rest_positions.iter())
            .chain(&top.rest_positions)
            .copied()
            .collect();
        let mut rest_apart = rest.clone();
        rest_apart[16..].iter_mut().for_each(|p| p.y = 1.0);
        let mut contacts = SelfContacts::new(&tris, &rest_apart, thickness, 0.0);
        let mut x = rest.clone();
        x[16..].iter_mut().for_each(|p| p.y = thickness);
        let w: Vec<f32> = (0..x.len())
            .map(|i| if i < 16 { 0.0 } else { 1.0 })
            .collect();
        let mut v = vec![Vec3::ZERO; x.len()];
        // Three times gravity, as a crease's springs pull a layer down.
        let (h, g) = (1.0 / 1200.0, Vec3::new(0.0, -30.0, 0.0));
        let (frames, substeps) = (10, 20);
        for _ in 0..frames {
            contacts.begin_step(0.002);
            for sub in 0..substeps {
                let start = x.clone();
                for (x, v) in x.iter_mut().zip(&mut v).skip(16) {
                    *v += g * h;
                    *x += *v * h;
                }
                let last = sub + 1 == substeps;
                substep(&mut contacts, (h, last), &start, (&mut x, &mut v), &w);
                let lowest = x[16..].iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
                assert!(
                    lowest >= thickness * (1.0 - DEFER) - 1e-6,
                    "sank to {lowest} m, past the slack"
                );
                if last {
                    assert!(
                        lowest >= thickness - 1e-6,
                        "a step ended with the layer {lowest} m apart"
                    );
                }
            }
        }
        let (resolved, all) = (contacts.resolutions(), frames * substeps);
        assert!(
            resolved > frames as u64 && 4 * resolved <= all as u64,
            "{resolved} resolutions in {all} substeps"
        );
    }

    #[test]
    fn a_vertex_that_passed_through_a_triangle_is_put_back_on_its_side() {
        for dip in [0.001, 0.004, 0.01] {
            let (mut c, start, mut x) = falling_vertex(dip);
            let mut v = vec![Vec3::ZERO; 6];
            v[3] = Vec3::new(0.1, -2.0, 0.0);
            let w = [0.0, 0.0, 0.0, 1.0, 1.0, 1.0];
            resolve(&mut c, &start, &mut x, &mut v, &w);
            assert!((x[3].y - 0.005).abs() < 1e-6, "dip {dip}: {}", x[3]);
            // The approach is removed, the sliding slowed by nothing (frictionless).
            assert!(
                v[3].y.abs() < 1e-6 && (v[3].x - 0.1).abs() < 1e-6,
                "{}",
                v[3]
            );
        }
    }

    #[test]
    fn a_part_that_comes_from_far_away_is_found_and_kept_apart() {
        // A fixed triangle, and another 2.8 m away that slides over it as a whole, 7 mm at a
        // time, then dips through it: no two neighbouring cubes move relative to each other,
        // so only the far bound sees them come together.
        let mut x = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.1, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 0.1),
            Vec3::new(2.02, 0.02, 2.02),
            Vec3::new(2.3, 0.02, 2.0),
            Vec3::new(2.0, 0.02, 2.3),
        ];
        let mut c = SelfContacts::new(&[0, 1, 2, 3, 4, 5], &x, 0.005, 0.0);
        let w = [0.0, 0.0, 0.0, 1.0, 1.0, 1.0];
        let mut v = vec![Vec3::ZERO; 6];
        let mut slide = |c: &mut SelfContacts, x: &mut Vec<Vec3>, by: Vec3| {
            let start = x.clone();
            for p in &mut x[3..] {
                *p += by;
            }
            resolve_within(c, 0.01, &start, x, &mut v, &w);
        };
        for _ in 0..400 {
            slide(&mut c, &mut x, Vec3::new(-0.005, 0.0, -0.005));
        }
        assert!(c.searches() > 1, "{} searches", c.searches());
        // Put back on its side, at least the thickness away.
        slide(&mut c, &mut x, Vec3::new(0.0, -0.03, 0.0));
        assert!(x[3].y > 0.005 - 1e-5, "{}", x[3]);
    }

    #[test]
    fn a_skipped_check_never_lets_particles_come_closer_than_the_reach() {
        // A 12×12 grid flying along fast and steadily, one half of it drifting off the other's
        // plane: no pair comes near, but the halves move apart (relative to each other) by a
        // little every substep, so the candidates must be found again now and then.
        let model = ClothModel::grid(&GridSpec::new(12, 12, 0.03)).unwrap();
        let rest = &model.rest_positions;
        let mut c = SelfContacts::new(&model.triangles, rest, 0.005, 0.0);
        let [a, b, d] = [0, 1, 12].map(|i| rest[i]);
        let normal = (b - a).cross(d - a).normalize();
        let at = |k: usize| -> Vec<Vec3> {
            let k = k as f32;
            rest.iter()
                .map(|p| {
                    let lift = if p.distance(a) > 0.2 { 3e-4 * k } else { 0.0 };
                    *p + Vec3::new(0.012, -0.004, 0.008) * k + normal * lift
                })
                .collect()
        };
        let w = vec![1.0; rest.len()];
        let (mut skipped, mut searches) = (0, 0);
        for k in 1..300 {
            let (start, mut x) = (at(k - 1), at(k));
            let mut v = vec![Vec3::ZERO; x.len()];
            resolve_within(&mut c, 0.01, &start, &mut x, &mut v, &w);
            if c.searches() > searches {
                searches = c.searches();
                continue;
            }
            skipped += usize::from(c.regions.skipped > 0);
            // Kept candidates hold every pair that came within the larger of their cubes' limits
            // of each other (neighbours), the far limit (within a block's size) or the wide limit
            // (any two), relative to where they were found, and each edge's ends within twice
            // the reach.
            let x = at(k);
            let moved: Vec<Vec3> = x.iter().zip(&c.found).map(|(x, f)| *x - *f).collect();
            let cube = |p: usize| c.regions.limit[c.regions.of[p] as usize];
            for p in 0..x.len() {
                for q in p + 1..x.len() {
                    let closer = moved[p].distance(moved[q]);
                    let apart = c.found[p].distance(c.found[q]) / c.regions.size;
                    // Particles found farther apart than a cube's side may come closer by their
                    // distance less two edges and the thickness (the far limit at a side).
                    let limit = if apart < 1.0 {
                        cube(p).max(cube(q))
                    } else {
                        c.far_limit + (apart - 1.0) * c.regions.size
                    };
                    assert!(
                        closer <= limit,
                        "substep {k}: {p}, {q} came {closer} closer"
                    );
                }
            }
            for &[a, b] in &c.edges {
                let closer = moved[a as usize].distance(moved[b as usize]);
                assert!(closer <= 2.0 * c.reach, "substep {k}: edge {a}, {b}");
            }
        }
        assert!(
            searches > 2 && skipped > 150,
            "{searches} searches, {skipped} skipped"
        );
    }

    #[test]
    fn the_far_limit_holds_for_elements_with_particles_in_cubes_not_neighbouring() {
        // Two triangles whose long edges (4 cm; the shortest edge 1 cm) lie along x, the second
        // beyond the first and 5 mm above its line, so that the first edge's near end and the
        // second's far end lie in cubes two apart while the edges' facing ends are a cube's size
        // less two edges apart. Any two particles may come closer by the far limit before the
        // cubes' check asks for a search, so every pair of elements with such particles must be
        // farther apart than that plus the thickness.
        let place = |size: f32| {
            let a = Vec3::new(0.99 * size, 0.0, 0.0);
            let c = a + Vec3::new(1.02 * size - 0.04, 0.005, 0.0);
            vec![
                a,
                a + Vec3::new(0.04, 0.0, 0.0),
                a + Vec3::new(0.0, 0.0, -0.01),
                c,
                c + Vec3::new(0.04, 0.0, 0.0),
                c + Vec3::new(0.04, 0.0, 0.01),
            ]
        };
        let thickness = 0.001;
        // The cubes' size depends on the edges' lengths only.
        let size = SelfContacts::new(&[0, 1, 2, 3, 4, 5], &place(0.1), thickness, 0.0)
            .regions
            .size;
        let x = place(size);
        let mut c = SelfContacts::new(&[0, 1, 2, 3, 4, 5], &x, thickness, 0.0);
        assert!((c.regions.size - size).abs() < 1e-6);
        let (mut moved, mut v, w) = (x.clone(), vec![Vec3::ZERO; 6], vec![1.0; 6]);
        resolve(&mut c, &x, &mut moved, &mut v, &w);
        assert_eq!(c.searches(), 1);
        let of = &c.regions.of;
        let apart = |p: usize, q: usize| {
            let cell = |i: usize| cell_of(x[i], 1.0 / c.regions.size);
            let (a, b) = (cell(p), cell(q));
            (0..3).any(|k| (a[k] - b[k]).abs() > 1)
        };
        assert!(
            apart(0, 4) && of[0] != of[4],
            "the ends are in cubes two apart"
        );
        let mut checked = 0;
        for e in &c.edges {
            for f in &c.edges {
                let quad = [e[0], e[1], f[0], f[1]].map(|i| i as usize);
                let far = (0..2).any(|i| (2..4).any(|j| apart(quad[i], quad[j])));
                if quad[..2].iter().any(|i| quad[2..].contains(i)) || !far {
                    continue;
                }
                let [a, b, p, q] = quad.map(|i| x[i]);
                let (s, t) = closest_on_segments(a, b, p, q);
                let gap = a.lerp(b, s).distance(p.lerp(q, t));
                assert!(
                    gap >= c.far_limit + thickness,
                    "edges {e:?} and {f:?} are {gap} apart, the far limit {}",
                    c.far_limit
                );
                checked += 1;
            }
        }
        assert!(checked > 0);
    }

    #[test]
    fn particles_in_blocks_not_neighbouring_search_again_past_the_wide_limit() {
        // Two triangles (1 cm sides) ten cubes apart along x, in blocks that are not neighbours:
        // the second slides toward the first, rigidly, so only the bound over any two particles
        // sees it.
        let triangle = |at: f32| {
            let a = Vec3::new(at, 0.0, 0.0);
            [
                a,
                a + Vec3::new(0.01, 0.0, 0.0),
                a + Vec3::new(0.0, 0.0, 0.01),
            ]
        };
        let size = SelfContacts::new(&[0, 1, 2], &triangle(0.0), 0.001, 0.0)
            .regions
            .size;
        let place = |shift: f32| -> Vec<Vec3> {
            triangle(0.0)
                .into_iter()
                .chain(triangle(10.0 * size - shift))
                .collect()
        };
        let w = vec![1.0; 6];
        // Searched where it starts, then slid over one substep (the first check after a search
        // takes the cubes' references from that substep, so only the slide counts).
        let slid = |by: f32| {
            let mut c = SelfContacts::new(&[0, 1, 2, 3, 4, 5], &place(0.0), 0.001, 0.0);
            let (start, mut x, mut v) = (place(0.0), place(0.0), vec![Vec3::ZERO; 6]);
            resolve(&mut c, &start, &mut x, &mut v, &w);
            assert_eq!(c.searches(), 1);
            let wide = c.wide_limit;
            assert!(wide > 0.0 && wide < 9.0 * size, "{wide}");
            let mut moved = place(by * wide);
            resolve(&mut c, &start, &mut moved, &mut v, &w);
            c.searches()
        };
        assert_eq!(slid(0.9), 1, "within the wide limit");
        assert_eq!(slid(1.1), 2, "past the wide limit");
    }

    #[test]
    fn a_mesh_of_uneven_edges_at_rest_searches_once() {
        // An eight-sector disc: its hem edges are 0.39 of its spokes and its longest edges (the
        // quads' diagonals) 2.7 times its shortest, so cubes sized by the shortest edge alone
        // would leave no far limit, and every substep would search again.
        use crate::sim::DiscSpec;
        let disc = ClothModel::disc(&DiscSpec::new(8, 12, 0.5)).unwrap();
        let x = disc.rest_positions.clone();
        let mut c = SelfContacts::new(&disc.triangles, &x, 0.005, 0.0);
        let w = vec![1.0; x.len()];
        for _ in 0..10 {
            let (mut moved, mut v) = (x.clone(), vec![Vec3::ZERO; x.len()]);
            resolve(&mut c, &x, &mut moved, &mut v, &w);
        }
        assert!(c.far_limit > 0.0, "{}", c.far_limit);
        assert_eq!(c.searches(), 1);
    }

    /// [`Vectors`] stored in another order: model particle `p` at `slot[p]`.
    struct Reordered<'a> {
        inner: Vectors<'a>,
        slot: Vec<usize>,
    }

    impl ContactState for Reordered<'_> {
        fn len(&self) -> usize {
            self.inner.len()
        }
        fn inv_mass(&self, i: usize) -> f32 {
            self.inner.inv_mass(i)
        }
        fn slot(&self, p: u32) -> usize {
            self.slot[p as usize]
        }
        fn start(&self, i: usize) -> Vec3 {
            self.inner.start(i)
        }
        fn position(&self, i: usize) -> Vec3 {
            self.inner.position(i)
        }
        fn velocity(&self, i: usize) -> Vec3 {
            self.inner.velocity(i)
        }
        fn set(&mut self, i: usize, x: Vec3, v: Vec3) {
            self.inner.set(i, x, v);
        }
        fn clearances(&self, near: crate::sim::contact::Near, within: f32, out: &mut [f32]) {
            self.inner.clearances(near, within, out);
        }
    }

    #[test]
    fn a_step_that_stores_the_particles_in_another_order_finds_its_pairs_again() {
        // A fixed triangle; free vertex 3 over it, and pinned vertex 4 (of another triangle) at
        // the same place. A step in the model's order finds the pair (3, triangle); the next step
        // stores 3 and 4 swapped and moves both through the triangle. Every particle moved alike
        // as far as the kept candidates can tell, so only noticing the new order makes the step
        // resolve particle 3 rather than the pinned particle now stored where 3 was.
        let over = Vec3::new(0.25, 0.006, 0.25);
        let start = vec![
            Vec3::ZERO,
            Vec3::X,
            Vec3::Z,
            over,
            over,
            Vec3::new(3.0, 0.0, 3.0),
            Vec3::new(4.0, 0.0, 3.0),
        ];
        let triangles = [0, 1, 2, 3, 5, 6, 4, 6, 5];
        // At rest vertex 4 lies on the triangle, so the pair (4, triangle) is exempt: no pair
        // but (3, triangle) can reach particle 3.
        let mut rest = start.clone();
        rest[4].y = 0.0;
        let mut c = SelfContacts::new(&triangles, &rest, 0.005, 0.0);
        let w = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0];
        let (mut x, mut v) = (start.clone(), vec![Vec3::ZERO; 7]);
        resolve_within(&mut c, 0.05, &start, &mut x, &mut v, &w);
        assert!(c.vt.contains(&(3, 0)), "{:?}", c.vt);
        // Stored order: 0 1 2 4 3 5 6.
        let order = [0, 1, 2, 4, 3, 5, 6];
        let swapped = |a: &[Vec3]| order.map(|p| a[p]).to_vec();
        let mut end = start.clone();
        end[3].y = -0.003;
        end[4].y = -0.003;
        let (stored_start, mut x) = (swapped(&end), swapped(&end));
        let stored_start: Vec<Vec3> = order
            .iter()
            .zip(&stored_start)
            .map(|(&p, e)| if p == 3 || p == 4 { over } else { *e })
            .collect();
        let mut v = vec![Vec3::ZERO; 7];
        let stored_w = order.map(|p| w[p]);
        c.begin_step(0.05);
        let mut state = Reordered {
            inner: Vectors {
                x: &mut x,
                v: &mut v,
                start: &stored_start,
                inv_mass: &stored_w,
                touches: None,
            },
            slot: vec![0, 1, 2, 4, 3, 5, 6],
        };
        c.resolve((1.0 / 1200.0, true), &mut state);
        // Back above the triangle by the thickness (its edges' pairs may lift it a little more).
        assert!(x[4].y > 0.005 - 1e-6, "particle 3 at {}", x[4]);
    }

    #[test]
    fn a_push_within_a_pass_counts_toward_the_later_pairs() {
        // A free vertex in a wedge between two fixed triangles, 1 mm above the floor one and
        // 7 mm from the tilted one (thickness 5 mm). Nothing moves, so nothing has drifted;
        // pushing the vertex up out of the floor brings it within the thickness of the tilted
        // one, which must then be tested in the same pass. The vertex is in no triangle.
        let (p0, n2) = (Vec3::new(0.25, 0.001, 0.25), Vec3::new(-0.6, -0.8, 0.0));
        let q = p0 - 0.007 * n2;
        let (t1, t2) = (Vec3::new(0.8, -0.6, 0.0), Vec3::Z);
        let start = vec![
            Vec3::new(-1.0, 0.0, -1.0),
            Vec3::new(-1.0, 0.0, 2.0),
            Vec3::new(2.0, 0.0, -1.0),
            q + 0.004 * t1 - t2,
            q + 0.004 * t1 + t2,
            q - t1,
            p0,
        ];
        // At rest the vertex is far away (so that neither pair is exempt).
        let mut rest = start.clone();
        rest[6].y = 1.0;
        let mut c = SelfContacts::new(&[0, 1, 2, 3, 4, 5], &rest, 0.005, 0.0);
        let (mut x, mut v) = (start.clone(), vec![Vec3::ZERO; start.len()]);
        let w = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];
        // A reach wide enough for the tilted triangle to be a candidate.
        resolve_within(&mut c, 0.01, &start, &mut x, &mut v, &w);
        let p = x[6];
        let floor = p.y;
        let tilted = (p - q).dot(n2);
        assert!(floor > 0.0044 && tilted > 0.0044, "{floor} {tilted}");
    }

    #[test]
    fn a_pair_of_free_particles_keeps_its_momentum() {
        let (c, start, mut x) = falling_vertex(0.003);
        let mut v: Vec<Vec3> = (0..6)
            .map(|i| Vec3::new(0.3 * i as f32, -1.0, 0.1))
            .collect();
        let w = [2.0, 1.0, 0.5, 1.0, 1.0, 1.0];
        let momentum = |v: &[Vec3]| -> Vec3 { v.iter().zip(&w).map(|(v, w)| *v / *w).sum() };
        let (p0, v0) = (momentum(&v), v.clone());
        let centre = |x: &[Vec3]| -> Vec3 { x.iter().zip(&w).map(|(x, w)| *x / *w).sum() };
        let c0 = centre(&x);
        let mut c = SelfContacts { friction: 0.5, ..c };
        resolve(&mut c, &start, &mut x, &mut v, &w);
        assert!(v != v0, "the contact acted");
        assert!(
            (momentum(&v) - p0).length() < 1e-5,
            "{} vs {p0}",
            momentum(&v)
        );
        assert!((centre(&x) - c0).length() < 1e-5);
    }

    #[test]
    fn edges_that_passed_through_each_other_are_put_back_apart() {
        // Edge 0–1 along x at y = 0 (fixed), edge 3–4 along z, which moves from above it to
        // below it over the substep; their triangles' other vertices are far away.
        let start = vec![
            Vec3::new(-1.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, -3.0),
            Vec3::new(0.0, 0.01, -1.0),
            Vec3::new(0.0, 0.01, 1.0),
            Vec3::new(-3.0, 0.01, 3.0),
        ];
        let mut x = start.clone();
        x[3].y = -0.01;
        x[4].y = -0.01;
        let mut c = SelfContacts::new(&[0, 1, 2, 3, 4, 5], &start, 0.005, 0.0);
        let mut v = vec![Vec3::ZERO; 6];
        let w = [0.0, 0.0, 0.0, 1.0, 1.0, 0.0];
        resolve(&mut c, &start, &mut x, &mut v, &w);
        // The closest points, at the edges' middles, are the edges' kept distance apart on the
        // starting side.
        let middle = 0.5 * (x[3] + x[4]);
        let kept = EDGES_APART * 0.005;
        assert!((middle.y - kept).abs() < 1e-4, "{} {}", x[3], x[4]);
    }

    #[test]
    fn edges_off_every_triangle_are_kept_their_distance_apart_on_their_side() {
        // Edge 3–4 crosses edge 0–1 obliquely at their middles and moves down from above it:
        // slowly to within their distance, or through it to twice the thickness below. Neither
        // of its ends is over triangle 0–1–2, and its own triangle stands upright, far from 0
        // and 1: only the edge pair sees them.
        for end in [0.004, -0.01] {
            let start = vec![
                Vec3::new(-1.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(0.0, 0.0, -3.0),
                Vec3::new(-0.9, 0.006, -0.5),
                Vec3::new(0.9, 0.006, 0.5),
                Vec3::new(0.0, 3.0, 0.0),
            ];
            let mut x = start.clone();
            x[3].y = end;
            x[4].y = end;
            let mut c = SelfContacts::new(&[0, 1, 2, 3, 4, 5], &start, 0.005, 0.0);
            let mut v = vec![Vec3::ZERO; 6];
            let w = [0.0, 0.0, 0.0, 1.0, 1.0, 0.0];
            resolve(&mut c, &start, &mut x, &mut v, &w);
            let middle = 0.5 * (x[3] + x[4]);
            assert!(
                (middle.y - EDGES_APART * 0.005).abs() < 1e-4,
                "end {end}: {} {}",
                x[3],
                x[4]
            );
        }
    }

    #[test]
    fn closest_points_of_crossing_and_parallel_segments() {
        let (s, t) = closest_on_segments(
            Vec3::new(-1.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.5, -1.0, 0.2),
            Vec3::new(0.5, 1.0, 0.2),
        );
        assert!((s - 0.75).abs() < 1e-6 && (t - 0.5).abs() < 1e-6, "{s} {t}");
        let (s, t) = closest_on_segments(
            Vec3::ZERO,
            Vec3::X,
            Vec3::new(2.0, 0.1, 0.0),
            Vec3::new(3.0, 0.1, 0.0),
        );
        assert_eq!((s, t), (1.0, 0.0));
    }

    #[test]
    fn point_triangle_distance_over_the_face_and_past_an_edge() {
        let (a, b, c) = (Vec3::ZERO, Vec3::X, Vec3::Y);
        assert!((point_triangle_distance(Vec3::new(0.2, 0.2, -0.3), a, b, c) - 0.3).abs() < 1e-6);
        let d = point_triangle_distance(Vec3::new(2.0, 0.0, 0.0), a, b, c);
        assert!((d - 1.0).abs() < 1e-6);
    }

    #[test]
    fn the_broad_phase_finds_exactly_the_pairs_within_the_margin() {
        // A 12×12 grid crumpled by a pseudo-random jitter of half its spacing: the broad phase's
        // pairs equal a brute-force search's (every pair sharing no vertex, closer than the
        // margin), each once.
        let model = ClothModel::grid(&GridSpec::new(12, 12, 0.03)).unwrap();
        let mut c = SelfContacts::new(&model.triangles, &model.rest_positions, 0.005, 0.0);
        let jitter = |i: usize, k: usize| ((i * 7919 + k * 104_729) % 1000) as f32 / 1000.0 - 0.5;
        let x: Vec<Vec3> = model
            .rest_positions
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let fold = Vec3::new(0.0, (p.x * 40.0).sin() * 0.05, 0.0);
                *p + fold + 0.015 * Vec3::new(jitter(i, 0), jitter(i, 1), jitter(i, 2))
            })
            .collect();
        let margin = 0.02;
        c.find_candidates(&x, margin, usize::MAX, NO_CULL);
        let mut vt = c.vt.clone();
        let mut ee = c.ee.clone();
        vt.sort_unstable();
        ee.sort_unstable();
        let [expected_vt, expected_ee] = pairs_within(&c, &x, margin);
        assert!(!expected_vt.is_empty() && !expected_ee.is_empty());
        assert_eq!(vt, expected_vt);
        assert_eq!(ee, expected_ee);
        assert_eq!(c.ee.len(), expected_ee.len(), "each pair once");
    }

    #[test]
    fn a_search_on_positions_that_are_not_finite_pairs_nothing() {
        // A crumpled grid with one particle at infinity and one NaN, searched through the patch
        // pairs and through the hash: no candidates (and no grid of cells spanning infinity).
        let model = ClothModel::grid(&GridSpec::new(12, 12, 0.02)).unwrap();
        let mut x: Vec<Vec3> = (model.rest_positions.iter())
            .map(|p| Vec3::new(p.x, (p.x * 30.0).sin() * 0.02, p.z))
            .collect();
        x[5].x = f32::INFINITY;
        x[40].y = f32::NAN;
        let mut c = SelfContacts::new(&model.triangles, &model.rest_positions, 0.005, 0.0);
        for loose in [false, true] {
            c.loose = loose;
            c.find_candidates(&x, 0.015, usize::MAX, Some((move |_| 1.0, 0.0)));
            assert_eq!(c.candidate_count(), (0, 0), "loose {loose}");
        }
    }

    #[test]
    fn a_cell_is_the_floor_of_the_scaled_point() {
        let values = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            2.999,
            -2.999,
            3.0,
            -3.0,
            1e-30,
            -1e-30,
            1e6 + 0.5,
            -1e6 - 0.5,
            3e9,
            -3e9,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        for x in values {
            let expected = Vec3::splat(x).floor().as_ivec3().x;
            assert_eq!(cell_of(Vec3::new(x, 0.0, 0.0), 1.0)[0], expected, "{x}");
        }
    }

    #[test]
    fn the_patch_pairs_find_what_the_hash_finds() {
        // A crumpled grid and a folded one, searched through the patch pairs and through the hash
        // (the path of a mesh with a loose vertex), with some patches culled and with none: the
        // same candidates, each once.
        let model = ClothModel::grid(&GridSpec::new(24, 24, 0.02)).unwrap();
        let jitter = |i: usize, k: usize| ((i * 7919 + k * 104_729) % 1000) as f32 / 1000.0 - 0.5;
        let rest = &model.rest_positions;
        let crumpled: Vec<Vec3> = (rest.iter().enumerate())
            .map(|(i, p)| {
                let fold = Vec3::new(0.0, (p.x * 30.0).sin() * 0.04, 0.0);
                *p + fold + 0.01 * Vec3::new(jitter(i, 0), jitter(i, 1), jitter(i, 2))
            })
            .collect();
        let folded: Vec<Vec3> = rest
            .iter()
            .map(|p| {
                if p.x < 0.0 {
                    *p
                } else {
                    Vec3::new(-p.x, 0.012, p.z)
                }
            })
            .collect();
        let mut c = SelfContacts::new(&model.triangles, rest, 0.005, 0.0);
        assert!(!c.loose);
        let search = |c: &mut SelfContacts, x: &[Vec3], flat: f32, loose: bool| {
            c.loose = loose;
            c.find_candidates(x, 0.015, usize::MAX, Some((move |_| flat, 0.0)));
            let (mut vt, mut ee) = (c.vt.clone(), c.ee.clone());
            vt.sort_unstable();
            ee.sort_unstable();
            (vt, ee)
        };
        for x in [&crumpled, &folded] {
            for flat in [1.0, -1.0] {
                let through_pairs = search(&mut c, x, flat, false);
                let through_hash = search(&mut c, x, flat, true);
                assert!(!through_hash.0.is_empty() && !through_hash.1.is_empty());
                assert_eq!(through_pairs, through_hash, "flat {flat}");
                let (vt, ee) = through_pairs;
                assert!(vt.windows(2).all(|w| w[0] != w[1]) && ee.windows(2).all(|w| w[0] != w[1]));
            }
        }
    }

    /// Every vertex–triangle and edge–edge pair of `c` at `x` sharing no vertex and closer than
    /// `margin`, found by brute force.
    fn pairs_within(c: &SelfContacts, x: &[Vec3], margin: f32) -> [Vec<(u32, u32)>; 2] {
        let mut vt = Vec::new();
        for p in 0..x.len() as u32 {
            for (t, tri) in c.tris.iter().enumerate() {
                let [a, b, d] = tri.map(|i| x[i as usize]);
                if !tri.contains(&p) && point_triangle_distance(x[p as usize], a, b, d) < margin {
                    vt.push((p, t as u32));
                }
            }
        }
        let mut ee = Vec::new();
        for (e, &[a, b]) in c.edges.iter().enumerate() {
            for (f, &[d, g]) in c.edges.iter().enumerate().skip(e + 1) {
                if [d, g].iter().any(|v| *v == a || *v == b) {
                    continue;
                }
                let [pa, pb, pd, pg] = [a, b, d, g].map(|i| x[i as usize]);
                let (s, t) = closest_on_segments(pa, pb, pd, pg);
                if pa.lerp(pb, s).distance(pd.lerp(pg, t)) < margin {
                    ee.push((e as u32, f as u32));
                }
            }
        }
        [vt, ee]
    }

    /// `n` particles scattered in a cube `across` wide about the origin (a cloth crushed into a
    /// ball), a different scatter for each `seed`.
    fn crushed(n: usize, across: f32, seed: u64) -> Vec<Vec3> {
        (0..n)
            .map(|i| {
                let h = |k: u64| unit_interval(mix64((i as u64 * 3 + k) ^ (seed << 32)));
                across * (Vec3::new(h(0), h(1), h(2)) - 0.5)
            })
            .collect()
    }

    #[test]
    fn a_full_list_ends_its_search_with_the_first_candidates() {
        // A 12×12 grid crushed into a ball a few millimetres across: every pair is within the
        // margin. Capped, each list holds exactly the first candidates of the uncapped search,
        // and a full list of one kind does not cut the other short.
        let model = ClothModel::grid(&GridSpec::new(12, 12, 0.03)).unwrap();
        let mut c = SelfContacts::new(&model.triangles, &model.rest_positions, 0.005, 0.0);
        let x = crushed(model.rest_positions.len(), 0.004, 0);
        let (margin, flat) = (0.02, 0.5);
        c.find_candidates(&x, margin, usize::MAX, Some((move |_| flat, 0.0)));
        assert!(
            !c.patches.pairs().is_empty(),
            "the ball is searched patch by patch"
        );
        let (vt, ee) = (c.vt.clone(), c.ee.clone());
        let vt_gaps = c.gap[..vt.len()].to_vec();
        let cap = vt.len() / 3;
        assert!(
            cap < ee.len() / 2 && ee.len() > vt.len(),
            "the cap binds both kinds"
        );
        c.find_candidates(&x, margin, cap, Some((move |_| flat, 0.0)));
        assert_eq!(c.vt, vt[..cap]);
        assert_eq!(c.ee, ee[..cap]);
        assert_eq!(c.gap[..cap], vt_gaps[..cap]);
        // A cap only the edge pairs reach leaves the vertex–triangle pairs whole.
        c.find_candidates(&x, margin, vt.len(), Some((move |_| flat, 0.0)));
        assert_eq!((c.vt.len(), c.ee.len()), (vt.len(), vt.len()));
        assert_eq!(c.ee, ee[..vt.len()]);
    }

    #[test]
    fn a_full_list_is_searched_again_only_in_the_next_step() {
        // A 12×12 grid crushed into a ball 2 cm across, its particles jostled every substep by
        // more than the search's reach: both lists fill up at each search. Within a step the
        // candidates are kept; the next step searches again.
        let model = ClothModel::grid(&GridSpec::new(12, 12, 0.03)).unwrap();
        let n = model.rest_positions.len();
        let mut c = SelfContacts::new(&model.triangles, &model.rest_positions, 0.005, 0.0);
        let w = vec![1.0; n];
        let mut x = crushed(n, 0.02, 0);
        let mut v = vec![Vec3::ZERO; n];
        let mut count = 0;
        for step in 1..=3 {
            c.begin_step(0.001);
            for _ in 0..4 {
                count += 1;
                let start = x.clone();
                x = crushed(n, 0.02, count);
                substep(&mut c, (1.0 / 1200.0, true), &start, (&mut x, &mut v), &w);
                assert!(c.full(), "the crushed ball fills a list");
            }
            assert_eq!(c.searches(), step, "one search in step {step}");
        }
    }

    #[test]
    fn flat_patches_are_not_searched_and_a_fold_is() {
        // A 16×16 grid (3 cm spacing) folded in half over a 1 cm radius: two flat layers 2 cm
        // apart (x is the arc length across the grid, centred on 0). With the normal-cone cull,
        // the flat layers are not searched against themselves, but every pair between the layers
        // within the margin is found.
        let model = ClothModel::grid(&GridSpec::new(16, 16, 0.03)).unwrap();
        let mut c = SelfContacts::new(&model.triangles, &model.rest_positions, 0.005, 0.0);
        let margin = 0.025;
        let flat = 1.0;
        c.find_candidates(
            &model.rest_positions,
            margin,
            usize::MAX,
            Some((move |_| flat, 0.0)),
        );
        assert!(c.patches.pairs().is_empty(), "a flat cloth is not searched");
        assert_eq!(c.candidate_count(), (0, 0));

        let r = 0.01;
        let layer = |p: Vec3| (p.x > std::f32::consts::FRAC_PI_2 * r) as u8;
        let x = folded(&model.rest_positions, 0.0, r);
        c.find_candidates(&x, margin, usize::MAX, Some((move |_| flat, 0.0)));
        let (vt, ee) = (c.vt.clone(), c.ee.clone());
        let [all_vt, all_ee] = pairs_within(&c, &x, margin);
        let rest = &model.rest_positions;
        let across = |v: &[u32]| {
            v.iter()
                .any(|&i| layer(rest[i as usize]) != layer(rest[v[0] as usize]))
        };
        let mut crossing = 0;
        for &(p, t) in &all_vt {
            let [a, b, d] = c.tris[t as usize];
            if across(&[p, a, b, d]) {
                crossing += 1;
                assert!(
                    vt.contains(&(p, t)),
                    "vertex {p} over triangle {t} across the fold"
                );
            }
        }
        for &(e, f) in &all_ee {
            let ([a, b], [d, g]) = (c.edges[e as usize], c.edges[f as usize]);
            if across(&[a, b, d, g]) {
                crossing += 1;
                assert!(ee.contains(&(e, f)), "edges {e} and {f} across the fold");
            }
        }
        assert!(crossing > 100, "{crossing}");
        assert!(
            vt.len() + ee.len() < all_vt.len() + all_ee.len(),
            "nothing culled"
        );
    }

    #[test]
    fn the_hash_finds_every_overlapping_box_once() {
        // Boxes on a jittered lattice, queried by boxes of every size up to a cell: the hash's
        // answers equal a brute-force overlap test's, each once.
        let mut hash = Hash::default();
        let jitter = |i: usize, k: usize| ((i * 7919 + k * 104_729) % 1000) as f32 / 1000.0;
        hash.boxes = (0..300)
            .map(|i| {
                let lo = Vec3::new(jitter(i, 0), jitter(i, 1), jitter(i, 2)) * 3.0 - 1.5;
                (
                    lo,
                    lo + Vec3::new(jitter(i, 3), jitter(i, 4), jitter(i, 5)) * 0.4,
                )
            })
            .collect();
        assert!(hash.build(|_| true));
        for q in 0..200 {
            let lo = Vec3::new(jitter(q, 6), jitter(q, 7), jitter(q, 8)) * 3.0 - 1.5;
            let hi = lo + Vec3::new(jitter(q, 9), jitter(q, 10), jitter(q, 11)) * 0.3;
            let mut found = Vec::new();
            hash.visit(lo, hi, |i| found.push(i));
            let mut expected: Vec<u32> = (0..hash.boxes.len() as u32)
                .filter(|&i| {
                    let (blo, bhi) = hash.boxes[i as usize];
                    blo.cmple(hi).all() && bhi.cmpge(lo).all()
                })
                .collect();
            found.sort_unstable();
            expected.sort_unstable();
            assert_eq!(found, expected, "query {q}");
        }
    }
}
