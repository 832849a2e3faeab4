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
//!    of the cloth keeps for the patches it holds (`ParticleCubes::limit`); a culled patch
//!    keeps its cone while each of its triangles' edges' ends move within twice the reach of each
//!    other. Each substep bounds the displacements cube by cube and block by block of cubes
//!    (`ParticleCubes`), and edge by edge where the cubes' bound exceeds twice the reach: a
//!    cloth moving as a whole keeps its candidates; one whose parts move relative to each other searches
//!    again, within a step if need be. A cloth at rest searches once, and while its particles
//!    stay within the slack the last check left, it is not checked either: one vector pass over
//!    the particles (`LastCheck`) shows they did.
//! 3. **Narrow phase and response, at every substep where the layers may have come closer** (at the
//!    step's last substep always; at others only once any two particles can have come
//!    [`DEFER_CLOSING`] of the thickness closer since the last one, so a resting fold or pile is resolved every few
//!    substeps, see `LastResolution`), on whatever layout the stepper keeps its particles in
//!    ([`ContactState`]): for each candidate whose distance at the broad phase, less how far its
//!    particles have since moved relative to the cloth, may have fallen to the thickness (a pile's
//!    candidates mostly have not; they are ordered by that distance, so the pass stops where none
//!    further can have, see [`GapBands`]), and that a quick test does not find clear, the signed
//!    distance at the end of the substep along the pair's normal (the triangle's, for a vertex over
//!    a triangle's interior; the line between the closest points, for two edges), with its sign
//!    taken from the start of the substep. A pair closer than the thickness (two edges:
//!    `EDGES_APART_SHARE` of it), or on the other side of each other than at the start (it passed
//!    through within the substep), is pushed apart to that distance on its starting side, each
//!    particle moved in proportion to its inverse mass and its weight in the pair (momentum is
//!    kept). Then the relative velocity's approaching normal part is removed and Coulomb friction
//!    acts on its tangential part, bounded by `friction` times the normal change (the velocity
//!    removed plus the push-out over the time since the last resolution). Passes repeat
//!    (Gauss-Seidel) over the pairs that acted in the first until none is pushed by more than
//!    `CONVERGED_PUSH` of its kept distance, at most `MAX_PASSES` times in all.
//!
//! Deciding the side from the start of each substep is what keeps a pile from passing through
//! itself: a proximity test alone pushes a particle that has already crossed further through. A
//! deferred resolution keeps that sound: no pair can cross while it closes by less than its kept
//! distance, and deferring stops at a share of it. Not covered: two elements that pass through each
//! other and beyond within a single substep (faster than the thickness per substep relative to each
//! other; that needs a continuous test), and more candidate pairs than the cap (a cloth crushed
//! into a ball: the search stops when a list is full, and is not run again until the next step).
//!
//! # Layout
//! This file holds [`SelfContacts`] and its narrow phase; [`search`] its broad phase (when to
//! search again, and the search through patch pairs or the spatial hash); [`cubes`] the cubes and
//! blocks that bound how much closer particles came since; [`patches`] the patches and their
//! normal cones; [`grouped`] the items grouped by patch or block. What self-contacts share with
//! the contacts between cloths (the response to a pair, the snapshots, the spatial hash, the
//! bands of distance) is in `contact::pairs`.

use glam::{Vec3, Vec3A};

use super::narrow::ContactState;
use super::pairs::{
    DEFER_CLOSING, GapBands, GatheredParticles, LastResolution, LayerSpacing, SpatialHash,
    closest_on_segments, edge_table, later_passes, map_four, max_or_infinite, pair_key,
    point_triangle_distance, storage_order_changed,
};
use super::vectors::Vectors;
use crate::error::ClothError;
use cubes::{LastCheck, ParticleCubes};
use grouped::ItemsByGroup;
use patches::Patches;
use search::{MAX_CANDIDATES_PER_TRIANGLE, NO_CULL, is_listed};

mod cubes;
mod grouped;
mod patches;
mod search;
#[cfg(test)]
mod tests;

