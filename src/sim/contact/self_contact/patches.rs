//! Patches of a cloth's triangles and their normal cones: what lets the self-contact broad phase
//! skip the parts of a cloth that cannot touch themselves.
//!
//! A patch is about two dozen edge-connected triangles, close together at rest. When all its
//! triangle normals lie within an angle `flat` below 90° of one direction, the patch is a height
//! field over the plane across that direction: it has no fold and cannot pass through itself
//! (Volino and Magnenat-Thalmann's normal-cone test). Its elements are then not paired with each
//! other, nor with those of a nearby patch (one sharing a vertex, or both sharing one with a
//! third) when the patches together (with the third) are within the narrowest of their `flat`.
//! A patch's `flat` leaves room for its normals to turn as far as the motion that the kept
//! candidates allow, which is further for thinner triangles (see `self_contact::cull_angle`), so a
//! culled patch stays unfolded until the next search.
//! A patch takes part in the search at all only while it is folded or its box meets a patch it is
//! not culled with, so a hanging or flat cloth's search is one pass over its triangles.
//! Culled pairs are kept from crossing, not held the thickness apart: a smooth patch's elements
//! that share no vertex lie about a triangle's altitude apart, but a sharply creased one (still
//! within `flat`) may bring some closer.

use glam::Vec3;

use crate::sim::contact::pairs::{boxes_meet, cell_of};

/// The patch of a vertex in no triangle: it is searched, and paired, always.
const LOOSE: u32 = u32::MAX;

/// Triangles per patch, about (the patches are cubes of the rest shape).
const SIZE: usize = 24;

/// A cloth's triangles grouped into patches, with each patch's box and normal cone as of the last
/// [`Patches::update`].
#[derive(Debug, Clone, Default)]
pub(super) struct Patches {
    /// Patch of each triangle.
    of_triangle: Vec<u32>,
    /// Patch of each vertex (that of the first triangle holding it; [`LOOSE`] for one in no
    /// triangle).
    of_vertex: Vec<u32>,
    /// The triangles, grouped by patch.
    members: Vec<u32>,
    /// Where each patch's triangles begin in `members` (one more than the patches).
    start: Vec<u32>,
    /// Where each patch's adjacent patches begin in `adjacent` (one more than the patches).
    adjacent_start: Vec<u32>,
    /// The patches sharing a vertex with each patch, sorted per patch.
    adjacent: Vec<u32>,
    /// Where each vertex's patches begin in `around` (one more than the vertices).
    around_start: Vec<u32>,
    /// The patches of the triangles with a corner at each vertex, sorted per vertex.
    around: Vec<u32>,
    /// Where each patch's nearby patches begin in `nearby` (one more than the patches).
    nearby_start: Vec<u32>,
    /// The patches adjacent to each patch or to one of its adjacent patches, sorted per patch.
    nearby: Vec<u32>,
    /// Per entry of `nearby`: whether the two patches' elements are not paired this search (one
    /// of a pair's two entries is marked).
    culled_with: Vec<bool>,
    /// Per triangle: its unit normal (zero if degenerate); scratch.
    normal: Vec<Vec3>,
    /// Per patch: the union of its triangles' boxes.
    bounds: Vec<(Vec3, Vec3)>,
    /// Per patch: the axis of its normal cone.
    axis: Vec<Vec3>,
    /// Per patch: the half-angle of its normal cone (π if it has no axis).
    angle: Vec<f32>,
    /// Per patch: the lowest and highest of its vertices along its axis, once a test of
    /// [`Self::separation`] has needed them in this update (most patches take none).
    extent: Vec<Option<(f32, f32)>>,
    /// Per patch: whether its elements take part in the search.
    live: Vec<bool>,
    /// Per patch: the widest normal cone (half-angle, radians) culled this time, which depends
    /// on how thin its triangles are.
    flat: Vec<f32>,
    /// Per triangle: its shortest altitude (scratch).
    altitude: Vec<f32>,
    /// Patches by the low x of their boxes (scratch of the sweep).
    order: Vec<u32>,
    /// The patches' boxes in that order (scratch of the sweep).
    sorted: Vec<(Vec3, Vec3)>,
    /// Per patch: its entry in the list of nearby patches of the patch being swept (`u32::MAX`
    /// for none), and whether it is adjacent to that patch (scratch of the sweep).
    near: Vec<(u32, bool)>,
    /// The pairs of patches whose elements this search pairs, `a <= b`: each folded patch with
    /// itself, and nearby or overlapping patches neither culled with each other nor apart.
    pairs: Vec<(u32, u32)>,
    /// Per patch: how far apart, at least, its elements and another patch's were at the last
    /// [`Self::update`] where the two patches are neither culled nor searched together (see
    /// [`Self::clear_of`]).
    clear_of: Vec<f32>,
}

