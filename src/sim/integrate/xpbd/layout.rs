//! How XPBD lays out a cloth's springs for its vector kernel ([`Projections`]): colour by colour,
//! in runs of slots whose particles can be read with whole vector loads; holes in a run are filled
//! with padding slots that change nothing, so that no spring of a regular cloth falls back to
//! scalar code. On grids of 32 columns or more the particles are stored in an order
//! ([`grid_order`]) in which every spring is such a contiguous access. Each colour is cut into two
//! shares that touch disjoint particles, which two threads may project at once: the kernel's
//! soundness rests on that, and on no particle appearing twice in a batch. Within a share, the
//! layout pairs vector batches that the kernel would otherwise project one at a time, where their
//! particles are disjoint, so that it has two of them in flight ([`Projections::solo`]); its
//! results rest on that. [`Projections::check`] proves all three; debug builds check every layout
//! they make.

use crate::sim::integrate::step::Order;
#[cfg(any(test, debug_assertions))]
use crate::sim::model::Springs;
use crate::sim::model::{ClothModel, GridSpec};
use crate::sim::runs;
use crate::sim::simd::{self, Build, Kernel};

/// Springs projected together by the vector kernel. Within one colour no two springs share a
/// particle, so a batch gives exactly the sequential Gauss-Seidel result.
pub(super) const LANES: usize = 8;

/// The slots of one AVX-512 vector: the batch that the kernel projects two at a time, either
/// from one run where its particles allow or from two places of one colour's share
/// ([`Projections::solo`]).
pub(super) const WIDE_BATCH: usize = 2 * LANES;

/// Fewest slots for which a step is shared between two threads (see
/// [`Projections::worth_sharing`]): below it, handing phases between threads costs more than the
/// second thread gains (measured; see CHANGELOG.md, 2026-11-23).
const SHARED_MIN_SLOTS: usize = 20_000;

/// How the particles of a [`Run`]'s slots are laid out in memory.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Layout {
    /// Slot `start + m` joins particles `a[start] + m` and `b[start] + m`, with `b - a ≥ LANES`:
    /// two contiguous blocks per batch.
    Contiguous,
    /// Batches of eight slots over windows of 16 consecutive particles, with `d = 1` or `2`: in the
    /// window starting at `a` of the batch's first slot, lane `l` joins particle
    /// `2d⌊l/d⌋ + l mod d` of the window to the one `d` places further (rows of a grid: `d = 1` for
    /// structural springs, `d = 2` for bend springs).
    Interleaved(u8),
    /// Any particles, gathered one by one.
    Scattered,
}

/// Slots `start..start + len` of one colour, all of one [`Layout`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Run {
    pub layout: Layout,
    pub start: u32,
    pub len: u32,
}

/// In an [`Layout::Interleaved`] run with index offset `d`, the position of slot `m`'s first
/// particle relative to the run's first (lane `m mod 8` of window `m / 8`; windows are 16 apart).
pub(super) const fn interleaved_offset(d: usize, m: usize) -> usize {
    2 * d * (m / d) + m % d
}

/// How many places slot `m`'s first particle lies after its run's first, in a run of index
/// offset `d` (the inverse of [`slot_at`]).
fn offset_of(layout: Layout, d: usize, m: usize) -> usize {
    match layout {
        Layout::Interleaved(_) => interleaved_offset(d, m),
        _ => m,
    }
}

/// The slot whose first particle is `offset` places after its run's first, if any.
fn slot_at(layout: Layout, offset: usize) -> Option<usize> {
    match layout {
        Layout::Contiguous => Some(offset),
        Layout::Interleaved(d) => {
            let d = d as usize;
            (offset % (2 * d) < d).then(|| offset / (2 * d) * d + offset % (2 * d))
        }
        Layout::Scattered => None,
    }
}

/// One colour's runs, `end` of the previous colour (0 for the first) to `end`, and where they split
/// into two shares that touch disjoint particles, so that two threads may project them at once:
/// runs before `cut` and runs from `cut` on (`cut == end`: the second share is empty).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Color {
    cut: u32,
    end: u32,
}

/// Scratch for [`Projections::cut`]: for each particle, the last stamp it was marked with.
struct Marks {
    of: Vec<u32>,
    stamp: u32,
}

