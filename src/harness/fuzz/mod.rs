//! The ECS edit fuzzer: seeded random sequences of spawns, despawns, component inserts, removals
//! and edits (valid and invalid), source mesh swaps, and anchor, joint, collider, wind and (with
//! the `avian` feature) physics body changes, on several cloths of every kind (grid, mesh asset,
//! skinned character with targets), stepping a headless app between operations and checking
//! after every step that:
//! - nothing panicked (each sequence runs under `catch_unwind`);
//! - every [`ClothState`](crate::ClothState)'s positions and velocities, and its mesh's
//!   positions, are finite, and no cloth was stopped by a failed step;
//! - a cloth that was running still runs: it keeps its state, and unless an accepted edit
//!   changed its topology (a new source, a swapped source mesh, simulation subdivision) its step
//!   count went on from where it was and its positions were not put back to rest;
//! - every cloth whose components the fuzzer knows to be valid is built and carries no
//!   rejection; an edit that made a running cloth invalid is reported as
//!   [`ClothEditRejected`](crate::ClothEditRejected), and a cloth that is not running and is
//!   invalid carries [`ClothInvalid`](crate::ClothInvalid).
//!
//! Everything follows from the seed: [`run_edit_fuzz`] runs many sequences, and
//! [`run_fuzz_sequence`] reruns one of them, tracing each operation and step. This file holds the
//! public API, the PRNG and the panic capture; `model` knows which cloths are valid, `ops` draws
//! and applies the operations, `check` compares the world with the model.

mod check;
mod model;
mod ops;

use std::cell::Cell;
use std::fmt;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, Once};

use check::{Snapshot, check_flags, check_step};

/// How sequences are drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FuzzOptions {
    /// Most operations in one sequence (each sequence draws between half of it and all of it).
    pub max_operations: usize,
    /// Most app updates (one fixed step each) between two operations (at least 1).
    pub max_steps_between: u32,
    /// With the `avian` feature: run every other sequence in an avian3d world, with physics
    /// bodies among the operations. Ignored without the feature.
    pub avian: bool,
    /// How many of the last operations a failure keeps to reproduce it.
    pub trail: usize,
    /// Draw invalid cloth components and meshes too (on by default). Off, every cloth stays
    /// valid, which checks that accepted edits keep cloths running without going through
    /// rejections (non-finite colliders and wind, which the plugin ignores, are still drawn).
    pub invalid_edits: bool,
}

impl Default for FuzzOptions {
    fn default() -> Self {
        Self {
            max_operations: 20,
            max_steps_between: 3,
            avian: true,
            trail: 8,
            invalid_edits: true,
        }
    }
}

/// What a failed check saw.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum FailureKind {
    /// The app panicked.
    Panic,
    /// A cloth's position or velocity, or a position of its mesh, was not finite.
    NonFinite,
    /// A cloth was stopped by a failed step (`ClothInvalid` with a divergence or instability).
    StepFailure,
    /// A running cloth lost its state, or was reset to rest by an edit that was rejected or kept
    /// its topology.
    Lost,
    /// An invalid edit or cloth was not reported (or an invalid cloth was built).
    Unreported,
    /// A cloth whose components are all valid was not built, or carries a rejection.
    SpuriousRejection,
}

impl FailureKind {
    /// A short name for reports.
    pub fn name(self) -> &'static str {
        match self {
            FailureKind::Panic => "panic",
            FailureKind::NonFinite => "non-finite value",
            FailureKind::StepFailure => "step failure",
            FailureKind::Lost => "lost cloth",
            FailureKind::Unreported => "unreported rejection",
            FailureKind::SpuriousRejection => "spurious rejection",
        }
    }
}

/// One failed check, with what it takes to reproduce it.
#[derive(Debug, Clone, PartialEq)]
pub struct FuzzFailure {
    /// What went wrong.
    pub kind: FailureKind,
    /// The run's seed.
    pub seed: u64,
    /// The sequence (rerun it with [`run_fuzz_sequence`]).
    pub sequence: usize,
    /// The operation within the sequence after which the check failed.
    pub operation: usize,
    /// The kind of that operation (failures group by it), e.g. `"ClothPins: out of range"`.
    pub operation_kind: &'static str,
    /// What the check saw, naming the cloth.
    pub message: String,
    /// The last operations of the sequence, oldest first, ending with the failing one.
    pub trail: Vec<String>,
}

