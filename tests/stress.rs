//! The stress suite (see `bevy_cloth::harness::stress`) at CI size: a few hundred seeded cases over
//! every integrator, and more for the default one. `cloth_cli stress` runs as many as you like.

use bevy_cloth::harness::stress::{StressLimits, StressOutcome, draw_case, run_case};
use bevy_cloth::sim::Integrator;

const SEED: u64 = 0x5EED_C10A;

/// Smaller cloths and shorter runs than `cloth_cli stress`, for a debug build.
fn limits() -> StressLimits {
    StressLimits {
        max_side: 64,
        max_work: 1.5e6,
        duration: 0.25,
    }
}

fn run(integrators: &[Integrator], cases: std::ops::Range<u64>) {
    let limits = limits();
    let mut failures = Vec::new();
    let (mut stable, mut detected) = (0, 0);
    for index in cases {
        let case = draw_case(SEED, index, integrators, &limits);
        let result = run_case(&case, &limits);
        match &result.outcome {
            StressOutcome::Stable => stable += 1,
            StressOutcome::DetectedUnstable(_) => detected += 1,
            StressOutcome::Failure(why) => failures.push(format!("case {index}: {why}\n{case:?}")),
        }
    }
    println!(
        "{stable} stable, {detected} stopped as unstable, {} failures",
        failures.len()
    );
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

#[test]
fn every_integrator_survives_200_stress_cases() {
    run(&Integrator::ALL, 0..200);
}

#[test]
fn the_default_integrator_survives_200_more() {
    run(&[Integrator::default()], 1000..1200);
}
