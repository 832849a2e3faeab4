//! Bit-for-bit regression guard: the final state of every preset scene (through the whole plugin)
//! and of the first stress cases of every integrator, hashed and compared with
//! `tests/data/state_hashes.txt`. A refactoring must leave every line unchanged; a deliberate
//! change of behaviour regenerates the file with `UPDATE_STATE_HASHES=1 cargo test --test
//! state_hashes` and says why in its commit. `cloth_cli state-hashes` prints the same lines for
//! larger runs.

use bevy_cloth::harness::scene_state_hash;
use bevy_cloth::harness::stress::{StressLimits, draw_case, run_case};
use bevy_cloth::sim::Integrator;

const FRAMES: u32 = 60;
const CASES: u64 = 40;
const SEED: u64 = 0x5EED_C10A;
const GOLDEN: &str = "tests/data/state_hashes.txt";

fn lines() -> Vec<String> {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut scenes: Vec<_> = std::fs::read_dir(root.join("assets/scenes"))
        .expect("assets/scenes")
        .map(|e| e.expect("scene entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "ron"))
        .collect();
    scenes.sort();
    let mut out = Vec::new();
    for path in scenes {
        let hash = scene_state_hash(&path, FRAMES).expect("preset scene runs");
        let name = path.file_name().unwrap().to_string_lossy();
        out.push(format!("scene {name} {FRAMES} {hash:016x}"));
    }
    let limits = StressLimits {
        max_side: 64,
        max_work: 1.5e6,
        duration: 0.25,
    };
    for integrator in Integrator::CHOICES {
        for index in 0..CASES {
            let r = run_case(&draw_case(SEED, index, &[integrator], &limits), &limits);
            let name = integrator.name().replace(' ', "-");
            out.push(format!(
                "stress {name} {index} {} {:016x}",
                r.steps_run, r.state_hash
            ));
        }
    }
    out
}

#[test]
fn final_states_match_the_recorded_hashes() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(GOLDEN);
    let now = lines();
    if std::env::var_os("UPDATE_STATE_HASHES").is_some() {
        std::fs::write(&path, now.join("\n") + "\n").expect("write the hashes");
        return;
    }
    let recorded = std::fs::read_to_string(&path).expect("tests/data/state_hashes.txt");
    let recorded: Vec<&str> = recorded.lines().collect();
    let differ: Vec<String> = now
        .iter()
        .zip(&recorded)
        .filter(|(a, b)| a != *b)
        .map(|(a, b)| format!("now {a}\nwas {b}"))
        .collect();
    assert_eq!(now.len(), recorded.len(), "number of hashed runs changed");
    assert!(
        differ.is_empty(),
        "{} of {} runs changed:\n{}",
        differ.len(),
        now.len(),
        differ.join("\n")
    );
}