impl Patches {
    /// Patches of the triangles `tris` of a mesh at rest at `rest`: the triangles whose centres lie
    /// in one cube of a grid about [`SIZE`] triangles wide, split into edge-connected parts (so
    /// that layers of a mesh folded at rest are patches of their own). `sides` lists every
    /// triangle side as (its two vertices as `low << 32 | high`, `3 × triangle + side`), sorted.
    pub fn new(tris: &[[u32; 3]], rest: &[Vec3], sides: &[(u64, usize)]) -> Self {
        let vertices = rest.len();
        let mut across: Vec<Vec<u32>> = vec![Vec::new(); tris.len()];
        let (mut length, mut count) = (0.0f32, 0usize);
        for (k, &(key, at)) in sides.iter().enumerate() {
            if k > 0 && sides[k - 1].0 == key {
                let (t, u) = (at / 3, sides[k - 1].1 / 3);
                across[t].push(u as u32);
                across[u].push(t as u32);
            } else {
                length += rest[(key >> 32) as usize].distance(rest[key as u32 as usize]);
                count += 1;
            }
        }
        let side = (SIZE as f32 / 2.0).sqrt() * length / count.max(1) as f32;
        let inv = if side.is_finite() && side > 0.0 {
            1.0 / side
        } else {
            0.0
        };
        let cube: Vec<[i32; 3]> = tris
            .iter()
            .map(|t| {
                let centre = t.iter().map(|&i| rest[i as usize]).sum::<Vec3>() / 3.0;
                cell_of(centre, inv)
            })
            .collect();
        let mut of_triangle = vec![u32::MAX; tris.len()];
        let mut members = Vec::with_capacity(tris.len());
        let mut start = vec![0u32];
        for seed in 0..tris.len() {
            if of_triangle[seed] != u32::MAX {
                continue;
            }
            let patch = start.len() as u32 - 1;
            of_triangle[seed] = patch;
            let mut next = members.len();
            members.push(seed as u32);
            while next < members.len() {
                let t = members[next] as usize;
                next += 1;
                for &u in &across[t] {
                    if of_triangle[u as usize] == u32::MAX && cube[u as usize] == cube[seed] {
                        of_triangle[u as usize] = patch;
                        members.push(u);
                    }
                }
            }
            start.push(members.len() as u32);
        }
        let patches = start.len() - 1;
        let mut of_vertex = vec![LOOSE; vertices];
        let mut holding: Vec<Vec<u32>> = vec![Vec::new(); vertices];
        for (t, tri) in tris.iter().enumerate() {
            for &v in tri {
                let v = v as usize;
                if of_vertex[v] == LOOSE {
                    of_vertex[v] = of_triangle[t];
                }
                holding[v].push(of_triangle[t]);
            }
        }
        let mut sets: Vec<Vec<u32>> = vec![Vec::new(); patches];
        let (mut around_start, mut around) = (vec![0u32], Vec::new());
        for list in &mut holding {
            list.sort_unstable();
            list.dedup();
            for &a in list.iter() {
                sets[a as usize].extend(list.iter().copied().filter(|&b| b != a));
            }
            around.extend_from_slice(list);
            around_start.push(around.len() as u32);
        }
        let mut adjacent_start = vec![0u32];
        let mut adjacent = Vec::new();
        for set in &mut sets {
            set.sort_unstable();
            set.dedup();
            adjacent.extend_from_slice(set);
            adjacent_start.push(adjacent.len() as u32);
        }
        let mut nearby_start = vec![0u32];
        let mut nearby = Vec::new();
        let mut near = Vec::new();
        for (a, set) in sets.iter().enumerate() {
            near.clear();
            for &b in set {
                near.push(b);
                near.extend(sets[b as usize].iter().filter(|&&c| c as usize != a));
            }
            near.sort_unstable();
            near.dedup();
            nearby.extend_from_slice(&near);
            nearby_start.push(nearby.len() as u32);
        }
        Self {
            of_triangle,
            of_vertex,
            members,
            start,
            culled_with: vec![false; nearby.len()],
            adjacent_start,
            adjacent,
            around_start,
            around,
            nearby_start,
            nearby,
            normal: Vec::with_capacity(tris.len()),
            bounds: vec![(Vec3::ZERO, Vec3::ZERO); patches],
            axis: vec![Vec3::ZERO; patches],
            angle: vec![0.0; patches],
            extent: vec![None; patches],
            live: vec![false; patches],
            flat: vec![-1.0; patches],
            altitude: Vec::new(),
            order: (0..patches as u32).collect(),
            sorted: Vec::new(),
            pairs: Vec::new(),
            clear_of: vec![0.0; patches],
            near: Vec::new(),
        }
    }

