//! XPBD with substeps (Macklin et al. 2016, "XPBD"; Macklin et al. 2019, "Small Steps in Physics
//! Simulation"): each substep predicts the particles' motion, projects every spring once per
//! iteration by coloured Gauss-Seidel, and takes the velocity from the displacement.
//!
//! The springs are projected by a vector kernel, eight at a time (sixteen on AVX-512 CPUs where
//! the layout allows). [`Projections`] lays them out for it: colour by colour, in runs of slots
//! whose particles can be read with whole vector loads; holes in a run are filled with padding
//! slots that change nothing, so that no spring of a regular cloth falls back to scalar code. On
//! grids of 32 columns or more the particles are stored in an order ([`grid_order`]) in which
//! every spring is such a contiguous access.
//!
//! Nothing here allocates inside a step.

use super::collision::{ContactState, Near};
use super::forces::Soa;
#[cfg(test)]
use super::model::Springs;
use super::model::{ClothModel, GridSpec};
use super::parallel::Spread;
use super::solver::{ClothSim, count_contact_work, pin_motion, soa_clearances};
use glam::Vec3;
use std::cell::UnsafeCell;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// Springs projected together by the vector kernel. Within one colour no two springs share a
/// particle, so a batch gives exactly the sequential Gauss-Seidel result.
const LANES: usize = 8;

/// Fewest slots for which a step is shared between two threads (see
/// [`Projections::worth_sharing`]). A 64×64 grid (23,938 springs) runs 10–17% faster on two
/// threads, a 128×128 one 30–70% (BENCHMARKS.md); smaller cloths stay on one.
const SHARED_MIN_SLOTS: usize = 20_000;

/// Longest hole (in slots) inside a run that is padded rather than ending the run: the row ends of
/// a grid's colours leave holes of one or two.
const MAX_GAP: usize = 2;

/// How the particles of a [`Run`]'s slots are laid out in memory.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Layout {
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
struct Run {
    layout: Layout,
    start: u32,
    len: u32,
}

