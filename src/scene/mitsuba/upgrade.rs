//! Scenes of Mitsuba 0.x (`version` below 2.0.0, most published scenes)
//! upgraded in memory as Mitsuba 3 upgrades them when it loads them (its
//! `src/core/xml.cpp`, "upgrade_tree"), before they are read:
//! - every property name (the `name` of any element but `<default>`) from
//!   camelCase to snake_case: at each lower-then-upper pair an underscore,
//!   the run of capitals lowered (`toWorld` → `to_world`, `intIOR` →
//!   `int_ior`, `sampleCount` → `sample_count`);
//! - `<lookAt>` → `<lookat>`;
//! - a `diffuse` BSDF's `diffuse_reflectance` → `reflectance`;
//! - `uoffset`, `voffset`, `uscale`, `vscale` floats → a `to_uv` transform,
//!   with a `translate` only where both offsets are non-zero and a `scale`
//!   only where both scales differ from 1, as Mitsuba 3 writes it.
//!
//! What changed is returned, one line per kind of change, for the scene's
//! warnings: a user sees that the file was read as a newer one.

use std::collections::BTreeMap;

use super::parse::Element;

/// The version from which no upgrade is needed.
const CURRENT: (u32, u32, u32) = (2, 0, 0);

/// `major.minor.patch` of a `version` attribute (missing parts 0), or
/// `None` if it is not one.
pub(super) fn parse_version(version: &str) -> Option<(u32, u32, u32)> {
    let mut parts = version.trim().split('.').map(str::parse::<u32>);
    let major = parts.next()?.ok()?;
    let minor = parts.next().transpose().ok()?.unwrap_or(0);
    let patch = parts.next().transpose().ok()?.unwrap_or(0);
    parts.next().is_none().then_some((major, minor, patch))
}

/// Upgrades `scene`, a document of `version`, in place; returns what was
/// changed (empty for a current document).
pub(super) fn upgrade(scene: &mut Element, version: (u32, u32, u32)) -> Vec<String> {
    if version >= CURRENT {
        return Vec::new();
    }
    let mut changed: BTreeMap<String, usize> = BTreeMap::new();
    walk(scene, None, &mut changed);
    changed
        .into_iter()
        .map(|(what, n)| format!("Mitsuba 0.x upgrade: {what} ({n}×)"))
        .collect()
}

/// Upgrades `el` (a child of an element of tag and type `parent`) and its
/// children, counting each change in `changed`.
fn walk(el: &mut Element, parent: Option<(&str, &str)>, changed: &mut BTreeMap<String, usize>) {
    let mut count = |what: String| *changed.entry(what).or_default() += 1;
    if el.tag == "lookAt" {
        el.tag = "lookat".into();
        count("<lookAt> read as <lookat>".into());
    }
    if el.tag != "default"
        && let Some((_, name)) = el.attrs.iter_mut().find(|(k, _)| k == "name")
    {
        let snake = snake_case(name);
        if snake != *name {
            count(format!("`{name}` read as `{snake}`"));
            *name = snake;
        }
        if parent == Some(("bsdf", "diffuse")) && name == "diffuse_reflectance" {
            *name = "reflectance".into();
            count("a diffuse BSDF's `diffuse_reflectance` read as `reflectance`".into());
        }
    }
    if uv_transform(el) {
        count("`uoffset`/`voffset`/`uscale`/`vscale` read as a `to_uv` transform".into());
    }
    let mut children = std::mem::take(&mut el.children);
    let parent = Some((el.tag.as_str(), el.attr("type").unwrap_or("")));
    for child in &mut children {
        walk(child, parent, changed);
    }
    el.children = children;
}

/// Mitsuba 3's camelCase → snake_case of a property name, step for step
/// (including its skipping of the character after a run of capitals).
fn snake_case(name: &str) -> String {
    let mut s: Vec<char> = name.chars().collect();
    let mut i = 0;
    while i + 1 < s.len() {
        if s[i].is_ascii_lowercase() && s[i + 1].is_ascii_uppercase() {
            s.insert(i + 1, '_');
            i += 2;
            while i < s.len() && s[i].is_ascii_uppercase() {
                s[i] = s[i].to_ascii_lowercase();
                i += 1;
            }
        }
        i += 1;
    }
    s.into_iter().collect()
}

/// Replaces `el`'s `uoffset`/`voffset`/`uscale`/`vscale` floats by a
/// `to_uv` transform, as Mitsuba 3 does; returns whether it had any. A
/// value that is not a number is kept as its default (0 or 1) here and
/// left for nothing else to read, as the element is removed.
fn uv_transform(el: &mut Element) -> bool {
    let names = ["uoffset", "voffset", "uscale", "vscale"];
    let is_uv =
        |c: &Element| c.tag == "float" && c.attr("name").is_some_and(|n| names.contains(&n));
    if !el.children.iter().any(is_uv) {
        return false;
    }
    let value = |name: &str, default: f64| {
        el.children
            .iter()
            .find(|c| c.tag == "float" && c.attr("name") == Some(name))
            .and_then(|c| c.attr("value")?.trim().parse::<f64>().ok())
            .unwrap_or(default)
    };
    let (offset, scale) = (
        [value("uoffset", 0.0), value("voffset", 0.0)],
        [value("uscale", 1.0), value("vscale", 1.0)],
    );
    let (line, column) = (el.line, el.column);
    let op = |tag: &str, [x, y]: [f64; 2]| Element {
        tag: tag.into(),
        attrs: vec![("x".into(), x.to_string()), ("y".into(), y.to_string())],
        children: Vec::new(),
        line,
        column,
    };
    let mut ops = Vec::new();
    if offset.iter().all(|&o| o != 0.0) {
        ops.push(op("translate", offset));
    }
    if scale.iter().all(|&s| s != 1.0) {
        ops.push(op("scale", scale));
    }
    el.children.retain(|c| !is_uv(c));
    el.children.push(Element {
        tag: "transform".into(),
        attrs: vec![("name".into(), "to_uv".into())],
        children: ops,
        line,
        column,
    });
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn property_names_become_snake_case_as_mitsuba_3_makes_them() {
        for (old, new) in [
            ("toWorld", "to_world"),
            ("intIOR", "int_ior"),
            ("extIOR", "ext_ior"),
            ("sampleCount", "sample_count"),
            ("maxDepth", "max_depth"),
            ("alphaU", "alpha_u"),
            ("specularReflectance", "specular_reflectance"),
            ("radiance", "radiance"),
            ("to_world", "to_world"),
            // The character after a run of capitals is skipped, as in Mitsuba.
            ("aBcD", "a_bcD"),
        ] {
            assert_eq!(snake_case(old), new, "{old}");
        }
    }

    #[test]
    fn versions_parse_with_missing_parts() {
        assert_eq!(parse_version("0.5.0"), Some((0, 5, 0)));
        assert_eq!(parse_version("3.0"), Some((3, 0, 0)));
        assert_eq!(parse_version("2"), Some((2, 0, 0)));
        assert_eq!(parse_version("x.1"), None);
        assert_eq!(parse_version("1.2.3.4"), None);
    }
}
