//! The plugin layout of docs/ARCHITECTURE.md ("Where to add"), checked on
//! the source text: each plugin family has one registry, the `plugins!`
//! invocation in its module, whose lines read `Variant(file::Type) =
//! "name",`; every registered plugin has its own file in the family's
//! folder defining its type, and the type is named nowhere else outside
//! tests but in its registry line — so adding a plugin is its file plus one
//! registry line.

use std::path::{Path, PathBuf};

/// The families: their module file (holding the registry), folder, and
/// Mitsuba reader if it is a generic property copier (the BSDF reader
/// still names Mitsuba's default `diffuse` and this project's own
/// `glossy`; the emitter reader reads `<point>` properties).
const FAMILIES: &[Family] = &[
    ("scene/material.rs", "scene/material", None),
    ("scene/emitter.rs", "scene/emitter", None),
    ("scene/texture.rs", "scene/texture", None),
    (
        "scene/shape.rs",
        "scene/shape",
        Some("scene/mitsuba/shape.rs"),
    ),
];

type Family = (&'static str, &'static str, Option<&'static str>);

/// Where the JSON document is read for every family: its types and loader.
const DOCUMENT_READERS: &[&str] = &["scene/format.rs", "scene/loader.rs", "scene/loader"];

/// One registry line.
#[derive(Debug)]
struct Registered {
    name: String,
    file: String,
    plugin: String,
}

/// The Rust files under `dir`.
fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    out.extend(crate::common::files_with(dir, &["rs"]));
}

/// Whether `path` holds only tests (a `tests.rs`, or a file under a
/// `tests/` folder of `src`): tests may name any plugin.
fn is_test_file(path: &Path) -> bool {
    path.file_stem().is_some_and(|s| s == "tests")
        || path.components().any(|c| c.as_os_str() == "tests")
}

/// The code of a file: comment lines and the inline test module removed.
fn code(text: &str) -> String {
    let text = match text.find("#[cfg(test)]\nmod tests {") {
        Some(at) => &text[..at],
        None => text,
    };
    text.lines()
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The lines of the `plugins!` invocation in a family's module.
fn registry(module: &str) -> Result<Vec<Registered>, String> {
    // The invocation starts a line (the macro's definition does not).
    let (start, _) = module
        .match_indices("plugins! {")
        .find(|(at, _)| *at == 0 || module[..*at].ends_with('\n'))
        .ok_or("no `plugins! {` invocation: the family has no one-line registry")?;
    let body = &module[start + "plugins! {".len()..];
    let body = &body[..body.find("\n}").ok_or("unterminated `plugins!`")?];
    body.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with("//"))
        .map(|line| {
            // Variant(file::Type) = "name",
            let parse = || {
                let (_, rest) = line.split_once('(')?;
                let (path, rest) = rest.split_once(')')?;
                let (file, plugin) = path.split_once("::")?;
                let name = rest.trim().strip_prefix("= \"")?.strip_suffix("\",")?;
                Some(Registered {
                    name: name.to_owned(),
                    file: file.to_owned(),
                    plugin: plugin.to_owned(),
                })
            };
            parse().ok_or(format!("not a registry line: {line}"))
        })
        .collect()
}

/// Whether `word` occurs in `text` as a whole identifier.
fn count_word(text: &str, word: &str) -> usize {
    text.match_indices(word)
        .filter(|(at, _)| {
            let ident = |c: char| c.is_ascii_alphanumeric() || c == '_';
            let before = text[..*at].chars().next_back();
            let after = text[at + word.len()..].chars().next();
            !before.is_some_and(ident) && !after.is_some_and(ident)
        })
        .count()
}

/// What breaks the layout under `src`, one message each.
fn layout_errors(src: &Path, families: &[Family]) -> Vec<String> {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    let sources: Vec<(PathBuf, String)> = files
        .into_iter()
        .filter(|f| !is_test_file(f.strip_prefix(src).unwrap()))
        .map(|f| {
            let text = code(&std::fs::read_to_string(&f).unwrap());
            (f, text)
        })
        .collect();
    let mut errors = Vec::new();
    for (module, folder, mitsuba) in families {
        let module_path = src.join(module);
        let Ok(text) = std::fs::read_to_string(&module_path) else {
            errors.push(format!("{module}: missing"));
            continue;
        };
        let plugins = match registry(&text) {
            Ok(plugins) => plugins,
            Err(e) => {
                errors.push(format!("{module}: {e}"));
                continue;
            }
        };
        for p in &plugins {
            let sharing = plugins.iter().filter(|q| q.file == p.file).count();
            if sharing > 1 {
                errors.push(format!(
                    "{module}: {} shares its file {}.rs",
                    p.name, p.file
                ));
            }
            let own = src.join(folder).join(format!("{}.rs", p.file));
            let Some((_, own_text)) = sources.iter().find(|(f, _)| *f == own) else {
                errors.push(format!("{}: no file {}", p.name, own.display()));
                continue;
            };
            if !own_text.contains(&format!("pub struct {}", p.plugin)) {
                errors.push(format!(
                    "{}: {} does not define {}",
                    p.name,
                    own.display(),
                    p.plugin
                ));
            }
            if text.contains(&format!("mod {};", p.file)) {
                errors.push(format!("{}: declared by hand in {module}", p.name));
            }
            for (file, code) in &sources {
                let uses = if *file == own {
                    0
                } else if *file == module_path {
                    // Its own registry line names it once; nothing else may.
                    count_word(code, &p.plugin).saturating_sub(1)
                } else {
                    count_word(code, &p.plugin)
                };
                if uses > 0 {
                    errors.push(format!(
                        "{}: {} names {} outside its file and registry line",
                        p.name,
                        file.display(),
                        p.plugin
                    ));
                }
                // Nor do the document's generic readers dispatch on the
                // plugin's name (a `match kind { "sphere" => … }`).
                let quoted = format!("\"{}\"", p.name);
                let reader = DOCUMENT_READERS
                    .iter()
                    .chain(mitsuba)
                    .any(|r| file.starts_with(src.join(r)));
                if reader && code.contains(&quoted) {
                    errors.push(format!(
                        "{}: {} handles {} by name",
                        p.name,
                        file.display(),
                        quoted
                    ));
                }
            }
        }
    }
    errors
}