/// In an [`Layout::Interleaved`] run with index offset `d`, the position of slot `m`'s first
/// particle relative to the run's first (lane `m mod 8` of window `m / 8`; windows are 16 apart).
const fn interleaved_offset(d: usize, m: usize) -> usize {
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
struct Color {
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

/// The springs of a cloth as XPBD projects them: per slot its particles, rest length, compliance
/// and multiplier, colour by colour, in [`Run`]s. A padding slot joins two particles that no
/// other slot of its batch touches and has rest length 0, which the kernel skips (springs of zero
/// rest length are never built): it writes back what it read.
#[derive(Debug, Clone, Default)]
pub(super) struct Projections {
    /// Particles of each slot, as storage positions (see [`Self::order`]).
    a: Vec<u32>,
    b: Vec<u32>,
    /// The spring in each slot; `None` for padding.
    spring: Vec<Option<u32>>,
    rest: Vec<f32>,
    compliance: Vec<f32>,
    /// Multipliers of the current substep (used with more than one iteration).
    lambda: Vec<f32>,
    runs: Vec<Run>,
    /// The runs of each colour, split in two shares for two threads.
    colors: Vec<Color>,
    /// Storage order of the particles during a step (empty: their own order).
    order: Vec<u32>,
    /// Where each particle is stored (empty with `order`).
    slot: Vec<u32>,
    /// Inverse masses in storage order.
    inv_mass: Vec<f32>,
    /// The wind's velocity change per substep, in storage order (scratch).
    wind_dv: Soa,
    /// Number of springs laid out.
    springs: usize,
}

impl Projections {
    /// Lays out the springs of `model`, in the storage order [`grid_order`] gives it. Call
    /// [`Self::set_constants`] before solving.
    pub(super) fn new(model: &ClothModel) -> Self {
        let (springs, particles) = (&model.springs, model.particle_count());
        let order = model.grid.as_ref().map_or_else(Vec::new, grid_order);
        let mut slot = vec![0; if order.is_empty() { 0 } else { particles }];
        for (s, &i) in order.iter().enumerate() {
            slot[i as usize] = s as u32;
        }
        let mut p = Self {
            springs: springs.len(),
            order,
            slot,
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
        p.rest = vec![0.0; p.a.len()];
        p.compliance = vec![0.0; p.a.len()];
        p.lambda = vec![0.0; p.a.len()];
        p.inv_mass = vec![0.0; particles];
        p.wind_dv = Soa::new(particles);
        p
    }

    /// Inverse masses in storage order.
    pub(super) fn inv_mass(&self) -> &[f32] {
        &self.inv_mass
    }

    /// Where particle `i` is stored.
    pub(super) fn stored(&self, i: u32) -> u32 {
        self.slot.get(i as usize).copied().unwrap_or(i)
    }

    /// Storage order of the particles during a step: `order()[s]` is the particle stored at `s`
    /// (empty: their own order).
    pub(super) fn order(&self) -> &[u32] {
        &self.order
    }

    /// Whether this layout was built for a set of `springs` springs.
    pub(super) fn fits(&self, springs: usize) -> bool {
        self.springs == springs && self.rest.len() == self.a.len()
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
    }

    /// Whether a step is worth sharing between two threads ([`Team`]).
    pub(super) fn worth_sharing(&self) -> bool {
        self.a.len() >= SHARED_MIN_SLOTS
    }

    /// The runs of colour `c`'s share `share` (0 or 1).
    fn share(&self, c: usize, share: usize) -> &[Run] {
        let begin = c.checked_sub(1).map_or(0, |c| self.colors[c].end) as usize;
        let Color { cut, end } = self.colors[c];
        let (cut, end) = (cut as usize, end as usize);
        let range = if share == 0 { begin..cut } else { cut..end };
        &self.runs[range]
    }

    /// The particles the slots of `runs` read and write (a padding slot writes back what it read,
    /// so its particles count too).
    #[cfg(test)]
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
    /// Within a colour only padding slots can touch the other share's particles; at a run
    /// boundary, padding at the end of a run that does is dropped (its run ends in single slots
    /// instead). Returns the first run of the second share, or the end (no second share).
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
            if self.runs[run].start as usize == k && self.drop_padding(first, &shared) {
                return run;
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
    fn drop_padding(&mut self, first: usize, shared: &[u32]) -> bool {
        let shared: std::collections::HashSet<u32> = shared.iter().copied().collect();
        let mut runs = Vec::with_capacity(self.runs.len() - first);
        for r in &self.runs[first..] {
            let slots = r.start as usize..(r.start + r.len) as usize;
            let real_end = slots
                .clone()
                .rfind(|&k| self.spring[k].is_some())
                .map_or(0, |k| k + 1);
            let mut len = slots.end;
            for k in slots.clone() {
                let touches = shared.contains(&self.a[k]) || shared.contains(&self.b[k]);
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
    #[cfg(test)]
    fn check(&self, springs: &Springs, particles: usize) -> Result<(), String> {
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

/// Storage order for XPBD on a grid of at least 32 columns: each row's columns grouped by their
/// residue mod 4 (columns 0, 4, 8, …, then 1, 5, 9, …). Every spring of the canonical grid then
/// joins two particles at least 8 storage places apart, in runs of equal offset, so that all of
/// them are projected by the contiguous kernel: the rows' springs (offsets 1 and 2 in the
/// particles' own order) need no shuffling. Narrower grids keep their own order.
fn grid_order(spec: &GridSpec) -> Vec<u32> {
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
/// follow each other with holes of at most [`MAX_GAP`] slots; the run is padded to whole batches
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
    let (mut last, mut k) = (0, i + 1);
    while k < end && b[k].checked_sub(a[k]) == Some(d as u32) && a[k] > a[i] {
        match slot_at(layout, (a[k] - a[i]) as usize) {
            Some(m) if m > last && m - last - 1 <= MAX_GAP => last = m,
            _ => break,
        }
        k += 1;
    }
    let (taken, slots) = (k - i, last + 1);
    let padded = slots.next_multiple_of(LANES);
    let slots = if a[i] as usize + offset_of(layout, d, padded - 1) + d < particles {
        padded
    } else {
        slots
    };
    // Half a batch of springs pays for the padding; fewer are gathered.
    (slots >= LANES && 2 * taken >= LANES).then_some((layout, taken, slots))
}

/// Positions during XPBD's projection, one slice per coordinate: where each particle began the
/// substep, and its displacement since. The corrections accumulate in the small displacements
/// rather than in the large positions, so that f32 keeps them (added to a position of about 1 m,
/// a correction below 1e-7 m would vanish, and the velocity `Δx / h` with it).
#[derive(Clone, Copy)]
struct Split {
    start: [Column; 3],
    delta: [Column; 3],
}

/// One array of `f32` during a sweep (a coordinate of the particles, or the multipliers), held as
/// a pointer and a length, so that the threads of a parallel sweep can share it: each writes only
/// the particles of its own share of a colour, and [`Projections`] proves the shares disjoint.
#[derive(Clone, Copy)]
struct Column {
    ptr: *mut f32,
    len: usize,
}

impl Column {
    /// The elements of `s`.
    ///
    /// # Safety
    /// While the column (or a copy) is used, `s` stays allocated and nothing but columns reads or
    /// writes it; columns used on different threads at once touch disjoint elements, and a column
    /// made from a shared slice (`start`) is only loaded from.
    unsafe fn new(s: *mut [f32]) -> Self {
        Self {
            ptr: s.cast(),
            len: s.len(),
        }
    }

    /// The first `n` elements, if there are as many.
    #[inline(always)]
    fn cut(self, n: usize) -> Option<Self> {
        (n <= self.len).then_some(Self {
            ptr: self.ptr,
            len: n,
        })
    }

    /// Copies `N` values starting at `i` (zeros past the end, which the runs never reach).
    #[inline(always)]
    fn load<const N: usize>(self, i: usize) -> [f32; N] {
        // The same test as slicing `i..i + N`, which the kernel's one check per batch covers.
        let end = i + N;
        if i <= end && end <= self.len {
            // SAFETY: in bounds (checked), and no other thread writes these elements (`new`).
            unsafe { self.ptr.add(i).cast::<[f32; N]>().read_unaligned() }
        } else {
            [0.0; N]
        }
    }

    /// Writes `values` to elements `i..i + N` (nothing past the end).
    #[inline(always)]
    fn store<const N: usize>(self, i: usize, values: &[f32; N]) {
        let end = i + N;
        if i <= end && end <= self.len {
            // SAFETY: in bounds (checked), and no other thread touches these elements (`new`).
            unsafe { self.ptr.add(i).cast::<[f32; N]>().write_unaligned(*values) }
        }
    }

    /// Elements `range`, as a slice.
    ///
    /// # Safety
    /// Nothing else reads or writes them while the slice lives.
    unsafe fn slice_mut<'a>(self, range: std::ops::Range<usize>) -> &'a mut [f32] {
        let range = range.start.min(self.len)..range.end.min(self.len);
        // SAFETY: in bounds (clamped), and exclusive (the caller's contract).
        unsafe { std::slice::from_raw_parts_mut(self.ptr.add(range.start), range.len()) }
    }

    /// Element `i`.
    #[inline(always)]
    fn get(self, i: usize) -> f32 {
        self.load::<1>(i)[0]
    }

    /// Sets element `i`.
    #[inline(always)]
    fn set(self, i: usize, value: f32) {
        self.store::<1>(i, &[value]);
    }
}

/// One XPBD step of `dt` seconds in `n` substeps. With `spread`, a large cloth's colours are
/// projected by two threads ([`Team`]); the result is bit-identical.
pub(super) fn step_xpbd(sim: &mut ClothSim, dt: f32, n: u32, spread: Option<&dyn Spread>) {
    match spread.filter(|_| sim.projections.worth_sharing()) {
        Some(spread) => {
            let team = Team::default();
            spread.join(&|| team.help(), &mut || {
                // The helper returns once this is dropped, even if the step panics.
                let _stop = Stop(&team);
                substeps(sim, dt, n, Some(&team));
            });
        }
        None => substeps(sim, dt, n, None),
    }
}

/// The substeps of [`step_xpbd`], with the sweeps shared with `team`'s helper if given.
fn substeps(sim: &mut ClothSim, dt: f32, n: u32, team: Option<&Team>) {
    let h = dt / n as f32;
    let inv_h = 1.0 / h;
    let inv_h2 = inv_h * inv_h;
    let motion = Motion {
        h,
        inv_h,
        keep: (-sim.settings.damping * h).exp(),
        gravity: (sim.settings.gravity * h).to_array(),
    };
    sim.load_soa_state();
    // Wind forces are held over the step (see `wind.rs`): their velocity change per substep, in
    // storage order.
    let wind = sim.wind.active;
    if wind {
        let forces = sim.wind.particle_forces();
        let p = &mut sim.projections;
        for (s, w) in p.inv_mass.iter().enumerate() {
            let f = forces[p.order.get(s).map_or(s, |&i| i as usize)];
            p.wind_dv.set(s, f * (*w * h));
        }
    }
    // Nothing happens to the state between the end of one substep and the start of the next but
    // the pins' drive, so the two particle passes are one: contacts are resolved just before it,
    // on the state the substep ends in (`AheadOfEnd`).
    let contacts = sim.contacts.is_active();
    // Tests compare this with contacts resolved after a separate end pass, on the end state.
    let after = contacts && sim.contacts_after_end();
    let ahead = contacts && !after;
    for sub in 0..n {
        if sub == 0 || after {
            advance::<false, true>(sim, &motion, wind, team);
        }
        // Pinned particles are given the displacement to their targets.
        let (t0, t1) = (sub as f32 / n as f32, (sub + 1) as f32 / n as f32);
        for pin in &sim.pins {
            let i = sim.soa_index(pin.particle);
            let (target, _) = pin_motion(pin, t0, t1, inv_h);
            sim.displacement.set(i, target - sim.soa.get(i));
        }
        // λ starts at 0 each substep, so one iteration needs no multiplier storage.
        let accumulate = sim.settings.iterations > 1;
        if accumulate {
            sim.projections.lambda.fill(0.0);
        }
        let (start, delta) = (&sim.soa, &mut sim.displacement);
        // SAFETY: until the sweeps below return, the arrays are used through these columns only:
        // `start` is only loaded from, and the team's helper writes only the particles and
        // multipliers of its own shares, which `Projections` keeps disjoint from the others.
        let (x, lambda) = unsafe {
            let read = |v: &[f32]| Column::new(std::ptr::from_ref(v).cast_mut());
            let write = |v: &mut [f32]| Column::new(v);
            let x = Split {
                start: [read(&start.x), read(&start.y), read(&start.z)],
                delta: [
                    write(&mut delta.x),
                    write(&mut delta.y),
                    write(&mut delta.z),
                ],
            };
            (x, write(&mut sim.projections.lambda))
        };
        let sweep = Sweep {
            p: &sim.projections,
            x,
            lambda,
            inv_h2,
        };
        for _ in 0..sim.settings.iterations {
            match team {
                Some(team) => {
                    for c in 0..sweep.p.colors.len() {
                        team.run(&|s| sweep.run(sweep.p.share(c, s), accumulate));
                    }
                }
                None => sweep.run(&sim.projections.runs, accumulate),
            }
        }
        // Contacts last, so every substep ends outside the colliders; their push-out is not
        // turned into velocity (see `collision.rs`).
        if ahead {
            resolve_contacts_ahead(sim, (t0, t1, h));
        }
        let begin = !after && sub + 1 < n;
        if begin {
            advance::<true, true>(sim, &motion, wind, team);
        } else {
            advance::<true, false>(sim, &motion, wind, team);
        }
        if ahead {
            apply_contact_velocities(sim, &motion, wind, begin);
        }
        // Pinned particles end on their targets, at the velocity that takes them there.
        sim.drive_soa_pins(t0, t1, inv_h);
        if after {
            sim.resolve_soa_contacts(sub, n, h);
        }
    }
    sim.store_soa_state();
}

/// What one Gauss-Seidel sweep works on, for the thread or threads that run it.
struct Sweep<'a> {
    p: &'a Projections,
    x: Split,
    lambda: Column,
    inv_h2: f32,
}

impl Sweep<'_> {
    /// Projects the springs of `runs` (with `accumulate`, keeping the multipliers).
    fn run(&self, runs: &[Run], accumulate: bool) {
        let (p, x, lambda, inv_h2) = (self.p, self.x, self.lambda, self.inv_h2);
        if accumulate {
            solve_springs::<true>(p, runs, x, lambda, inv_h2);
        } else {
            solve_springs::<false>(p, runs, x, lambda, inv_h2);
        }
    }
}

/// Two threads sharing a step's work, as phases of two shares each: a colour of a sweep (its
/// shares touch disjoint particles, [`Projections::cut`]), or a particle pass (the two halves of
/// the particles). The step's thread publishes a phase, does its first share and then claims the
/// second, unless the helper has claimed it already; then it waits for the helper to finish it.
/// The helper only ever claims second shares, so that each thread keeps to its own half of the
/// cloth, and its caches. The step's thread never waits on a share nobody has claimed, so it
/// finishes the step alone if the helper never starts (a busy or single-threaded pool), and a
/// helper started late finds nothing left. Which thread does which share changes no result.
#[derive(Default)]
struct Team {
    /// The latest published phase, counted from 1 over the step.
    phase: AtomicUsize,
    /// The latest phase whose second share was claimed, by either thread.
    claimed: AtomicUsize,
    /// The latest phase whose second share the helper has finished.
    finished: AtomicUsize,
    /// Set when the step is over: the helper returns.
    stop: AtomicBool,
    /// The current phase's work, given the share. Written by the step's thread only while the
    /// helper holds no claim.
    job: UnsafeCell<Option<Job>>,
}

/// A phase's work, given the share (0 or 1), with its lifetime erased: it lives until the phase
/// is over ([`Team::run`]).
type Job = *const (dyn Fn(usize) + Sync);

// SAFETY: `job` is written only by the step's thread while the helper holds no claim (every claim
// it took is finished), before the phase that publishes it is released; the helper reads it only
// while holding a claim, after acquiring that phase (see `Team`).
unsafe impl Sync for Team {}

// SAFETY: a column's elements are touched by one thread at a time (`Column::new`'s contract).
unsafe impl Send for Column {}
// SAFETY: as above.
unsafe impl Sync for Column {}

/// Marks phase `.1`'s second share finished when dropped.
struct Finish<'a>(&'a Team, usize);

impl Drop for Finish<'_> {
    fn drop(&mut self) {
        self.0.finished.store(self.1, Ordering::Release);
    }
}

/// Marks a [`Team`]'s step over when dropped.
struct Stop<'a>(&'a Team);

impl Drop for Stop<'_> {
    fn drop(&mut self) {
        self.0.stop.store(true, Ordering::Release);
    }
}

impl Team {
    /// Runs `job`'s two shares, with the helper (on the step's thread), and returns when both
    /// are done.
    fn run(&self, job: &(dyn Fn(usize) + Sync)) {
        let q = self.phase.load(Ordering::Relaxed) + 1;
        // SAFETY: every claim on an earlier phase is finished (the previous call waited for it),
        // so the helper does not read the job; it reads the pointer only under a claim on this
        // phase, which ends before this call returns. Only the trait object's lifetime changes.
        unsafe {
            *self.job.get() =
                Some(std::mem::transmute::<*const (dyn Fn(usize) + Sync + '_), Job>(job));
        }
        self.phase.store(q, Ordering::Release);
        // A panic in the first share must not unwind past the job while the helper may be
        // running it: caught, then raised again once the second share is settled.
        let first = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| job(0)));
        if self.claim(q) {
            if first.is_ok() {
                job(1);
            }
        } else {
            let mut spins = 0;
            while self.finished.load(Ordering::Acquire) < q {
                pause(&mut spins);
            }
        }
        if let Err(panic) = first {
            std::panic::resume_unwind(panic);
        }
    }

    /// Claims phase `q`'s second share, unless it is claimed already.
    fn claim(&self, q: usize) -> bool {
        self.claimed
            .compare_exchange(q - 1, q, Ordering::Acquire, Ordering::Relaxed)
            .is_ok()
    }

    /// The helper's side: claims second shares until the step is over.
    fn help(&self) {
        let (mut seen, mut spins) = (0, 0);
        loop {
            let q = self.phase.load(Ordering::Acquire);
            if q > seen {
                seen = q;
                spins = 0;
                if self.claim(q) {
                    // Finished even if the job panics, so that the step's thread does not wait
                    // forever (the panic reaches it when the `Spread` joins the helper).
                    let _finish = Finish(self, q);
                    // SAFETY: the job is not written, and outlives, while this claim is
                    // unfinished (see `Team::run`).
                    if let Some(job) = unsafe { *self.job.get() } {
                        unsafe { (*job)(1) };
                    }
                }
            } else if self.stop.load(Ordering::Acquire) {
                return;
            } else {
                pause(&mut spins);
            }
        }
    }
}

/// Waits a little: spins at first, then yields the core.
fn pause(spins: &mut u32) {
    *spins += 1;
    if *spins < 1 << 10 {
        std::hint::spin_loop();
    } else {
        std::thread::yield_now();
    }
}

/// XPBD's arrays between a substep's projections and its end pass, as the contact response's
/// state: each particle starts the substep at `x` and ends it at `x + d`, moving at `d / h`
/// unless a contact has set its velocity (listed in `touched`, for [`apply_contact_velocities`];
/// `entry[i]` is 1 + its place there, 0 for none). Moving a particle changes its `d`.
struct AheadOfEnd<'a> {
    x: &'a Soa,
    d: &'a mut Soa,
    inv_h: f32,
    layout: &'a Projections,
    touched: &'a mut Vec<(u32, Vec3)>,
    entry: &'a mut [u32],
}

impl ContactState for AheadOfEnd<'_> {
    fn len(&self) -> usize {
        self.x.len()
    }
    fn inv_mass(&self, i: usize) -> f32 {
        self.layout.inv_mass[i]
    }
    fn slot(&self, p: u32) -> usize {
        self.layout.stored(p) as usize
    }
    fn start(&self, i: usize) -> Vec3 {
        self.x.get(i)
    }
    fn position(&self, i: usize) -> Vec3 {
        // The end pass's `x += d`, coordinate by coordinate.
        self.x.get(i) + self.d.get(i)
    }
    fn velocity(&self, i: usize) -> Vec3 {
        match self.entry[i] {
            0 => self.d.get(i) * self.inv_h,
            k => self.touched[k as usize - 1].1,
        }
    }
    fn set(&mut self, i: usize, x: Vec3, v: Vec3) {
        self.d.set(i, x - self.x.get(i));
        match self.entry[i] {
            0 => {
                // At most one entry per particle, within the capacity reserved for all of them.
                self.touched.push((i as u32, v));
                self.entry[i] = self.touched.len() as u32;
            }
            k => self.touched[k as usize - 1].1 = v,
        }
    }
    fn clearances(&self, near: Near, out: &mut [f32]) {
        soa_clearances::<true>(self.x, self.d, near, out);
    }
}

/// The contact response for substep `[t0, t1]` of length `h`, ahead of the end pass
/// ([`AheadOfEnd`]); with contact work tracked, the energy it adds is counted.
fn resolve_contacts_ahead(sim: &mut ClothSim, t: (f32, f32, f32)) {
    let before = sim.contact_work.map(|_| energy_ahead(sim, 1.0 / t.2));
    let (touched, entry) = &mut sim.contact_velocities;
    entry.resize(sim.soa.len(), 0);
    let mut state = AheadOfEnd {
        x: &sim.soa,
        d: &mut sim.displacement,
        inv_h: 1.0 / t.2,
        layout: &sim.projections,
        touched,
        entry,
    };
    sim.contacts
        .resolve_state(t, &sim.model.triangles, &mut state);
    if let Some(before) = before {
        let after = energy_ahead(sim, 1.0 / t.2);
        count_contact_work(&mut sim.contact_work, before, after);
    }
}

/// The total energy of the state [`AheadOfEnd`] describes (`inv_h` = 1/substep), through the
/// particle vectors, which the step rewrites at its end anyway (only for tracked contact work).
fn energy_ahead(sim: &mut ClothSim, inv_h: f32) -> f64 {
    let (touched, entry) = &sim.contact_velocities;
    for (s, &e) in entry.iter().enumerate().take(sim.soa.len()) {
        let (x, d) = (sim.soa.get(s), sim.displacement.get(s));
        let v = match e {
            0 => d * inv_h,
            k => touched[k as usize - 1].1,
        };
        let p = sim.projections.order().get(s).map_or(s, |&p| p as usize);
        (sim.positions[p], sim.velocities[p]) = (x + d, v);
    }
    sim.energy().total()
}

/// After the end pass, the velocities the contacts set replace the displacement's: in the next
/// substep's start (`begin`, the same formula as [`advance`]'s) or, at the step's end, in
/// `velocity_soa`.
fn apply_contact_velocities(sim: &mut ClothSim, m: &Motion, wind: bool, begin: bool) {
    let (touched, entry) = &mut sim.contact_velocities;
    let g = Vec3::from_array(m.gravity);
    for &(i, v) in touched.iter() {
        let i = i as usize;
        entry[i] = 0;
        if !begin {
            sim.velocity_soa.set(i, v);
            continue;
        }
        let a = if wind {
            sim.projections.wind_dv.get(i)
        } else {
            Vec3::ZERO
        };
        sim.displacement.set(i, ((v + g + a) * m.keep) * m.h);
    }
    touched.clear();
}

/// The constants of a step's particle passes: substep `h`, `1/h`, the velocity kept over a
/// substep `e^{-c h}` and gravity's velocity change `g h`.
struct Motion {
    h: f32,
    inv_h: f32,
    keep: f32,
    gravity: [f32; 3],
}

/// The per-particle work around the projections. With `END`, the end of a substep: the velocity
/// `v = Δ/h` from the displacement itself, which holds every correction in full (added to the
/// position, corrections below its f32 resolution would vanish, and the lost ones bias the
/// dynamics: a cloth can gain energy), and the position `x += Δ`, rounded once. With `BEGIN`, the
/// start of the next: the unconstrained symplectic Euler move `v ← (v + g h + a) e^{-c h}`,
/// `Δ = v h`, where `a` is the wind's velocity change (with `wind`); that velocity is not stored
/// (the end of the substep replaces it).
///
/// On x86-64 CPUs with AVX2 the loops run as 8-wide vectors; the results are the same.
///
/// With `team`, the two threads each take half of the particles, the halves the colours' shares
/// mostly keep to.
fn advance<const END: bool, const BEGIN: bool>(
    sim: &mut ClothSim,
    m: &Motion,
    wind: bool,
    team: Option<&Team>,
) {
    let wind_dv = wind.then_some(&sim.projections.wind_dv);
    let (x, v, d) = (&mut sim.soa, &mut sim.velocity_soa, &mut sim.displacement);
    let Some(team) = team else {
        return advance_slices::<END, BEGIN>(
            [&mut x.x, &mut x.y, &mut x.z],
            [&mut v.x, &mut v.y, &mut v.z],
            [&mut d.x, &mut d.y, &mut d.z],
            wind_dv.map(|w| [&w.x[..], &w.y[..], &w.z[..]]),
            m,
        );
    };
    let n = x.len();
    let mid = (n / 2).next_multiple_of(2 * LANES).min(n);
    // SAFETY: until `run` returns, the arrays are used through these columns only, each half by
    // one thread at a time.
    let cols = unsafe {
        let write = |v: &mut [f32]| Column::new(v);
        [
            [&mut x.x, &mut x.y, &mut x.z].map(|a| write(a)),
            [&mut v.x, &mut v.y, &mut v.z].map(|a| write(a)),
            [&mut d.x, &mut d.y, &mut d.z].map(|a| write(a)),
        ]
    };
    team.run(&|share| {
        let range = if share == 0 { 0..mid } else { mid..n };
        // SAFETY: the two shares' ranges are disjoint, and nothing else uses the arrays.
        let [x, v, d] = cols.map(|c| c.map(|c| unsafe { c.slice_mut(range.clone()) }));
        let wind = wind_dv.map(|w| {
            [
                &w.x[range.clone()],
                &w.y[range.clone()],
                &w.z[range.clone()],
            ]
        });
        advance_slices::<END, BEGIN>(x, v, d, wind, m);
    });
}

/// [`advance_body`] on AVX2 CPUs if possible.
fn advance_slices<const END: bool, const BEGIN: bool>(
    x: [&mut [f32]; 3],
    v: [&mut [f32]; 3],
    d: [&mut [f32]; 3],
    wind_dv: Option<[&[f32]; 3]>,
    m: &Motion,
) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports the feature the function is compiled for (checked above).
        unsafe { advance_avx2::<END, BEGIN>(x, v, d, wind_dv, m) };
        return;
    }
    advance_body::<END, BEGIN>(x, v, d, wind_dv, m);
}

