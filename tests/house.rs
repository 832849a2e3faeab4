//! Guards of the solver's house, read from its behaviour and its source:
//!
//! - bit for bit: the final state of every preset scene (through the whole plugin) and of the
//!   first stress cases of every integrator, hashed and compared with
//!   `tests/data/state_hashes.txt`. A refactoring must leave every line unchanged; a deliberate
//!   change of behaviour regenerates the file with `UPDATE_STATE_HASHES=1 cargo test --test
//!   house` and says why in its commit. `cloth_cli state-hashes` prints the same lines for larger
//!   runs;
//! - layering: every module of `src/sim` uses only the modules listed before it in [`LAYERS`]
//!   (the order `sim`'s module docs give), so no two import each other; and nothing in `src/sim`
//!   reaches the ECS, the harness or the render layer;
//! - one-way imports crate-wide: at every level of the module tree, no two sibling modules use
//!   each other, directly or through a third (the source reader is `house/source.rs`);
//! - size: no source file is over [`MAX_LINES`] lines, its unit tests included.

use bevy_cloth::harness::scene_state_hash;
use bevy_cloth::harness::stress::{StressLimits, draw_case, run_case};
use bevy_cloth::sim::Integrator;
use source::{Crate, cycles, files, library_text};
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

#[path = "house/source.rs"]
mod source;

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

/// The top-level modules of `src/sim`, bottom up: each may use only those before it.
const LAYERS: [&str; 13] = [
    "soa",
    "simd",
    "runs",
    "model",
    "settings",
    "forces",
    "state",
    "pressure",
    "contact",
    "aero",
    "wind",
    "integrate",
    "cloth_sim",
];

/// Paths nothing in `src/sim` may name: the ECS layer, the harness, Bevy's ECS, app and assets.
const FORBIDDEN: [&str; 10] = [
    "crate::plugin",
    "crate::components",
    "crate::render",
    "crate::scene",
    "crate::harness",
    "crate::inspector",
    "bevy::ecs",
    "bevy::app",
    "bevy::asset",
    "bevy::prelude",
];

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// For each top-level module of `src/sim`, the other top-level modules its library code names.
fn uses() -> BTreeMap<String, BTreeSet<String>> {
    let krate = Crate::read(root());
    let sim = ["sim".to_string()];
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for child in krate.children(&sim) {
        graph.entry(child).or_default();
    }
    for (from, to) in krate.sibling_uses().keys() {
        if from.len() == 2 && from.starts_with(&sim) {
            graph
                .entry(from[1].clone())
                .or_default()
                .insert(to[1].clone());
        }
    }
    graph
}

#[test]
fn every_solver_module_uses_only_the_layers_below_it() {
    let graph = uses();
    let rank = |m: &str| LAYERS.iter().position(|l| *l == m);
    for module in graph.keys() {
        assert!(
            rank(module).is_some(),
            "src/sim/{module} is not in LAYERS (nor in sim's module docs)"
        );
    }
    let mut edges = 0;
    for (module, targets) in &graph {
        for target in targets {
            edges += 1;
            assert!(
                rank(target) < rank(module),
                "sim::{module} uses sim::{target}, which is not below it"
            );
        }
    }
    // The scan found the imports (an empty graph would pass trivially).
    assert!(edges >= 20, "only {edges} uses found: {graph:?}");
    assert!(graph["cloth_sim"].contains("integrate"));
    assert!(graph["integrate"].contains("contact"));
}

#[test]
fn the_solver_knows_no_ecs_harness_or_renderer() {
    let mut all = Vec::new();
    files(&root().join("src/sim"), &mut all);
    for path in all {
        let text = library_text(&path);
        for forbidden in FORBIDDEN {
            assert!(
                !text.contains(forbidden),
                "{} names {forbidden}",
                path.display()
            );
        }
    }
}

/// The most lines a source file may have, its unit tests included.
const MAX_LINES: usize = 800;

#[test]
fn no_source_file_is_over_800_lines() {
    let mut all = Vec::new();
    for dir in ["src", "tests", "examples", "benches"] {
        files(&root().join(dir), &mut all);
    }
    all.sort();
    let long: Vec<String> = all
        .iter()
        .filter_map(|path| {
            let lines = std::fs::read_to_string(path)
                .expect("source")
                .lines()
                .count();
            let name = path.strip_prefix(root()).unwrap().display();
            (lines > MAX_LINES).then(|| format!("  {name}: {lines} lines"))
        })
        .collect();
    assert!(
        long.is_empty(),
        "{} source files are over {MAX_LINES} lines (split them by concern, tests into a \
         sibling tests.rs or, for integration tests, modules of their own):\n{}",
        long.len(),
        long.join("\n")
    );
}

#[test]
fn no_two_modules_import_each_other() {
    let edges = Crate::read(root()).sibling_uses();
    // The scan found the imports (an empty graph would pass trivially).
    let edge = |a: &str, b: &str| {
        let path = |m: &str| m.split("::").map(String::from).collect::<Vec<_>>();
        edges.contains_key(&(path(a), path(b)))
    };
    assert!(edges.len() >= 50, "only {} uses found", edges.len());
    assert!(edge("plugin", "sim") && edge("sim::cloth_sim", "sim::integrate"));
    assert!(edge("subdivision::obj", "subdivision::error"));
    let cycles = cycles(&edges);
    let mut report = String::new();
    for cycle in &cycles {
        let name = |m: &Vec<String>| m.join("::");
        let names: Vec<String> = cycle.iter().chain(&cycle[..1]).map(name).collect();
        report += &format!("{}\n", names.join(" -> "));
        for (a, b) in cycle.iter().zip(cycle.iter().cycle().skip(1)) {
            let at = &edges[&(a.clone(), b.clone())];
            report += &format!("    {} -> {}: {at}\n", name(a), name(b));
        }
    }
    assert!(
        cycles.is_empty(),
        "import cycles among sibling modules: {} (move what both need into a module below \
         them):\n{report}",
        cycles.len()
    );
}
