//! `cloth_cli work-precision`: run time against error for every integrator, and for tolerance
//! mode, on the accuracy scenes, at two horizons (0.2 s and 0.5 s).
//!
//! For each scene and horizon: an f64 reference solution (Dormand–Prince 5(4) at `--tolerance`,
//! checked against one at a 10× tighter tolerance, and against one started from positions moved by
//! 1e-7 of the spacing: how much the scene itself amplifies a perturbation), then for each
//! integrator a sweep of its cost knob (substeps; and CG or Gauss-Seidel iterations) and tolerance
//! mode at tolerances 1e-2 to 1e-5, each run timed (best of a few repetitions, solver only, one
//! thread) and compared with the reference: the RMS and the largest particle position difference
//! at the end, divided by the cloth's diagonal. Unstable runs (non-finite, or error > 1) are kept
//! as failures. Writes a Markdown report, a JSON dump and a log-log PNG plot per horizon.

use std::fmt::Write as _;
use std::path::Path;
use std::time::{Duration, Instant};

use super::machine::{commit, cpu};
use bevy_cloth::harness::reference::{ReferenceProblem, ReferenceSolution};
use bevy_cloth::harness::scenes::{AccuracyScene, relative_max_error, relative_rms_error};
use bevy_cloth::sim::{Accuracy, Integrator, MAX_SUBSTEPS, SolverSettings};
use indicatif::{ProgressBar, ProgressStyle};

#[path = "work_precision/report.rs"]
mod report;
use report::*;

/// One timed run of one configuration on one scene.
#[derive(Debug, Clone)]
pub struct Measurement {
    /// The integrator configured.
    pub integrator: Integrator,
    /// The method that ran ([`Integrator::Auto`]'s choice, else `integrator`).
    pub method: Integrator,
    /// Substeps per frame actually taken (in tolerance mode, their mean over the run).
    pub substeps: u32,
    /// `SolverSettings::iterations` (XPBD sweeps; implicit Euler CG cap).
    pub iterations: u32,
    /// Whether this is `SolverSettings::default()`'s numerical configuration.
    pub is_default: bool,
    /// Whether the substep count came from the stability bound (`auto_substeps`).
    pub auto: bool,
    /// Particles in the scene.
    pub particles: usize,
    /// Wall time per simulated frame, ms (best of the repetitions).
    pub ms_per_frame: f64,
    /// Relative RMS error at the end; `None` when the run failed.
    pub error: Option<f64>,
    /// Relative largest particle error at the end; `None` when the run failed.
    pub max_error: Option<f64>,
    /// The tolerance (relative, per second) of a tolerance-mode run.
    pub tolerance: Option<f32>,
    /// Tolerance mode's own estimate of the error at the end (its summed estimates, relative).
    pub estimated: Option<f64>,
    /// Why the run failed, if it did.
    pub failure: Option<String>,
}

impl Measurement {
    /// Milliseconds per frame per 1000 particles.
    pub fn ms_per_kparticle(&self) -> f64 {
        self.ms_per_frame / (self.particles as f64 / 1000.0)
    }
}

