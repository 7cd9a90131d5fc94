//! The repository is self-contained: every `docs/math.md §n` cited in the
//! code resolves to a heading of `docs/math.md`, and nothing points at files
//! outside the repository; and what the READMEs list (the presets) is what
//! the code has.

use std::path::{Path, PathBuf};

fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    out.extend(crate::common::files_with(
        dir,
        &["rs", "md", "py", "toml", "sh"],
    ));
}

fn sources() -> Vec<(PathBuf, String)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut paths = vec![root.join("README.md")];
    for dir in ["src", "tests", "benches", "examples", "docs", "config"] {
        files(&root.join(dir), &mut paths);
    }
    paths
        .into_iter()
        .map(|p| {
            let text = std::fs::read_to_string(&p).unwrap();
            (p, text)
        })
        .collect()
}

/// Section numbers (`3`, `3.1`) of the headings of `docs/math.md`.
fn math_sections() -> Vec<String> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(root.join("docs/math.md")).unwrap();
    text.lines()
        .filter(|l| l.starts_with('#'))
        .filter_map(|l| {
            let number = l.trim_start_matches('#').split_whitespace().next()?;
            let number = number.trim_end_matches('.');
            number
                .chars()
                .all(|c| c.is_ascii_digit() || c == '.')
                .then(|| number.to_owned())
        })
        .collect()
}

#[test]
fn every_math_reference_resolves_to_a_heading() {
    let sections = math_sections();
    assert!(sections.len() >= 10, "{sections:?}");
    let mut checked = 0;
    for (path, text) in sources() {
        for (at, _) in text.match_indices("math.md §") {
            // `§3`, `§3.1`, and lists such as `§3, §7`.
            let rest = &text[at + "math.md ".len()..];
            let list: String = rest
                .chars()
                .take_while(|c| c.is_ascii_digit() || matches!(c, '§' | '.' | ',' | ' '))
                .collect();
            for item in list.split(',') {
                let number = item.trim().trim_start_matches('§').trim_end_matches('.');
                if number.is_empty() || !item.trim().starts_with('§') {
                    continue;
                }
                assert!(
                    sections.iter().any(|s| s == number),
                    "{}: docs/math.md §{number} is not a heading",
                    path.display()
                );
                checked += 1;
            }
        }
    }
    assert!(checked >= 50, "only {checked} references found");
}

#[test]
fn nothing_points_outside_the_repository() {
    for (path, text) in sources() {
        if path.ends_with("tests/it/docs_references.rs") {
            continue;
        }
        for needle in ["shared/", "bmc-math.md", "targets.md"] {
            assert!(
                !text.contains(needle),
                "{} mentions {needle}",
                path.display()
            );
        }
    }
}

/// The README's preset table and the Python README name every preset the
/// service has, in its order, and no other; the default is the one marked.
#[test]
fn the_docs_name_every_preset() {
    use bmc_irradiance::Preset;
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let names: Vec<String> = Preset::ALL
        .iter()
        .map(|p| {
            serde_json::to_value(p)
                .unwrap()
                .as_str()
                .unwrap()
                .to_owned()
        })
        .collect();
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    let table = &readme[readme.find("| preset |").expect("the preset table")..];
    let rows: Vec<&str> = table
        .lines()
        .skip(2)
        .take_while(|line| line.starts_with('|'))
        .collect();
    let listed: Vec<String> = rows
        .iter()
        .map(|row| row.split('`').nth(1).unwrap_or_default().to_owned())
        .collect();
    assert_eq!(listed, names, "README.md's preset table");
    let default = serde_json::to_value(Preset::default()).unwrap();
    let marked: Vec<&&str> = rows.iter().filter(|r| r.contains("(default)")).collect();
    assert_eq!(marked.len(), 1, "{marked:?}");
    assert!(marked[0].contains(&format!("`{}`", default.as_str().unwrap())));
    let python = std::fs::read_to_string(root.join("python/README.md")).unwrap();
    let line = python
        .lines()
        .find(|l| l.starts_with("client.presets()"))
        .expect("python/README.md shows client.presets()");
    for name in &names {
        assert!(line.contains(name.as_str()), "python/README.md: {line}");
    }
}

