//! The particles grouped into cubes and blocks of cubes by where they were at the last broad
//! phase, which bound how much closer any two elements can have come since, and the last check
//! of them, which lets substeps skip the next.

use std::collections::HashMap;
use std::hash::BuildHasherDefault;

use glam::{Vec3, Vec3A};

use super::grouped::ItemsByGroup;
use crate::hash::IntHasher;
use crate::sim::contact::narrow::ContactState;
use crate::sim::contact::pairs::{cell_of, for_cells, largest_root, max_or_infinite};
use crate::sim::soa::Soa;

/// Cubes along each side of a block of `ParticleCubes`.
pub(super) const BLOCK_CUBES: i32 = 3;

/// The particles grouped into cubes of side `size` by where they were at the last broad phase, and
/// the cubes into blocks of [`BLOCK_CUBES`]³ cubes. Two particles that were closer than `size` then lie
/// in the same or neighbouring cubes, and two closer than `BLOCK_CUBES` times that in the same or
/// neighbouring blocks; the displacements since then, compared cube by cube and block by block,
/// bound how much closer any two elements can have come: a cloth that swings or falls as a whole,
/// however fast, moves little within and between neighbouring cubes and need not search again.
#[derive(Debug, Clone, Default)]
pub(super) struct ParticleCubes {
    /// Side of the cubes, m (at least the broad phase's margin).
    pub(super) size: f32,
    /// Each stored particle's cube.
    pub(super) of: Vec<u32>,
    /// Particles per cube.
    pub(super) count: Vec<u32>,
    /// Pairs of neighbouring cubes (a cube with itself too), `a <= b`.
    pub(super) pairs: Vec<(u32, u32)>,
    /// Per cube: how much closer one of its particles and one of a neighbouring cube may come
    /// before a search is due (a pair of cubes takes the larger of their two limits; set after
    /// [`Self::assign`], see [`Self::limit`]).
    pub(super) limit: Vec<f32>,
    /// The least and the largest of `limit`.
    pub(super) least: f32,
    pub(super) most: f32,
    /// Cube index of each occupied cell.
    pub(super) index: HashMap<[i32; 3], u32, BuildHasherDefault<IntHasher>>,
    /// Each cube's cell.
    pub(super) cell: Vec<[i32; 3]>,
    /// Each cube's block.
    pub(super) block: Vec<u32>,
    /// The cubes of each block.
    pub(super) block_cubes: ItemsByGroup,
    /// Scratch of [`neighbouring_cells`].
    pub(super) dense: Vec<u32>,
    /// Pairs of neighbouring blocks (a block with itself too), `a <= b`.
    pub(super) block_pairs: Vec<(u32, u32)>,
    /// Block index of each occupied block cell (scratch of [`Self::assign`]).
    pub(super) block_index: HashMap<[i32; 3], u32, BuildHasherDefault<IntHasher>>,
    /// Per block: a displacement (the mean of its cubes' references) and the largest distance
    /// of one of its particles' displacements from it (scratch).
    pub(super) block_reference: Vec<(Vec3, u32)>,
    pub(super) block_deviation: Vec<f32>,
    /// Per pair of neighbouring blocks (as `block_pairs`): the bound on how much closer two of
    /// their particles can have come, which bounds that of every pair of their cubes (scratch).
    pub(super) block_bound: Vec<f32>,
    /// Per cube: the displacement its particles' displacements are measured from (any point
    /// would do; the cube's mean displacement extrapolated from the last two
    /// [`Self::closing`]s keeps the deviations small).
    pub(super) reference: Vec<Vec3>,
    /// Per cube: its mean displacement at the last [`Self::closing`].
    pub(super) last_mean: Vec<Vec3>,
    /// Whether no [`Self::closing`] has run since [`Self::assign`] (the references are unknown).
    pub(super) fresh: bool,
    /// Substeps skipped since the last [`Self::closing`] (see [`Self::skip`]).
    pub(super) skipped: u32,
    /// Per cube: sum of displacements (scratch).
    pub(super) sum: Vec<Vec3A>,
    /// Per cube: largest distance of a displacement from the cube's reference (scratch).
    pub(super) deviation: Vec<f32>,
    /// Per stored particle: its displacement since [`Self::assign`] at the last
    /// [`Self::closing`].
    pub(super) moved: Vec<Vec3A>,
}