/// The configurations swept for each integrator.
fn sweep(quick: bool) -> Vec<SolverSettings> {
    let base = SolverSettings {
        auto_substeps: false,
        ..Default::default()
    };
    let mut out = Vec::new();
    let (xpbd_substeps, xpbd_iterations): (&[u32], &[u32]) = if quick {
        (&[5, 20, 80, 320], &[1])
    } else {
        (&[5, 10, 20, 40, 80, 160, 320, 640, 1024], &[1, 4])
    };
    // The default's one knob, over both ranges (it runs XPBD below the stability bound and Verlet
    // from it on); `run` adds each scene's bound itself.
    let mut auto: Vec<u32> = xpbd_substeps.to_vec();
    auto.extend_from_slice(if quick {
        &[64, 128]
    } else {
        &[12, 16, 24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768]
    });
    auto.sort_unstable();
    auto.dedup();
    for substeps in auto {
        out.push(SolverSettings {
            integrator: Integrator::Auto,
            substeps,
            ..base
        });
    }
    for &iterations in xpbd_iterations {
        for &substeps in xpbd_substeps {
            out.push(SolverSettings {
                integrator: Integrator::Xpbd,
                substeps,
                iterations,
                ..base
            });
        }
    }
    let explicit: &[u32] = if quick {
        &[16, 32, 64, 128, 256, 512]
    } else {
        &[
            8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024,
        ]
    };
    for integrator in [Integrator::SymplecticEuler, Integrator::Verlet] {
        for &substeps in explicit {
            out.push(SolverSettings {
                integrator,
                substeps,
                ..base
            });
        }
        // The substep count of the stability bound alone.
        out.push(SolverSettings {
            integrator,
            substeps: 1,
            auto_substeps: true,
            ..base
        });
    }
    for tolerance in TOLERANCES {
        out.push(SolverSettings {
            accuracy: Accuracy::relative(tolerance, MAX_SUBSTEPS),
            ..base
        });
    }
    let (implicit_substeps, cg): (&[u32], &[u32]) = if quick {
        (&[1, 4, 16, 64], &[50])
    } else {
        (&[1, 2, 4, 8, 16, 32, 64, 128, 256], &[20, 100])
    };
    for &iterations in cg {
        for &substeps in implicit_substeps {
            out.push(SolverSettings {
                integrator: Integrator::ImplicitEuler,
                substeps,
                iterations,
                ..base
            });
        }
    }
    out
}

/// The tolerances of the tolerance-mode runs (relative to the cloth's size, per second).
pub const TOLERANCES: [f32; 4] = [1e-2, 1e-3, 1e-4, 1e-5];

/// The horizons measured, s: the first is the plot and goal check of earlier reports.
pub const HORIZONS: [f64; 2] = [0.2, 0.5];

/// The largest error a tolerance-mode run at `tolerance` may have: the tolerance itself down to
/// 1e-3, twice it below.
fn allowed(tolerance: f32) -> f64 {
    let t = f64::from(tolerance);
    if t >= 1e-3 { t } else { 2.0 * t }
}

/// Runs `settings` on `scene` for `frames` frames (repeating for timing until `min_time` has
/// passed, at most [`REPETITIONS`] runs) and measures its error against `reference`.
fn measure(
    scene: AccuracyScene,
    settings: &SolverSettings,
    is_default: bool,
    (reference, frames): (&ReferenceSolution, u32),
    min_time: Duration,
) -> Result<Measurement, bevy_cloth::ClothError> {
    let dt = AccuracyScene::FRAME_DT;
    let mut best = f64::INFINITY;
    let mut spent = Duration::ZERO;
    let mut result: Option<Measurement> = None;
    for _ in 0..REPETITIONS {
        let mut sim = scene.build(settings)?;
        let mut substeps = sim.substeps_for(dt);
        let mut taken = 0u64;
        let start = Instant::now();
        let mut failure = None;
        for _ in 0..frames {
            if let Err(e) = sim.step(dt) {
                failure = Some(e.to_string());
                break;
            }
            if let Some(r) = sim.accuracy_report() {
                taken += u64::from(r.substeps);
            }
        }
        let elapsed = start.elapsed();
        let report = sim.accuracy_report();
        if report.is_some() {
            substeps = (taken as f64 / f64::from(frames.max(1))).round() as u32;
        }
        spent += elapsed;
        best = best.min(elapsed.as_secs_f64() * 1e3 / frames as f64);
        if result.is_none() {
            let error = relative_rms_error(sim.positions(), &reference.positions, scene.diagonal());
            let max_error =
                relative_max_error(sim.positions(), &reference.positions, scene.diagonal());
            if failure.is_none() && (error.is_nan() || max_error > 1.0) {
                failure = Some(format!("error {max_error:.3e} > 1"));
            }
            result = Some(Measurement {
                integrator: settings.integrator,
                method: sim.active_integrator(),
                substeps,
                iterations: settings.iterations,
                is_default,
                auto: settings.auto_substeps && settings.integrator.is_explicit(),
                particles: sim.positions().len(),
                ms_per_frame: 0.0,
                error: failure.is_none().then_some(error),
                max_error: failure.is_none().then_some(max_error),
                tolerance: settings.accuracy.tolerance,
                estimated: report.map(|r| r.estimated_error / scene.diagonal()),
                failure,
            });
        }
        if result.as_ref().is_some_and(|r| r.failure.is_some()) || spent >= min_time {
            break;
        }
    }
    let mut m = result.expect("at least one run");
    m.ms_per_frame = best;
    Ok(m)
}