/// Every file and folder under the repository root (relative, `/`-separated;
/// folders with a trailing `/`), without `target/` and hidden ones.
fn repository_paths(dir: &Path, root: &Path, out: &mut Vec<String>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy();
        if name.starts_with('.') || path == root.join("target") {
            continue;
        }
        let relative = path.strip_prefix(root).unwrap().to_string_lossy();
        if path.is_dir() {
            out.push(format!("{relative}/"));
            repository_paths(&path, root, out);
        } else {
            out.push(relative.into_owned());
        }
    }
}

/// The backticked spans of a Markdown text outside fenced code blocks.
fn backticked(text: &str) -> Vec<String> {
    let mut spans = Vec::new();
    let mut fenced = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if !fenced {
            spans.extend(line.split('`').skip(1).step_by(2).map(str::to_owned));
        }
    }
    spans
}

fn is_identifier(s: &str) -> bool {
    let mut chars = s.chars();
    chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// The code of `src/` (comment lines left out), one string per file, and the
/// names of its modules (file and folder names).
fn source_code() -> (Vec<String>, Vec<String>) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut paths = Vec::new();
    files(&root.join("src"), &mut paths);
    let mut modules = Vec::new();
    let mut code = Vec::new();
    for path in paths
        .iter()
        .filter(|p| p.extension().is_some_and(|e| e == "rs"))
    {
        let relative = path.strip_prefix(root.join("src")).unwrap();
        modules.extend(
            relative
                .with_extension("")
                .components()
                .map(|c| c.as_os_str().to_string_lossy().into_owned()),
        );
        let text = std::fs::read_to_string(path).unwrap();
        code.push(
            text.lines()
                .filter(|l| !l.trim_start().starts_with("//"))
                .collect::<Vec<_>>()
                .join("\n"),
        );
    }
    (code, modules)
}

/// Whether `name` is defined in `code`: an item (`fn`, `struct`, `enum`,
/// `trait`, `type`, `const`, `static`, `mod`, `macro_rules!`), or a line
/// opening with it as an enum variant or a field does (`Name(`, `Name {`,
/// `Name,`, `name:`, after an optional `pub`).
fn defined(name: &str, code: &[String]) -> bool {
    let is_word_end =
        |rest: &str| !rest.starts_with(|c: char| c.is_ascii_alphanumeric() || c == '_');
    code.iter().flat_map(|file| file.lines()).any(|line| {
        let line = line.trim_start();
        let line = line.strip_prefix("pub(crate) ").unwrap_or(line);
        let line = line.strip_prefix("pub(super) ").unwrap_or(line);
        let line = line.strip_prefix("pub ").unwrap_or(line);
        if let Some(rest) = line.strip_prefix(name) {
            let rest = rest.trim_start();
            let variant = name.starts_with(|c: char| c.is_ascii_uppercase())
                && (rest.is_empty() || rest.starts_with(['(', '{', ',']));
            if variant || rest.starts_with(':') && !rest.starts_with("::") {
                return true;
            }
        }
        [
            "fn ",
            "struct ",
            "enum ",
            "trait ",
            "type ",
            "const ",
            "static ",
            "mod ",
            "macro_rules! ",
        ]
        .iter()
        .any(|keyword| {
            line.match_indices(&format!("{keyword}{name}"))
                .any(|(at, _)| {
                    let before = line[..at].chars().next_back();
                    !before.is_some_and(|c| c.is_ascii_alphanumeric() || c == '_')
                        && is_word_end(&line[at + keyword.len() + name.len()..])
                })
        })
    })
}

/// Whether `word` occurs in `code` as a whole word.
fn occurs(word: &str, code: &[String]) -> bool {
    let is_word = |c: char| c.is_ascii_alphanumeric() || c == '_';
    code.iter().any(|file| {
        file.match_indices(word).any(|(at, _)| {
            !file[..at].chars().next_back().is_some_and(is_word)
                && !file[at + word.len()..].starts_with(is_word)
        })
    })
}

/// Whether `code` calls `name` as a method (`.name(`): a method of a type
/// from outside the crate that the code uses (axum's `route_layer`).
fn called(name: &str, code: &[String]) -> bool {
    let needle = format!(".{name}(");
    code.iter().any(|file| file.contains(&needle))
}

/// Names in `docs/ARCHITECTURE.md` that are not this crate's: the standard
/// library's trait and an HTTP header.
const FROM_ELSEWHERE: &[&str] = &["From", "ETag"];