    /// Number of patches.
    pub fn len(&self) -> usize {
        self.start.len() - 1
    }

    /// Patch of triangle `t`.
    pub fn of_triangle(&self, t: u32) -> u32 {
        self.of_triangle[t as usize]
    }

    /// Patch of vertex `p`.
    pub fn of_vertex(&self, p: u32) -> u32 {
        self.of_vertex[p as usize]
    }

    /// The least of `of_patch` (by patch) over the patches of the triangles with a corner at
    /// vertex `p`, which are those of every element with a particle at `p` (`None` for a vertex
    /// in no triangle).
    pub fn least_around(&self, p: u32, of_patch: &[f32]) -> Option<f32> {
        let range =
            self.around_start[p as usize] as usize..self.around_start[p as usize + 1] as usize;
        (self.around[range].iter())
            .map(|&a| of_patch[a as usize])
            .reduce(f32::min)
    }

    /// The box of patch `p` as of the last [`Self::update`]: the union of its triangles' boxes.
    pub fn bounds(&self, p: u32) -> (Vec3, Vec3) {
        self.bounds[p as usize]
    }

    /// The pairs of patches whose elements this search pairs (see [`Self::update`]): every pair
    /// of elements closer than the search's margin that is not culled lies in one of them.
    pub fn pairs(&self) -> &[(u32, u32)] {
        &self.pairs
    }

    /// Whether patch `a`'s elements take part in this search.
    pub fn live(&self, a: u32) -> bool {
        a == LOOSE || self.live[a as usize]
    }

    /// Whether the elements of patches `a` and `b` (the same patch or two) are not paired.
    pub fn culled(&self, a: u32, b: u32) -> bool {
        if a == LOOSE {
            return false;
        }
        if a == b {
            return self.angle[a as usize] <= self.flat[a as usize];
        }
        // The sweep marks one of the pair's two entries.
        let marked = |a: u32, b: u32| {
            self.entry(a as usize, b as usize)
                .is_some_and(|k| self.culled_with[k])
        };
        marked(a, b) || marked(b, a)
    }

    /// How far apart, at least, an element of patch `p` and another element were at the last
    /// [`Self::update`] where it left them unpaired and uncovered: their patches neither culled
    /// together nor searched together, as far as the update looked (its `margin` doubled and its
    /// `out`). (The elements of patches searched together that the search does not pair are its
    /// `margin` apart.) A part of the cloth far from any fold is left much farther from the
    /// elements it is not searched with.
    pub fn clear_of(&self, p: u32) -> f32 {
        self.clear_of[p as usize]
    }