/// [`advance_body`] compiled for AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline(never)]
fn advance_avx2<const END: bool, const BEGIN: bool>(
    x: [&mut [f32]; 3],
    v: [&mut [f32]; 3],
    d: [&mut [f32]; 3],
    wind_dv: Option<[&[f32]; 3]>,
    m: &Motion,
) {
    advance_body::<END, BEGIN>(x, v, d, wind_dv, m);
}

#[inline(always)]
fn advance_body<const END: bool, const BEGIN: bool>(
    x: [&mut [f32]; 3],
    v: [&mut [f32]; 3],
    d: [&mut [f32]; 3],
    wind_dv: Option<[&[f32]; 3]>,
    m: &Motion,
) {
    let [x0, x1, x2] = x;
    let [v0, v1, v2] = v;
    let [d0, d1, d2] = d;
    let w = wind_dv.map(|w| w.map(Some)).unwrap_or([None; 3]);
    let coords = [(x0, v0, d0, w[0]), (x1, v1, d1, w[1]), (x2, v2, d2, w[2])];
    for (c, (x, v, d, wind)) in coords.into_iter().enumerate() {
        let (g, keep, h, inv_h) = (m.gravity[c], m.keep, m.h, m.inv_h);
        // The velocity a substep starts with is only read by that start, so it is stored only
        // where a substep ends without the next one starting (the step's last, or before contacts).
        let step = |x: &mut f32, v: &mut f32, d: &mut f32, a: f32| {
            let mut u = *v;
            if END {
                u = *d * inv_h;
                *x += *d;
            }
            if BEGIN {
                *d = ((u + g + a) * keep) * h;
            } else {
                *v = u;
            }
        };
        match wind {
            Some(wind) => {
                for (((x, v), d), a) in x.iter_mut().zip(v.iter_mut()).zip(d.iter_mut()).zip(wind) {
                    step(x, v, d, *a);
                }
            }
            None => {
                for ((x, v), d) in x.iter_mut().zip(v.iter_mut()).zip(d.iter_mut()) {
                    step(x, v, d, 0.0);
                }
            }
        }
    }
}

