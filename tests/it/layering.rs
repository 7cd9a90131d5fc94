//! The layering rules of docs/ARCHITECTURE.md, checked on the source text:
//! no two children of one module (files or directory modules) import each
//! other, even through others — whether they name each other by `super::`,
//! by `crate::` paths or through an item their parent's `mod.rs`
//! re-exports — and lower layers never name upper ones.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The Rust files under `dir`.
fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    out.extend(crate::common::files_with(dir, &["rs"]));
}

/// The text of a file without its inline `#[cfg(test)]` module (tests may
/// use anything); other test-only items, and a `#[cfg(test)] mod tests;`
/// declaration, cut nothing.
fn non_test_text(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap();
    let mut from = 0;
    while let Some(at) = text[from..].find("#[cfg(test)]").map(|i| i + from) {
        let after = &text[at + "#[cfg(test)]".len()..];
        let item = &after[..after.find(['{', ';']).unwrap_or(after.len())];
        let inline_module = after.as_bytes().get(item.len()) == Some(&b'{')
            && item
                .trim_start()
                .trim_start_matches("pub(crate) ")
                .starts_with("mod ");
        if inline_module {
            return text[..at].to_owned();
        }
        from = at + 1;
    }
    text
}

/// The source text without test modules and comment lines, where a path
/// names what the code uses (doc links included would count prose).
fn code_text(path: &Path) -> String {
    non_test_text(path)
        .lines()
        .filter(|line| !line.trim_start().starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The module path of a source file: `src/a/b.rs` and `src/a/b/mod.rs` are `[a, b]`.
fn module_of(src: &Path, file: &Path) -> Vec<String> {
    let relative = file.strip_prefix(src).unwrap().with_extension("");
    let mut parts: Vec<String> = relative
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if parts.last().is_some_and(|p| p == "mod") {
        parts.pop();
    }
    parts
}

fn identifier(text: &str) -> String {
    text.chars()
        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
        .collect()
}

/// Every path a file's code names through `crate::` or `super::`, as
/// absolute module paths (`use a::{b, c::d}` gives `a::b` and `a::c::d`).
fn named_paths(module: &[String], text: &str) -> Vec<Vec<String>> {
    let mut found = Vec::new();
    for (prefix, start) in [("crate::", 0usize), ("super::", 1)] {
        for (at, _) in text.match_indices(prefix) {
            // `super::super::…` is read once, from its first `super`.
            if prefix == "super::" && text[..at].ends_with("super::") {
                continue;
            }
            let before = text[..at].chars().next_back();
            if before.is_some_and(|c| c.is_ascii_alphanumeric() || c == '_') {
                continue;
            }
            let mut base: Vec<String> = if start == 0 {
                Vec::new()
            } else {
                module[..module.len().saturating_sub(1)].to_vec()
            };
            let mut rest = &text[at + prefix.len()..];
            while let Some(r) = rest.strip_prefix("super::") {
                base.pop();
                rest = r;
            }
            paths_in(&base, rest, &mut found);
        }
    }
    found
}

/// Paths starting at `rest` (after `base::`), following one level of braces.
fn paths_in(base: &[String], rest: &str, out: &mut Vec<Vec<String>>) {
    let mut path = base.to_vec();
    let mut rest = rest;
    loop {
        if let Some(inner) = rest.strip_prefix('{') {
            let mut depth = 1;
            let end = inner
                .char_indices()
                .find(|&(_, c)| {
                    depth += match c {
                        '{' => 1,
                        '}' => -1,
                        _ => 0,
                    };
                    depth == 0
                })
                .map_or(inner.len(), |(i, _)| i);
            for item in split_top_level(&inner[..end]) {
                paths_in(&path, item.trim_start(), out);
            }
            return;
        }
        let name = identifier(rest);
        if name.is_empty() {
            break;
        }
        path.push(name.clone());
        rest = &rest[name.len()..];
        match rest.strip_prefix("::") {
            Some(r) => rest = r,
            None => break,
        }
    }
    out.push(path);
}

/// `a, b::{c, d}, e` split at the commas outside braces.
fn split_top_level(text: &str) -> Vec<&str> {
    let (mut items, mut depth, mut start) = (Vec::new(), 0, 0);
    for (i, c) in text.char_indices() {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                items.push(&text[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    items.push(&text[start..]);
    items
}

/// The cycles of the import graphs between the children (files and
/// directory modules) of every module below the crate root: a file's
/// references through `crate::` or `super::` to a sibling of any of its
/// ancestors are edges between those siblings, and a reference to an item a
/// parent's `mod.rs` re-exports (`pub use child::Item`) is an edge to that child.
fn import_cycles(src: &Path) -> Vec<String> {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    let modules: BTreeSet<Vec<String>> = files.iter().map(|f| module_of(src, f)).collect();
    // Parent module → (re-exported item → the child it comes from).
    let mut reexports: BTreeMap<Vec<String>, BTreeMap<String, String>> = BTreeMap::new();
    for file in files.iter().filter(|f| f.ends_with("mod.rs")) {
        let module = module_of(src, file);
        let text = code_text(file);
        for (at, _) in text.match_indices("pub use ") {
            let rest = &text[at + "pub use ".len()..];
            let child = identifier(rest);
            let statement = &rest[..rest.find(';').unwrap_or(rest.len())];
            let mut found = Vec::new();
            paths_in(&[], statement, &mut found);
            for path in found {
                if let Some(item) = path.last() {
                    reexports
                        .entry(module.clone())
                        .or_default()
                        .insert(item.clone(), child.clone());
                }
            }
        }
    }
    // Parent module → (child → children it names).
    let mut graphs: BTreeMap<Vec<String>, BTreeMap<String, BTreeSet<String>>> = BTreeMap::new();
    for file in &files {
        let name = file.file_stem().unwrap().to_string_lossy();
        if name == "lib" || name == "main" || name == "tests" {
            continue;
        }
        let module = module_of(src, file);
        for target in named_paths(&module, &code_text(file)) {
            let common = module
                .iter()
                .zip(&target)
                .take_while(|(a, b)| a == b)
                .count();
            // Below the crate root only: the layer rules govern the top.
            if common == 0 || common >= module.len() {
                continue;
            }
            let parent = module[..common].to_vec();
            let from = module[common].clone();
            let to = if common < target.len()
                && modules.contains(&[parent.clone(), vec![target[common].clone()]].concat())
            {
                target[common].clone()
            } else if let Some(child) = target
                .get(common)
                .and_then(|item| reexports.get(&parent)?.get(item))
            {
                child.clone()
            } else {
                continue;
            };
            if from != to {
                graphs
                    .entry(parent)
                    .or_default()
                    .entry(from)
                    .or_default()
                    .insert(to);
            }
        }
    }
    let mut cycles = Vec::new();
    for (parent, graph) in &graphs {
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
            if let Some(cycle) = visit(node, graph, &mut state, &mut Vec::new()) {
                cycles.push(format!("{}: {}", parent.join("::"), cycle.join(" → ")));
                break;
            }
        }
    }
    cycles
}

#[test]
fn modules_import_each_other_without_cycles() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let cycles = import_cycles(&src);
    assert!(cycles.is_empty(), "import cycles:\n{}", cycles.join("\n"));
}

#[test]
fn cycles_through_directory_modules_and_crate_paths_are_found() {
    let dir = tempfile::tempdir().unwrap();
    let write = |path: &str, text: &str| {
        let path = dir.path().join(path);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, text).unwrap();
    };
    write("lib.rs", "pub mod math;\n");
    write(
        "math/mod.rs",
        "mod kernel_mean;\nmod quadrature;\npub use quadrature::Rule;\n",
    );
    write(
        "math/quadrature.rs",
        "use super::kernel_mean::exact;\npub struct Rule;\n",
    );
    write("math/kernel_mean/mod.rs", "pub mod exact;\n");
    write(
        "math/kernel_mean/exact.rs",
        "// use crate::math::Rule;\npub fn f() {}\n",
    );
    assert!(
        import_cycles(dir.path()).is_empty(),
        "a comment is no import"
    );
    // Through the parent's re-export, from inside a directory module.
    write("math/kernel_mean/exact.rs", "use crate::math::Rule;\n");
    assert_eq!(
        import_cycles(dir.path()),
        ["math: kernel_mean → quadrature → kernel_mean"]
    );
    // Through a full `crate::` path in a braced group.
    write(
        "math/kernel_mean/exact.rs",
        "use crate::math::{quadrature::{Rule}};\n",
    );
    assert_eq!(import_cycles(dir.path()).len(), 1);
    // Through `super::super::` from the directory module's own file.
    write(
        "math/kernel_mean/exact.rs",
        "use super::super::quadrature::Rule;\n",
    );
    assert_eq!(import_cycles(dir.path()).len(), 1);
}

#[test]
fn lower_layers_never_name_upper_ones() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    // The layers, lowest first: each must not name any above it. `sphere`
    // and `bmc` are one layer, the math (a sample set's errors are BMC
    // errors); point estimators sit above light transport and below the
    // record store, whose records serve them as a prior.
    let layers: [&[&str]; 8] = [
        &["stats", "color"],
        &["sphere", "bmc", "optics"],
        &["scene"],
        &["render"],
        &["estimators"],
        &["cache"],
        &["integrator"],
        &["service", "cli"],
    ];
    let mut rules = Vec::new();
    for (i, layer) in layers.iter().enumerate() {
        let mut above: Vec<&str> = layers[i + 1..]
            .iter()
            .flat_map(|l| l.iter().copied())
            .collect();
        for &module in *layer {
            if module == "cache" {
                // The record store traces no ray.
                above.push("Transport");
            }
            if !above.is_empty() {
                rules.push((module, above.clone()));
            }
        }
    }
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
            for upper in &above {
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

/// Routes translate (docs/ARCHITECTURE.md): none names the machinery the
/// library's point query and tile jobs run — priors, estimators' caches,
/// record placement, the estimate calls themselves.
#[test]
fn routes_hold_no_estimator_logic() {
    let machinery = [
        "point_priors",
        "EstimatorCaches",
        "PointEstimator",
        "place_among",
        "estimate_to_target",
        "RecordsPrior",
        "DirectPrior",
        "prior_sources(",
        "priors_combined",
        "render_tile(",
    ];
    let routes = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/service/routes");
    let mut files = Vec::new();
    rust_files(&routes, &mut files);
    for path in files {
        let text = non_test_text(&path);
        let named: Vec<&str> = machinery
            .iter()
            .copied()
            .filter(|name| text.contains(name))
            .collect();
        assert!(named.is_empty(), "{} runs {named:?}", path.display());
    }
}

/// `Transport` is the scene's light-transport state; the kernels built on
/// it are types of their own (`PathTracer`, `HemisphereRule`), so no module
/// outside `render` adds methods to it.
#[test]
fn only_render_adds_methods_to_transport() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    for path in files {
        if path.starts_with(src.join("render")) {
            continue;
        }
        let text = non_test_text(&path);
        assert!(
            !text.contains("impl Transport"),
            "{} adds methods to Transport",
            path.display()
        );
    }
}