    /// The widest normal cone culled in any patch at the last [`Self::update`].
    #[cfg(test)]
    pub fn flat(&self) -> f32 {
        self.flat.iter().copied().fold(f32::NEG_INFINITY, f32::max)
    }

    /// Takes the patches' boxes (the union of their triangles' `boxes`) and normal cones from the
    /// triangles `tris` at positions `x`, and decides which patches take part in the search and
    /// which nearby pairs are culled: a patch within `flat(h)` (radians) of one direction, where
    /// `h` is its shortest triangle altitude at `x` (thinner triangles turn further for the same
    /// motion), and two within the narrower of theirs. Two patches whose boxes meet but which lie
    /// farther than `margin` apart along one of their axes (the two sides of a curve, seen across
    /// it) need not be searched for each other's sake. `boxes` are the triangles' boxes grown by
    /// `margin`; pairs of patches up to `out` farther apart are looked at for [`Self::clear_of`],
    /// and nearby ones among them are culled when flat together (their elements are farther
    /// apart than the margin anyway), so that they leave it as it is.
    pub fn update(
        &mut self,
        x: &[Vec3],
        tris: &[[u32; 3]],
        boxes: &[(Vec3, Vec3)],
        (flat, margin, out): (impl Fn(f32) -> f32, f32, f32),
    ) {
        normals(x, tris, &mut self.normal, &mut self.altitude);
        for p in 0..self.len() {
            let members = &self.members[self.start[p] as usize..self.start[p + 1] as usize];
            let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
            let mut sum = Vec3::ZERO;
            let mut degenerate = false;
            let mut thinnest = f32::INFINITY;
            for &t in members {
                let (blo, bhi) = boxes[t as usize];
                lo = lo.min(blo);
                hi = hi.max(bhi);
                let n = self.normal[t as usize];
                degenerate |= n == Vec3::ZERO;
                sum += n;
                thinnest = thinnest.min(self.altitude[t as usize]);
            }
            self.flat[p] = flat(thinnest);
            self.bounds[p] = (lo, hi);
            let axis = sum.normalize_or_zero();
            self.axis[p] = axis;
            self.angle[p] = if degenerate || axis == Vec3::ZERO {
                std::f32::consts::PI
            } else {
                let cos = members
                    .iter()
                    .map(|&t| self.normal[t as usize].dot(axis))
                    .fold(1.0f32, f32::min);
                // NaN (a position not finite) makes the patch folded.
                if cos.is_nan() {
                    std::f32::consts::PI
                } else {
                    cos.clamp(-1.0, 1.0).acos()
                }
            };
            self.extent[p] = None;
            self.live[p] = self.angle[p] > self.flat[p];
        }
        self.pairs.clear();
        self.pairs.extend(
            (0..self.len() as u32)
                .filter(|&p| self.live[p as usize])
                .map(|p| (p, p)),
        );
        self.culled_with.fill(false);
        let bounds = &self.bounds;
        self.order
            .sort_unstable_by(|&a, &b| bounds[a as usize].0.x.total_cmp(&bounds[b as usize].0.x));
        let mut sorted = std::mem::take(&mut self.sorted);
        sorted.clear();
        sorted.extend(self.order.iter().map(|&p| bounds[p as usize]));
        // Patch `a`'s nearby patches, marked with their entries in its list, and its adjacent
        // ones (scratch, unmarked again after each `a`).
        let mut near = std::mem::take(&mut self.near);
        near.clear();
        near.resize(self.len(), (u32::MAX, false));
        // The boxes are grown by `margin` on every side: two that do not meet hold elements at
        // least their gap and twice that apart.
        let out = out.max(0.0);
        let looked = 2.0 * margin + out;
        self.clear_of.fill(looked);
        for i in 0..self.order.len() {
            let a = self.order[i] as usize;
            let (alo, ahi) = self.bounds[a];
            let entries = self.nearby_start[a] as usize..self.nearby_start[a + 1] as usize;
            for k in entries.clone() {
                near[self.nearby[k] as usize].0 = k as u32;
            }
            for &c in self.adjacent(a) {
                near[c as usize].1 = true;
            }
            for (j, &(blo, bhi)) in sorted.iter().enumerate().skip(i + 1) {
                if blo.x > ahi.x + out {
                    break;
                }
                // Most pairs of the sweep lie too far apart along another axis to matter, which
                // the sorted boxes tell.
                let meet = boxes_meet((blo, bhi), (alo, ahi));
                let gap = (blo - ahi).max(alo - bhi).max_element() + 2.0 * margin;
                // A NaN gap is not below what was looked at: nothing to do, as for a pair far
                // apart.
                if !(meet || gap < looked) {
                    continue;
                }
                let b = self.order[j] as usize;
                let (entry, adjacent) = near[b];
                if !meet {
                    // Nothing to lower: the pair's cull does not matter either, for elements
                    // that far apart are not paired.
                    if !(gap < self.clear_of[a] || gap < self.clear_of[b]) {
                        continue;
                    }
                    if entry != u32::MAX && self.flat_together(a, b, adjacent) {
                        self.culled_with[entry as usize] = true;
                    } else {
                        uncovered(&mut self.clear_of, (a, b), gap);
                    }
                    continue;
                }
                if entry != u32::MAX && self.flat_together(a, b, adjacent) {
                    self.culled_with[entry as usize] = true;
                    continue;
                }
                let apart = self.separation(a, b, (tris, x));
                if apart > margin {
                    uncovered(&mut self.clear_of, (a, b), apart);
                } else {
                    self.live[a] = true;
                    self.live[b] = true;
                    self.pairs.push((a.min(b) as u32, a.max(b) as u32));
                }
            }
            for k in entries {
                near[self.nearby[k] as usize].0 = u32::MAX;
            }
            for &c in self.adjacent(a) {
                near[c as usize].1 = false;
            }
        }
        self.near = near;
        self.sorted = sorted;
    }