/// One Gauss-Seidel sweep over the springs of `runs` (every colour, or one thread's share of
/// one), run by run: the XPBD update
/// `Δλ = (-C - α̃ λ) / (w_a + w_b + α̃)`, `α̃ = α / h²`, `C = |x_a - x_b| - L`, then
/// `x_a += w_a Δλ n`, `x_b -= w_b Δλ n` with `n = (x_a - x_b) / |x_a - x_b|`.
///
/// Slots go in batches of [`LANES`] along the [`Run`]s: contiguous and interleaved runs are read
/// and written with whole vector loads and stores, scattered ones gathered particle by particle;
/// the arithmetic (square root and division included) is the same lane-wise code for all, so the
/// layout never changes a result. With `ACCUMULATE = false` (one iteration per substep) λ is known
/// to be 0 and is neither read nor stored.
///
/// On x86-64 CPUs the kernel runs as 8-wide AVX2 vectors, or with AVX-512 as 16-wide ones where a
/// contiguous run allows (chosen at run time); the results are bit-identical either way (no fused
/// multiply-add: Rust never contracts `a * b + c`).
fn solve_springs<const ACCUMULATE: bool>(
    p: &Projections,
    runs: &[Run],
    x: Split,
    lambda: Column,
    inv_h2: f32,
) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx512f") {
        // SAFETY: the CPU supports the feature the function is compiled for (checked above).
        unsafe { solve_springs_avx512::<ACCUMULATE>(p, runs, x, lambda, inv_h2) };
        return;
    }
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports the feature the function is compiled for (checked above).
        unsafe { solve_springs_avx2::<ACCUMULATE>(p, runs, x, lambda, inv_h2) };
        return;
    }
    solve_springs_body::<ACCUMULATE, false>(p, runs, x, lambda, inv_h2);
}

