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
    must_not(&core, "collision", &["daa", "reference", "pipeline"]);
    only(
        &core,
        "reference",
        "collision",
        &["bodies", "config", "events"],
    );
    must_not(&core, "reference", &["pipeline", "daa"]);
    only(&core, "daa", "collision", &["bodies"]);
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
    // The MAVLink codec is below the two ways bytes come in; neither knows the other.
    let inputs = ["codec", "logs", "links"];
    must_not(&app, "codec", &[&inputs[1..], &wiring[..]].concat());
    must_not(&app, "logs", &[&["links"][..], &wiring[..]].concat());
    must_not(&app, "links", &[&["logs"][..], &wiring[..]].concat());
    for module in ["codec", "logs", "links"] {
        must_not(&app, module, &["feed", "observe", "viz", "session"]);
    }
    must_not(&app, "feed", &[&inputs[1..], &wiring[..]].concat());
    must_not(
        &app,
        "session",
        &[
            "app", "live", "study", "batch", "bench", "runs", "replay", "viz", "links",
        ],
    );
    // What a run shows, between the session and the viewer: neither is below it.
    must_not(&app, "observe", &[&inputs[..], &wiring[..]].concat());
    must_not(&app, "live", &["app", "study", "batch", "bench", "runs"]);
    must_not(&app, "replay", &["app", "live", "study", "batch", "bench"]);
    must_not(&app, "runs", &["app", "live", "study", "batch", "bench"]);
    must_not(&app, "batch", &["app", "live", "study", "bench", "viz"]);
    must_not(&app, "study", &["app", "bench", "viz", "batch"]);
    must_not(&app, "bench", &["app", "live", "study", "batch", "viz"]);
    must_not(
        &app,
        "viz",
        &[&inputs[..], &["feed"][..], &wiring[..]].concat(),
    );
    must_not(&app, "error", &[&inputs[..], &wiring[..]].concat());
    // A planner's link is below the loop that asks it.
    must_not(
        &app,
        "companion",
        &[&["lockstep", "sim"][..], &wiring[..]].concat(),
    );
}

/// Every file of the crate under `src` as its module path (`a/b.rs` and `a/b/mod.rs` are
/// `["a", "b"]`; `lib.rs` and `main.rs` are left out), with its text before its unit tests.
fn files(src: &Path) -> BTreeMap<Vec<String>, String> {
    let mut out = BTreeMap::new();
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
            let rel = path.strip_prefix(src).unwrap().with_extension("");
            let mut module: Vec<String> = rel
                .components()
                .map(|c| c.as_os_str().to_string_lossy().into_owned())
                .collect();
            if module.last().is_some_and(|m| m == "mod") {
                module.pop();
            }
            if module == ["lib"] || module == ["main"] {
                continue;
            }
            let text = std::fs::read_to_string(&path).unwrap();
            let text = text
                .split("#[cfg(test)]\nmod tests")
                .next()
                .unwrap()
                .to_string();
            out.insert(module, text);
        }
    }
    out
}