    /// How far apart patches `a` and `b` (of triangles `tris` at `x`) lie along the axis of
    /// either, whichever is farther (negative where they overlap along both, NaN for a position
    /// that is not finite).
    fn separation(&mut self, a: usize, b: usize, mesh: (&[[u32; 3]], &[Vec3])) -> f32 {
        let mut beyond = |p: usize, q: usize| {
            let axis = self.axis[p];
            let (lo, hi) = match self.extent[p] {
                Some(e) => e,
                None => {
                    let e = along(axis, self.members(p), mesh.0, mesh.1);
                    self.extent[p] = Some(e);
                    e
                }
            };
            let (qlo, qhi) = along(axis, self.members(q), mesh.0, mesh.1);
            (qlo - hi).max(lo - qhi)
        };
        // `max` would drop a NaN: kept, so that the pair is searched.
        let (ab, ba) = (beyond(a, b), beyond(b, a));
        if ab.is_nan() || ba.is_nan() {
            f32::NAN
        } else {
            ab.max(ba)
        }
    }

    /// The triangles of patch `p`.
    fn members(&self, p: usize) -> &[u32] {
        &self.members[self.start[p] as usize..self.start[p + 1] as usize]
    }

    /// Where patch `b` is in patch `a`'s list of nearby patches, if it is there.
    fn entry(&self, a: usize, b: usize) -> Option<usize> {
        let from = self.nearby_start[a] as usize;
        let to = self.nearby_start[a + 1] as usize;
        self.nearby[from..to]
            .binary_search(&(b as u32))
            .ok()
            .map(|k| from + k)
    }

    /// The patches adjacent to patch `a`.
    fn adjacent(&self, a: usize) -> &[u32] {
        &self.adjacent[self.adjacent_start[a] as usize..self.adjacent_start[a + 1] as usize]
    }