/// [`solve_springs_body`] compiled for AVX-512, with 16-lane batches where a contiguous run
/// allows them.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline(never)]
fn solve_springs_avx512<const ACCUMULATE: bool>(
    p: &Projections,
    runs: &[Run],
    x: Split,
    lambda: Column,
    inv_h2: f32,
) {
    solve_springs_body::<ACCUMULATE, true>(p, runs, x, lambda, inv_h2);
}

/// [`solve_springs_body`] compiled for AVX2 (8-lane vectors).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline(never)]
fn solve_springs_avx2<const ACCUMULATE: bool>(
    p: &Projections,
    runs: &[Run],
    x: Split,
    lambda: Column,
    inv_h2: f32,
) {
    solve_springs_body::<ACCUMULATE, false>(p, runs, x, lambda, inv_h2);
}

/// The per-slot constants of the batch at slots `k..k + N`, and where its multipliers live.
struct Batch<'a, const N: usize> {
    rest: &'a [f32; N],
    compliance: &'a [f32; N],
    lambda: Column,
    k: usize,
}

impl<'a, const N: usize> Batch<'a, N> {
    /// Slots `k..k + N`, or `None` past the end (which the runs never reach).
    #[inline(always)]
    fn at(rest: &'a [f32], compliance: &'a [f32], lambda: Column, k: usize) -> Option<Self> {
        Some(Self {
            rest: rest.get(k..k + N)?.try_into().ok()?,
            compliance: compliance.get(k..k + N)?.try_into().ok()?,
            lambda,
            k,
        })
    }
}

