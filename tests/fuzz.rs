//! The ECS edit fuzzer (`bevy_cloth::harness::fuzz`) over fixed seeds: random sequences of
//! spawns, despawns, valid and invalid edits, source mesh swaps and anchor, joint, collider,
//! wind (and avian body) changes on cloths of every kind, checked after every step: no panic,
//! finite values, running cloths kept running from where they were, every rejection reported.
//! A failure prints the report, with the seed and sequence to rerun each kind of failure
//! (`cloth_cli fuzz --seed S --sequence N`). Headless.

use bevy_cloth::harness::fuzz::{FuzzOptions, run_edit_fuzz, run_fuzz_sequence};

/// The seed of the suite.
const SEED: u64 = 1;

#[test]
fn random_edits_never_panic_lose_a_cloth_or_go_unreported() {
    const SEQUENCES: usize = 400;
    let report = run_edit_fuzz(SEED, SEQUENCES, &FuzzOptions::default());
    assert_eq!(report.sequences, SEQUENCES);
    // The fuzzer reaches the rejections it is there to check.
    assert!(report.rejections_expected > SEQUENCES / 2, "{report}");
    assert!(report.is_clean(), "{report}");
}

#[test]
fn random_valid_edits_keep_every_cloth_running() {
    const SEQUENCES: usize = 100;
    let options = FuzzOptions {
        invalid_edits: false,
        ..FuzzOptions::default()
    };
    let report = run_edit_fuzz(SEED + 1, SEQUENCES, &options);
    assert_eq!(report.sequences, SEQUENCES);
    assert_eq!(report.rejections_expected, 0, "{report}");
    assert!(report.is_clean(), "{report}");
}

#[test]
fn a_sequence_is_the_same_every_time_it_runs() {
    let trace = |index| {
        let mut lines = Vec::new();
        let outcome = run_fuzz_sequence(SEED, index, &FuzzOptions::default(), &mut |l| {
            lines.push(l.to_string())
        });
        (lines, outcome)
    };
    for index in [0, 1] {
        let (a, b) = (trace(index), trace(index));
        assert!(a.0.len() > 3, "{:?}", a.0);
        assert_eq!(a, b, "sequence {index}");
    }
}
