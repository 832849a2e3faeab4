//! Threads lent to a step: [`Spread`], which [`ClothSim::step_in_parallel`] uses to project a
//! large cloth's springs on two threads at once, and [`ScopedThread`], a [`Spread`] for programs
//! without a task pool. The plugin lends Bevy's compute pool.
//!
//! [`ClothSim::step_in_parallel`]: super::ClothSim::step_in_parallel

/// A source of one more thread for a step.
pub trait Spread: Sync {
    /// Runs `helper` on another thread if one is free and `main` on this one, and returns once
    /// both have returned. `helper` may also run after `main` has returned, or not at all: `main`
    /// finishes the work alone, and a late `helper` finds nothing left and returns at once.
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