impl Marks {
    /// Marks `particles` with a new stamp, and returns it.
    fn mark(&mut self, particles: impl Iterator<Item = u32>) -> u32 {
        self.stamp += 1;
        for i in particles {
            self.of[i as usize] = self.stamp;
        }
        self.stamp
    }
}

/// The springs of a cloth as XPBD projects them: per slot its particles, rest length and
/// compliance, colour by colour, in [`Run`]s. A padding slot joins two particles that no
/// other slot of its batch touches and has rest length 0, which the kernel skips (springs of zero
/// rest length are never built): it writes back what it read.
#[derive(Debug, Clone, Default)]
pub(super) struct Projections {
    /// Particles of each slot, as storage positions (see [`Self::storage`]).
    pub a: Vec<u32>,
    pub b: Vec<u32>,
    /// The spring in each slot; `None` for padding.
    pub(super) spring: Vec<Option<u32>>,
    /// Per slot, for the first slot of each batch of [`Projections::wide_singles`]: whether the
    /// kernel projects it alone. The others go in pairs, in the order the kernel meets them in
    /// a share (the first with the second, the third with the fourth, …), and the layout makes
    /// the two of every pair touch disjoint particles, padding included (a padding slot writes
    /// back what it read, which the pair's other batch may be moving).
    pub(super) solo: Vec<bool>,
    pub rest: Vec<f32>,
    pub compliance: Vec<f32>,
    /// Per slot, the shares of a spring's correction that its two ends take in a substep of one
    /// iteration, `w_a / (w_a + w_b + α̃)` and `w_b / (w_a + w_b + α̃)` with `α̃ = α / h²`, for
    /// the `1/h²` in `weighted_for` ([`Self::set_weights`]).
    pub weights: [Vec<f32>; 2],
    /// Per slot, its two ends' inverse masses, set with the constants, so that setting the
    /// weights reads contiguous values.
    pub(super) ends_inv_mass: [Vec<f32>; 2],
    /// The `1/h²` that `weights` are for; `None` until they are set for the current constants.
    pub(super) weighted_for: Option<f32>,
    pub runs: Vec<Run>,
    /// The runs of each colour, split in two shares for two threads.
    pub(super) colors: Vec<Color>,
    /// Storage order of the particles during a step.
    pub(super) order: Order,
    /// Inverse masses in storage order.
    pub inv_mass: Vec<f32>,
    /// Number of springs laid out.
    pub(super) springs: usize,
}

impl Projections {
    /// Lays out the springs of `model`, in the storage order [`grid_order`] gives it. Call
    /// [`Self::set_constants`] before solving.
    pub(super) fn new(model: &ClothModel) -> Self {
        let (springs, particles) = (&model.springs, model.particle_count());
        let mut order = model.storage_grid().map_or_else(Vec::new, grid_order);
        // A torn grid's copies follow the grid's particles, in their own order.
        if !order.is_empty() {
            order.extend(order.len() as u32..particles as u32);
        }
        let mut p = Self {
            springs: springs.len(),
            order: Order::new(order),
            ..Self::default()
        };
        let mut marks = Marks {
            of: vec![0; particles],
            stamp: 0,
        };
        for c in 0..springs.color_count() {
            // The colour's springs between storage positions, ordered by index offset and then
            // by first particle, so that regular topology forms long runs.
            let range = springs.color_offsets[c] as usize..springs.color_offsets[c + 1] as usize;
            let mut color: Vec<(u32, u32, u32)> = range
                .map(|s| {
                    let (a, b) = (p.stored(springs.a[s]), p.stored(springs.b[s]));
                    (a.min(b), a.max(b), s as u32)
                })
                .collect();
            color.sort_unstable_by_key(|&(a, b, _)| (b - a, a));
            let first = p.runs.len();
            p.add_color(&color, particles);
            p.order_runs(first);
            let cut = p.cut(first, &mut marks);
            p.colors.push(Color {
                cut: cut as u32,
                end: p.runs.len() as u32,
            });
        }
        p.solo = vec![false; p.a.len()];
        for c in 0..p.colors.len() {
            for share in 0..2 {
                p.pair_singles(c, share, &mut marks);
            }
        }
        p.rest = vec![0.0; p.a.len()];
        p.compliance = vec![0.0; p.a.len()];
        p.inv_mass = vec![0.0; particles];
        #[cfg(debug_assertions)]
        assert_eq!(p.check(springs, particles), Ok(()));
        p
    }