/// `docs/ARCHITECTURE.md` names only what exists: each backticked path is a
/// file or folder of the repository (as written from the root, or ending a
/// longer path: `service/server.rs`), each `A::b` has every segment defined
/// in `src/` (a module, an item, a variant or a field), each other Rust name
/// is defined in `src/` (or called there as a method), each macro is invoked
/// there, and each plain lower-case word occurs in its code; spans that are none of these (HTTP routes, JSON, expressions) are
/// not checked.
#[test]
fn architecture_names_what_the_code_has() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(root.join("docs/ARCHITECTURE.md")).unwrap();
    let mut paths = Vec::new();
    repository_paths(root, root, &mut paths);
    let (code, modules) = source_code();
    let is_defined = |name: &str| modules.iter().any(|m| m == name) || defined(name, &code);
    let mut missing = Vec::new();
    let mut checked = 0;
    for span in backticked(&text) {
        // `&Cancel`, `.at(path)`, `point_rng(seed, i)`, `PathDepth::default()`.
        let mut name = span.trim_start_matches(['&', '.']).trim_end_matches('?');
        if name.ends_with(')')
            && let Some(open) = name.find('(')
        {
            name = &name[..open];
        }
        let name = name.trim_end_matches("::");
        let found = if name.contains('/')
            && !name.starts_with('/')
            && name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.' | '/'))
        {
            paths.iter().any(|p| {
                let p = p.as_str();
                let dir = p.strip_suffix('/').unwrap_or(p);
                let name = name.trim_end_matches('/');
                dir == name || dir.ends_with(&format!("/{name}"))
            })
        } else if name.contains("::") && name.split("::").all(is_identifier) {
            name.split("::")
                .filter(|s| !matches!(*s, "crate" | "self" | "super"))
                .all(is_defined)
        } else if let Some(inner) = name.strip_suffix('!').filter(|n| is_identifier(n)) {
            code.iter().any(|file| file.contains(&format!("{inner}!")))
        } else if let Some((outer, inner)) = name
            .strip_suffix('>')
            .and_then(|n| n.split_once('<'))
            .filter(|(o, i)| is_identifier(o) && is_identifier(i))
        {
            is_defined(outer) && is_defined(inner)
        } else if is_identifier(name) && name.contains(|c: char| c.is_ascii_uppercase() || c == '_')
        {
            FROM_ELSEWHERE.contains(&name) || is_defined(name) || called(name, &code)
        } else if is_identifier(name) {
            // A plain lower-case word (`lookup`, `eval`, `k`): in the code.
            is_defined(name) || occurs(name, &code)
        } else {
            continue;
        };
        checked += 1;
        if !found {
            missing.push(span);
        }
    }
    assert!(checked >= 150, "only {checked} names checked");
    assert!(
        missing.is_empty(),
        "docs/ARCHITECTURE.md names what the repository does not have: {missing:?}"
    );
}

/// The names in the first column of the first table after `heading` in
/// `doc` (the backticked word opening a row's first cell).
fn table_names(doc: &str, heading: &str) -> Vec<String> {
    let start = doc
        .lines()
        .position(|l| l == heading)
        .unwrap_or_else(|| panic!("no heading {heading:?}"));
    doc.lines()
        .skip(start + 1)
        .skip_while(|l| !l.starts_with('|'))
        .take_while(|l| l.starts_with('|'))
        .filter_map(|row| {
            let first = row.split('|').nth(1)?.trim();
            first
                .strip_prefix('`')?
                .split('`')
                .next()
                .map(str::to_owned)
        })
        .collect()
}

/// docs/scene-format.md's tables of materials, textures, shapes and lights name
/// exactly the plugins the registries accept, in their order.
#[test]
fn the_scene_format_tables_are_the_registries() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let doc = std::fs::read_to_string(root.join("docs/scene-format.md")).unwrap();
    use bmc_irradiance::scene::{emitter, material, shape, texture};
    for (heading, registry) in [
        ("## Materials", material::plugin_names()),
        ("### Textures", texture::plugin_names()),
        ("## Shapes", shape::plugin_names()),
        ("### Lights", emitter::light_names()),
    ] {
        assert_eq!(table_names(&doc, heading), registry, "{heading}");
    }
}
