//! The module graph of the library: each stage (a folder of `src/`) uses only the stages
//! before it, and no two modules use each other, directly or through others. Read from the
//! source: every `crate::a::b` path outside comments and test modules is an edge.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The stages in data-flow order; a stage may use those before it.
const STAGES: [&str; 7] = [
    "input", "mesh", "model", "force", "step", "output", "analysis",
];
/// Modules every stage may use.
const SHARED: [&str; 3] = ["error", "lanes", "parallel"];

fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            sources(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The code of a file without comments and without its `#[cfg(test)]` module (tests may use
/// anything; they sit at the end of a file).
fn code(text: &str) -> String {
    let text = text.split("#[cfg(test)]").next().unwrap();
    text.lines()
        .map(|l| l.split("//").next().unwrap())
        .collect::<Vec<_>>()
        .join("\n")
}

/// The module a file defines: `model` for `model/mod.rs`, `force::contact` for
/// `force/contact/overlap.rs` (a module's private children are the module).
fn node_of(src: &Path, file: &Path) -> String {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let parts: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .filter(|p| p != "mod")
        .collect();
    parts.into_iter().take(2).collect::<Vec<_>>().join("::")
}

/// The module a path `crate::a::b::...` names, at most two levels deep.
fn node_of_path(src: &Path, segments: &[&str]) -> String {
    let first = segments[0];
    match segments.get(1) {
        Some(second)
            if src.join(first).join(format!("{second}.rs")).exists()
                || src.join(first).join(second).is_dir() =>
        {
            format!("{first}::{second}")
        }
        _ => first.to_string(),
    }
}

/// The paths of a `use` group's top-level items, from the text after its `{`: `b`, `c::d`,
/// `self` (nested groups keep their prefix only).
fn group_items(text: &str) -> Vec<String> {
    let mut depth = 0;
    let mut items = vec![String::new()];
    for c in text.chars() {
        match c {
            '{' => depth += 1,
            '}' if depth == 0 => break,
            '}' => depth -= 1,
            ',' if depth == 0 => items.push(String::new()),
            _ if depth == 0 => items.last_mut().unwrap().push(c),
            _ => {}
        }
    }
    items
        .iter()
        .map(|i| {
            i.trim()
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_' || *c == ':')
                .collect()
        })
        .filter(|i: &String| !i.is_empty())
        .collect()
}

fn graph() -> BTreeMap<String, BTreeSet<String>> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    sources(&src, &mut files);
    let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for file in files {
        if file.ends_with("main.rs") || file.ends_with("lib.rs") {
            continue;
        }
        let from = node_of(&src, &file);
        let code = code(&std::fs::read_to_string(&file).unwrap());
        let targets = edges.entry(from.clone()).or_default();
        for (i, _) in code.match_indices("crate::") {
            let rest = &code[i + "crate::".len()..];
            let path: String = rest
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_' || *c == ':')
                .collect();
            let prefix: Vec<&str> = path.split("::").filter(|s| !s.is_empty()).collect();
            // `crate::a::{b, c::d, self}` names `a::b`, `a::c` and `a`.
            let group = rest[path.len()..]
                .strip_prefix('{')
                .map_or_else(Vec::new, group_items);
            let paths: Vec<Vec<&str>> = if group.is_empty() {
                vec![prefix]
            } else {
                group
                    .iter()
                    .map(|item| {
                        let mut p = prefix.clone();
                        p.extend(item.split("::").filter(|s| !s.is_empty() && *s != "self"));
                        p
                    })
                    .collect()
            };
            for segments in paths.iter().filter(|s| !s.is_empty()) {
                let to = node_of_path(&src, segments);
                if to != from {
                    targets.insert(to);
                }
            }
        }
    }
    edges
}

fn stage(node: &str) -> &str {
    node.split("::").next().unwrap()
}

#[test]
fn every_stage_uses_only_the_stages_before_it() {
    let mut wrong = Vec::new();
    for (from, targets) in graph() {
        let Some(rank) = STAGES.iter().position(|s| *s == stage(&from)) else {
            assert!(
                SHARED.contains(&from.as_str()),
                "{from}: a module outside the stages"
            );
            continue;
        };
        for to in targets {
            match STAGES.iter().position(|s| *s == stage(&to)) {
                Some(r) if r > rank => wrong.push(format!("{from} -> {to}")),
                Some(_) => {}
                None => assert!(
                    SHARED.contains(&stage(&to)),
                    "{from} uses {to}, outside the stages"
                ),
            }
        }
    }
    assert!(wrong.is_empty(), "later stages used: {wrong:#?}");
}

#[test]
fn the_module_graph_has_no_cycle() {
    let g = graph();
    // Depth-first search; a module met again while on the path closes a cycle.
    fn visit(
        g: &BTreeMap<String, BTreeSet<String>>,
        n: &str,
        path: &mut Vec<String>,
        done: &mut BTreeSet<String>,
    ) -> Option<Vec<String>> {
        if let Some(k) = path.iter().position(|p| p == n) {
            let mut cycle = path[k..].to_vec();
            cycle.push(n.to_string());
            return Some(cycle);
        }
        if done.contains(n) {
            return None;
        }
        path.push(n.to_string());
        for m in g.get(n).into_iter().flatten() {
            if let Some(c) = visit(g, m, path, done) {
                return Some(c);
            }
        }
        path.pop();
        done.insert(n.to_string());
        None
    }
    let mut done = BTreeSet::new();
    for n in g.keys() {
        if let Some(cycle) = visit(&g, n, &mut Vec::new(), &mut done) {
            panic!("a cycle of modules: {}", cycle.join(" -> "));
        }
    }
    // The graph is not empty: the check would pass on nothing.
    assert!(g.len() > 20 && g.values().map(BTreeSet::len).sum::<usize>() > 40);
}
