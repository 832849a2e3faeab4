//! `cloth_cli`: run cloth scenes headless, through the real plugin in a Bevy App.
//!
//! ```text
//! cargo run --release --example cloth_cli -- simulate assets/scenes/hanging.ron --frames 120 --output out.json
//! cargo run --release --example cloth_cli -- bench assets/scenes/hanging.ron --frames 600
//! cargo run --release --example cloth_cli -- benchmarks
//! cargo run --release --example cloth_cli -- subdivide in.obj --level 2 --rule tuned --output out.obj
//! cargo run --release --example cloth_cli -- analysis
//! cargo run --release --example cloth_cli -- work-precision --quick
//! cargo run --release --example cloth_cli -- stress --cases 10000 --seed 1
//! cargo run --example cloth_cli -- fuzz --seed 1 --sequences 300
//! cargo run --release --example cloth_cli -- state-hashes --cases 500 > hashes.txt
//! ```

use std::path::PathBuf;
use std::time::Instant;

use bevy::prelude::*;
use bevy_cloth::harness::reference::REFERENCE_TOLERANCE;
use bevy_cloth::harness::scenes::AccuracyScene;
use bevy_cloth::prelude::*;
use bevy_cloth::subdivision::{parse_obj, refine_positions, write_obj};
use clap::{Parser, Subcommand};

#[path = "cloth_cli/bench.rs"]
mod bench;
#[path = "cloth_cli/benchmarks.rs"]
mod benchmarks;
#[path = "cloth_cli/fuzz.rs"]
mod fuzz;
#[path = "cloth_cli/machine.rs"]
mod machine;
#[path = "cloth_cli/plot.rs"]
mod plot;
#[path = "cloth_cli/stress.rs"]
mod stress;
#[path = "cloth_cli/work_precision.rs"]
mod work_precision;