    /// Where particle `i` is stored.
    pub(super) fn stored(&self, i: u32) -> u32 {
        self.order.stored(i)
    }

    /// Storage order of the particles during a step.
    pub(super) fn storage(&self) -> &Order {
        &self.order
    }

    /// Number of colours.
    pub(super) fn color_count(&self) -> usize {
        self.colors.len()
    }

    /// Number of slots.
    pub(super) fn slot_count(&self) -> usize {
        self.a.len()
    }

    /// Whether this layout was built for `springs` springs among `particles` particles (a
    /// default, unbuilt layout fits none: every model has a particle).
    pub(super) fn fits(&self, springs: usize, particles: usize) -> bool {
        self.springs == springs
            && self.rest.len() == self.a.len()
            && self.inv_mass.len() == particles
    }

    /// Sets each slot's rest length and compliance `1/k` from the springs' (a zero stiffness
    /// becomes a huge, finite compliance: the spring does nothing), and the inverse masses.
    pub(super) fn set_constants(&mut self, rest: &[f32], stiffness: &[f32], inv_mass: &[f32]) {
        for ((s, r), c) in self
            .spring
            .iter()
            .zip(&mut self.rest)
            .zip(&mut self.compliance)
        {
            (*r, *c) = s.map_or((0.0, 0.0), |s| {
                let s = s as usize;
                (rest[s], 1.0 / stiffness[s].max(1e-6))
            });
        }
        for (i, w) in inv_mass.iter().enumerate() {
            let s = self.stored(i as u32) as usize;
            self.inv_mass[s] = *w;
        }
        for w in &mut self.weights {
            w.resize(self.a.len(), 0.0);
        }
        let inv_mass = &self.inv_mass;
        self.ends_inv_mass =
            [&self.a, &self.b].map(|e| e.iter().map(|&i| inv_mass[i as usize]).collect());
        self.weighted_for = None;
    }

    /// Sets [`Self::weights`] for substeps with `1/h² = inv_h2`, unless they are set for it
    /// already: one pass over the slots when the substep's length or the constants change, so
    /// that a sweep of one iteration needs neither the inverse masses nor the compliances.
    pub(super) fn set_weights(&mut self, inv_h2: f32) {
        if self.weighted_for == Some(inv_h2) {
            return;
        }
        simd::run(self.weigh(inv_h2));
        self.weighted_for = Some(inv_h2);
    }