/// At most this many pairs of each kind (vertex–triangle, edge–edge) per triangle may lie within
/// the thickness at rest, where they are exempt for good and stored. A flat grid has none up to
/// 0.7 of its mean edge length and about 18 edge–edge pairs per triangle at
/// [`MAX_THICKNESS_PER_EDGE`](crate::sim::MAX_THICKNESS_PER_EDGE) times it; more means a rest
/// shape in layers closer than the thickness, whose pairs would grow without bound.
pub(crate) const MAX_EXEMPT_PAIRS_PER_TRIANGLE: usize = 32;

/// Share of the thickness that the two sides of a tear are kept apart until they have parted by
/// the thickness: they lay within it at rest (pulled apart by most of it where the cloth tore,
/// less at a jagged corner), so the full thickness would push them apart at once, but nothing
/// must let them pass through each other.
const PARTING_SHARE: f32 = 0.5;

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
    /// The pairs across a tear that lay within the thickness at rest, kept only
    /// [`PARTING_SHARE`] of it apart until they part (see [`Self::mark_parting`]), sorted.
    parting_vt: Vec<u64>,
    parting_ee: Vec<u64>,
    /// The triangles in patches, whose normal cones cull the search.
    patches: Patches,
    /// Patch of each edge (that of the triangle owning it).
    edge_patch: Vec<u32>,
    /// The vertices of each patch (see `Patches::of_vertex`), its triangles and its edges.
    patch_vertices: ItemsByGroup,
    patch_triangles: ItemsByGroup,
    patch_edges: ItemsByGroup,
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
    hash: SpatialHash,
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
    bands: [GapBands; 2],
    /// Scratch of the ordering into bands: the new order, and the lists being reordered.
    order: Vec<u32>,
    reordered_pairs: Vec<(u32, u32)>,
    reordered_gaps: Vec<f32>,
    /// The particles of `involved`, copied out of the state for the narrow phase and written
    /// back after it (scratch).
    gathered: GatheredParticles,
    /// The stored particles the last resolution moved.
    moved: Vec<u32>,
    /// Where each model particle is stored in the state being resolved.
    slot: Vec<u32>,
    /// Positions (by model particle) when the candidates were found; scratch of the search.
    found_at: Vec<Vec3>,
    /// Each stored particle's position at the start of the substep and its move over it, at
    /// the search (scratch).
    path_starts: Vec<Vec3>,
    path_steps: Vec<Vec3>,
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
    /// How much closer particles in cubes (`cubes`) that are not neighbours (in the same or
    /// neighbouring blocks) may come before a search is due: they were at least the cubes' size
    /// apart, so the elements they belong to were at least that less twice the longest edge apart
    /// (less one edge for a vertex and a triangle).
    far_limit: f32,
    /// How much closer particles in blocks (of `cubes`) that are not neighbours may come: as
    /// `far_limit`, for particles at least the blocks' size apart.
    wide_limit: f32,
    /// Per patch: how much closer the particles of its elements may come to those of neighbouring
    /// cubes (scratch of the search, see `ParticleCubes::limit`).
    patch_limit: Vec<f32>,
    /// The particles' cubes at the last broad phase, whose motion since tells when to search
    /// again.
    cubes: ParticleCubes,
    /// Where the particles were at the last check of `cubes`, which lets substeps skip it.
    last_check: LastCheck,
    /// Where the particles were at the last resolution, which lets substeps defer the next.
    last_resolution: LastResolution,
    /// The candidates that acted in a substep's first pass (scratch).
    acting: Vec<u32>,
    /// Whether the next resolution is a step's first (whose stepper may store the particles in
    /// another order than the last step's).
    new_step: bool,
}