    /// Whether nearby patches `a` and `b` (`adjacent` if they are) make a connected surface
    /// within the narrowest of their `flat` of one direction: the two, if adjacent, or with a
    /// patch adjacent to both.
    fn flat_together(&self, a: usize, b: usize, adjacent: bool) -> bool {
        let cone = |p: usize| (self.axis[p], self.angle[p]);
        if adjacent {
            return within(cone(a), cone(b), self.flat[a].min(self.flat[b]));
        }
        self.adjacent(a).iter().any(|&c| {
            let flat = self.flat[a].min(self.flat[b]).min(self.flat[c as usize]);
            self.adjacent(c as usize).binary_search(&(b as u32)).is_ok()
                && within(merge(cone(c as usize), cone(a)), cone(b), flat)
        })
    }
}

/// Whether the narrowest cone holding cones `(u, a)` and `(v, b)` (unit axes) is within `flat`
/// (radians): its half-angle is the largest of `a`, `b`, and half the sum of `a`, `b` and the
/// angle between the axes. False for a zero axis or a NaN.
fn within((u, a): (Vec3, f32), (v, b): (Vec3, f32), flat: f32) -> bool {
    if u == Vec3::ZERO || v == Vec3::ZERO || !(a <= flat && b <= flat) {
        return false;
    }
    // The angle between the axes may be up to `spread` (at least 0 here).
    let spread = 2.0 * flat - a - b;
    spread >= std::f32::consts::PI || u.dot(v) >= spread.cos()
}

/// The narrowest cone (axis, half-angle) holding cones `(u, a)` and `(v, b)` (unit axes): the
/// wider one if it holds the other, else the one whose sides touch both, about an axis between
/// theirs. Half-angle π when no axis is found, NaN for a zero axis.
fn merge((u, a): (Vec3, f32), (v, b): (Vec3, f32)) -> (Vec3, f32) {
    if u == Vec3::ZERO || v == Vec3::ZERO {
        return (u, f32::NAN);
    }
    let theta = u.angle_between(v);
    if theta + b <= a {
        return (u, a);
    }
    if theta + a <= b {
        return (v, b);
    }
    let half = 0.5 * (theta + a + b);
    let sin = theta.sin();
    if half >= std::f32::consts::PI || sin.is_nan() || sin <= 1e-6 {
        return (u, std::f32::consts::PI);
    }
    // Turned from u toward v by half − a, within the plane of the two.
    let t = half - a;
    let axis = (u * (theta - t).sin() + v * t.sin()) / sin;
    (axis.normalize_or_zero(), half)
}

/// The lowest and highest of the vertices of triangles `members` (of `tris`, at `x`) along `axis`
/// (NaN for a zero axis: apart from nothing).
fn along(axis: Vec3, members: &[u32], tris: &[[u32; 3]], x: &[Vec3]) -> (f32, f32) {
    if axis == Vec3::ZERO {
        return (f32::NAN, f32::NAN);
    }
    members
        .iter()
        .flat_map(|&t| tris[t as usize])
        .map(|i| x[i as usize].dot(axis))
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), h| {
            (lo.min(h), hi.max(h))
        })
}

/// Triangles at a time in [`normals`].
const LANES: usize = 8;