    /// [`Self::set_weights`]' pass for `inv_h2`, as a [`Kernel`] to run.
    fn weigh(&mut self, inv_h2: f32) -> Weigh<'_> {
        let [weight_a, weight_b] = &mut self.weights;
        let [wa, wb] = &self.ends_inv_mass;
        Weigh {
            inv_mass: (wa, wb),
            compliance: &self.compliance,
            inv_h2,
            out: (weight_a, weight_b),
        }
    }

    /// [`Self::set_weights`] in `build`, from scratch, if the CPU has it; returns whether it ran.
    /// For the test that compares the builds.
    #[cfg(test)]
    pub(super) fn set_weights_in(&mut self, build: Build, inv_h2: f32) -> bool {
        let ran = simd::run_as(build, self.weigh(inv_h2));
        self.weighted_for = ran.then_some(inv_h2);
        ran
    }

    /// Whether [`Self::weights`] are set for `inv_h2`.
    pub(super) fn weighted_for(&self, inv_h2: f32) -> bool {
        self.weighted_for == Some(inv_h2)
    }

    /// Whether a step is worth sharing between two threads (see `team.rs`).
    pub(super) fn worth_sharing(&self) -> bool {
        self.a.len() >= SHARED_MIN_SLOTS
    }

    /// The runs of colour `c`'s share `share` (0 or 1).
    pub(super) fn share(&self, c: usize, share: usize) -> &[Run] {
        let begin = c.checked_sub(1).map_or(0, |c| self.colors[c].end) as usize;
        let Color { cut, end } = self.colors[c];
        let (cut, end) = (cut as usize, end as usize);
        let range = if share == 0 { begin..cut } else { cut..end };
        &self.runs[range]
    }

    /// The first slots of the batches of [`WIDE_BATCH`] slots that the kernel projects one by one
    /// in `runs` (on a CPU with AVX-512), in the order it meets them: in a contiguous run whose
    /// ends are at least that far apart, those left after its groups of `4 * LANES` slots.
    pub(super) fn wide_singles(&self, runs: &[Run]) -> impl Iterator<Item = usize> {
        runs.iter()
            .filter(|r| r.layout == Layout::Contiguous)
            .flat_map(|r| {
                let (start, len) = (r.start as usize, r.len as usize);
                let offset = (self.b[start] - self.a[start]) as usize;
                let grouped = if offset >= 4 * LANES {
                    len / (4 * LANES) * (4 * LANES)
                } else {
                    0
                };
                let singles = if offset >= WIDE_BATCH {
                    (len - grouped) / WIDE_BATCH
                } else {
                    0
                };
                (0..singles).map(move |m| start + grouped + m * WIDE_BATCH)
            })
    }

    /// Sets [`Self::solo`] for the batches of colour `c`'s share `share`: each batch is paired
    /// with the next one if their particles are disjoint, and projected alone otherwise.
    fn pair_singles(&mut self, c: usize, share: usize, marks: &mut Marks) {
        let batches: Vec<usize> = self.wide_singles(self.share(c, share)).collect();
        let mut waiting: Option<(usize, u32)> = None;
        for k in batches {
            if let Some((w, stamp)) = waiting.take() {
                let disjoint = self
                    .touched_slots(k..k + WIDE_BATCH)
                    .all(|i| marks.of[i as usize] != stamp);
                if disjoint {
                    continue;
                }
                self.solo[w] = true;
            }
            waiting = Some((k, marks.mark(self.touched_slots(k..k + WIDE_BATCH))));
        }
    }

    /// The particles the slots of `runs` read and write (a padding slot writes back what it read,
    /// so its particles count too).
    #[cfg(any(test, debug_assertions))]
    fn touched(&self, runs: &[Run]) -> impl Iterator<Item = u32> {
        runs.iter()
            .flat_map(|r| self.touched_slots(r.start as usize..(r.start + r.len) as usize))
    }

    /// The particles slots `slots` read and write.
    fn touched_slots(&self, slots: std::ops::Range<usize>) -> impl Iterator<Item = u32> {
        slots.flat_map(|k| [self.a[k], self.b[k]])
    }

    /// Puts the runs from `first` on (one colour's) in the order of their first particles, their
    /// slots with them: the rows of a grid then follow each other, so that the colour can be cut
    /// between two rows ([`Self::cut`]; sorted by index offset, a grid's colour comes in families
    /// whose padding slots touch the other families' particles). The springs of a colour touch
    /// disjoint particles and a padding slot writes back what it read, so the order changes no
    /// result.
    fn order_runs(&mut self, first: usize) {
        let mut runs: Vec<(Run, u32)> = self.runs[first..].iter().map(|&r| (r, r.len)).collect();
        runs.sort_by_key(|(r, _)| self.a[r.start as usize]);
        self.relay(first, runs);
    }

    /// Lays the slots of the runs from `first` on (one colour's) out again, in the order of
    /// `runs`: each `(run, len)` names one of them as it is now and keeps its first `len` slots.
    fn relay(&mut self, first: usize, runs: Vec<(Run, u32)>) {
        let Some(begin) = self.runs.get(first).map(|r| r.start as usize) else {
            return;
        };
        self.runs.truncate(first);
        let (a, b) = (self.a.split_off(begin), self.b.split_off(begin));
        let spring = self.spring.split_off(begin);
        for (r, len) in runs {
            let from = r.start as usize - begin;
            let slots = from..from + len as usize;
            self.runs.push(Run {
                start: self.a.len() as u32,
                len,
                ..r
            });
            self.a.extend_from_slice(&a[slots.clone()]);
            self.b.extend_from_slice(&b[slots.clone()]);
            self.spring.extend_from_slice(&spring[slots]);
        }
    }

    /// Splits the runs from `first` to the end (one colour's) into two shares that touch
    /// disjoint particles, at the run boundary, or the boundary of a pair of batches inside a run
    /// (which is then split in two), nearest the middle of the colour's slots at which that holds.
    /// Within a colour only padding slots can touch the other share's particles; padding at the
    /// end of a run that does is dropped (its run ends in single slots instead). Returns the
    /// first run of the second share, or the end (no second share).
    fn cut(&mut self, first: usize, marks: &mut Marks) -> usize {
        let (Some(head), Some(last)) = (self.runs.get(first), self.runs.last()) else {
            return self.runs.len();
        };
        let (begin, end) = (head.start as usize, (last.start + last.len) as usize);
        let mut candidates = Vec::new();
        for r in &self.runs[first..] {
            let inside = (0..r.len as usize)
                .step_by(2 * LANES)
                .map(|m| r.start as usize + m);
            candidates.extend(inside.filter(|&k| k > begin));
        }
        candidates.sort_unstable_by_key(|&k| (2 * (k - begin)).abs_diff(end - begin));
        for &k in candidates.iter().take(8) {
            let run =
                first + self.runs[first..].partition_point(|r| (r.start + r.len) as usize <= k);
            let stamp = marks.mark(self.touched_slots(begin..k));
            let shared: Vec<u32> = self
                .touched_slots(k..end)
                .filter(|&i| marks.of[i as usize] == stamp)
                .collect();
            if shared.is_empty() {
                return self.split_run(run, k);
            }
            // Dropping padding lays the slots out again: the cut keeps its place in its run.
            let offset = k - self.runs[run].start as usize;
            if self.drop_padding(first, &shared, marks) {
                let r = self.runs[run];
                return match offset {
                    0 => run,
                    o if o < r.len as usize => self.split_run(run, r.start as usize + o),
                    _ => run + 1,
                };
            }
        }
        self.runs.len()
    }

    /// Splits run `run` at slot `k` (a batch boundary inside it, or its start) and returns the
    /// run that starts at `k`.
    fn split_run(&mut self, run: usize, k: usize) -> usize {
        let r = self.runs[run];
        let k = k as u32;
        if r.start == k {
            return run;
        }
        self.runs[run].len = k - r.start;
        let rest = Run {
            start: k,
            len: r.start + r.len - k,
            ..r
        };
        self.runs.insert(run + 1, rest);
        run + 1
    }

    /// Drops the padding slots of the runs from `first` on that touch a particle of `shared`, if
    /// they all end their runs (with every slot after them padding too); returns whether it did.
    fn drop_padding(&mut self, first: usize, shared: &[u32], marks: &mut Marks) -> bool {
        let stamp = marks.mark(shared.iter().copied());
        let shared = |p: u32| marks.of[p as usize] == stamp;
        let mut runs = Vec::with_capacity(self.runs.len() - first);
        for r in &self.runs[first..] {
            let slots = r.start as usize..(r.start + r.len) as usize;
            let real_end = slots
                .clone()
                .rfind(|&k| self.spring[k].is_some())
                .map_or(0, |k| k + 1);
            let mut len = slots.end;
            for k in slots.clone() {
                let touches = shared(self.a[k]) || shared(self.b[k]);
                if self.spring[k].is_none() && touches {
                    if k < real_end {
                        return false;
                    }
                    len = len.min(k);
                }
            }
            runs.push((*r, (len - slots.start) as u32));
        }
        self.relay(first, runs);
        true
    }

    /// Lays out the springs of one colour, given as `(a, b, spring)` with storage positions
    /// `a < b`, sorted by `b - a` and then `a`: runs where the positions allow, the others
    /// gathered in one scattered run at the end.
    fn add_color(&mut self, color: &[(u32, u32, u32)], particles: usize) {
        let a: Vec<u32> = color.iter().map(|c| c.0).collect();
        let b: Vec<u32> = color.iter().map(|c| c.1).collect();
        let mut scattered = Vec::new();
        let mut i = 0;
        while i < color.len() {
            let Some((layout, taken, slots)) = find_run(&a, &b, i, color.len(), particles) else {
                scattered.push(i);
                i += 1;
                continue;
            };
            let start = self.a.len();
            let (a0, d) = (a[i] as usize, (b[i] - a[i]) as usize);
            let mut next = i;
            for m in 0..slots {
                let first = a0 + offset_of(layout, d, m);
                let real = next < i + taken && a[next] as usize == first;
                self.spring.push(real.then(|| color[next].2));
                next += usize::from(real);
                self.a.push(first as u32);
                self.b.push((first + d) as u32);
            }
            self.runs.push(Run {
                layout,
                start: start as u32,
                len: slots as u32,
            });
            i += taken;
        }
        if !scattered.is_empty() {
            self.runs.push(Run {
                layout: Layout::Scattered,
                start: self.a.len() as u32,
                len: scattered.len() as u32,
            });
            for k in scattered {
                self.a.push(a[k]);
                self.b.push(b[k]);
                self.spring.push(Some(color[k].2));
            }
        }
    }

    /// Checks that the slots hold every spring once, with its particles, each run in one colour,
    /// that every run's [`Layout`] describes its slots' particles, and that no particle appears
    /// twice in a vector batch (which the kernel relies on). The message names the first problem.
    #[cfg(any(test, debug_assertions))]
    pub(super) fn check(&self, springs: &Springs, particles: usize) -> Result<(), String> {
        let mut seen = vec![false; springs.len()];
        let color_of = |s: usize| springs.color_offsets.partition_point(|&o| o as usize <= s) - 1;
        let mut next = 0;
        for (r, run) in self.runs.iter().enumerate() {
            let (start, len) = (run.start as usize, run.len as usize);
            if start != next || start + len > self.a.len() {
                return Err(format!("run {r} does not continue the runs before it"));
            }
            next += len;
            let mut color = None;
            for k in start..start + len {
                let (a, b) = (self.a[k] as usize, self.b[k] as usize);
                if a >= particles || b >= particles || a == b {
                    return Err(format!("slot {k} joins particles {a} and {b}"));
                }
                if let Some(s) = self.spring[k] {
                    let s = s as usize;
                    if std::mem::replace(&mut seen[s], true) {
                        return Err(format!("spring {s} is in two slots"));
                    }
                    let ends = [springs.a[s], springs.b[s]].map(|i| self.stored(i) as usize);
                    if ends != [a, b] && ends != [b, a] {
                        return Err(format!("slot {k} does not join spring {s}'s particles"));
                    }
                    if *color.get_or_insert(color_of(s)) != color_of(s) {
                        return Err(format!("run {r} crosses a colour boundary"));
                    }
                }
                let m = k - start;
                let fits = match run.layout {
                    Layout::Contiguous => {
                        a == self.a[start] as usize + m
                            && b - a == self.b[start] as usize - self.a[start] as usize
                            && b - a >= LANES
                    }
                    Layout::Interleaved(d) => {
                        let window = self.a[start + m / LANES * LANES] as usize;
                        a == window + interleaved_offset(d as usize, m % LANES)
                            && b == a + d as usize
                    }
                    Layout::Scattered => true,
                };
                if !fits {
                    return Err(format!("slot {k} is not where run {r}'s layout puts it"));
                }
            }
            if run.layout != Layout::Scattered {
                for batch in (start..start + len / LANES * LANES).step_by(LANES) {
                    let mut ends: Vec<u32> = (batch..batch + LANES)
                        .flat_map(|k| [self.a[k], self.b[k]])
                        .collect();
                    ends.sort_unstable();
                    if ends.windows(2).any(|w| w[0] == w[1]) {
                        return Err(format!("the batch at slot {batch} uses a particle twice"));
                    }
                }
            }
        }
        // The colours' runs, in order, and their shares disjoint.
        let mut begin = 0;
        for (c, &Color { cut, end }) in self.colors.iter().enumerate() {
            let (cut, end) = (cut as usize, end as usize);
            if !(begin <= cut && cut <= end && end <= self.runs.len()) {
                return Err(format!("colour {c}'s runs are out of order"));
            }
            for run in &self.runs[begin..end] {
                let slots = run.start as usize..(run.start + run.len) as usize;
                if let Some(s) = slots.filter_map(|k| self.spring[k]).next()
                    && color_of(s as usize) != c
                {
                    return Err(format!("colour {c} holds a run of another colour"));
                }
            }
            for share in 0..2 {
                let paired = self
                    .wide_singles(self.share(c, share))
                    .filter(|&k| !self.solo[k])
                    .collect::<Vec<_>>();
                for pair in paired.chunks_exact(2) {
                    let first: std::collections::HashSet<u32> =
                        self.touched_slots(pair[0]..pair[0] + WIDE_BATCH).collect();
                    let mut second = self.touched_slots(pair[1]..pair[1] + WIDE_BATCH);
                    if let Some(i) = second.find(|i| first.contains(i)) {
                        return Err(format!(
                            "the paired batches at slots {} and {} both touch particle {i}",
                            pair[0], pair[1]
                        ));
                    }
                }
            }
            let first: std::collections::HashSet<u32> = self.touched(self.share(c, 0)).collect();
            if let Some(i) = self.touched(self.share(c, 1)).find(|i| first.contains(i)) {
                return Err(format!("both shares of colour {c} touch particle {i}"));
            }
            begin = end;
        }
        if begin != self.runs.len() {
            return Err(format!(
                "the colours hold {begin} of {} runs",
                self.runs.len()
            ));
        }
        match seen.iter().position(|s| !s) {
            _ if next != self.a.len() => {
                Err(format!("runs cover {next} of {} slots", self.a.len()))
            }
            Some(s) => Err(format!("spring {s} is in no slot")),
            None => Ok(()),
        }
    }
}