/// Timed runs of each configuration at most: the fastest is kept, so that the same computation
/// configured two ways (the default at the stability bound, and Verlet there) times alike.
const REPETITIONS: usize = 15;

/// Gives runs that are the same computation the same time, the fastest of theirs: the same method
/// at the same substeps (and, for XPBD and implicit Euler, iterations) with the same result, as
/// when the default runs Verlet at the substeps of a Verlet run. Timed separately, two copies
/// differ by the machine's noise (up to a third here), which would rank one above the other.
fn pool_identical(runs: &mut [Measurement]) {
    let same = |a: &Measurement, b: &Measurement| {
        a.tolerance.is_none()
            && b.tolerance.is_none()
            && a.method == b.method
            && a.substeps == b.substeps
            && (a.method.is_explicit() || a.iterations == b.iterations)
            && a.error.is_some()
            && a.error == b.error
    };
    for i in 0..runs.len() {
        let fastest = runs
            .iter()
            .filter(|r| same(r, &runs[i]))
            .map(|r| r.ms_per_frame)
            .fold(runs[i].ms_per_frame, f64::min);
        runs[i].ms_per_frame = fastest;
    }
}

/// The lower-left envelope of the successful runs: `(ms per frame, largest error)` sorted by
/// time, each point more accurate than every cheaper one.
pub fn pareto_front<'a>(runs: impl Iterator<Item = &'a Measurement>) -> Vec<(f64, f64)> {
    let mut points: Vec<(f64, f64)> = runs
        .filter_map(|m| m.max_error.map(|e| (m.ms_per_frame, e)))
        .collect();
    points.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut front: Vec<(f64, f64)> = Vec::new();
    for p in points {
        if front.last().is_none_or(|last| p.1 < last.1) {
            front.push(p);
        }
    }
    front
}

/// Best error reachable within `budget` ms per frame on a Pareto front.
fn best_within(front: &[(f64, f64)], budget: f64) -> Option<f64> {
    front
        .iter()
        .filter(|(t, _)| *t <= budget)
        .map(|(_, e)| *e)
        .next_back()
}

/// The goal check of one scene: the default configuration's point, and the default integrator's
/// front against the best of all integrators at each measured budget.
struct GoalCheck {
    default_error: Option<f64>,
    default_ms_per_kparticle: f64,
    /// The default integrator's cheapest run with error ≤ 1e-3: ms per frame per 1000 particles
    /// and its substeps.
    cheapest_accurate: Option<(f64, u32)>,
    /// Largest ratio (default integrator's best error / best error of all) over the budgets where
    /// the default integrator has a stable run, and the budget where it occurs.
    worst_ratio: (f64, f64),
    /// The same with the default integrator's budget [`TIMING_SLACK`] larger: the ratio a
    /// timing difference that small cannot decide.
    worst_ratio_with_slack: (f64, f64),
    /// Budgets (ms per frame) below the default integrator's cheapest stable run at which another
    /// integrator already has a stable run.
    uncovered_budgets: usize,
}

/// Relative timing difference below which the goal check does not rank two runs (see
/// [`GoalCheck::worst_ratio_with_slack`]): repeated timings of one computation on this shared
/// machine differ by more.
const TIMING_SLACK: f64 = 0.05;