impl SelfContacts {
    /// Self-contacts of a cloth with triangles `triangles` (three model particles each) whose
    /// particles rest at `rest`, `thickness` apart with `friction` between layers. Errors with
    /// [`ClothError::TooMany`] when more than [`MAX_EXEMPT_PAIRS_PER_TRIANGLE`] pairs per
    /// triangle of either kind lie within the thickness at rest (the search stops at one more).
    pub fn new(
        triangles: &[u32],
        rest: &[Vec3],
        thickness: f32,
        friction: f32,
    ) -> Result<Self, ClothError> {
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
            ItemsByGroup::new(groups, (0..rest.len() as u32).map(|p| patches.of_vertex(p)));
        let loose = (0..rest.len() as u32).any(|p| patches.of_vertex(p) as usize >= groups);
        let patch_edges = ItemsByGroup::new(groups, edge_patch.iter().copied());
        let patch_triangles = ItemsByGroup::new(
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
            cubes: ParticleCubes {
                size: (8.0 * (thickness + 2.0 * cap)).max(3.0 * longest + thickness),
                ..ParticleCubes::default()
            },
            ..Self::default()
        };
        // The pairs within the thickness at rest are exactly the candidates of a broad phase on
        // the rest positions with no motion; a full list stops the search.
        let cap = MAX_EXEMPT_PAIRS_PER_TRIANGLE * contacts.tris.len();
        contacts.find_candidates(rest, thickness, cap + 1, NO_CULL);
        let found = contacts.vt.len().max(contacts.ee.len());
        if found > cap {
            return Err(ClothError::TooMany {
                field: "pairs within self_collision.thickness at rest",
                count: found as u64,
                bound: cap as u64,
                why: format!(
                    "MAX_EXEMPT_PAIRS_PER_TRIANGLE = {MAX_EXEMPT_PAIRS_PER_TRIANGLE} of each kind \
                     per triangle, at thickness {thickness} m: more of the rest shape lies \
                     within the thickness of itself than of a flat cloth at the largest \
                     thickness; lower the thickness"
                ),
            });
        }
        contacts.exempt_vt = contacts.vt.iter().map(|&(p, t)| pair_key(p, t)).collect();
        contacts.exempt_ee = contacts.ee.iter().map(|&(e, f)| pair_key(e, f)).collect();
        contacts.exempt_vt.sort_unstable();
        contacts.exempt_ee.sort_unstable();
        // The steps' candidate lists grow to their own (capped) size; these may be larger.
        contacts.vt = Vec::new();
        contacts.ee = Vec::new();
        contacts.gap = Vec::new();
        Ok(contacts)
    }

    /// Takes the exempt pairs whose elements are not `linked` (no particle of one linked to a
    /// particle of the other) off the exempt lists, as parting: a torn cloth's sides lay within
    /// the thickness at rest and still do where it tore, so until they have parted by the
    /// thickness ([`Self::release_parted`]) they are kept only [`PARTING_SHARE`] of it apart
    /// (and never let through each other), and from then on like any other layers.
    pub fn mark_parting(&mut self, linked: impl Fn(u32, u32) -> bool) {
        let (tris, edges) = (&self.tris, &self.edges);
        self.parting_vt = self
            .exempt_vt
            .iter()
            .copied()
            .filter(|&key| {
                let (p, t) = ((key >> 32) as u32, key as u32);
                !tris[t as usize].iter().any(|&q| linked(p, q))
            })
            .collect();
        self.parting_ee = self
            .exempt_ee
            .iter()
            .copied()
            .filter(|&key| {
                let (e, f) = (edges[(key >> 32) as usize], edges[key as u32 as usize]);
                !e.iter().any(|&p| f.iter().any(|&q| linked(p, q)))
            })
            .collect();
        // Both lists are sorted, and the parting ones were taken from the exempt ones in order.
        let (parting_vt, parting_ee) = (&self.parting_vt, &self.parting_ee);
        self.exempt_vt
            .retain(|k| parting_vt.binary_search(k).is_err());
        self.exempt_ee
            .retain(|k| parting_ee.binary_search(k).is_err());
    }