#[derive(Parser)]
#[command(about = "Headless bevy_cloth scenes: simulate and benchmark")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Simulate a scene and write the final particle positions (canonical index order) and timing
    /// as JSON.
    Simulate {
        /// Scene file (RON).
        scene: PathBuf,
        /// Number of fixed steps (frames) to simulate.
        #[arg(long, default_value_t = 60)]
        frames: u32,
        /// Output JSON file.
        #[arg(long)]
        output: PathBuf,
    },
    /// Refine an OBJ polygon mesh with Catmull-Clark subdivision and write it as OBJ.
    Subdivide {
        /// Input OBJ file (positions, optional texture coordinates, polygon faces).
        input: PathBuf,
        /// Refinement level.
        #[arg(long, default_value_t = 1)]
        level: u32,
        /// Interior vertex rule.
        #[arg(long, value_enum, default_value_t = Rule::Original)]
        rule: Rule,
        /// Boundary interpolation.
        #[arg(long, value_enum, default_value_t = Boundary::EdgeOnly)]
        boundary: Boundary,
        /// Output OBJ file.
        #[arg(long)]
        output: PathBuf,
    },
    /// Print the eigen-analysis of the three Catmull-Clark vertex rules (valence 3–12) and their
    /// curvature proxies at levels 1–5 on paraboloid discs.
    Analysis,
    /// Time a scene: prints one JSON line with the median and spread of milliseconds per whole
    /// App frame (one fixed step: simulation, render refresh, mesh write), the constraint solves
    /// per second that implies, and how many frames the cloths slept through.
    Bench {
        /// Scene file (RON).
        scene: PathBuf,
        /// Number of timed frames.
        #[arg(long, default_value_t = 300)]
        frames: u32,
        /// Frames run before the timed ones.
        #[arg(long, default_value_t = 10)]
        warm_up: u32,
        /// Copies of the scene's cloth on its layout (they step in parallel across threads);
        /// default the scene's own `copies`. 0 times the App with no cloth: Bevy's schedules
        /// alone.
        #[arg(long)]
        copies: Option<u32>,
        /// Threads of Bevy's compute task pool (default: one per core).
        #[arg(long)]
        threads: Option<usize>,
        /// Run the app's schedules on Bevy's single-threaded executor instead of the
        /// multi-threaded one, with Bevy's static-scene transform tracking off
        /// (`harness::use_single_threaded_frame`).
        #[arg(long)]
        single_threaded: bool,
        /// Leave the scene's levels of detail, viewer and budget out: every cloth at full
        /// quality.
        #[arg(long)]
        full_quality: bool,
        /// Leave the scene's further cloths (`also`) out: its own copies only.
        #[arg(long)]
        first_only: bool,
        /// A budget for the cloths' steps, ms a frame (`ClothBudget`), in place of the scene's.
        #[arg(long)]
        budget_ms: Option<f32>,
        /// Hold every cloth at this level of detail (full, reduced, coarse or frozen), seen from
        /// the scene's viewer (or one 1 km up), without a budget.
        #[arg(long, value_parser = ["full", "reduced", "coarse", "frozen"])]
        level: Option<String>,
    },
    /// The stress suite: seeded random cloths at the limits of every setting, checked every step
    /// (no NaN, no panic, bounded energy, nothing inside a collider, pins exact). Prints a table
    /// per integrator and every failure; exits with an error if any case failed.
    Stress {
        /// Number of cases.
        #[arg(long, default_value_t = 1000)]
        cases: u64,
        /// Seed of the suite (case i of seed s is always the same case).
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Index of the first case (to rerun one case: `--from I --cases 1`).
        #[arg(long, default_value_t = 0)]
        from: u64,
        /// Integrators to draw from (auto, xpbd, symplectic-euler, verlet, implicit-euler); all by
        /// default.
        #[arg(long, value_delimiter = ',')]
        integrators: Vec<String>,
        /// Print every step's energies and fastest particle (for rerunning one case).
        #[arg(long)]
        trace: bool,
        /// Turn self-collision on in every case (thickness a quarter of the grid's spacing).
        #[arg(long)]
        self_collision: bool,
        /// Make every case a closed cloth with air inside (an icosphere of about the grid's
        /// particle count keeping a volume or holding a gas).
        #[arg(long)]
        air: bool,
        /// Tear every case: tearing under strain at a drawn stretch (three cases in four) and
        /// a cut at a drawn step (a plane, a blade or a ray's hole; three in four).
        #[arg(long)]
        tearing: bool,
        /// Run every case in tolerance mode at this tolerance (relative to the cloth's size, per
        /// second; the default cap of substeps).
        #[arg(long)]
        tolerance: Option<f32>,
        /// Threads to run cases on (the results do not depend on it); all the machine's by
        /// default, one with `--trace`.
        #[arg(long)]
        threads: Option<usize>,
    },
    /// The ECS edit fuzzer: seeded random sequences of spawns, despawns, valid and invalid
    /// component edits, source mesh swaps and anchor, joint, collider, wind (and avian body)
    /// changes on cloths of every kind, checked after every step (no panic, finite values, running
    /// cloths kept running, every rejection reported). Prints the report; exits with an error if a
    /// check failed.
    Fuzz {
        /// Seed (sequence i of seed s is always the same); a fresh one from the clock by default,
        /// printed.
        #[arg(long)]
        seed: Option<u64>,
        /// Number of sequences.
        #[arg(long, default_value_t = 300)]
        sequences: usize,
        /// Rerun only this sequence, printing every operation and step.
        #[arg(long)]
        sequence: Option<usize>,
        /// Most operations per sequence.
        #[arg(long, default_value_t = 20)]
        operations: usize,
        /// Valid cloth components and meshes only (checks accepted edits without rejections).
        #[arg(long)]
        valid_only: bool,
    },
    /// Bit-for-bit fingerprints: one line per preset scene (assets/scenes, run through the
    /// plugin) and per stress case of every integrator, with the hash of its final positions and
    /// velocities. Diff two builds' outputs to prove a change leaves behaviour unchanged.
    StateHashes {
        /// Stress cases per integrator (the first ones of the suite).
        #[arg(long, default_value_t = 500)]
        cases: u64,
        /// Fixed steps per preset scene.
        #[arg(long, default_value_t = 120)]
        frames: u32,
        /// Seed of the stress suite.
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// Time every scene file in a folder on both of Bevy's executors, several rounds, and write
    /// the table of current figures (BENCHMARKS.md) with the machine, commit and date.
    Benchmarks {
        /// Folder of scene files (RON).
        #[arg(long, default_value = "assets/scenes")]
        scenes: PathBuf,
        /// Timed frames per scene and executor in each round.
        #[arg(long, default_value_t = 600)]
        frames: u32,
        /// Rounds (scenes and executors alternate within each).
        #[arg(long, default_value_t = 5)]
        runs: u32,
        /// Output file.
        #[arg(long, default_value = "BENCHMARKS.md")]
        output: PathBuf,
    },
    /// Run time against error of every integrator on the accuracy scenes (solver only, against an
    /// f64 reference): writes work-precision.md, .json and .png into the output folder.
    WorkPrecision {
        /// A shorter sweep (fewer substep counts, one iteration count).
        #[arg(long)]
        quick: bool,
        /// Tolerance of the f64 reference integrator (it is also run at a tenth of this, to show
        /// its own error).
        #[arg(long, default_value_t = REFERENCE_TOLERANCE)]
        tolerance: f64,
        /// Scenes to run (swing, stiff, curtain); all by default.
        #[arg(long, value_delimiter = ',')]
        scenes: Vec<String>,
        /// Output folder.
        #[arg(long, default_value = "docs")]
        out: PathBuf,
    },
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum Rule {
    Original,
    Enhanced,
    Tuned,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum Boundary {
    EdgeOnly,
    EdgeAndCorner,
}

/// Refines `input` and writes the result; prints the vertex and face counts.
fn subdivide(
    input: &PathBuf,
    level: u32,
    rule: Rule,
    boundary: Boundary,
    output: &PathBuf,
) -> Result<(), Box<dyn std::error::Error>> {
    let rule = match rule {
        Rule::Original => VertexRule::Original,
        Rule::Enhanced => VertexRule::Enhanced,
        Rule::Tuned => VertexRule::Tuned,
    };
    let boundary = match boundary {
        Boundary::EdgeOnly => BoundaryMode::EdgeOnly,
        Boundary::EdgeAndCorner => BoundaryMode::EdgeAndCorner,
    };
    let text = std::fs::read_to_string(input)
        .map_err(|e| format!("cannot read {}: {e}", input.display()))?;
    let mesh = parse_obj(&text).map_err(|e| format!("{}: {e}", input.display()))?;
    let refined = refine_positions(&mesh, level, rule, boundary)?;
    let header = format!(
        "{} refined to level {level} ({rule:?}, {boundary:?}) by bevy_cloth",
        input.display()
    );
    std::fs::write(output, write_obj(&refined, &header))?;
    eprintln!(
        "{} vertices, {} faces -> {} vertices, {} faces",
        mesh.vertex_count(),
        mesh.face_count(),
        refined.vertex_count(),
        refined.face_count()
    );
    Ok(())
}

/// The eigenvalues and curvature proxies of every vertex rule, as text tables.
fn analysis() -> Result<(), Box<dyn std::error::Error>> {
    use bevy_cloth::subdivision::analysis::{DiscLayout, curvature_proxy, eigen_report};
    println!(
        "rule n: one-ring weights (diagonal, edge, vertex); λ, λ², bowl μ, ν, μ/λ², negative eigenvalues"
    );
    for rule in VertexRule::ALL {
        for n in 3..=12 {
            let r = eigen_report(n, rule)?;
            let w = rule.one_ring_weights(n);
            println!(
                "{rule:?} n={n:2}: α={:.6} β={:.6} γ={:.6}; λ={:.6} λ²={:.6} μ={:.6} ν={:.6} μ/λ²={:.4} negative={:?}",
                w.diagonal,
                w.edge,
                w.vertex,
                r.lambda,
                r.lambda * r.lambda,
                r.mu,
                r.nu,
                r.mu_over_lambda_squared,
                r.negative
            );
        }
    }
    println!(
        "\ncurvature proxy at the extraordinary vertex, levels 1-5, relative to the regular (valence-4) value"
    );
    for layout in [DiscLayout::Characteristic, DiscLayout::UniformRadius] {
        for rule in VertexRule::ALL {
            for n in [3, 5, 6, 8] {
                let c = curvature_proxy(n, rule, layout, 5)?;
                let ratios: Vec<String> = c
                    .samples
                    .iter()
                    .map(|s| format!("{:+.4}", s.ratio))
                    .collect();
                println!("{layout:?} {rule:?} n={n}: [{}]", ratios.join(", "));
            }
        }
    }
    Ok(())
}

/// Prints the `state-hashes` lines: preset scenes first (sorted by name), then `cases` stress
/// cases per integrator.
fn state_hashes(cases: u64, frames: u32, seed: u64) -> Result<(), Box<dyn std::error::Error>> {
    use bevy_cloth::harness::stress::{StressLimits, draw_case, run_case};
    let mut scenes: Vec<PathBuf> = std::fs::read_dir("assets/scenes")?
        .map(|e| e.map(|e| e.path()))
        .collect::<Result<_, _>>()?;
    scenes.retain(|p| p.extension().is_some_and(|e| e == "ron"));
    scenes.sort();
    for path in scenes {
        let hash = bevy_cloth::harness::scene_state_hash(&path, frames)?;
        println!("scene {} {frames} {hash:016x}", path.display());
    }
    let limits = StressLimits::default();
    for integrator in Integrator::CHOICES {
        for index in 0..cases {
            let r = run_case(&draw_case(seed, index, &[integrator], &limits), &limits);
            let name = integrator.name().replace(' ', "-");
            println!(
                "stress {name} {index} {} {:016x}",
                r.steps_run, r.state_hash
            );
        }
    }
    Ok(())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    match Cli::parse().command {
        Command::Simulate {
            scene,
            frames,
            output,
        } => {
            let (mut app, entity, parsed) = bench::load(&scene)?;
            let start = Instant::now();
            let mut times = bench::run(&mut app, entity, frames)?;
            let total = start.elapsed().as_secs_f64() * 1e3;
            let state = app
                .world()
                .get::<ClothState>(entity)
                .ok_or("cloth was not built")?;
            let positions: Vec<[f32; 3]> = state.positions().iter().map(|p| p.to_array()).collect();
            let json = serde_json::json!({
                "scene": scene.display().to_string(),
                "frames": frames,
                "dt": parsed.dt,
                "time_s": frames as f64 * parsed.dt as f64,
                "particles": positions.len(),
                "positions": positions,
                "timing": { "total_ms": total, "per_frame": bench::stats(&mut times) },
            });
            std::fs::write(&output, serde_json::to_string_pretty(&json)?)?;
            eprintln!(
                "wrote {} positions after {frames} frames to {}",
                positions.len(),
                output.display()
            );
        }
        Command::Subdivide {
            input,
            level,
            rule,
            boundary,
            output,
        } => subdivide(&input, level, rule, boundary, &output)?,
        Command::Analysis => analysis()?,
        Command::Bench {
            scene,
            frames,
            copies,
            threads,
            single_threaded,
            full_quality,
            first_only,
            budget_ms,
            warm_up,
            level,
        } => {
            if let Some(threads) = threads {
                // Before the App exists, so that its TaskPoolPlugin finds this pool.
                bevy::tasks::ComputeTaskPool::get_or_init(|| {
                    bevy::tasks::TaskPoolBuilder::new()
                        .num_threads(threads.max(1))
                        .build()
                });
            }
            let line = bench::bench_scene(
                &scene,
                frames,
                bench::Variant {
                    copies,
                    single_threaded,
                    full_quality,
                    first_only,
                    budget_ms,
                    warm_up,
                    // One of the names the parser accepted.
                    level: level.and_then(|l| LodLevel::ALL.into_iter().find(|k| k.name() == l)),
                },
            )?;
            println!("{line}");
        }
        Command::Stress {
            cases,
            seed,
            from,
            integrators,
            trace,
            self_collision,
            air,
            tearing,
            tolerance,
            threads,
        } => {
            let mut chosen = Vec::new();
            for name in &integrators {
                chosen.push(match name.as_str() {
                    "auto" => Integrator::Auto,
                    "xpbd" => Integrator::Xpbd,
                    "symplectic-euler" => Integrator::SymplecticEuler,
                    "verlet" => Integrator::Verlet,
                    "implicit-euler" => Integrator::ImplicitEuler,
                    other => return Err(format!("unknown integrator {other:?}").into()),
                });
            }
            let threads = threads.unwrap_or_else(|| {
                std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get)
            });
            if !stress::run(
                from..from + cases,
                seed,
                &chosen,
                stress::Variants {
                    self_collision,
                    air,
                    tearing,
                    tolerance,
                    trace,
                },
                threads,
            ) {
                return Err("stress cases failed (listed above)".into());
            }
        }
        Command::StateHashes {
            cases,
            frames,
            seed,
        } => state_hashes(cases, frames, seed)?,
        Command::Fuzz {
            seed,
            sequences,
            sequence,
            operations,
            valid_only,
        } => {
            let args = fuzz::Args {
                seed,
                sequences,
                sequence,
                operations,
                valid_only,
            };
            if !fuzz::run(&args) {
                return Err("fuzz checks failed (listed above)".into());
            }
        }
        Command::Benchmarks {
            scenes,
            frames,
            runs,
            output,
        } => benchmarks::run(&scenes, frames, runs, &output)?,
        Command::WorkPrecision {
            quick,
            tolerance,
            scenes,
            out,
        } => {
            let mut chosen = Vec::new();
            for name in &scenes {
                match AccuracyScene::ALL.iter().find(|s| s.name() == name) {
                    Some(s) => chosen.push(*s),
                    None => {
                        return Err(format!(
                            "unknown scene {name:?}: expected swing, stiff or curtain"
                        )
                        .into());
                    }
                }
            }
            if chosen.is_empty() {
                chosen = AccuracyScene::ALL.to_vec();
            }
            work_precision::run(quick, tolerance, &chosen, &out)?;
        }
    }
    Ok(())
}