fn goal_check(runs: &[Measurement], default_integrator: Integrator) -> GoalCheck {
    let default = runs.iter().find(|m| m.is_default);
    let fixed = || runs.iter().filter(|m| m.tolerance.is_none());
    let all = pareto_front(fixed());
    let mine = pareto_front(fixed().filter(|m| m.integrator == default_integrator));
    let (mut worst, mut worst_with_slack) = ((1.0, 0.0), (1.0, 0.0));
    let mut uncovered = 0;
    for (budget, best) in &all {
        match best_within(&mine, *budget) {
            Some(e) => {
                if e / best > worst.0 {
                    worst = (e / best, *budget);
                }
                let e = best_within(&mine, *budget * (1.0 + TIMING_SLACK)).unwrap_or(e);
                if e / best > worst_with_slack.0 {
                    worst_with_slack = (e / best, *budget);
                }
            }
            None => uncovered += 1,
        }
    }
    let cheapest_accurate = runs
        .iter()
        .filter(|m| {
            m.tolerance.is_none()
                && m.integrator == default_integrator
                && m.max_error.is_some_and(|e| e <= 1e-3)
        })
        .min_by(|a, b| a.ms_per_frame.total_cmp(&b.ms_per_frame))
        .map(|m| (m.ms_per_kparticle(), m.substeps));
    GoalCheck {
        default_error: default.and_then(|d| d.max_error),
        default_ms_per_kparticle: default.map_or(f64::NAN, Measurement::ms_per_kparticle),
        cheapest_accurate,
        worst_ratio: worst,
        worst_ratio_with_slack: worst_with_slack,
        uncovered_budgets: uncovered,
    }
}