#[inline(always)]
fn solve_springs_body<const ACCUMULATE: bool, const WIDE: bool>(
    p: &Projections,
    runs: &[Run],
    x: Split,
    lambda: Column,
    inv_h2: f32,
) {
    let (rest, compliance) = (&p.rest, &p.compliance);
    let inv_mass = &p.inv_mass[..];
    // Every column cut to the particle count, so that one bounds check per batch covers them all.
    let n = inv_mass.len();
    let (Some(s0), Some(s1), Some(s2), Some(d0), Some(d1), Some(d2)) = (
        x.start[0].cut(n),
        x.start[1].cut(n),
        x.start[2].cut(n),
        x.delta[0].cut(n),
        x.delta[1].cut(n),
        x.delta[2].cut(n),
    ) else {
        return;
    };
    let x = Split {
        start: [s0, s1, s2],
        delta: [d0, d1, d2],
    };
    for run in runs {
        let (start, end) = (run.start as usize, (run.start + run.len) as usize);
        let mut k = start;
        // Two batches at once where their 32 particles are distinct.
        if WIDE && run.layout == Layout::Contiguous && p.b[k] - p.a[k] >= 2 * LANES as u32 {
            while k + 2 * LANES <= end {
                let Some(batch) = Batch::at(rest, compliance, lambda, k) else {
                    break;
                };
                let (a, b) = (p.a[k] as usize, p.b[k] as usize);
                solve_contiguous::<ACCUMULATE, { 2 * LANES }>(x, inv_mass, a, b, batch, inv_h2);
                k += 2 * LANES;
            }
        }
        while k + LANES <= end {
            let Some(batch) = Batch::at(rest, compliance, lambda, k) else {
                break;
            };
            let (a, b) = (p.a[k] as usize, p.b[k] as usize);
            match run.layout {
                Layout::Contiguous => {
                    solve_contiguous::<ACCUMULATE, LANES>(x, inv_mass, a, b, batch, inv_h2)
                }
                Layout::Interleaved(1) => {
                    solve_interleaved::<ACCUMULATE, 1>(x, inv_mass, a, batch, inv_h2)
                }
                Layout::Interleaved(_) => {
                    solve_interleaved::<ACCUMULATE, 2>(x, inv_mass, a, batch, inv_h2)
                }
                Layout::Scattered => {
                    solve_gathered::<ACCUMULATE, LANES>(&p.a, &p.b, x, inv_mass, batch, inv_h2)
                }
            }
            k += LANES;
        }
        // Whatever is left of the run, one slot at a time.
        for k in k..end {
            let Some(batch) = Batch::<1>::at(rest, compliance, lambda, k) else {
                break;
            };
            solve_gathered::<ACCUMULATE, 1>(&p.a, &p.b, x, inv_mass, batch, inv_h2);
        }
    }
}

/// The lane-wise XPBD update of `N` independent slots: `s[0..3]` are the first ends' x, y, z
/// at the start of the substep and `s[3..6]` the second ends', `d` their displacements since,
/// which the update moves.
#[inline(always)]
fn project<const ACCUMULATE: bool, const N: usize>(
    s: &[[f32; N]; 6],
    d: &mut [[f32; N]; 6],
    wa: &[f32; N],
    wb: &[f32; N],
    batch: Batch<'_, N>,
    inv_h2: f32,
) {
    let mut lambda = if ACCUMULATE {
        batch.lambda.load::<N>(batch.k)
    } else {
        [0.0; N]
    };
    for l in 0..N {
        // The start vectors and the displacements are differenced separately, so that the
        // small displacements keep their precision.
        let dx = (s[0][l] - s[3][l]) + (d[0][l] - d[3][l]);
        let dy = (s[1][l] - s[4][l]) + (d[1][l] - d[4][l]);
        let dz = (s[2][l] - s[5][l]) + (d[2][l] - d[5][l]);
        let len2 = dx * dx + dy * dy + dz * dz;
        let lam = lambda[l];
        let alpha = batch.compliance[l] * inv_h2;
        let rest = batch.rest[l];
        let len = len2.sqrt();
        let scale = (rest - len - alpha * lam) / ((wa[l] + wb[l] + alpha) * len);
        // A spring of (near) zero length has no direction and is skipped, and so is a padding
        // slot (rest length 0). A spring whose ends are both pinned (w = 0) gets a finite step
        // (α̃ > 0) that its zero inverse masses ignore.
        let scale = if len2 > 1e-20 && rest > 0.0 {
            scale
        } else {
            0.0
        };
        if ACCUMULATE {
            lambda[l] = lam + scale * len;
        }
        let (sa, sb) = (scale * wa[l], scale * wb[l]);
        d[0][l] += dx * sa;
        d[1][l] += dy * sa;
        d[2][l] += dz * sa;
        d[3][l] -= dx * sb;
        d[4][l] -= dy * sb;
        d[5][l] -= dz * sb;
    }
    if ACCUMULATE {
        batch.lambda.store(batch.k, &lambda);
    }
}

/// Copies `N` values starting at `i` out of `v` (an empty batch past the end, which the runs
/// never reach).
#[inline(always)]
fn load<const N: usize>(v: &[f32], i: usize) -> [f32; N] {
    v.get(i..i + N)
        .and_then(|s| s.try_into().ok())
        .unwrap_or([0.0; N])
}

/// Slots joining particles `ia..ia + N` to `ib..ib + N`.
#[inline(always)]
fn solve_contiguous<const ACCUMULATE: bool, const N: usize>(
    x: Split,
    inv_mass: &[f32],
    ia: usize,
    ib: usize,
    batch: Batch<'_, N>,
    inv_h2: f32,
) {
    if ia.max(ib) + N > inv_mass.len() {
        return;
    }
    // The x, y, z of particles `ia..ia + N`, then of `ib..ib + N`.
    let ends = |v: [Column; 3]| {
        [
            v[0].load(ia),
            v[1].load(ia),
            v[2].load(ia),
            v[0].load(ib),
            v[1].load(ib),
            v[2].load(ib),
        ]
    };
    let (s, mut d) = (ends(x.start), ends(x.delta));
    let (wa, wb) = (load(inv_mass, ia), load(inv_mass, ib));
    project::<ACCUMULATE, N>(&s, &mut d, &wa, &wb, batch, inv_h2);
    for (c, coord) in x.delta.iter().enumerate() {
        coord.store(ia, &d[c]);
        coord.store(ib, &d[c + 3]);
    }
}

/// Eight slots over the 16 particles `window..window + 16` (see [`Layout::Interleaved`]).
#[inline(always)]
fn solve_interleaved<const ACCUMULATE: bool, const D: usize>(
    x: Split,
    inv_mass: &[f32],
    window: usize,
    batch: Batch<'_, LANES>,
    inv_h2: f32,
) {
    if window + 2 * LANES > inv_mass.len() {
        return;
    }
    let (start, delta) = (x.start, x.delta);
    let win: [[f32; 16]; 7] = [
        start[0].load(window),
        start[1].load(window),
        start[2].load(window),
        delta[0].load(window),
        delta[1].load(window),
        delta[2].load(window),
        load(inv_mass, window),
    ];
    let (mut s, mut d) = ([[0.0f32; LANES]; 6], [[0.0f32; LANES]; 6]);
    let (mut wa, mut wb) = ([0.0f32; LANES], [0.0f32; LANES]);
    for l in 0..LANES {
        let (a, b) = (interleaved_offset(D, l), interleaved_offset(D, l) + D);
        for c in 0..3 {
            (s[c][l], s[c + 3][l]) = (win[c][a], win[c][b]);
            (d[c][l], d[c + 3][l]) = (win[c + 3][a], win[c + 3][b]);
        }
        (wa[l], wb[l]) = (win[6][a], win[6][b]);
    }
    project::<ACCUMULATE, LANES>(&s, &mut d, &wa, &wb, batch, inv_h2);
    for (c, coord) in delta.iter().enumerate() {
        let mut out = [0.0f32; 16];
        for l in 0..LANES {
            out[interleaved_offset(D, l)] = d[c][l];
            out[interleaved_offset(D, l) + D] = d[c + 3][l];
        }
        coord.store(window, &out);
    }
}