    /// Keeps the parting pairs ([`Self::mark_parting`]) that are now farther apart than the
    /// thickness, the particles at `x`, the full thickness apart from now on.
    pub fn release_parted(&mut self, x: &[Vec3]) {
        if self.parting_vt.is_empty() && self.parting_ee.is_empty() {
            return;
        }
        let thickness = self.thickness;
        let (tris, edges) = (&self.tris, &self.edges);
        let parted_vt: Vec<u64> = self
            .parting_vt
            .iter()
            .copied()
            .filter(|&key| {
                let (p, t) = ((key >> 32) as usize, key as u32 as usize);
                let [a, b, c] = tris[t].map(|i| x[i as usize]);
                point_triangle_distance(x[p], a, b, c) > thickness
            })
            .collect();
        let parted_ee: Vec<u64> = self
            .parting_ee
            .iter()
            .copied()
            .filter(|&key| {
                let ([a, b], [c, d]) = (edges[(key >> 32) as usize], edges[key as u32 as usize]);
                let [a, b, c, d] = [a, b, c, d].map(|i| x[i as usize]);
                let (s, t) = closest_on_segments(a, b, c, d);
                (a + s * (b - a)).distance(c + t * (d - c)) > thickness
            })
            .collect();
        for (parting, parted) in [
            (&mut self.parting_vt, parted_vt),
            (&mut self.parting_ee, parted_ee),
        ] {
            // Both lists are sorted, `parted` taken from `parting` in order.
            parting.retain(|k| parted.binary_search(k).is_err());
        }
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

    /// Number of pairs across a tear not yet parted ([`Self::mark_parting`]).
    #[cfg(test)]
    pub fn parting_count(&self) -> usize {
        self.parting_vt.len() + self.parting_ee.len()
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

    /// Number of substeps whose pairs were resolved so far (see [`DEFER_CLOSING`]).
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
    fn spacing(&self) -> LayerSpacing {
        LayerSpacing {
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
        self.last_resolution.order_checked = false;
    }

    /// The narrow phase and response at the end of a substep of length `h` (see the module docs),
    /// or nothing while no two particles can have come [`DEFER_CLOSING`] of the thickness closer since
    /// the last resolution, unless the substep is the step's `last` (every step ends resolved).
    /// Returns whether any particle moved.
    pub fn resolve<S: ContactState>(&mut self, (h, last): (f32, bool), state: &mut S) -> bool {
        self.moved.clear();
        if self.tris.is_empty() {
            return false;
        }
        if self.new_step && !self.last_resolution.order_checked {
            // A stepper may store the particles in another order from one step to the next.
            self.last_resolution.order_checked = true;
            if storage_order_changed(state, &self.slot) {
                self.stale = true;
                self.last_resolution.forget();
            }
        }
        let deferred = self.last_resolution.deferred;
        let slack = DEFER_CLOSING * self.thickness;
        if !last && self.last_resolution.holds(state, |r, _| 2.0 * r <= slack) {
            self.cubes.skip();
            return false;
        }
        self.resolutions += 1;
        let any = self.resolve_now(h * (deferred + 1) as f32, state);
        self.last_resolution.forget();
        // A cloth with no candidates (hanging, or flat) has nothing to defer.
        self.last_resolution.due = !(self.vt.is_empty() && self.ee.is_empty());
        any
    }

    /// Ends a substep's contacts: after a resolution, once the colliders have had their last
    /// word, keeps the positions that the next substeps' motion is measured from (taken before
    /// the colliders, a layer pushed into the floor and back would count as motion).
    pub fn end_substep<S: ContactState>(&mut self, state: &S) {
        if std::mem::take(&mut self.last_resolution.due) {
            self.last_resolution.take(state);
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
                let [a, b, c, d] = map_four(self.quads[k], |i| drift[i as usize]);
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
    fn measure_drift(
        &self,
        gathered: &GatheredParticles,
        (m0, m1): (Vec3, Vec3),
        drift: &mut Vec<f32>,
    ) {
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
        let [a, b, c, d] = map_four(self.quads[k], |i| drift[i as usize]);
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
        let quad = map_four(self.quads[k], |i| i as usize);
        let mut spacing = self.spacing();
        if self.is_parting(k) {
            spacing.thickness *= PARTING_SHARE;
        }
        if k < self.vt.len() {
            spacing.vertex_triangle(state, quad, inv_h, drift)
        } else {
            spacing.edge_edge(state, quad, inv_h, drift)
        }
    }

    /// Whether candidate `k` is a pair across a tear not yet parted.
    fn is_parting(&self, k: usize) -> bool {
        match self.vt.get(k) {
            Some(&(p, t)) => is_listed(&self.parting_vt, pair_key(p, t)),
            None => {
                let (e, f) = self.ee[k - self.vt.len()];
                is_listed(&self.parting_ee, pair_key(e, f))
            }
        }
    }
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