/// Runs the benchmark and writes `work-precision.md`, `work-precision.json` and a plot per horizon
/// (`work-precision.png` for the first, `work-precision-<T>s.png` for the others) into `out_dir`.
pub fn run(
    quick: bool,
    tolerance: f64,
    scenes: &[AccuracyScene],
    out_dir: &Path,
) -> Result<(), Box<dyn std::error::Error>> {
    // Before the run writes its files into the checkout.
    // Its own earlier output (the report, its data and plots) does not count as a change.
    let outputs = out_dir.join("work-precision*");
    let commit = commit(&[outputs.as_path()]);
    let configs = sweep(quick);
    let default = SolverSettings::default();
    let min_time = Duration::from_millis(if quick { 60 } else { 300 });
    let total = (HORIZONS.len() * scenes.len()) as u64 * (configs.len() as u64 + 3 + 2);
    let bar = ProgressBar::new(total);
    bar.set_style(
        ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {pos}/{len} {msg}")?
            .progress_chars("=> "),
    );
    let mut horizons = Vec::new();
    for horizon in HORIZONS {
        let frames = AccuracyScene::frames_in(horizon);
        let duration = f64::from(frames) * f64::from(AccuracyScene::FRAME_DT);
        let mut results = Vec::new();
        let mut references = Vec::new();
        for &scene in scenes {
            bar.set_message(format!("{} to {horizon} s: references", scene.name()));
            let initial = scene.build(&default)?;
            let problem = ReferenceProblem::from_sim(&initial);
            let t = Instant::now();
            let reference = problem.solve(duration, tolerance)?;
            let seconds = t.elapsed().as_secs_f64();
            bar.inc(1);
            let tighter = problem.solve(duration, tolerance / 10.0)?;
            bar.inc(1);
            let perturbed = problem
                .perturbed(1e-7 * scene.spacing())
                .solve(duration, tolerance)?;
            bar.inc(1);
            let rms = |a: &[glam::DVec3], b: &[glam::DVec3]| {
                (a.iter()
                    .zip(b)
                    .map(|(a, b)| a.distance_squared(*b))
                    .sum::<f64>()
                    / a.len() as f64)
                    .sqrt()
                    / scene.diagonal()
            };
            let largest = |a: &[glam::DVec3], b: &[glam::DVec3]| {
                a.iter()
                    .zip(b)
                    .map(|(a, b)| a.distance(*b))
                    .fold(0.0, f64::max)
                    / scene.diagonal()
            };
            // The f32 simulation's own floor: Verlet at its bound and at twice as many substeps
            // differ by far more than their truncation errors once the round-off is amplified.
            let bound = initial.stable_substeps(AccuracyScene::FRAME_DT);
            let verlet = |substeps| SolverSettings {
                integrator: Integrator::Verlet,
                substeps,
                auto_substeps: false,
                ..default
            };
            let mut a = scene.build(&verlet(bound))?;
            let mut b = scene.build(&verlet(2 * bound))?;
            for _ in 0..frames {
                a.step(AccuracyScene::FRAME_DT)?;
                b.step(AccuracyScene::FRAME_DT)?;
            }
            let b: Vec<glam::DVec3> = b.positions().iter().map(|x| x.as_dvec3()).collect();
            references.push(ReferenceInfo {
                scene,
                against_tighter: rms(&reference.positions, &tighter.positions),
                sensitivity: largest(&reference.positions, &perturbed.positions),
                rounding: relative_max_error(a.positions(), &b, scene.diagonal()),
                steps: reference.steps,
                rejected: reference.rejected,
                seconds,
            });
            let mut runs = Vec::new();
            let mut all: Vec<(SolverSettings, bool)> =
                configs.iter().map(|c| (*c, false)).collect();
            all.push((
                SolverSettings {
                    integrator: Integrator::Auto,
                    substeps: initial.stable_substeps(AccuracyScene::FRAME_DT),
                    auto_substeps: false,
                    ..default
                },
                false,
            ));
            all.push((default, true));
            for (settings, is_default) in all {
                bar.set_message(format!(
                    "{} to {horizon} s: {}",
                    scene.name(),
                    match settings.accuracy.tolerance {
                        Some(t) => format!("tolerance {t:e}"),
                        None => format!(
                            "{} × {} substeps",
                            settings.integrator.name(),
                            settings.substeps
                        ),
                    }
                ));
                runs.push(measure(
                    scene,
                    &settings,
                    is_default,
                    (&reference, frames),
                    min_time,
                )?);
                bar.inc(1);
            }
            pool_identical(&mut runs);
            results.push((scene, runs));
        }
        horizons.push((horizon, references, results));
    }
    bar.finish_with_message("done");

    std::fs::create_dir_all(out_dir)?;
    let plot_name = |i: usize, horizon: f64| {
        if i == 0 {
            "work-precision.png".to_string()
        } else {
            format!("work-precision-{horizon}s.png")
        }
    };
    for (i, (horizon, _, results)) in horizons.iter().enumerate() {
        super::plot::write_plot(&out_dir.join(plot_name(i, *horizon)), results, *horizon)?;
    }
    let mut md = String::new();
    writeln!(
        md,
        "# Work-precision benchmark{}\n",
        if quick { " (quick)" } else { "" }
    )?;
    writeln!(
        md,
        "Generated by `cargo run --release --example cloth_cli -- work-precision{}` at {} on {} \
         ({} hardware thread(s)); timings are wall time per simulated 1/60 s frame of the solver \
         alone (one thread, best of up to 15 runs; runs that are the same computation, such as \
         the default running Verlet at the substeps of a Verlet run, share the fastest time). \
         Errors are the RMS and the largest particle position difference at the horizon, \
         divided by the cloth's diagonal, against an f64 Dormand–Prince 5(4) reference at \
         tolerance {tolerance:e}; the plots and fronts use the largest. Damping is off. Unstable \
         runs are listed, not dropped. Tolerance-mode runs (`SolverSettings::accuracy`, relative \
         tolerance per second, capped at {MAX_SUBSTEPS} substeps) list their mean substeps per \
         frame and the integrator of their last step.\n",
        if quick { " --quick" } else { "" },
        commit,
        cpu(),
        std::thread::available_parallelism().map_or(1, |n| n.get()),
    )?;
    writeln!(
        md,
        "Curves: {}, and orange: tolerance mode at tolerances {} (largest first). Dots are single \
         runs, lines each integrator's Pareto front; the gold lines mark error 1e-3 at 1 ms per \
         frame per 1000 particles.\n",
        super::plot::CURVES
            .iter()
            .map(|i| format!("{} {}", super::plot::color_name(*i), i.name()))
            .collect::<Vec<_>>()
            .join(", "),
        TOLERANCES
            .iter()
            .map(|t| format!("{t:.0e}"))
            .collect::<Vec<_>>()
            .join(", ")
    )?;
    for (i, (horizon, references, results)) in horizons.iter().enumerate() {
        writeln!(md, "# Horizon {horizon} s\n")?;
        writeln!(
            md,
            "![work-precision plot at {horizon} s]({})\n",
            plot_name(i, *horizon)
        )?;
        writeln!(md, "## Reference solutions\n")?;
        writeln!(
            md,
            "| scene | steps | rejected | time (s) | RMS difference to tolerance {:.0e} | largest difference after a start moved by 1e-7 of the spacing (sensitivity) | f32: largest difference between Verlet at its bound and at twice the substeps |",
            tolerance / 10.0
        )?;
        writeln!(md, "|---|---|---|---|---|---|---|")?;
        for r in references {
            writeln!(
                md,
                "| {} | {} | {} | {:.1} | {:.1e} | {:.1e} | {:.1e} |",
                r.scene.name(),
                r.steps,
                r.rejected,
                r.seconds,
                r.against_tighter,
                r.sensitivity,
                r.rounding
            )?;
        }
        writeln!(md, "\n## Tolerance mode\n")?;
        writeln!(
            md,
            "Allowed: the tolerance at 1e-3 and above, twice it below (the tolerance is per second, \
             so over a horizon under 1 s the mode aims lower). Floor: the larger of the two \
             sensitivities above; an allowance below it is unreachable by any setting (the \
             scene amplifies the positions' round-off that far) and is marked so, not counted as \
             a failure. Cost ratios: the run's time over the cheapest fixed run (any integrator, \
             same sweep) whose largest error is at most the run's, and at most the allowance. \
             The estimate's range below leaves out unreachable runs, whose error is the floor's.\n"
        )?;
        writeln!(
            md,
            "| scene | tolerance | RMS error | largest error | allowed | met? | ms/frame (last integrator × mean substeps) | cheapest fixed run as accurate: ms/frame | ratio | cheapest fixed run within the allowance: ms/frame | ratio | estimated error | estimate / measured |"
        )?;
        writeln!(md, "|---|---|---|---|---|---|---|---|---|---|---|---|---|")?;
        let mut worst_track: (f64, f64) = (f64::INFINITY, 0.0);
        for ((scene, runs), r) in results.iter().zip(references) {
            for m in runs.iter().filter(|m| m.tolerance.is_some()) {
                let c = ToleranceCheck::new(m, runs, r.sensitivity.max(r.rounding));
                let t = m.tolerance.unwrap_or(0.0);
                let track = match (m.estimated, m.max_error) {
                    (Some(est), Some(e)) if e > 0.0 => Some(est / e),
                    _ => None,
                };
                if let Some(k) = track
                    && c.reachable()
                {
                    worst_track = (worst_track.0.min(k), worst_track.1.max(k));
                }
                writeln!(
                    md,
                    "| {} | {t:.0e} | {} | {} | {:.0e} | {} | {} | {} | {} | {} | {} | {} | {} |",
                    scene.name(),
                    m.error.map_or("–".into(), |e| format!("{e:.2e}")),
                    m.max_error.map_or(
                        format!("**unstable** ({})", m.failure.as_deref().unwrap_or("?")),
                        |e| format!("{e:.2e}")
                    ),
                    allowed(t),
                    if c.met() {
                        "yes".to_string()
                    } else if !c.reachable() {
                        format!("unreachable (floor {:.1e})", c.floor)
                    } else {
                        "**no**".to_string()
                    },
                    fmt_run(Some(m)),
                    fmt_run(c.same_error),
                    fmt_ratio(c.ratio(c.same_error)),
                    fmt_run(c.within),
                    fmt_ratio(c.ratio(c.within)),
                    m.estimated.map_or("–".into(), |e| format!("{e:.2e}")),
                    track.map_or("–".into(), |k| format!("{k:.2}")),
                )?;
            }
        }
        if worst_track.1 > 0.0 {
            writeln!(
                md,
                "\nEstimate over measured largest error, runs with a reachable allowance: {:.2} to {:.2}.",
                worst_track.0, worst_track.1
            )?;
        }
        writeln!(
            md,
            "\n## Goal check (default: {} at {} substeps{})\n",
            default.integrator.name(),
            default.substeps,
            if default.integrator == Integrator::Auto {
                ": Verlet where they are within its stability bound, else XPBD".to_string()
            } else {
                String::new()
            }
        )?;
        writeln!(
            md,
            "| scene | default largest error | default ms/frame per 1k particles | largest error ≤ 1e-3 within 1 ms at the default? | {0}'s cheapest run with largest error ≤ 1e-3: ms/frame per 1k particles (substeps) | worst ratio of {0}'s best error to the best of all, at budget (ms/frame) | the same, allowing {0} {1:.0}% more time | budgets where {0} has no stable run |",
            default.integrator.name(),
            100.0 * TIMING_SLACK
        )?;
        writeln!(md, "|---|---|---|---|---|---|---|---|")?;
        for (scene, runs) in results {
            let g = goal_check(runs, default.integrator);
            let ok =
                g.default_error.is_some_and(|e| e <= 1e-3) && g.default_ms_per_kparticle <= 1.0;
            writeln!(
                md,
                "| {} | {} | {:.3} | {} | {} | {:.2} at {:.3} | {:.2} at {:.3} | {} |",
                scene.name(),
                g.default_error
                    .map_or("unstable".into(), |e| format!("{e:.2e}")),
                g.default_ms_per_kparticle,
                if ok { "yes" } else { "**no**" },
                g.cheapest_accurate
                    .map_or("none".into(), |(t, n)| format!("{t:.3} ({n})")),
                g.worst_ratio.0,
                g.worst_ratio.1,
                g.worst_ratio_with_slack.0,
                g.worst_ratio_with_slack.1,
                g.uncovered_budgets
            )?;
        }
        for (scene, runs) in results {
            writeln!(
                md,
                "\n## {} to {horizon} s: {}\n",
                scene.name(),
                scene.description()
            )?;
            writeln!(
                md,
                "| run | substeps | iterations | ms/frame | ms/frame per 1k particles | RMS error | largest error |"
            )?;
            writeln!(md, "|---|---|---|---|---|---|---|")?;
            for m in runs {
                writeln!(
                    md,
                    "| {}{}{} | {} | {} | {:.4} | {:.4} | {} |",
                    match m.tolerance {
                        Some(_) => format!("{} (last: {})", describe(m), m.method.name()),
                        None => describe(m),
                    },
                    if m.is_default { " (default)" } else { "" },
                    if m.auto { " (auto substeps)" } else { "" },
                    m.substeps,
                    if m.method.is_explicit() {
                        "–".to_string()
                    } else {
                        m.iterations.to_string()
                    },
                    m.ms_per_frame,
                    m.ms_per_kparticle(),
                    fmt_error(m)
                )?;
            }
        }
        writeln!(md)?;
    }
    std::fs::write(out_dir.join("work-precision.md"), md)?;
    let json = serde_json::json!({
        "quick": quick,
        "tolerance": tolerance,
        "horizons": horizons.iter().map(|(horizon, references, results)| serde_json::json!({
            "seconds": horizon,
            "references": references.iter().map(|r| serde_json::json!({
                "scene": r.scene.name(), "difference_to_tighter": r.against_tighter,
                "sensitivity": r.sensitivity, "f32_sensitivity": r.rounding, "steps": r.steps, "rejected": r.rejected,
                "seconds": r.seconds,
            })).collect::<Vec<_>>(),
            "scenes": results.iter().map(|(s, runs)| serde_json::json!({
                "scene": s.name(),
                "runs": runs.iter().map(|m| serde_json::json!({
                    "integrator": m.integrator.name(), "method": m.method.name(),
                    "tolerance": m.tolerance, "substeps": m.substeps, "iterations": m.iterations,
                    "default": m.is_default, "auto_substeps": m.auto, "particles": m.particles,
                    "ms_per_frame": m.ms_per_frame, "error": m.error, "max_error": m.max_error,
                    "estimated_error": m.estimated, "failure": m.failure,
                })).collect::<Vec<_>>(),
            })).collect::<Vec<_>>(),
        })).collect::<Vec<_>>(),
    });
    std::fs::write(
        out_dir.join("work-precision.json"),
        serde_json::to_string_pretty(&json)?,
    )?;
    eprintln!(
        "wrote {0}/work-precision.md, {0}/work-precision.json and the plots",
        out_dir.display()
    );
    Ok(())
}