/// [`Projections::set_weights`]' arguments, as a vector [`Kernel`]: each slot's ends' inverse
/// masses and compliance, and where its weights go (the same bits in every build).
struct Weigh<'a> {
    inv_mass: (&'a [f32], &'a [f32]),
    compliance: &'a [f32],
    inv_h2: f32,
    out: (&'a mut [f32], &'a mut [f32]),
}

impl Kernel for Weigh<'_> {
    const WIDEST: Build = Build::Avx512;

    #[inline(always)]
    fn body<const WIDE: bool>(self) {
        let Self {
            inv_mass: (wa, wb),
            compliance,
            inv_h2,
            out: (weight_a, weight_b),
        } = self;
        let slots = wa.iter().zip(wb).zip(compliance);
        for (((&wa, &wb), &c), (ca, cb)) in slots.zip(weight_a.iter_mut().zip(weight_b)) {
            let sum = wa + wb + c * inv_h2;
            // Both ends pinned and no compliance: nothing moves.
            (*ca, *cb) = if sum > 0.0 {
                (wa / sum, wb / sum)
            } else {
                (0.0, 0.0)
            };
        }
    }
}

/// Storage order for XPBD on a grid of at least 32 columns: each row's columns grouped by their
/// residue mod 4 (columns 0, 4, 8, …, then 1, 5, 9, …). Every spring of the canonical grid then
/// joins two particles at least 8 storage places apart, in runs of equal offset, so that all of
/// them are projected by the contiguous kernel: the rows' springs (offsets 1 and 2 in the
/// particles' own order) need no shuffling. Narrower grids keep their own order.
pub(super) fn grid_order(spec: &GridSpec) -> Vec<u32> {
    let nx = spec.nx;
    if nx < 4 * LANES as u32 {
        return Vec::new();
    }
    let mut order = Vec::with_capacity((nx * spec.ny) as usize);
    for j in 0..spec.ny {
        for r in 0..4 {
            order.extend((r..nx).step_by(4).map(|i| spec.index(i, j)));
        }
    }
    order
}

/// The run of slots that starts at spring `i` of a colour ending at `end`, if it is worth a vector
/// kernel: its layout, the number of springs it takes (`i..i + taken`) and its slot count. Springs
/// follow each other with holes of at most [`MAX_GAP`](runs::MAX_GAP) slots; the run is padded to whole batches
/// where the padding's particles exist.
fn find_run(
    a: &[u32],
    b: &[u32],
    i: usize,
    end: usize,
    particles: usize,
) -> Option<(Layout, usize, usize)> {
    // Springs given with `b < a` (a user's model may) are simply gathered.
    let d = b[i].checked_sub(a[i])? as usize;
    let layout = match d {
        1 | 2 => Layout::Interleaved(d as u8),
        _ if d >= LANES => Layout::Contiguous,
        _ => return None,
    };
    let (taken, slots) = runs::extent(a, b, i, end, |offset| slot_at(layout, offset));
    let padded = slots.next_multiple_of(LANES);
    let slots = if a[i] as usize + offset_of(layout, d, padded - 1) + d < particles {
        padded
    } else {
        slots
    };
    // Half a batch of springs pays for the padding; fewer are gathered.
    (slots >= LANES && 2 * taken >= LANES).then_some((layout, taken, slots))
}