impl fmt::Display for FuzzFailure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{} after operation {} ({}) of sequence {} (seed {}): {}",
            self.kind.name(),
            self.operation,
            self.operation_kind,
            self.sequence,
            self.seed,
            self.message
        )?;
        for line in &self.trail {
            writeln!(f, "    {line}")?;
        }
        Ok(())
    }
}

/// What a fuzz run did and found. A sequence stops at its first failed check (every failure
/// that check found is counted), so the counts are of failures seen, not of distinct bugs: see
/// [`FuzzReport::groups`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FuzzReport {
    /// The run's seed.
    pub seed: u64,
    /// Sequences run.
    pub sequences: usize,
    /// Operations applied.
    pub operations: usize,
    /// App updates (one fixed step each).
    pub steps: usize,
    /// Rejections expected (a cloth made invalid, or spawned invalid).
    pub rejections_expected: usize,
    /// Of those, how many were reported as expected.
    pub rejections_reported: usize,
    /// Sequences that panicked.
    pub panics: usize,
    /// Cloths seen with a non-finite value.
    pub non_finite: usize,
    /// Cloths stopped by a failed step.
    pub step_failures: usize,
    /// Running cloths lost or reset.
    pub lost: usize,
    /// Rejections not reported.
    pub unreported: usize,
    /// Valid cloths not built or carrying a rejection.
    pub spurious: usize,
    /// Every failure, in the order found.
    pub failures: Vec<FuzzFailure>,
}

impl FuzzReport {
    /// Whether no check failed.
    pub fn is_clean(&self) -> bool {
        self.failures.is_empty()
    }

    /// The failures grouped by kind and operation kind: `(kind, operation kind, count, first
    /// failure)`, most frequent first.
    pub fn groups(&self) -> Vec<(FailureKind, &'static str, usize, &FuzzFailure)> {
        let mut groups: Vec<(FailureKind, &'static str, usize, &FuzzFailure)> = Vec::new();
        for f in &self.failures {
            match groups
                .iter_mut()
                .find(|g| g.0 == f.kind && g.1 == f.operation_kind)
            {
                Some(g) => g.2 += 1,
                None => groups.push((f.kind, f.operation_kind, 1, f)),
            }
        }
        groups.sort_by(|a, b| b.2.cmp(&a.2).then(a.0.cmp(&b.0)));
        groups
    }

    fn count(&mut self, failure: FuzzFailure) {
        match failure.kind {
            FailureKind::Panic => self.panics += 1,
            FailureKind::NonFinite => self.non_finite += 1,
            FailureKind::StepFailure => self.step_failures += 1,
            FailureKind::Lost => self.lost += 1,
            FailureKind::Unreported => self.unreported += 1,
            FailureKind::SpuriousRejection => self.spurious += 1,
        }
        self.failures.push(failure);
    }
}

impl fmt::Display for FuzzReport {
    /// The counts, then each group of failures with its count and its first failure in full.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "edit fuzz, seed {}: {} sequences, {} operations, {} steps; {} of {} expected \
             rejections reported",
            self.seed,
            self.sequences,
            self.operations,
            self.steps,
            self.rejections_reported,
            self.rejections_expected
        )?;
        writeln!(
            f,
            "panics {}, non-finite {}, step failures {}, lost {}, unreported {}, spurious \
             rejections {}",
            self.panics,
            self.non_finite,
            self.step_failures,
            self.lost,
            self.unreported,
            self.spurious
        )?;
        for (kind, op, count, first) in self.groups() {
            writeln!(f, "\n{} × {} after {op}; first:", count, kind.name())?;
            write!(f, "{first}")?;
        }
        Ok(())
    }
}

/// What one sequence did: its counts and failures (a panic, or the failures of its first failed
/// check).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SequenceOutcome {
    /// Operations applied (including the one that failed).
    pub operations: usize,
    /// App updates.
    pub steps: usize,
    /// Rejections expected and reported.
    pub rejections: (usize, usize),
    /// The failures found.
    pub failures: Vec<FuzzFailure>,
}

/// Runs `sequences` seeded sequences (sequence `i` of seed `s` is always the same) and reports
/// what the checks found. Panics are caught per sequence, without printing.
pub fn run_edit_fuzz(seed: u64, sequences: usize, options: &FuzzOptions) -> FuzzReport {
    let mut report = FuzzReport {
        seed,
        ..Default::default()
    };
    with_panics_captured(|| {
        for index in 0..sequences {
            let outcome = sequence(seed, index, options, &mut |_| {});
            report.sequences += 1;
            report.operations += outcome.operations;
            report.steps += outcome.steps;
            report.rejections_expected += outcome.rejections.0;
            report.rejections_reported += outcome.rejections.1;
            for failure in outcome.failures {
                report.count(failure);
            }
        }
    });
    report
}

