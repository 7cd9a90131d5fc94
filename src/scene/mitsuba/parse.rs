//! XML text → an owned element tree with line numbers, `<default>` and
//! `$name` substitution applied, depth and size capped, ids indexed.
//!
//! The tree keeps only what Mitsuba's XML carries: element names, attributes
//! and child elements (text content and comments are ignored, as Mitsuba
//! does).

use std::collections::{BTreeMap, HashMap};

use super::XmlError;

/// Deepest accepted element nesting (Mitsuba scenes are a handful deep; this
/// keeps recursion over the tree far from the stack limit).
pub const MAX_DEPTH: usize = 64;
/// Largest number of XML nodes accepted (elements, attributes count apart).
const MAX_NODES: u32 = 4_000_000;

/// One XML element.
#[derive(Debug)]
pub struct Element {
    pub tag: String,
    pub attrs: Vec<(String, String)>,
    pub children: Vec<Element>,
    /// 1-based position of the element's start tag.
    pub line: u32,
    pub column: u32,
}

impl Element {
    pub fn attr(&self, name: &str) -> Option<&str> {
        self.attrs
            .iter()
            .find(|(k, _)| k == name)
            .map(|(_, v)| v.as_str())
    }

    /// `<shape type="cube" id="box">`-style label for messages.
    pub fn label(&self) -> String {
        let mut s = format!("<{}", self.tag);
        for key in ["type", "name", "id"] {
            if let Some(v) = self.attr(key) {
                s.push_str(&format!(" {key}=\"{v}\""));
            }
        }
        s.push('>');
        s
    }

    /// An error located at this element.
    pub fn error(&self, attribute: &str, message: impl Into<String>) -> XmlError {
        let field = if attribute.is_empty() {
            self.label()
        } else {
            format!("{}.{attribute}", self.label())
        };
        XmlError {
            line: self.line,
            column: self.column,
            field,
            message: message.into(),
            source: None,
        }
    }

    /// Identity of the element within one document (its start position).
    pub fn key(&self) -> (u32, u32) {
        (self.line, self.column)
    }
}

/// Parses `text` into the `<scene>` element. `parameters` are user-given
/// values for `$name` that take precedence over `<default>` declarations.
pub fn parse(text: &str, parameters: &BTreeMap<String, String>) -> Result<Element, XmlError> {
    let options = roxmltree::ParsingOptions {
        allow_dtd: false,
        nodes_limit: MAX_NODES,
        ..Default::default()
    };
    let doc = roxmltree::Document::parse_with_options(text, options).map_err(|e| {
        let pos = e.pos();
        XmlError {
            line: pos.row,
            column: pos.col,
            field: "xml".into(),
            message: format!("malformed XML: {e}"),
            source: None,
        }
    })?;
    let root = doc.root_element();
    let mut params = parameters.clone();
    let scene = convert(&doc, root, 0, &mut params)?;
    if scene.tag != "scene" {
        return Err(scene.error("", "the root element must be <scene>"));
    }
    Ok(scene)
}

fn convert(
    doc: &roxmltree::Document,
    node: roxmltree::Node,
    depth: usize,
    params: &mut BTreeMap<String, String>,
) -> Result<Element, XmlError> {
    let pos = doc.text_pos_at(node.range().start);
    let tag = node.tag_name().name().to_string();
    let mut element = Element {
        tag,
        attrs: Vec::new(),
        children: Vec::new(),
        line: pos.row,
        column: pos.col,
    };
    if depth >= MAX_DEPTH {
        return Err(element.error(
            "",
            format!("elements nested deeper than {MAX_DEPTH} levels"),
        ));
    }
    for a in node.attributes() {
        let value = substitute(a.value(), params).map_err(|m| element.error(a.name(), m))?;
        element.attrs.push((a.name().to_string(), value));
    }
    if element.tag == "default" {
        let (Some(name), Some(value)) = (element.attr("name"), element.attr("value")) else {
            return Err(element.error("", "<default> needs `name` and `value`"));
        };
        // Values given by the caller win over the file's defaults.
        params
            .entry(name.to_string())
            .or_insert_with(|| value.to_string());
    }
    for child in node.children().filter(|c| c.is_element()) {
        element
            .children
            .push(convert(doc, child, depth + 1, params)?);
    }
    Ok(element)
}

