//! `cloth_cli stress`: runs the seeded stress suite of `bevy_cloth::harness::stress` with a progress
//! bar, then prints a Markdown table per integrator (cases, stable, stopped as unstable, failures,
//! worst values, and the stability limits the cases found) and every failure.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use bevy_cloth::harness::stress::{
    StressLimits, StressOutcome, StressResult, draw_case, trace_case, trace_line,
};
use bevy_cloth::sim::Integrator;
use indicatif::{ProgressBar, ProgressStyle};

/// Per-integrator tallies.
#[derive(Default)]
struct Tally {
    cases: u32,
    stable: u32,
    unstable: u32,
    failures: u32,
    max_penetration: f32,
    max_pin_error: f32,
    max_speed: f32,
    /// Largest dt, stiffness and h·ω_max among stable cases.
    stable_dt: f32,
    stable_stiffness: f32,
    stable_h_omega: f32,
    /// Smallest h·ω_max among cases stopped as unstable.
    unstable_h_omega: f32,
}

/// What every case of a run has on top of what it draws.
pub struct Variants {
    /// Self-collision on.
    pub self_collision: bool,
    /// A closed cloth with air inside.
    pub air: bool,
    /// Tearing under strain and a cut (`StressCase::with_tearing`).
    pub tearing: bool,
    /// Tolerance mode at this tolerance.
    pub tolerance: Option<f32>,
    /// Print every step of every case.
    pub trace: bool,
}

/// Runs cases `cases` of suite `seed` over `integrators`, each case with the `variants`, on
/// `threads` threads (one with `variants.trace`); returns whether all passed. The cases are
/// independent, and the tables and failures come out in case order whatever the thread count.
pub fn run(
    cases: std::ops::Range<u64>,
    seed: u64,
    integrators: &[Integrator],
    variants: Variants,
    threads: usize,
) -> bool {
    let Variants {
        self_collision,
        air,
        tearing,
        tolerance,
        trace,
    } = variants;
    let limits = StressLimits::default();
    let bar = ProgressBar::new(cases.end - cases.start);
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} cases, {elapsed} elapsed, eta {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let start = Instant::now();
    let run_one = |index: u64| {
        let mut case = draw_case(seed, index, integrators, &limits);
        if self_collision {
            case = case.with_self_collision();
        }
        if air {
            case = case.with_air();
        }
        if tearing {
            case = case.with_tearing();
        }
        if let Some(tolerance) = tolerance {
            case = case.with_tolerance(tolerance);
        }
        let r = trace_case(&case, &limits, |step, sim| {
            if trace {
                bar.suspend(|| println!("case {index} step {step}: {}", trace_line(sim)));
            }
        });
        bar.inc(1);
        r
    };
    let threads = if trace { 1 } else { threads.max(1) };
    let next = AtomicU64::new(cases.start);
    let mut results: Vec<(u64, StressResult)> = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..threads)
            .map(|_| {
                scope.spawn(|| {
                    let mut done = Vec::new();
                    loop {
                        let index = next.fetch_add(1, Ordering::Relaxed);
                        if index >= cases.end {
                            return done;
                        }
                        done.push((index, run_one(index)));
                    }
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect()
    });
    results.sort_by_key(|(index, _)| *index);
    let mut tallies: Vec<(Integrator, Tally)> = Integrator::CHOICES
        .iter()
        .map(|i| (*i, Tally::default()))
        .collect();
    let mut failures: Vec<StressResult> = Vec::new();
    let (mut torn, mut splits) = (0, 0);
    for (_, r) in results {
        torn += u32::from(r.splits > 0);
        splits += r.splits;
        let Some((_, t)) = tallies
            .iter_mut()
            .find(|(i, _)| *i == r.case.settings.integrator)
        else {
            continue;
        };
        t.cases += 1;
        t.max_penetration = t.max_penetration.max(r.max_penetration);
        t.max_pin_error = t.max_pin_error.max(r.max_pin_error);
        t.max_speed = t.max_speed.max(r.max_speed);
        match &r.outcome {
            StressOutcome::Stable => {
                t.stable += 1;
                t.stable_dt = t.stable_dt.max(r.case.dt);
                t.stable_stiffness = t.stable_stiffness.max(r.case.settings.stiffness.structural);
                t.stable_h_omega = t.stable_h_omega.max(r.h_omega);
            }
            StressOutcome::DetectedUnstable(_) => {
                t.unstable += 1;
                t.unstable_h_omega = if t.unstable_h_omega == 0.0 {
                    r.h_omega
                } else {
                    t.unstable_h_omega.min(r.h_omega)
                };
            }
            StressOutcome::Failure(_) => {
                t.failures += 1;
                failures.push(r);
            }
        }
    }
    bar.finish_and_clear();
    println!(
        "stress suite: seed {seed}, cases {}..{}, {:.1} s on {threads} thread(s)\n",
        cases.start,
        cases.end,
        start.elapsed().as_secs_f64()
    );
    println!(
        "| integrator | cases | stable | stopped as unstable | failures | deepest in a collider (m) | worst pin error (m) | fastest particle (m/s) | largest stable dt (s) | stiffest stable (N/m) | largest stable hω | smallest unstable hω |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
    for (integrator, t) in tallies.iter().filter(|(_, t)| t.cases > 0) {
        println!(
            "| {} | {} | {} | {} | {} | {:.1e} | {:.1e} | {:.0} | {:.4} | {:.2e} | {:.2} | {} |",
            integrator.name(),
            t.cases,
            t.stable,
            t.unstable,
            t.failures,
            t.max_penetration,
            t.max_pin_error,
            t.max_speed,
            t.stable_dt,
            t.stable_stiffness,
            t.stable_h_omega,
            if t.unstable > 0 {
                format!("{:.2}", t.unstable_h_omega)
            } else {
                "–".into()
            }
        );
    }
    if tearing {
        println!("\n{torn} cases tore, {splits} particles split in all.");
    }
    for f in &failures {
        if let StressOutcome::Failure(why) = &f.outcome {
            println!(
                "\nFAILED case {} (seed {}, {} substeps, hω {:.2}): {why}\n{:?}",
                f.case.index, f.case.seed, f.substeps, f.h_omega, f.case
            );
        }
    }
    failures.is_empty()
}
