//! `benchmarks`: every scene file in a folder timed through the whole plugin on both of Bevy's
//! executors, written as the current figures of `BENCHMARKS.md` with machine, commit and date.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use bevy_cloth::scene::ClothScene;

use super::bench::{Variant, bench_scene};
use super::machine;

/// The scene the others are compared with in the table's last column.
const REFERENCE_SCENE: &str = "grid64.ron";

/// One scene's frames on one executor in one round.
struct Timing {
    median_ms: f64,
    p10_ms: f64,
    p90_ms: f64,
    asleep: u64,
}

/// What a scene's runs report about its cloth (the same in every run).
struct SceneFacts {
    copies: u64,
    particles: u64,
    springs: u64,
    substeps: u64,
    integrator: String,
}

struct SceneRows {
    path: PathBuf,
    /// `Some(0)`: the scene's App with no cloth (Bevy's schedules alone); `None`: its cloths.
    copies: Option<u32>,
    /// Frames timed per run ([`frames_for`] its copies).
    frames: u32,
    facts: Option<SceneFacts>,
    /// Per round: single-threaded, multi-threaded.
    rounds: Vec<[Timing; 2]>,
}

/// Times every `.ron` scene in `scenes` (sorted by name) for `frames` frames, `runs` rounds
/// (scenes and executors alternate within a round, so that a slow minute of a shared machine
/// spreads over all of them), and writes the report to `output`.
pub fn run(
    scenes: &Path,
    frames: u32,
    runs: u32,
    output: &Path,
) -> Result<(), Box<dyn std::error::Error>> {
    // Before the run writes its file into the checkout.
    let commit = machine::commit(&[output]);
    let mut paths: Vec<PathBuf> = std::fs::read_dir(scenes)
        .map_err(|e| format!("cannot read {}: {e}", scenes.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "ron"))
        .collect();
    paths.sort();
    if paths.is_empty() {
        return Err(format!("no .ron scene in {}", scenes.display()).into());
    }
    let mut rows = paths
        .into_iter()
        .map(|path| {
            let copies = ClothScene::load(&path)?.copies.count;
            Ok(SceneRows {
                frames: frames_for(frames, copies),
                path,
                copies: None,
                facts: None,
                rounds: Vec::new(),
            })
        })
        .collect::<Result<Vec<_>, bevy_cloth::prelude::ClothError>>()?;
    // The reference scene's App without its cloth: what the executors cost by themselves.
    if let Some(reference) = rows.iter().find(|r| file_name(&r.path) == REFERENCE_SCENE) {
        let bare = SceneRows {
            path: reference.path.clone(),
            copies: Some(0),
            frames,
            facts: None,
            rounds: Vec::new(),
        };
        rows.push(bare);
    }
    let started = std::time::Instant::now();
    for round in 0..runs.max(1) {
        for row in &mut rows {
            let (frames, copies) = (row.frames, row.copies);
            let mut time = |single_threaded: bool| -> Result<Timing, Box<dyn std::error::Error>> {
                let variant = Variant {
                    copies,
                    single_threaded,
                    warm_up: 10,
                    ..Variant::default()
                };
                let line = bench_scene(&row.path, frames, variant)?;
                let number = |key: &str| line[key].as_f64().unwrap_or(f64::NAN);
                let count = |key: &str| line[key].as_u64().unwrap_or(0);
                row.facts.get_or_insert_with(|| SceneFacts {
                    copies: count("copies"),
                    particles: count("particles"),
                    springs: count("springs"),
                    substeps: count("substeps"),
                    integrator: line["integrator"].as_str().unwrap_or("–").to_string(),
                });
                eprintln!(
                    "round {}/{runs}, {} ({}): {:.3} ms ({:.0} s so far)",
                    round + 1,
                    row_name(row),
                    if single_threaded { "single" } else { "multi" },
                    number("median_ms"),
                    started.elapsed().as_secs_f64()
                );
                Ok(Timing {
                    median_ms: number("median_ms"),
                    p10_ms: number("p10_ms"),
                    p90_ms: number("p90_ms"),
                    asleep: count("cloth_frames_asleep"),
                })
            };
            let single = time(true)?;
            let multi = time(false)?;
            row.rounds.push([single, multi]);
        }
    }
    let mut report = render(&rows, frames, runs.max(1), &commit);
    report.push_str(&first_second(scenes, runs.max(1))?);
    report.push_str(&crowds(&scenes.join("crowd"))?);
    std::fs::write(output, report)?;
    eprintln!("wrote {}", output.display());
    Ok(())
}