/// Replaces every `$name` (name = letters, digits, `_`) by its parameter.
fn substitute(value: &str, params: &BTreeMap<String, String>) -> Result<String, String> {
    if !value.contains('$') {
        return Ok(value.to_string());
    }
    let mut out = String::with_capacity(value.len());
    let mut rest = value;
    while let Some(i) = rest.find('$') {
        out.push_str(&rest[..i]);
        let after = &rest[i + 1..];
        let end = after
            .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
            .unwrap_or(after.len());
        let name = &after[..end];
        match params.get(name) {
            Some(v) if !name.is_empty() => out.push_str(v),
            _ => {
                return Err(format!(
                    "parameter `${name}` has no value (declare <default name=\"{name}\" value=\"...\"/> before its use)"
                ));
            }
        }
        rest = &after[end..];
    }
    out.push_str(rest);
    Ok(out)
}

/// Every element with an `id`, anywhere in the tree; duplicates are errors.
pub fn index_ids(scene: &Element) -> Result<HashMap<String, &Element>, XmlError> {
    fn walk<'a>(
        e: &'a Element,
        ids: &mut HashMap<String, &'a Element>,
        is_root: bool,
    ) -> Result<(), XmlError> {
        // A <ref id> names another element; it does not declare one.
        if let Some(id) = e.attr("id").filter(|_| !is_root && e.tag != "ref") {
            if let Some(first) = ids.get(id) {
                return Err(e.error(
                    "id",
                    format!(
                        "duplicate id {id:?} (first declared on line {})",
                        first.line
                    ),
                ));
            }
            ids.insert(id.to_string(), e);
        }
        for c in &e.children {
            walk(c, ids, false)?;
        }
        Ok(())
    }
    let mut ids = HashMap::new();
    walk(scene, &mut ids, true)?;
    Ok(ids)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(pairs: &[(&str, &str)]) -> BTreeMap<String, String> {
        pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect()
    }

    #[test]
    fn substitution_uses_defaults_and_caller_parameters() {
        let text = r#"<scene version="3.0.0">
            <default name="spp" value="64"/>
            <default name="w" value="8"/>
            <integer name="a" value="$spp"/>
            <integer name="b" value="x$w-$w"/>
        </scene>"#;
        let scene = parse(text, &params(&[("spp", "16")])).unwrap();
        assert_eq!(scene.children[2].attr("value"), Some("16"));
        assert_eq!(scene.children[3].attr("value"), Some("x8-8"));
    }

    #[test]
    fn undefined_parameter_is_an_error_with_its_line() {
        let text = "<scene version=\"3.0.0\">\n  <integer name=\"a\" value=\"$nope\"/>\n</scene>";
        let e = parse(text, &BTreeMap::new()).unwrap_err();
        assert_eq!(e.line, 2);
        assert!(e.message.contains("$nope"), "{}", e.message);
        assert!(e.field.ends_with(".value"), "{}", e.field);
    }

    #[test]
    fn malformed_xml_reports_its_line() {
        let text = "<scene version=\"3.0.0\">\n<shape type=\"cube\">\n</scene>";
        let e = parse(text, &BTreeMap::new()).unwrap_err();
        assert_eq!(e.line, 3);
        assert!(e.message.starts_with("malformed XML"), "{}", e.message);
    }

    #[test]
    fn deep_nesting_is_capped() {
        let depth = 100_000;
        let text = format!(
            "<scene version=\"3.0.0\">{}{}</scene>",
            "<bsdf type=\"twosided\">".repeat(depth),
            "</bsdf>".repeat(depth)
        );
        let e = parse(&text, &BTreeMap::new()).unwrap_err();
        assert!(e.message.contains("nested deeper"), "{}", e.message);
    }

    #[test]
    fn duplicate_ids_are_rejected() {
        let text = "<scene version=\"3.0.0\">\n<bsdf type=\"diffuse\" id=\"a\"/>\n<bsdf type=\"diffuse\" id=\"a\"/>\n</scene>";
        let scene = parse(text, &BTreeMap::new()).unwrap();
        let e = index_ids(&scene).unwrap_err();
        assert_eq!(e.line, 3);
        assert!(e.message.contains("line 2"), "{}", e.message);
    }

    #[test]
    fn root_must_be_scene() {
        let e = parse("<bsdf type=\"diffuse\"/>", &BTreeMap::new()).unwrap_err();
        assert!(e.message.contains("<scene>"));
    }
}