/// Each of the triangles `tris`' unit normal at `x` (zero if degenerate or not finite) into
/// `normal`, and its shortest altitude into `altitude`. [`LANES`] triangles at a time, so that the
/// square roots and divisions run in vector registers; each lane does the arithmetic of one
/// triangle at a time (`normal_of` in the tests), in the same order, so the results are the
/// same bits.
fn normals(x: &[Vec3], tris: &[[u32; 3]], normal: &mut Vec<Vec3>, altitude: &mut Vec<f32>) {
    normal.clear();
    altitude.clear();
    for chunk in tris.chunks(LANES) {
        // Per lane: the sides b − a, c − a and c − b, coordinate by coordinate.
        let mut side = [[[0.0f32; LANES]; 3]; 3];
        for (k, t) in chunk.iter().enumerate() {
            let [a, b, c] = t.map(|i| x[i as usize]);
            for (s, d) in side.iter_mut().zip([b - a, c - a, c - b]) {
                for (axis, v) in s.iter_mut().zip(d.to_array()) {
                    axis[k] = v;
                }
            }
        }
        let [[ux, uy, uz], [vx, vy, vz], [wx, wy, wz]] = side;
        let (mut n, mut h) = ([[0.0f32; LANES]; 3], [0.0f32; LANES]);
        for k in 0..LANES {
            let (nx, ny, nz) = (
                uy[k] * vz[k] - vy[k] * uz[k],
                uz[k] * vx[k] - vz[k] * ux[k],
                ux[k] * vy[k] - vx[k] * uy[k],
            );
            let length = ((nx * nx) + (ny * ny) + (nz * nz)).sqrt();
            let square = |x: f32, y: f32, z: f32| (x * x) + (y * y) + (z * z);
            let longest = square(ux[k], uy[k], uz[k])
                .max(square(wx[k], wy[k], wz[k]))
                .max(square(vx[k], vy[k], vz[k]));
            h[k] = length / longest.sqrt();
            // `normalize_or_zero`, with the length kept.
            let rcp = 1.0 / length;
            let keep = rcp.is_finite() && rcp > 0.0;
            for (n, v) in n.iter_mut().zip([nx, ny, nz]) {
                n[k] = if keep { v * rcp } else { 0.0 };
            }
        }
        for k in 0..chunk.len() {
            normal.push(Vec3::new(n[0][k], n[1][k], n[2][k]));
            altitude.push(h[k]);
        }
    }
}

/// One triangle's unit normal (zero if degenerate or not finite) and shortest altitude.
#[cfg(test)]
fn normal_of([a, b, c]: [Vec3; 3]) -> (Vec3, f32) {
    let n = (b - a).cross(c - a);
    let length = n.length();
    let longest = (b - a)
        .length_squared()
        .max((c - b).length_squared())
        .max((a - c).length_squared());
    let rcp = length.recip();
    let normal = if rcp.is_finite() && rcp > 0.0 {
        n * rcp
    } else {
        Vec3::ZERO
    };
    (normal, length / longest.sqrt())
}