/// Reruns sequence `index` of `seed`, giving `trace` a line per operation, per step and per
/// failure.
pub fn run_fuzz_sequence(
    seed: u64,
    index: usize,
    options: &FuzzOptions,
    trace: &mut dyn FnMut(&str),
) -> SequenceOutcome {
    with_panics_captured(|| sequence(seed, index, options, trace))
}

/// The first panic's message and place since the last sequence started, kept by the hook that
/// [`with_panics_captured`] installs. Shared by all threads: Bevy may panic on a worker thread.
static LAST_PANIC: Mutex<Option<String>> = Mutex::new(None);

/// How many [`with_panics_captured`] calls are running, on any thread.
static CAPTURING: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    /// Whether this thread is inside [`with_panics_captured`].
    static CAPTURING_HERE: Cell<bool> = const { Cell::new(false) };
}

/// Runs `f` with its panics recorded (message and location) instead of printed. The recording
/// hook is installed once and stays: a panic on a thread inside such a call is recorded
/// silently; one on a worker of Bevy's task pools while such a call runs is recorded and passed
/// on to the hook it replaced, as is every other panic (another test's, say).
fn with_panics_captured<T>(f: impl FnOnce() -> T) -> T {
    static INSTALL: Once = Once::new();
    INSTALL.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            let here = CAPTURING_HERE.with(Cell::get);
            let worker = CAPTURING.load(Ordering::SeqCst) > 0
                && std::thread::current()
                    .name()
                    .is_some_and(|n| n.contains("Task Pool"));
            if here || worker {
                let payload = info.payload();
                let message = payload
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| payload.downcast_ref::<String>().cloned())
                    .unwrap_or_else(|| "(no message)".into());
                let place = info
                    .location()
                    .map_or_else(String::new, |l| format!(" at {}:{}", l.file(), l.line()));
                if let Ok(mut last) = LAST_PANIC.lock() {
                    // The first panic is the cause; Bevy re-panics after a system's.
                    last.get_or_insert(format!("{message}{place}"));
                }
            }
            if !here {
                previous(info);
            }
        }));
    });
    let outer = CAPTURING_HERE.with(|c| c.replace(true));
    CAPTURING.fetch_add(1, Ordering::SeqCst);
    let result = catch_unwind(AssertUnwindSafe(f));
    CAPTURING.fetch_sub(1, Ordering::SeqCst);
    CAPTURING_HERE.with(|c| c.set(outer));
    result.unwrap_or_else(|e| std::panic::resume_unwind(e))
}

