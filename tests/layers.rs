//! The solver's layering, read from its source: every module of `src/sim` uses only the modules
//! listed before it in [`LAYERS`] (the order `sim`'s module docs give), so no two import each
//! other; and nothing in `src/sim` reaches the ECS, the harness or the render layer.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

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