/// The batch's slots at arbitrary particles `a[k..]`, `b[k..]`: gather, project, scatter.
#[inline(always)]
fn solve_gathered<const ACCUMULATE: bool, const N: usize>(
    a: &[u32],
    b: &[u32],
    x: Split,
    inv_mass: &[f32],
    batch: Batch<'_, N>,
    inv_h2: f32,
) {
    let (start, delta) = (x.start, x.delta);
    let (a, b) = (&a[batch.k..batch.k + N], &b[batch.k..batch.k + N]);
    let (mut s, mut d) = ([[0.0f32; N]; 6], [[0.0f32; N]; 6]);
    let (mut wa, mut wb) = ([0.0f32; N], [0.0f32; N]);
    for l in 0..N {
        for (e, i) in [(0, a[l] as usize), (3, b[l] as usize)] {
            for c in 0..3 {
                (s[e + c][l], d[e + c][l]) = (start[c].get(i), delta[c].get(i));
            }
        }
        (wa[l], wb[l]) = (inv_mass[a[l] as usize], inv_mass[b[l] as usize]);
    }
    project::<ACCUMULATE, N>(&s, &mut d, &wa, &wb, batch, inv_h2);
    for l in 0..N {
        for (e, i) in [(0, a[l] as usize), (3, b[l] as usize)] {
            for c in 0..3 {
                delta[c].set(i, d[e + c][l]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::WindField;
    use crate::sim::{ClothModel, Collider, ColliderShape, Friction, GridSpec, Integrator, Pose};
    use bevy::math::primitives::Sphere;
    use glam::Vec3;

    /// A still sphere of radius `r` at `at`, with a 1 cm margin.
    fn ball(r: f32, at: Vec3, friction: Friction) -> Collider {
        Collider::fixed(
            ColliderShape::Sphere(Sphere::new(r)),
            Pose::from_translation(at),
            friction,
            0.01,
        )
    }

    /// Sea-level air moving at `velocity`, without gusts.
    fn air(velocity: Vec3) -> WindField {
        WindField {
            velocity,
            air_density: 1.225,
            ..Default::default()
        }
    }

    /// Checks the layout and returns the number of gathered (scattered or tail) springs.
    fn gathered(model: &ClothModel) -> usize {
        let (s, n) = (&model.springs, model.particle_count());
        let p = Projections::new(model);
        p.check(s, n).unwrap();
        p.runs
            .iter()
            .map(|r| match r.layout {
                Layout::Scattered => r.len as usize,
                _ => r.len as usize % LANES,
            })
            .sum()
    }

    #[test]
    fn grid_springs_are_projected_as_vectors() {
        let model = ClothModel::grid(&GridSpec::new(64, 64, 0.1)).unwrap();
        let p = Projections::new(&model);
        // The row ends are padded, so that only the last run of a colour, whose padding would
        // run past the last particle, can leave springs to scalar code; the padding costs a few
        // percent.
        let tails = gathered(&model);
        assert!(
            tails < LANES * model.springs.color_count(),
            "{tails} gathered"
        );
        let padding = p.spring.iter().filter(|s| s.is_none()).count();
        assert!(
            padding * 50 < p.spring.len(),
            "{padding} of {} slots",
            p.spring.len()
        );
        // Odd sizes break the row patterns but never the layout.
        for (nx, ny) in [(9, 7), (2, 2), (3, 17), (50, 31)] {
            let model = ClothModel::grid(&GridSpec::new(nx, ny, 0.1)).unwrap();
            gathered(&model);
        }
        let quad = [0, 1, 2, 3];
        let p = [Vec3::ZERO, Vec3::X, Vec3::ONE, Vec3::Y];
        gathered(&ClothModel::from_mesh(&p, None, &quad, 4).unwrap());
    }

    #[test]
    fn grid_colours_split_into_balanced_shares() {
        for (nx, ny) in [(64, 64), (128, 128), (100, 37)] {
            let model = ClothModel::grid(&GridSpec::new(nx, ny, 0.1)).unwrap();
            let p = Projections::new(&model);
            p.check(&model.springs, model.particle_count()).unwrap();
            assert!(p.worth_sharing(), "{nx}×{ny}");
            for c in 0..p.colors.len() {
                let [first, second] =
                    [0, 1].map(|s| p.share(c, s).iter().map(|r| r.len).sum::<u32>());
                let total = first + second;
                assert!(
                    first.abs_diff(second) * 10 <= total,
                    "{nx}×{ny}, colour {c}: shares of {first} and {second} slots"
                );
            }
        }
    }

    #[test]
    fn shared_sweeps_match_one_thread_bit_for_bit() {
        use crate::sim::{ClothSim, Environment, ScopedThread, SolverSettings, Spread};
        /// Runs the helper only after the step: the step's thread must do all the work.
        struct Late;
        impl Spread for Late {
            fn join(&self, helper: &(dyn Fn() + Sync), main: &mut dyn FnMut()) {
                main();
                helper();
            }
        }
        // A 96×48 cloth (27,000 springs, so it is shared) pinned at two corners, blown onto a
        // sphere, with one iteration and with three (which keep multipliers).
        let sphere = [ball(0.4, Vec3::new(0.5, -0.45, 0.3), Friction::default())];
        let wind = air(Vec3::new(2.0, 0.0, 5.0));
        let env = Environment {
            colliders: &sphere,
            wind: Some(&wind),
            ..Default::default()
        };
        for iterations in [1, 3] {
            let run = |spread: Option<&dyn Spread>| {
                let model = ClothModel::grid(&GridSpec::new(96, 48, 0.05)).unwrap();
                let settings = SolverSettings {
                    integrator: Integrator::Xpbd,
                    iterations,
                    ..Default::default()
                };
                let mut sim = ClothSim::new(model, settings, |p| p).unwrap();
                assert!(sim.projections.worth_sharing());
                sim.set_pins([(0, sim.positions()[0]), (95, sim.positions()[95])])
                    .unwrap();
                let mut touching = 0;
                for _ in 0..15 {
                    match spread {
                        Some(spread) => sim.step_in_parallel(1.0 / 60.0, &env, spread),
                        None => sim.step_in(1.0 / 60.0, &env),
                    }
                    .unwrap();
                    touching += sim.active_colliders();
                }
                assert!(touching > 0, "the sphere was never in reach");
                (sim.positions().to_vec(), sim.velocities().to_vec())
            };
            let alone = run(None);
            assert!(run(Some(&ScopedThread)) == alone, "{iterations} iterations");
            assert!(
                run(Some(&Late)) == alone,
                "{iterations} iterations, late helper"
            );
        }
    }

    #[test]
    fn the_grid_storage_order_changes_no_result() {
        use crate::sim::{ClothSim, Environment, SolverSettings};
        // The same 40×12 cloth with and without its grid (which alone selects the storage
        // order): pinned and moved, draped over a sphere, in wind. The lane arithmetic is the
        // same in every layout, so the positions must be bit-identical.
        let masses = (0..40 * 12).map(|i| 0.002 * (1 + i % 7) as f32).collect();
        let grid = ClothModel::grid(&GridSpec::new(40, 12, 0.05))
            .unwrap()
            .with_particle_masses(masses)
            .unwrap();
        let mut plain = grid.clone();
        plain.grid = None;
        assert!(!grid_order(grid.grid.as_ref().unwrap()).is_empty());
        let sphere = [ball(0.2, Vec3::new(0.3, -0.35, 0.05), Friction::default())];
        let wind = air(Vec3::new(3.0, 0.0, 4.0));
        let env = Environment {
            colliders: &sphere,
            wind: Some(&wind),
            ..Default::default()
        };
        let run = |model: ClothModel| {
            let settings = SolverSettings {
                integrator: Integrator::Xpbd,
                ..Default::default()
            };
            let mut sim = ClothSim::new(model, settings, |p| p).unwrap();
            // Corners stay where they are stored; particle 22 moves to the third column block.
            let ends = [Vec3::new(-1.0, 0.0, 0.3), Vec3::new(0.1, 0.0, 0.3)];
            let pins = [(0, ends[0]), (22, ends[1]), (39, Vec3::new(1.0, 0.0, 0.3))];
            sim.set_pins(pins).unwrap();
            for frame in 0..40 {
                let x = 0.01 * frame as f32;
                let right = Vec3::new(1.0 - x, 0.0, 0.3);
                sim.move_pins([ends[0] + Vec3::X * x, ends[1] + Vec3::Y * x, right]);
                sim.step_in(1.0 / 60.0, &env).unwrap();
            }
            assert!(sim.active_colliders() > 0, "the sphere was never in reach");
            (sim.positions().to_vec(), sim.velocities().to_vec())
        };
        let (a, b) = (run(grid), run(plain));
        assert!(a == b, "the storage order changed the result");
    }

    #[test]
    fn contacts_ahead_of_the_end_pass_match_contacts_after_it() {
        use crate::sim::{ClothSim, Environment, SolverSettings};
        // A 40×12 cloth (stored in the grid order) blown onto spheres and pinned at two corners:
        // contacts resolved on the state the substep ends in, then the fused end-and-start pass,
        // against contacts on the end state after a separate end pass (a test-only path). They
        // differ by rounding only: the end position `x + Δ` is rounded once more after a push
        // (measured: 1.4e-6 m and 9e-5 m/s after 30 frames; keeping only the first of a
        // particle's contact velocities in a substep gives 8e-6 m and 3e-4 m/s, leaving out the
        // velocity write-back 3e-4 m).
        // A second sphere overlapping the first, and a small one (smaller than the cloth's edges,
        // so triangles are tested too): particles are pushed more than once in a substep.
        let friction = Friction::new(0.4);
        let sphere = [
            ball(0.25, Vec3::new(0.9, -0.3, 0.4), friction),
            ball(0.25, Vec3::new(1.0, -0.3, 0.4), friction),
            ball(0.03, Vec3::new(0.5, -0.04, 0.3), friction),
        ];
        let wind = air(Vec3::new(0.0, 0.0, 6.0));
        let env = Environment {
            colliders: &sphere,
            wind: Some(&wind),
            ..Default::default()
        };
        let run = |after: bool, tracked: bool| {
            let model = ClothModel::grid(&GridSpec::new(40, 12, 0.05)).unwrap();
            let settings = SolverSettings {
                integrator: Integrator::Xpbd,
                ..Default::default()
            };
            let mut sim = ClothSim::new(model, settings, |p| p).unwrap();
            sim.set_pins([(0, sim.positions()[0]), (39, sim.positions()[39])])
                .unwrap();
            sim.contacts_after_end = after;
            if tracked {
                sim.track_contact_work();
            }
            let mut touching = 0;
            for _ in 0..30 {
                sim.step_in(1.0 / 60.0, &env).unwrap();
                touching += sim.active_colliders();
            }
            assert!(
                touching > 10,
                "the sphere was in reach for {touching} steps"
            );
            (sim.positions().to_vec(), sim.velocities().to_vec())
        };
        let ((xa, va), (xb, vb)) = (run(false, false), run(true, false));
        // Counting the energy contacts add (the stress suite) changes nothing.
        assert!(
            run(false, true) == (xa.clone(), va.clone()),
            "tracking changed the result"
        );
        assert_ne!(xa, xb, "the two paths are distinct");
        let worst = |a: &[Vec3], b: &[Vec3]| {
            a.iter()
                .zip(b)
                .map(|(a, b)| a.distance(*b))
                .fold(0.0, f32::max)
        };
        assert!(
            worst(&xa, &xb) < 4e-6,
            "positions differ by {}",
            worst(&xa, &xb)
        );
        assert!(
            worst(&va, &vb) < 1.8e-4,
            "velocities differ by {}",
            worst(&va, &vb)
        );
    }

    #[test]
    fn padding_slots_change_nothing() {
        // A contiguous run of three springs, padded to a batch of eight.
        let n = 32;
        let mut start = Soa::new(n);
        for i in 0..n {
            start.set(i, Vec3::new(i as f32 * 0.1, (i % 3) as f32, 0.0));
        }
        let mut delta = Soa::new(n);
        for i in 0..n {
            delta.set(i, Vec3::splat(1e-3 * i as f32));
        }
        let before = delta.clone();
        let p = &mut Projections {
            a: (0..8).collect(),
            b: (16..24).collect(),
            spring: (0..8).map(|m| (m < 3).then_some(m)).collect(),
            runs: vec![Run {
                layout: Layout::Contiguous,
                start: 0,
                len: 8,
            }],
            springs: 3,
            ..Projections::default()
        };
        p.rest = vec![0.0; 8];
        p.compliance = vec![0.0; 8];
        p.lambda = vec![0.0; 8];
        p.inv_mass = vec![0.0; n];
        p.set_constants(&[0.5, 0.5, 0.5], &[1e3, 1e3, 1e3], &vec![1.0; n]);
        // SAFETY: the arrays are used through the columns only, on this thread, until the sweep
        // returns.
        let (x, lambda) = unsafe {
            let start = [&mut start.x, &mut start.y, &mut start.z].map(|v| Column::new(&mut v[..]));
            let delta = [&mut delta.x, &mut delta.y, &mut delta.z].map(|v| Column::new(&mut v[..]));
            (Split { start, delta }, Column::new(&mut p.lambda[..]))
        };
        solve_springs::<false>(p, &p.runs, x, lambda, 3600.0);
        for i in 0..n {
            let moved = delta.get(i) != before.get(i);
            assert_eq!(moved, matches!(i, 0..3 | 16..19), "particle {i}");
        }
    }
}