/// The frames a scene of `copies` cloths is timed for: `frames / copies`, but at least 60 (a
/// second) and at most `frames`, so that a crowd takes about as long as one cloth.
fn frames_for(frames: u32, copies: u32) -> u32 {
    (frames / copies.max(1)).max(60).min(frames)
}

fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    match values.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => values[n / 2],
        n => 0.5 * (values[n / 2 - 1] + values[n / 2]),
    }
}

/// Median over the rounds, with the rounds' range when there are several.
fn fmt_spread(values: Vec<f64>) -> String {
    let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let mid = median(values.clone());
    if values.len() > 1 {
        format!("**{mid:.3}** ({lo:.3}–{hi:.3})")
    } else {
        format!("**{mid:.3}**")
    }
}

/// The scene file's opening comment, joined into one line.
fn description(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    text.lines()
        .map_while(|l| l.trim_start().strip_prefix("//"))
        .map(str::trim)
        .collect::<Vec<_>>()
        .join(" ")
}

/// A row's name in the tables: the scene file, marked when it is the App without cloths.
fn row_name(row: &SceneRows) -> String {
    match row.copies {
        Some(0) => format!("`{}`, no cloth", file_name(&row.path)),
        _ => format!("`{}`", file_name(&row.path)),
    }
}

fn file_name(path: &Path) -> String {
    path.file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
}

fn render(rows: &[SceneRows], frames: u32, runs: u32, commit: &str) -> String {
    let reference = rows
        .iter()
        .find(|r| r.copies.is_none() && file_name(&r.path) == REFERENCE_SCENE);
    let mut out = String::new();
    let w = &mut out;
    let _ = writeln!(w, "# Benchmarks\n");
    let _ = writeln!(
        w,
        "Current figures only, written by one command (this file is its output; edit the \
         command, not the file):\n\n```sh\ncargo run --release --example cloth_cli -- \
         benchmarks\n```\n\nCommit {commit}, {date}, on {cpu} with {threads} threads ({rustc}). \
         Past figures and what changed them: [CHANGELOG.md](CHANGELOG.md) and git.\n",
        date = machine::date(),
        cpu = machine::cpu(),
        threads = machine::threads(),
        rustc = machine::rustc(),
    );
    let _ = writeln!(
        w,
        "## The whole App frame of each scene\n\n\
         Each scene file in `assets/scenes/`, run through the whole plugin in a headless App: one \
         fixed step per frame (the solver's substeps, render positions and normals, the mesh \
         write and Bevy's own schedules). A row is what\n`cargo run --release --example cloth_cli \
         -- bench assets/scenes/SCENE --frames {frames} [--single-threaded]`\nmeasures: \
         milliseconds per frame, the median of {frames} frames after 10 warm-up frames (a scene of \
         K copies, {frames}/K frames, at least 60), on Bevy's single-threaded executor \
         (static-scene transform tracking off, as `harness::use_single_threaded_frame` sets it) and on its default multi-threaded one. \
         {runs} rounds alternate the scenes and executors; a cell is the median of the rounds' \
         medians with their range in brackets, and a ratio is the median of the ratios taken \
         within each round. Machines like this one are shared and noisy: compare ratios, not \
         times from different runs.\n"
    );
    let _ = writeln!(
        w,
        "| scene | copies × particles | springs (each) | integrator × substeps | single-threaded \
         frame (ms) | multi-threaded frame (ms) | multi / single | single ÷ {REFERENCE_SCENE} | \
         cloth-frames asleep |"
    );
    let _ = writeln!(w, "|---|---:|---:|---|---:|---:|---:|---:|---:|");
    for row in rows {
        let facts = row.facts.as_ref();
        let single: Vec<f64> = row.rounds.iter().map(|r| r[0].median_ms).collect();
        let multi: Vec<f64> = row.rounds.iter().map(|r| r[1].median_ms).collect();
        let ratio = median(
            row.rounds
                .iter()
                .map(|r| r[1].median_ms / r[0].median_ms)
                .collect(),
        );
        let relative = reference.map(|reference| {
            median(
                row.rounds
                    .iter()
                    .zip(&reference.rounds)
                    .map(|(r, q)| r[0].median_ms / q[0].median_ms)
                    .collect(),
            )
        });
        let asleep: u64 = row.rounds.iter().map(|r| r[0].asleep + r[1].asleep).sum();
        // The App without cloths has no cloth to describe.
        let cloth = match facts.filter(|f| f.copies > 0) {
            Some(f) => format!(
                "{} × {} | {} | {} × {}",
                f.copies, f.particles, f.springs, f.integrator, f.substeps
            ),
            None => "0 | – | –".to_string(),
        };
        let _ = writeln!(
            w,
            "| {} | {cloth} | {} | {} | {ratio:.2} | {} | {asleep} of {} |",
            row_name(row),
            fmt_spread(single),
            fmt_spread(multi),
            relative.map_or("–".into(), |r| format!("{r:.2}")),
            2 * facts.map_or(0, |f| f.copies) * row.frames as u64 * row.rounds.len() as u64,
        );
    }
    let _ = writeln!(
        w,
        "\nThe 10th and 90th percentiles of each scene's frames, single-threaded, in the round \
         with the median time:\n"
    );
    let _ = writeln!(w, "| scene | p10 (ms) | median (ms) | p90 (ms) |");
    let _ = writeln!(w, "|---|---:|---:|---:|");
    for row in rows {
        let mut order: Vec<&[Timing; 2]> = row.rounds.iter().collect();
        order.sort_by(|a, b| a[0].median_ms.total_cmp(&b[0].median_ms));
        if let Some(t) = order.get(order.len() / 2).map(|r| &r[0]) {
            let _ = writeln!(
                w,
                "| {} | {:.3} | {:.3} | {:.3} |",
                row_name(row),
                t.p10_ms,
                t.median_ms,
                t.p90_ms
            );
        }
    }
    let _ = writeln!(w, "\n## The scenes\n");
    for row in rows {
        let text = match row.copies {
            Some(0) => String::from(
                "The same headless App with no cloth spawned (`--copies 0`): Bevy's own \
                 schedules, which the multi-threaded executor hands to its worker threads and \
                 back. On the single-threaded executor they take microseconds; the difference \
                 between the two columns is what the multi-threaded executor costs any frame \
                 on this machine, before any cloth.",
            ),
            _ => description(&row.path),
        };
        let _ = writeln!(w, "- {}: {text}", row_name(row));
    }
    let _ = writeln!(
        w,
        "\n## Other measurements and their commands\n\n\
         These take longer or compare code rather than scenes; each writes or prints its own \
         figures:\n\n\
         | what | command | where the figures go |\n|---|---|---|\n\
         | run time against error of every integrator and of tolerance mode, against an f64 \
         reference | `cargo run --release --example cloth_cli -- work-precision` | \
         [docs/work-precision.md](docs/work-precision.md), explained in \
         [docs/accuracy.md](docs/accuracy.md) |\n\
         | the stress suite: seeded random cloths at the limits of every setting, every \
         integrator | `cargo run --release --example cloth_cli -- stress --cases 10000 --seed S` \
         | its table, printed |\n\
         | the solver step, subdivision, the paper's scene, avian, a tear (one split, a row \
         cut, the check when nothing tears), the air of a closed cloth and a crowd, as \
         micro-benchmarks | `cargo bench --bench step`, `--bench subdivision`, `--bench \
         pipeline`, `--features avian --bench avian`, `--bench tearing`, `--bench pressure`, \
         `--bench crowd` | criterion's report in `target/criterion/` |\n\
         | bevy_silk 0.10 on the same cloth | `compare/bevy_silk/run.sh 5 600` | printed |"
    );
    out
}

