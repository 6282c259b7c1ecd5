//! docs/ARCHITECTURE.md's import rules, checked on the source: every `crate::` path each file
//! names (in `use` lines and in code, comments left out) is an edge from its top-level module;
//! no two top-level modules of a crate import each other, even through others, and each
//! "must not import" of the table holds.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Top-level module -> (the module it names, the submodule or item after it) for every
/// `crate::X::Y` in the files under `src`.
fn edges(src: &Path) -> BTreeMap<String, BTreeSet<(String, String)>> {
    let mut out: BTreeMap<String, BTreeSet<(String, String)>> = BTreeMap::new();
    let mut stack = vec![src.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
                continue;
            }
            if path.extension().is_none_or(|x| x != "rs") {
                continue;
            }
            let rel = path.strip_prefix(src).unwrap();
            let first = rel.components().next().unwrap().as_os_str();
            let top = first.to_string_lossy().trim_end_matches(".rs").to_string();
            if top == "lib" || top == "main" {
                continue;
            }
            let text = std::fs::read_to_string(&path).unwrap();
            for line in text.lines().map(str::trim).filter(|l| !l.starts_with("//")) {
                let mut rest = line;
                while let Some(at) = rest.find("crate::") {
                    let after = &rest[at + "crate::".len()..];
                    let word = |s: &str| -> String {
                        s.chars()
                            .take_while(|c| c.is_alphanumeric() || *c == '_')
                            .collect()
                    };
                    let module = word(after);
                    let next = after[module.len()..]
                        .strip_prefix("::")
                        .map(word)
                        .unwrap_or_default();
                    // `savsim_core::` and `$crate::` are not this crate's `crate::`.
                    let before = &rest[..at];
                    if !before.ends_with('_') && !before.ends_with('$') && module != top {
                        out.entry(top.clone()).or_default().insert((module, next));
                    }
                    rest = after;
                }
            }
        }
    }
    out
}

/// The modules `from` reaches through the edges (itself left out unless it is on a cycle).
fn reach(graph: &BTreeMap<String, BTreeSet<(String, String)>>, from: &str) -> BTreeSet<String> {
    let mut seen = BTreeSet::new();
    let mut todo = vec![from.to_string()];
    while let Some(m) = todo.pop() {
        for (to, _) in graph.get(&m).into_iter().flatten() {
            if seen.insert(to.clone()) {
                todo.push(to.clone());
            }
        }
    }
    seen
}

fn no_cycles(graph: &BTreeMap<String, BTreeSet<(String, String)>>) {
    for m in graph.keys() {
        assert!(
            !reach(graph, m).contains(m),
            "{m} reaches itself through the modules it imports: {graph:?}"
        );
    }
}

/// `module` names none of `forbidden` (a module, or `module::item` for one part of it).
fn must_not(
    graph: &BTreeMap<String, BTreeSet<(String, String)>>,
    module: &str,
    forbidden: &[&str],
) {
    for (to, next) in graph.get(module).into_iter().flatten() {
        for f in forbidden {
            let hit = match f.split_once("::") {
                Some((m, item)) => to == m && next == item,
                None => to == f,
            };
            assert!(
                !hit,
                "{module} imports {to}::{next}, which ARCHITECTURE.md forbids"
            );
        }
    }
}

/// `module` names no other module of its crate.
fn imports_nothing(graph: &BTreeMap<String, BTreeSet<(String, String)>>, module: &str) {
    let edges = graph.get(module).cloned().unwrap_or_default();
    assert!(
        edges.is_empty(),
        "{module} imports {edges:?}; ARCHITECTURE.md says it imports no other module"
    );
}

/// `module` names of `allowed_module` only the listed submodules.
fn only(
    graph: &BTreeMap<String, BTreeSet<(String, String)>>,
    module: &str,
    allowed_module: &str,
    items: &[&str],
) {
    for (to, next) in graph.get(module).into_iter().flatten() {
        if to == allowed_module {
            assert!(
                items.contains(&next.as_str()),
                "{module} imports {to}::{next}; of {to} it may import only {items:?}"
            );
        }
    }
}

#[test]
fn the_core_imports_downward_only() {
    let core = edges(&crate::common::root().join("crates/savsim-core/src"));
    assert!(core.contains_key("pipeline") && core.contains_key("collision"));
    no_cycles(&core);
    imports_nothing(&core, "bounds");
    must_not(
        &core,
        "sensors",
        &[
            "geo",
            "scene",
            "world",
            "collision",
            "reference",
            "daa",
            "pipeline",
        ],
    );
    must_not(
        &core,
        "geo",
        &[
            "scene",
            "world",
            "collision",
            "reference",
            "daa",
            "pipeline",
        ],
    );
    must_not(
        &core,
        "scene",
        &["world", "collision", "reference", "daa", "pipeline"],
    );
    must_not(
        &core,
        "world",
        &["collision", "reference", "daa", "pipeline"],
    );
    must_not(&core, "collision", &["reference", "pipeline"]);
    only(
        &core,
        "reference",
        "collision",
        &["bodies", "config", "events"],
    );
    must_not(&core, "reference", &["pipeline", "daa"]);
    only(&core, "daa", "collision", &["approach"]);
    must_not(&core, "daa", &["reference", "pipeline"]);
}

#[test]
fn savsim_imports_downward_only() {
    let app = edges(&crate::common::root().join("src"));
    assert!(app.contains_key("study") && app.contains_key("live"));
    no_cycles(&app);
    let wiring = [
        "app", "live", "session", "study", "batch", "bench", "viz", "runs", "replay",
    ];
    imports_nothing(&app, "files");
    for leaf in ["scene", "costs", "bundled"] {
        must_not(&app, leaf, &wiring);
    }
    must_not(&app, "ingest", &wiring);
    must_not(&app, "feed", &wiring);
    must_not(
        &app,
        "session",
        &["app", "live", "study", "batch", "bench", "runs", "replay"],
    );
    must_not(&app, "live", &["app", "study", "batch", "bench", "runs"]);
    must_not(&app, "replay", &["app", "live", "study", "batch", "bench"]);
    must_not(&app, "runs", &["app", "live", "study", "batch", "bench"]);
    must_not(&app, "batch", &["app", "live", "study", "bench", "viz"]);
    must_not(&app, "study", &["app", "bench", "viz"]);
    must_not(&app, "bench", &["app", "live", "study", "batch", "viz"]);
    must_not(
        &app,
        "viz",
        &["app", "live", "study", "batch", "bench", "session"],
    );
    must_not(
        &app,
        "error",
        &["ingest", "session", "live", "study", "batch", "app"],
    );
}
