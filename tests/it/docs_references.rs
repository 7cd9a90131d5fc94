//! The repository is self-contained: every `docs/math.md §n` cited in the
//! code resolves to a heading of `docs/math.md`, and nothing points at files
//! outside the repository; and what the READMEs list (the presets) is what
//! the code has.

use std::path::{Path, PathBuf};

fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            files(&path, out);
        } else if path
            .extension()
            .is_some_and(|e| e == "rs" || e == "md" || e == "py" || e == "toml" || e == "sh")
        {
            out.push(path);
        }
    }
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