/// The bounds [`ParticleCubes::closing`] found on how much closer particles can have come, and
/// their mean displacement.
pub(super) struct ClosingBounds {
    /// How much closer two particles of the same or neighbouring cubes can have come.
    pub(super) near: f32,
    /// How much closer still two such particles may come before their cubes' limit (see
    /// [`ParticleCubes::limit`]); negative once one pair has passed it.
    pub(super) slack: f32,
    /// How much closer two particles of cubes that are not neighbours, in the same or
    /// neighbouring blocks, can have come, less a cube's side for each cube between them beyond
    /// the first (they were farther apart by as much).
    pub(super) mid: f32,
    /// How much closer any two particles can have come.
    pub(super) far: f32,
    /// The particles' mean displacement at the start and at the end of the substep.
    pub(super) mean: (Vec3, Vec3),
}

impl ParticleCubes {
    /// Groups the particles at `x` (by model particle, stored at `slot`) into cubes.
    pub(super) fn assign(&mut self, x: &[Vec3], slot: &[u32]) {
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
        neighbouring_cells(&self.index, &mut self.pairs, &mut self.dense);
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
            let block = cell.map(|c| c.div_euclid(BLOCK_CUBES));
            self.block[a as usize] = *self.block_index.entry(block).or_insert(next);
            self.cell[a as usize] = *cell;
        }
        self.block_cubes
            .regroup(self.block_index.len(), self.block.iter().copied());
        neighbouring_cells(&self.block_index, &mut self.block_pairs, &mut self.dense);
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
    /// (see [`SelfContacts::refresh_candidates`](super::SelfContacts::refresh_candidates)), two particles of neighbouring cubes may come
    /// closer by the larger of their cubes' limits: an element with a particle in a cube belongs
    /// to one of those patches, and the pair of elements is within both limits.
    pub(super) fn limit(&mut self, slot: &[u32], of_particle: impl Fn(usize) -> f32) {
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

    /// The bound of [`ClosingBounds::mid`] from each pair of cubes in the same or neighbouring blocks
    /// that are not neighbours.
    ///
    /// Needs [`Self::block_bounds`] of this check: a pair of blocks whose bound cannot raise the
    /// largest found so far is passed over (a bound computed in floating point may exceed the
    /// exact one by a few units in the last place: such a pair is passed over only where its
    /// bound falls short by more).
    pub(super) fn cubes_apart(&self) -> f32 {
        let (cubes, cell) = (&self.block_cubes, &self.cell);
        // The pair with the largest bound first (and again in its turn, which changes nothing),
        // so that the others are compared with its worst.
        let first = (0..self.block_pairs.len())
            .max_by(|&a, &b| self.block_bound[a].total_cmp(&self.block_bound[b]));
        let mut worst = 0.0;
        for k in first.into_iter().chain(0..self.block_pairs.len()) {
            if self.block_bound[k] * (1.0 + 1e-5) < worst {
                continue;
            }
            let (ba, bb) = self.block_pairs[k];
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

    /// Fills [`Self::block_bound`] from the cubes' references and deviations of this check, and
    /// returns the largest (infinite for a NaN).
    fn block_bounds(&mut self) -> f32 {
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
        let (deviation, reference) = (&self.block_deviation, &self.block_reference);
        self.block_bound.clear();
        self.block_bound
            .extend(self.block_pairs.iter().map(|&(a, b)| {
                let (a, b) = (a as usize, b as usize);
                deviation[a] + deviation[b] + reference[a].0.distance(reference[b].0)
            }));
        self.block_bound.iter().copied().fold(0.0, max_or_infinite)
    }

    /// Each cube's sum of [`Self::moved`] and the largest distance of one from its reference (a
    /// NaN is lost to the maximum but kept by the sum).
    pub(super) fn scatter(&mut self) {
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
    pub(super) fn skip(&mut self) {
        self.skipped = self.skipped.saturating_add(1);
    }

    /// How much closer particles of `state` can have come since [`Self::assign`], when they were
    /// at `found` (by stored particle, as many as `state` holds and as were assigned): one pass
    /// over the particles. Infinite if a displacement is not finite. Pairs of neighbouring blocks
    /// are looked at only if the far bound exceeds every limit, pairs of neighbouring cubes only
    /// if the blocks' bound exceeds the least of the cubes' limits or `spare` (below which the
    /// near bound is close enough), and pairs of cubes that are not neighbours, within
    /// neighbouring blocks, only if it exceeds `mid_limit`.
    pub(super) fn closing<S: ContactState>(
        &mut self,
        state: &S,
        found: &[Vec3],
        (spare, mid_limit): (f32, f32),
    ) -> ClosingBounds {
        let n = self.of.len();
        if n == 0 {
            return ClosingBounds {
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
        let by_blocks = far > self.most.max(mid_limit);
        let blocks = if by_blocks {
            self.block_bounds().min(far)
        } else {
            far
        };
        let mid = if blocks <= mid_limit {
            blocks
        } else {
            if !by_blocks {
                self.block_bounds();
            }
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
        ClosingBounds {
            near,
            slack,
            mid,
            far,
            mean: (m0, m1),
        }
    }
}

impl ParticleCubes {
    /// How much closer the ends of `edges` (by stored particle) came, at most, by the last
    /// [`Self::closing`] (infinite if a displacement is not finite).
    pub(super) fn edges_closing(&self, edges: &[[u32; 2]]) -> f32 {
        let moved = &self.moved;
        largest_root(edges.len(), |k| {
            let [a, b] = edges[k];
            moved[a as usize].distance_squared(moved[b as usize])
        })
    }
}

/// Fills `pairs` with the pairs `(a, b)`, `a <= b`, of the cells of `index` (each to its index)
/// that are the same or neighbours (`dense` is scratch).
pub(super) fn neighbouring_cells(
    index: &HashMap<[i32; 3], u32, BuildHasherDefault<IntHasher>>,
    pairs: &mut Vec<(u32, u32)>,
    dense: &mut Vec<u32>,
) {
    pairs.clear();
    // Generic in the lookup, so that each kind is compiled into the loop.
    fn each(
        index: &HashMap<[i32; 3], u32, BuildHasherDefault<IntHasher>>,
        pairs: &mut Vec<(u32, u32)>,
        lookup: impl Fn([i32; 3]) -> Option<u32>,
    ) {
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
    }
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
            let dense = &*dense;
            each(index, pairs, |c| {
                place(c).map(|i| dense[i]).filter(|&b| b != u32::MAX)
            });
        }
        _ => each(index, pairs, |c| index.get(&c).copied()),
    }
}

/// Where the particles were at the last check of the cubes ([`ParticleCubes::closing`]) that found the
/// candidates still good, and how much closer two particles could still come then. Two particles'
/// displacements since then differ by at most twice the largest distance of one from any common
/// vector, so while that stays within the slack the check would still pass and is skipped: one
/// vector pass over the particles instead of the cubes' gather and scatter. A cloth at rest pays
/// only that pass.
#[derive(Debug, Clone, Default)]
pub(super) struct LastCheck {
    /// Each stored particle's position at the check.
    pub(super) at: Soa,
    /// The particles' mean displacement since the broad phase, at the check.
    pub(super) mean: Vec3,
    /// How much closer particles could still come, at the check, before a search is due.
    pub(super) slack: f32,
    /// The common displacement since the check expected at the next substep (any vector keeps
    /// the bound valid; this one keeps it small).
    pub(super) guess: Vec3,
    /// Whether `at` holds a check's positions that the candidates are still good for.
    pub(super) valid: bool,
}

impl LastCheck {
    /// Keeps `state`'s positions after a check that passed with `slack` to spare, when the
    /// particles' mean displacement since the broad phase was `mean` (at the substep's start, at
    /// its end).
    pub(super) fn take<S: ContactState>(&mut self, state: &S, slack: f32, (m0, m1): (Vec3, Vec3)) {
        state.ends(&mut self.at);
        self.mean = m1;
        self.slack = slack;
        self.guess = m1 - m0;
        self.valid = true;
    }

    /// The particles' mean displacement since the broad phase, at the substep's start and end, if
    /// no two particles can have come closer since the check than its slack allows.
    pub(super) fn unchanged<S: ContactState>(&mut self, state: &S) -> Option<(Vec3, Vec3)> {
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
