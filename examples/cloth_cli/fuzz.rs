//! `cloth_cli fuzz`: runs the ECS edit fuzzer of `bevy_cloth::harness::fuzz` (random spawns,
//! edits, asset swaps and despawns on cloths of every kind, checked after every step) and prints
//! its report; or, with `--sequence`, reruns one sequence and traces every operation and step.

use std::time::{Instant, SystemTime, UNIX_EPOCH};

use bevy_cloth::harness::fuzz::{FuzzOptions, run_edit_fuzz, run_fuzz_sequence};

/// What to run.
pub struct Args {
    /// The seed; a fresh one from the clock when not given.
    pub seed: Option<u64>,
    /// Sequences to run.
    pub sequences: usize,
    /// Rerun only this sequence, traced.
    pub sequence: Option<usize>,
    /// Most operations per sequence.
    pub operations: usize,
    /// Valid cloth components and meshes only.
    pub valid_only: bool,
}

/// Runs the fuzzer; returns whether every check passed.
pub fn run(args: &Args) -> bool {
    let seed = args.seed.unwrap_or_else(|| {
        let now = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as u64);
        println!("seed {now} (from the clock)");
        now
    });
    let options = FuzzOptions {
        max_operations: args.operations.max(1),
        invalid_edits: !args.valid_only,
        ..FuzzOptions::default()
    };
    if let Some(index) = args.sequence {
        let outcome = run_fuzz_sequence(seed, index, &options, &mut |line| println!("{line}"));
        println!(
            "{} operations, {} steps, {} of {} expected rejections reported, {} failure(s)",
            outcome.operations,
            outcome.steps,
            outcome.rejections.1,
            outcome.rejections.0,
            outcome.failures.len()
        );
        return outcome.failures.is_empty();
    }
    let start = Instant::now();
    let report = run_edit_fuzz(seed, args.sequences, &options);
    let elapsed = start.elapsed().as_secs_f64();
    println!("{report}");
    println!(
        "{elapsed:.1} s ({:.2} s per 100 sequences); rerun one with --seed {seed} --sequence N",
        elapsed * 100.0 / args.sequences.max(1) as f64
    );
    report.is_clean()
}
