//! The layering rules of docs/ARCHITECTURE.md, checked on the source text:
//! no two files of one module import each other, even through others (the
//! graph of `super::file` references between sibling files is acyclic), and
//! lower layers never name upper ones.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The text of a file without its `#[cfg(test)]` module (tests may use anything).
fn non_test_text(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap();
    match text.find("#[cfg(test)]") {
        Some(at) => text[..at].to_owned(),
        None => text,
    }
}

#[test]
fn sibling_files_import_each_other_without_cycles() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    // Directory → (file stem → sibling stems it names through `super::`).
    let mut modules: BTreeMap<PathBuf, BTreeMap<String, BTreeSet<String>>> = BTreeMap::new();
    for path in &files {
        let stem = path.file_stem().unwrap().to_string_lossy().into_owned();
        if stem == "mod" || stem == "lib" || stem == "main" || stem == "tests" {
            continue;
        }
        let dir = path.parent().unwrap().to_owned();
        let siblings: BTreeSet<String> = std::fs::read_dir(&dir)
            .unwrap()
            .filter_map(|e| {
                let p = e.unwrap().path();
                let name = p.file_stem()?.to_string_lossy().into_owned();
                (name != "mod").then_some(name)
            })
            .collect();
        let text = non_test_text(path);
        let used: BTreeSet<String> = text
            .match_indices("super::")
            .filter_map(|(at, _)| {
                let rest = &text[at + "super::".len()..];
                let name: String = rest
                    .chars()
                    .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                    .collect();
                (siblings.contains(&name) && name != stem).then_some(name)
            })
            .collect();
        modules.entry(dir).or_default().insert(stem, used);
    }
    for (dir, graph) in &modules {
        // Depth-first search for a back edge.
        fn visit(
            node: &str,
            graph: &BTreeMap<String, BTreeSet<String>>,
            state: &mut BTreeMap<String, u8>,
            path: &mut Vec<String>,
        ) -> Option<Vec<String>> {
            match state.get(node) {
                Some(2) => return None,
                Some(1) => {
                    path.push(node.to_owned());
                    return Some(path.clone());
                }
                _ => {}
            }
            state.insert(node.to_owned(), 1);
            path.push(node.to_owned());
            for next in graph.get(node).into_iter().flatten() {
                if let Some(cycle) = visit(next, graph, state, path) {
                    return Some(cycle);
                }
            }
            path.pop();
            state.insert(node.to_owned(), 2);
            None
        }
        let mut state = BTreeMap::new();
        for node in graph.keys() {
            let cycle = visit(node, graph, &mut state, &mut Vec::new());
            assert!(
                cycle.is_none(),
                "{}: import cycle {:?}",
                dir.display(),
                cycle.unwrap()
            );
        }
    }
}

#[test]
fn lower_layers_never_name_upper_ones() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    // Each layer and the modules above it that it must not name.
    let rules: [(&str, &[&str]); 7] = [
        (
            "stats",
            &[
                "bmc",
                "sphere",
                "scene",
                "render",
                "cache",
                "integrator",
                "service",
            ],
        ),
        // `sphere` and `bmc` are one layer, the math (a sample set's errors are BMC errors).
        (
            "sphere",
            &["scene", "render", "cache", "integrator", "service", "cli"],
        ),
        (
            "bmc",
            &["scene", "render", "cache", "integrator", "service", "cli"],
        ),
        (
            "scene",
            &["render", "cache", "integrator", "service", "cli"],
        ),
        ("render", &["cache", "integrator", "service", "cli"]),
        ("cache", &["integrator", "service", "cli", "Transport"]),
        ("integrator", &["service", "cli"]),
    ];
    for (layer, above) in rules {
        let mut files = Vec::new();
        let single = src.join(format!("{layer}.rs"));
        if single.exists() {
            files.push(single);
        } else {
            rust_files(&src.join(layer), &mut files);
        }
        for path in files {
            let text = non_test_text(&path);
            for upper in above {
                let needle = if upper.chars().next().unwrap().is_uppercase() {
                    (*upper).to_owned()
                } else {
                    format!("crate::{upper}::")
                };
                assert!(!text.contains(&needle), "{} names {needle}", path.display());
            }
        }
    }
}

#[test]
fn routes_never_import_each_other() {
    let routes = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/service/routes");
    let mut files = Vec::new();
    rust_files(&routes, &mut files);
    for path in files {
        if path.ends_with("mod.rs") {
            continue;
        }
        let text = non_test_text(&path);
        assert!(
            !text.contains("crate::service::routes::") && !text.contains("super::"),
            "{} imports another route",
            path.display()
        );
    }
}