/// Notes that patches `a` and `b` are left uncovered with their elements at least `gap` apart.
fn uncovered(clear_of: &mut [f32], (a, b): (usize, usize), gap: f32) {
    clear_of[a] = clear_of[a].min(gap);
    clear_of[b] = clear_of[b].min(gap);
}
#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;
    use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};

    /// Whether cone `(axis, angle)` holds every direction of cone `(u, a)`, sampled on its rim.
    fn holds((axis, angle): (Vec3, f32), (u, a): (Vec3, f32)) -> bool {
        let side = u.any_orthonormal_vector();
        (0..64).all(|k| {
            let turn = Quat::from_axis_angle(u, k as f32 / 64.0 * std::f32::consts::TAU);
            let rim = Quat::from_axis_angle(turn * side, a) * u;
            axis.angle_between(rim) <= angle + 1e-4
        })
    }

    #[test]
    fn normals_eight_at_a_time_are_those_of_one_at_a_time() {
        // 21 triangles (two whole lanes' worth and a part): scattered, one degenerate, one with
        // a corner that is not a number, one that is not finite.
        let h = |k: u32| ((k as f32 * 12.9898).sin() * 43_758.547).fract();
        let mut x: Vec<Vec3> = (0..63)
            .map(|i| Vec3::new(h(3 * i), h(3 * i + 1), h(3 * i + 2)))
            .collect();
        x[7] = x[6];
        x[8] = x[6];
        x[31] = Vec3::NAN;
        x[44] = Vec3::new(f32::INFINITY, 0.0, 0.0);
        let tris: Vec<[u32; 3]> = (0..21).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
        let (mut normal, mut altitude) = (Vec::new(), Vec::new());
        normals(&x, &tris, &mut normal, &mut altitude);
        assert_eq!(normal.len(), 21);
        for (t, tri) in tris.iter().enumerate() {
            let (n, a) = normal_of(tri.map(|i| x[i as usize]));
            let bits = |v: Vec3| v.to_array().map(f32::to_bits);
            assert_eq!(bits(normal[t]), bits(n), "{t}");
            assert_eq!(altitude[t].to_bits(), a.to_bits(), "{t}");
        }
        assert_eq!(normal[2], Vec3::ZERO);
    }

    #[test]
    fn a_merged_cone_holds_both_and_is_no_wider_than_needed() {
        let cases = [
            ((Vec3::Y, 0.1), (Vec3::X, 0.2)),
            ((Vec3::Y, 0.5), (Vec3::new(0.1, 1.0, 0.0).normalize(), 0.05)),
            ((Vec3::Z, 0.3), (Vec3::new(1.0, 0.0, 1.0).normalize(), 0.3)),
            ((Vec3::X, 0.0), (Vec3::new(0.0, 1.0, 1.0).normalize(), 0.0)),
        ];
        for (c1, c2) in cases {
            let merged = merge(c1, c2);
            assert!(
                holds(merged, c1) && holds(merged, c2),
                "{merged:?} misses one of {c1:?} {c2:?}"
            );
            // The narrowest cone holding both is half their angle apart plus their own angles (or
            // the wider one, where it holds the other).
            let theta = c1.0.angle_between(c2.0);
            let narrowest = (0.5 * (theta + c1.1 + c2.1)).max(c1.1).max(c2.1);
            assert!(
                (merged.1 - narrowest).abs() < 1e-4,
                "{merged:?} vs {narrowest}"
            );
        }
        // Opposite axes need the whole sphere; a zero axis is no cone.
        assert_eq!(merge((Vec3::Y, 0.1), (Vec3::NEG_Y, 0.1)).1, PI);
        assert!(merge((Vec3::ZERO, 0.1), (Vec3::Y, 0.1)).1.is_nan());
        // A right angle between two flat patches is a quarter turn's cone.
        let (_, half) = merge((Vec3::X, 0.0), (Vec3::Y, 0.0));
        assert!((half - FRAC_PI_4).abs() < 1e-5 && half < FRAC_PI_2);
    }

    #[test]
    fn two_cones_are_within_an_angle_when_their_merged_cone_is() {
        let axis = |k: usize| {
            let turn =
                Quat::from_rotation_y(0.7 * k as f32) * Quat::from_rotation_x(0.37 * k as f32);
            turn * Vec3::Y
        };
        let mut both = [0, 0];
        for i in 0..12 {
            for j in 0..12 {
                let (u, v) = (axis(i), axis(j));
                for (a, b) in [(0.0, 0.0), (0.1, 0.4), (0.5, 0.2), (0.9, 0.05), (1.3, 0.6)] {
                    for flat in [0.3, 0.8, 1.0, 1.4] {
                        let half = merge((u, a), (v, b)).1;
                        if (half - flat).abs() < 1e-4 {
                            continue; // on the edge, within rounding
                        }
                        let merged = half <= flat;
                        assert_eq!(
                            within((u, a), (v, b), flat),
                            merged,
                            "{u} {a} {v} {b} {flat}"
                        );
                        both[usize::from(merged)] += 1;
                    }
                }
            }
        }
        assert!(both[0] > 100 && both[1] > 100, "{both:?}");
        assert!(!within((Vec3::ZERO, 0.0), (Vec3::Y, 0.0), 1.0));
        assert!(!within((Vec3::Y, f32::NAN), (Vec3::Y, 0.0), 1.0));
    }

    #[test]
    fn extents_along_an_axis_bound_the_patch() {
        let x = [
            Vec3::new(0.0, 0.1, 0.0),
            Vec3::new(1.0, 0.3, 0.0),
            Vec3::new(0.0, -0.2, 1.0),
        ];
        let tris = [[0, 1, 2]];
        assert_eq!(along(Vec3::Y, &[0], &tris, &x), (-0.2, 0.3));
        let (lo, hi) = along(Vec3::ZERO, &[0], &tris, &x);
        assert!(lo.is_nan() && hi.is_nan());
    }
}