/// The scenes whose first second is timed, without and with self-collision.
const FIRST_SECOND: [&str; 2] = ["swing64.ron", "swing64_self_collision.ron"];

/// The first second of the swing without and with self-collision: the mean of its 60 steps
/// from the start, `runs` rounds alternating the two; empty without the scenes.
fn first_second(scenes: &Path, runs: u32) -> Result<String, Box<dyn std::error::Error>> {
    let paths = FIRST_SECOND.map(|name| scenes.join(name));
    if !paths.iter().all(|p| p.exists()) {
        return Ok(String::new());
    }
    let mut means: [Vec<f64>; 2] = Default::default();
    let mut ratios = Vec::new();
    for round in 0..runs {
        let mut mean = [0.0; 2];
        for (k, path) in paths.iter().enumerate() {
            let variant = Variant {
                single_threaded: true,
                warm_up: 0,
                ..Variant::default()
            };
            let line = bench_scene(path, 60, variant)?;
            mean[k] = line["cloth_steps"]["mean_ms"].as_f64().unwrap_or(f64::NAN);
            means[k].push(mean[k]);
            eprintln!(
                "round {}/{runs}, first second of {}: {:.3} ms",
                round + 1,
                file_name(path),
                mean[k]
            );
        }
        ratios.push(mean[1] / mean[0]);
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let mut out = String::new();
    let w = &mut out;
    let _ = writeln!(
        w,
        "\n## A swing's first second, with and without self-collision\n\n\
         The swing's cloth steps over its first 60 frames, from the start: what\n\
         `cargo run --release --example cloth_cli -- bench assets/scenes/SCENE --frames 60 \
         --warm-up 0 --single-threaded` reports as `cloth_steps.mean_ms`, the median of {runs} \
         rounds that alternate the two scenes; the ratio is the median of the rounds' ratios.\n"
    );
    let _ = writeln!(
        w,
        "| scene | first second, mean step (ms) | ÷ without self-collision |"
    );
    let _ = writeln!(w, "|---|---:|---:|");
    let ratio = median(&mut ratios);
    for (k, name) in FIRST_SECOND.iter().enumerate() {
        let _ = writeln!(
            w,
            "| `{name}` | **{:.3}** | {:.2} |",
            median(&mut means[k]),
            if k == 0 { 1.0 } else { ratio }
        );
    }
    Ok(out)
}

/// Frames each crowd row is timed for, and run before (the resting crowd falls asleep in them).
const CROWD_FRAMES: u32 = 180;
const CROWD_WARM_UP: u32 = 150;

/// The crowd table: each scene in `folder` once on each executor, the first (`crowd.ron`) also
/// at full quality; empty without the folder.
fn crowds(folder: &Path) -> Result<String, Box<dyn std::error::Error>> {
    let Ok(entries) = std::fs::read_dir(folder) else {
        return Ok(String::new());
    };
    let mut paths: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "ron"))
        .collect();
    paths.sort();
    let mut out = String::new();
    let w = &mut out;
    let _ = writeln!(
        w,
        "\n## Crowds\n\n\
         Each scene file in `assets/scenes/crowd/` (many cloths, with levels of detail), once on \
         each executor: a row is what\n`cargo run --release --example cloth_cli -- bench \
         assets/scenes/crowd/SCENE --frames {CROWD_FRAMES} --warm-up {CROWD_WARM_UP} \
         [--single-threaded] [--full-quality]`\nmeasures: the whole frame, the cloths' steps \
         summed (CPU time across threads) and the cloth-frames at each level of detail \
         (full / reduced / coarse / frozen / culled), medians of {CROWD_FRAMES} frames. Both columns \
         run with Bevy's default task pools, whose compute pool has one thread on a 2-core \
         machine, so the cloths step one after another in both; `--threads 2` gives it both \
         cores (CHANGELOG.md has that figure).\n"
    );
    let _ = writeln!(
        w,
        "| scene | cloths | single-threaded frame (ms) | its cloths' steps (ms) | \
         multi-threaded frame (ms) | single / multi | levels (full / reduced / coarse / frozen / culled) \
         | cloth-frames asleep |"
    );
    let _ = writeln!(w, "|---|---:|---:|---:|---:|---:|---|---:|");
    let mut described = Vec::new();
    for (k, path) in paths.iter().enumerate() {
        for full_quality in [false, true] {
            if full_quality && k > 0 {
                continue;
            }
            let run = |single_threaded: bool| {
                let variant = Variant {
                    single_threaded,
                    full_quality,
                    warm_up: CROWD_WARM_UP,
                    ..Variant::default()
                };
                let line = bench_scene(path, CROWD_FRAMES, variant);
                eprintln!(
                    "crowd {}{}: {}",
                    file_name(path),
                    if full_quality { ", full quality" } else { "" },
                    line.as_ref()
                        .map_or(f64::NAN, |l| l["median_ms"].as_f64().unwrap_or(f64::NAN))
                );
                line
            };
            let (single, multi) = (run(true)?, run(false)?);
            let number = |l: &serde_json::Value, key: &str| l[key].as_f64().unwrap_or(f64::NAN);
            let levels = &single["cloth_frames_by_level"];
            let level = |name: &str| levels[name].as_u64().unwrap_or(0);
            let _ = writeln!(
                w,
                "| `{}`{} | {} | **{:.3}** | {:.3} | **{:.3}** | {:.2} | {} / {} / {} / {} / {} | {} |",
                file_name(path),
                if full_quality {
                    " `--full-quality`"
                } else {
                    ""
                },
                single["copies"],
                number(&single, "median_ms"),
                number(&single, "cloth_steps_median_ms"),
                number(&multi, "median_ms"),
                number(&single, "median_ms") / number(&multi, "median_ms"),
                level("full"),
                level("reduced"),
                level("coarse"),
                level("frozen"),
                level("culled"),
                single["cloth_frames_asleep"],
            );
        }
        described.push(format!("- `{}`: {}", file_name(path), description(path)));
    }
    let _ = writeln!(w, "\n{}", described.join("\n"));
    Ok(out)
}
