//! Two threads sharing a step: [`Spread`], the source of the second thread (the plugin lends
//! Bevy's compute pool; [`ScopedThread`] starts one), and [`share`], which runs a step with a
//! [`Lead`] that hands phases of two shares to a helper on that thread.

use std::cell::UnsafeCell;
use std::marker::PhantomData;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// A source of one more thread for a step.
pub trait Spread: Sync {
    /// Runs `helper` on another thread if one is free and `main` on this one, and returns once
    /// both have returned. `helper` may also run after `main` has returned, or not at all: `main`
    /// finishes the work alone, and a late `helper` finds nothing left and returns at once. It
    /// must not run on this thread before `main`: it returns only once `main` has finished.
    fn join(&self, helper: &(dyn Fn() + Sync), main: &mut dyn FnMut());
}

/// A [`Spread`] that starts one operating-system thread per step (`std::thread::scope`).
/// Starting a thread costs tens of microseconds, so it pays for large cloths only; programs with
/// a thread pool should lend that instead.
#[derive(Debug, Clone, Copy, Default)]
pub struct ScopedThread;

impl Spread for ScopedThread {
    fn join(&self, helper: &(dyn Fn() + Sync), main: &mut dyn FnMut()) {
        std::thread::scope(|s| {
            s.spawn(helper);
            main();
        });
    }
}

/// Two threads sharing a step's work, as phases of two shares each: a colour of a sweep (its
/// shares touch disjoint particles, [`Projections::cut`](super::layout::Projections::cut)), or a particle pass (the two halves of
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
/// is over ([`Lead::run`]).
type Job = *const (dyn Fn(usize) + Sync);

// SAFETY: `job` is written only by the step's thread (through the one `Lead`) while the helper
// holds no claim (every claim it took is finished), before the phase that publishes it is
// released; the helper reads it only while holding a claim, after acquiring that phase.
unsafe impl Sync for Team {}

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

/// The step's side of a [`Team`]: the only handle that publishes phases. There is one per team,
/// lent by [`share`] to the step's thread, and it is neither `Send` nor `Sync`, so no job (which
/// must be `Sync`) can hold it, and no other thread can publish a phase while the helper may be
/// reading the current one.
pub(super) struct Lead<'t> {
    team: &'t Team,
    single: PhantomData<*const ()>,
}

/// Runs `main` with a [`Lead`] on this thread and the team's helper on one more thread from
/// `spread`, if it lends one; returns `main`'s result once the helper has returned. If the
/// `Spread` never calls `main`, it runs here afterwards, without a helper.
pub(super) fn share<R>(spread: &dyn Spread, main: impl FnOnce(Option<&Lead>) -> R) -> R {
    let team = Team::default();
    let (mut main, mut out) = (Some(main), None);
    spread.join(&|| team.help(), &mut || {
        // The helper returns once this is dropped, even if the step panics.
        let _stop = Stop(&team);
        let lead = Lead {
            team: &team,
            single: PhantomData,
        };
        if let Some(main) = main.take() {
            out = Some(main(Some(&lead)));
        }
    });
    match (out, main) {
        (Some(out), _) => out,
        (None, Some(main)) => main(None),
        (None, None) => unreachable!("`main` ran, so it returned a result"),
    }
}

impl Lead<'_> {
    /// Runs `job`'s two shares, with the helper (on the step's thread), and returns when both
    /// are done.
    pub fn run(&self, job: &(dyn Fn(usize) + Sync)) {
        let team = self.team;
        let q = team.phase.load(Ordering::Relaxed) + 1;
        // SAFETY: this is the team's only `Lead`, on one thread, and every claim on an earlier
        // phase is finished (the previous call waited for it), so nobody reads the job; the
        // helper reads the pointer only under a claim on this phase, which ends before this call
        // returns. Only the trait object's lifetime changes.
        unsafe {
            *team.job.get() =
                Some(std::mem::transmute::<*const (dyn Fn(usize) + Sync + '_), Job>(job));
        }
        team.phase.store(q, Ordering::Release);
        // A panic in the first share must not unwind past the job while the helper may be
        // running it: caught, then raised again once the second share is settled.
        let first = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| job(0)));
        if team.claim(q) {
            if first.is_ok() {
                job(1);
            }
        } else {
            let mut spins = 0;
            while team.finished.load(Ordering::Acquire) < q {
                pause(&mut spins);
            }
        }
        if let Err(panic) = first {
            std::panic::resume_unwind(panic);
        }
    }
}

impl Team {
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
                    // unfinished (see `Lead::run`).
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