#[test]
fn each_plugin_is_its_file_plus_one_registry_line() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let errors = layout_errors(&src, FAMILIES);
    assert!(errors.is_empty(), "{}", errors.join("\n"));
}

#[test]
fn the_old_split_layouts_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let write = |path: &str, text: &str| {
        let path = dir.path().join(path);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, text).unwrap();
    };
    let family = [("scene/material.rs", "scene/material", None)];
    // A name → parser table, parameters and model in two layers: no registry.
    write(
        "scene/material.rs",
        "mod conductor;\nconst PLUGINS: &[(&str, Parse)] = &[\n    (\"roughconductor\", conductor::parse_rough),\n];\n",
    );
    write("scene/material/conductor.rs", "pub fn parse_rough() {}\n");
    write(
        "render/bsdf.rs",
        "pub enum Bsdf { RoughConductor(RoughConductor) }\n",
    );
    let errors = layout_errors(dir.path(), &family);
    assert!(errors[0].contains("no `plugins! {`"), "{errors:?}");
    // A registry, but the model dispatched elsewhere and two plugins in one file.
    write(
        "scene/material.rs",
        "plugins! {\n    Conductor(conductor::ConductorMaterial) = \"conductor\",\n    RoughConductor(conductor::RoughConductorMaterial) = \"roughconductor\",\n}\n",
    );
    write(
        "scene/material/conductor.rs",
        "pub struct ConductorMaterial;\npub struct RoughConductorMaterial;\n",
    );
    write(
        "render/bsdf.rs",
        "fn build() -> RoughConductorMaterial {}\n// RoughConductorMaterial in a comment is no use\n",
    );
    let errors = layout_errors(dir.path(), &family);
    assert_eq!(errors.len(), 3, "{errors:?}");
    assert!(
        errors
            .iter()
            .any(|e| e.contains("render/bsdf.rs names RoughConductorMaterial"))
    );
    // One file per plugin, named only in its registry line: accepted.
    write(
        "scene/material.rs",
        "plugins! {\n    Conductor(conductor::ConductorMaterial) = \"conductor\",\n}\n",
    );
    write(
        "scene/material/conductor.rs",
        "pub struct ConductorMaterial;\n",
    );
    write("render/bsdf.rs", "pub use crate::scene::material::Bsdf;\n");
    assert!(layout_errors(dir.path(), &family).is_empty());
}

#[test]
fn a_half_registered_shape_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let write = |path: &str, text: &str| {
        let path = dir.path().join(path);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, text).unwrap();
    };
    let family = [(
        "scene/shape.rs",
        "scene/shape",
        Some("scene/mitsuba/shape.rs"),
    )];
    let registry = "plugins! {\n    Sphere(sphere::SphereShape) = \"sphere\",\n    Disk(disk::DiskShape) = \"disk\",\n}\n";
    write("scene/shape.rs", registry);
    write("scene/shape/sphere.rs", "pub struct SphereShape;\n");
    // A registry line without its file.
    let errors = layout_errors(dir.path(), &family);
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert!(errors[0].starts_with("disk: no file"), "{errors:?}");
    // Its file, but the kind still dispatched by name in the loader.
    write("scene/shape/disk.rs", "pub struct DiskShape;\n");
    write(
        "scene/loader/geometry.rs",
        "fn build() { let _ = DiskShape; }\n",
    );
    let errors = layout_errors(dir.path(), &family);
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert!(
        errors[0].contains("geometry.rs names DiskShape"),
        "{errors:?}"
    );
    write("scene/loader/geometry.rs", "fn build() {}\n");
    assert!(layout_errors(dir.path(), &family).is_empty());
    // The Mitsuba reader reading a kind's properties by its name.
    write(
        "scene/mitsuba/shape.rs",
        "fn add() { match kind { \"sphere\" => radius(), _ => {} } }\n",
    );
    let errors = layout_errors(dir.path(), &family);
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert!(
        errors[0].contains("handles \"sphere\" by name"),
        "{errors:?}"
    );
}