/// The files each file names: through `crate::`, `super::` and `self::` paths, and a folder's
/// module through the `child::` paths of the modules it declares; a path stands for the
/// longest file it starts with. A file naming its own folders' modules (a child using what
/// its parent defines) is left out: a module and its children are one room.
fn file_edges(
    files: &BTreeMap<Vec<String>, String>,
) -> BTreeMap<Vec<String>, BTreeSet<Vec<String>>> {
    let word = |s: &str| -> String {
        s.chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect()
    };
    let file_of = |path: &[String]| -> Option<Vec<String>> {
        (1..=path.len())
            .rev()
            .map(|k| path[..k].to_vec())
            .find(|p| files.contains_key(p))
    };
    let mut out: BTreeMap<Vec<String>, BTreeSet<Vec<String>>> = BTreeMap::new();
    for (module, text) in files {
        let children: Vec<String> = text
            .lines()
            .filter_map(|l| {
                let l = l
                    .trim()
                    .trim_start_matches("pub(crate) ")
                    .trim_start_matches("pub ");
                l.strip_prefix("mod ")?
                    .strip_suffix(';')
                    .map(str::to_string)
            })
            .collect();
        let mut named = |path: Vec<String>| {
            if let Some(target) = file_of(&path) {
                let ancestor = target.len() < module.len() && module.starts_with(&target);
                if &target != module && !ancestor {
                    out.entry(module.clone()).or_default().insert(target);
                }
            }
        };
        for line in text.lines() {
            let line = line.split("//").next().unwrap_or("");
            let mut rest = line;
            while let Some(at) = rest.find("::") {
                let before = &rest[..at];
                let head: String = before
                    .chars()
                    .rev()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect::<Vec<char>>()
                    .into_iter()
                    .rev()
                    .collect();
                let prefix = &before[..before.len() - head.len()];
                let free = !(prefix.ends_with(':') || prefix.ends_with('$'));
                let mut tail = Vec::new();
                let mut after = &rest[at..];
                while let Some(next) = after.strip_prefix("::") {
                    let w = word(next);
                    if w.is_empty() {
                        break;
                    }
                    after = &next[w.len()..];
                    tail.push(w);
                }
                if free {
                    match head.as_str() {
                        "crate" => named(tail.clone()),
                        "super" => named([&module[..module.len() - 1], &tail[..]].concat()),
                        "self" => named([&module[..], &tail[..]].concat()),
                        h if children.iter().any(|c| c == h) => {
                            named([&module[..], &[h.to_string()], &tail[..]].concat())
                        }
                        _ => {}
                    }
                }
                rest = &rest[at + 2..];
            }
        }
    }
    out
}

/// The circles of files (each a file list that import each other in a loop), found by
/// Tarjan's strongly connected components.
fn circles(edges: &BTreeMap<Vec<String>, BTreeSet<Vec<String>>>) -> Vec<Vec<String>> {
    struct Walk<'e> {
        edges: &'e BTreeMap<Vec<String>, BTreeSet<Vec<String>>>,
        index: BTreeMap<Vec<String>, (usize, usize)>,
        stack: Vec<Vec<String>>,
        found: Vec<Vec<String>>,
    }
    fn visit(w: &mut Walk<'_>, v: &Vec<String>) {
        let n = w.index.len();
        w.index.insert(v.clone(), (n, n));
        w.stack.push(v.clone());
        for to in w.edges.get(v).into_iter().flatten() {
            if !w.index.contains_key(to) {
                visit(w, to);
                let low = w.index[to].1.min(w.index[v].1);
                w.index.get_mut(v).unwrap().1 = low;
            } else if w.stack.contains(to) {
                let low = w.index[to].0.min(w.index[v].1);
                w.index.get_mut(v).unwrap().1 = low;
            }
        }
        if w.index[v].0 == w.index[v].1 {
            let mut circle = Vec::new();
            while let Some(top) = w.stack.pop() {
                circle.push(top.join("/"));
                if &top == v {
                    break;
                }
            }
            if circle.len() > 1 {
                w.found.push(circle);
            }
        }
    }
    let mut w = Walk {
        edges,
        index: BTreeMap::new(),
        stack: Vec::new(),
        found: Vec::new(),
    };
    for v in edges.keys() {
        if !w.index.contains_key(v) {
            visit(&mut w, v);
        }
    }
    w.found
}

/// No two files of either crate import each other, even through others (a module and its
/// own children aside): each file stands on the ones it uses.
#[test]
fn no_file_imports_itself_through_others() {
    for src in ["src", "crates/savsim-core/src"] {
        let files = files(&crate::common::root().join(src));
        let edges = file_edges(&files);
        assert!(
            edges.len() > 20,
            "{src}: {} files import others",
            edges.len()
        );
        let found = circles(&edges);
        assert!(found.is_empty(), "{src}: circles of files: {found:?}");
    }
}
