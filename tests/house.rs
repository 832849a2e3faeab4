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
//!   reaches the ECS, the harness or the render layer.

use bevy_cloth::harness::scene_state_hash;
use bevy_cloth::harness::stress::{StressLimits, draw_case, run_case};
use bevy_cloth::sim::Integrator;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

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
const LAYERS: [&str; 12] = [
    "soa",
    "simd",
    "runs",
    "model",
    "settings",
    "forces",
    "state",
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

fn sim_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src/sim")
}

/// Every `.rs` file below `dir`.
fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("src/sim is readable") {
        let path = entry.expect("a directory entry").path();
        if path.is_dir() {
            files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The code of `path`: without its unit tests (a `tests.rs` file, or a `mod tests` at the end)
/// and without comments (a doc link is no dependency).
fn library_text(path: &Path) -> String {
    if path.file_name().is_some_and(|n| n == "tests.rs") {
        return String::new();
    }
    let text = std::fs::read_to_string(path).expect("source is readable");
    let code = match text.find("#[cfg(test)]\nmod tests {") {
        Some(i) => &text[..i],
        None => &text,
    };
    code.lines()
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The names a path continues with after `prefix` at each place it occurs: `a` for `prefix a::…`
/// or `prefix a;`, and each of `a`, `b` for `prefix {a, b::c}`.
fn names_after(text: &str, prefix: &str) -> Vec<String> {
    let mut out = Vec::new();
    for (i, _) in text.match_indices(prefix) {
        let before = text[..i].chars().next_back();
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':') {
            continue;
        }
        let rest = &text[i + prefix.len()..];
        if let Some(group) = rest.strip_prefix('{') {
            let group = &group[..group.find('}').unwrap_or(group.len())];
            out.extend(group.split(',').map(|s| first_segment(s.trim())));
        } else {
            out.push(first_segment(rest));
        }
    }
    out.retain(|n| !n.is_empty());
    out
}

fn first_segment(path: &str) -> String {
    path.chars()
        .take_while(|c| c.is_alphanumeric() || *c == '_')
        .collect()
}

/// `src/sim/mod.rs`'s re-exports: item name → the module it comes from.
fn reexports() -> BTreeMap<String, String> {
    let text = std::fs::read_to_string(sim_dir().join("mod.rs")).expect("sim/mod.rs");
    let mut map = BTreeMap::new();
    for (i, _) in text.match_indices("pub use ") {
        let rest = &text[i + "pub use ".len()..];
        let statement = &rest[..rest.find(';').unwrap_or(rest.len())];
        let module = first_segment(statement);
        let items = statement[module.len()..].trim_start_matches("::");
        let items = items.trim_start_matches('{').trim_end_matches('}');
        for item in items.split(',') {
            let item = item.trim().rsplit("::").next().unwrap_or("").trim();
            if !item.is_empty() {
                map.insert(item.to_string(), module.clone());
            }
        }
    }
    map
}

/// For each top-level module of `src/sim`, the other top-level modules its library code names.
fn uses() -> BTreeMap<String, BTreeSet<String>> {
    let root = sim_dir();
    let reexports = reexports();
    let mut all = Vec::new();
    files(&root, &mut all);
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for path in all {
        let relative = path.strip_prefix(&root).unwrap();
        let parts: Vec<String> = relative
            .iter()
            .map(|p| p.to_string_lossy().trim_end_matches(".rs").to_string())
            .collect();
        if parts == ["mod"] {
            continue;
        }
        let top = parts[0].clone();
        let text = library_text(&path);
        let mut named: Vec<String> = names_after(&text, "crate::sim::");
        // `super::` of a file directly in `src/sim` (or of a `mod.rs` one folder down) is `sim`;
        // deeper files reach `sim` through `super::super::`.
        let depth = parts.len() - usize::from(parts.last().is_some_and(|p| p == "mod"));
        let to_sim = "super::".repeat(depth);
        named.extend(names_after(&text, &to_sim));
        let targets = graph.entry(top.clone()).or_default();
        for name in named {
            let module = if LAYERS.contains(&name.as_str()) {
                name
            } else if let Some(module) = reexports.get(&name) {
                module.clone()
            } else {
                continue;
            };
            if module != top {
                targets.insert(module);
            }
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
    files(&sim_dir(), &mut all);
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