/// The seed of sequence `index` of `seed`.
fn sequence_seed(seed: u64, index: usize) -> u64 {
    let mut s = seed ^ (index as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    splitmix64(&mut s)
}

/// The running parts of one sequence, outside the `catch_unwind` so that they survive a panic.
struct Progress {
    outcome: SequenceOutcome,
    trail: Vec<String>,
    operation: usize,
    operation_kind: &'static str,
}

fn sequence(
    seed: u64,
    index: usize,
    options: &FuzzOptions,
    trace: &mut dyn FnMut(&str),
) -> SequenceOutcome {
    if let Ok(mut last) = LAST_PANIC.lock() {
        *last = None;
    }
    let mut progress = Progress {
        outcome: SequenceOutcome::default(),
        trail: Vec::new(),
        operation: 0,
        operation_kind: "setup",
    };
    let failure = |progress: &Progress, kind, message: String| FuzzFailure {
        kind,
        seed,
        sequence: index,
        operation: progress.operation,
        operation_kind: progress.operation_kind,
        message,
        trail: progress.trail.clone(),
    };
    let run = catch_unwind(AssertUnwindSafe(|| {
        run_sequence(seed, index, options, trace, &mut progress, &failure)
    }));
    if run.is_err() {
        let message = LAST_PANIC
            .lock()
            .ok()
            .and_then(|mut last| last.take())
            .unwrap_or_else(|| "(no message)".into());
        trace(&format!("PANIC: {message}"));
        let f = failure(&progress, FailureKind::Panic, message);
        progress.outcome.failures.push(f);
    }
    progress.outcome
}

fn run_sequence(
    seed: u64,
    index: usize,
    options: &FuzzOptions,
    trace: &mut dyn FnMut(&str),
    progress: &mut Progress,
    failure: &dyn Fn(&Progress, FailureKind, String) -> FuzzFailure,
) {
    let mut rng = Rng(sequence_seed(seed, index));
    let avian = options.avian && cfg!(feature = "avian") && index % 2 == 1;
    let mut fixture = ops::new_fixture(avian, options.invalid_edits, &mut rng);
    let max = options.max_operations.max(1);
    let operations = max.div_ceil(2) + rng.below(max as u64 / 2 + 1) as usize;
    trace(&format!(
        "sequence {index} of seed {seed}: {operations} operations{}",
        if avian { ", avian world" } else { "" }
    ));
    for operation in 0..operations {
        let before = Snapshot::take(&fixture);
        let applied = ops::apply_random(&mut fixture, &mut rng);
        for cloth in &mut fixture.cloths {
            cloth.topology_pending |= applied.topology.contains(&cloth.entity);
        }
        progress.operation = operation;
        progress.operation_kind = applied.kind;
        progress.outcome.operations += 1;
        let line = format!("#{operation} [{}] {}", applied.kind, applied.detail);
        trace(&line);
        progress.trail.push(line);
        let keep = options.trail.max(1);
        if progress.trail.len() > keep {
            progress.trail.drain(..progress.trail.len() - keep);
        }
        let steps =
            (1 + rng.below(options.max_steps_between.max(1) as u64) as u32).max(applied.min_steps);
        let mut found = Vec::new();
        for step in 1..=steps {
            fixture.app.update();
            progress.outcome.steps += 1;
            found.extend(check_step(&fixture, &before, step));
            trace(&format!("  step {step}: {}", fixture.describe()));
            if !found.is_empty() {
                break;
            }
        }
        // A valid cloth has been rebuilt for any edit of its topology by now.
        for cloth in &mut fixture.cloths {
            if cloth.validity(&fixture.meshes) == model::Validity::Valid {
                cloth.topology_pending = false;
            }
        }
        if found.is_empty() {
            let (expected, reported, problems) = check_flags(&fixture, &before);
            progress.outcome.rejections.0 += expected;
            progress.outcome.rejections.1 += reported;
            found = problems;
        }
        if !found.is_empty() {
            for (kind, message) in found {
                trace(&format!("FAILED: {}: {message}", kind.name()));
                let f = failure(progress, kind, message);
                progress.outcome.failures.push(f);
            }
            return;
        }
    }
}

/// One step of splitmix64: a small, fast PRNG whose whole state is one `u64`.
fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The fuzzer's random numbers (splitmix64), so that a seed means the same sequences everywhere.
#[derive(Debug, Clone)]
pub(crate) struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        splitmix64(&mut self.0)
    }

    /// A number in `0..n` (0 when `n` is 0).
    pub(crate) fn below(&mut self, n: u64) -> u64 {
        if n == 0 { 0 } else { self.next_u64() % n }
    }

    /// A number in `lo..=hi`.
    pub(crate) fn range(&mut self, lo: u32, hi: u32) -> u32 {
        lo + self.below((hi - lo) as u64 + 1) as u32
    }

    /// A float in `lo..hi`.
    pub(crate) fn float(&mut self, lo: f32, hi: f32) -> f32 {
        let unit = (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32;
        lo + (hi - lo) * unit
    }

    /// True with probability `p`.
    pub(crate) fn chance(&mut self, p: f32) -> bool {
        self.float(0.0, 1.0) < p
    }

    /// An index into a list of `len` (0 when empty).
    pub(crate) fn index(&mut self, len: usize) -> usize {
        self.below(len as u64) as usize
    }

    /// One of `items`, which must not be empty.
    pub(crate) fn pick<T: Copy>(&mut self, items: &[T]) -> T {
        items[self.index(items.len())]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_prng_is_deterministic_and_spreads() {
        let (mut a, mut b) = (Rng(7), Rng(7));
        let xs: Vec<u64> = (0..100).map(|_| a.below(10)).collect();
        let ys: Vec<u64> = (0..100).map(|_| b.below(10)).collect();
        assert_eq!(xs, ys);
        for digit in 0..10 {
            assert!(xs.contains(&digit), "{digit} never drawn");
        }
        let f = Rng(3).float(-1.0, 2.0);
        assert!((-1.0..2.0).contains(&f));
        assert_ne!(sequence_seed(1, 0), sequence_seed(1, 1));
        assert_ne!(sequence_seed(1, 0), sequence_seed(2, 0));
    }
}
