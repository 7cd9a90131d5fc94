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
/// Longest attribute value, in bytes, that `$name` substitution may produce.
/// Real parameters are numbers, names and file names; without a cap a chain
/// of `<default>`s that each repeat the previous one ten times expands
/// exponentially (ten levels of a one-byte value are 10⁹ bytes).
pub const MAX_SUBSTITUTED_VALUE_BYTES: usize = 64 * 1024;
/// Most bytes that `$name` substitution may produce over a whole document
/// (the sum of the lengths of every substituted value), so that many values
/// just under [`MAX_SUBSTITUTED_VALUE_BYTES`] cannot add up to gigabytes.
pub const MAX_SUBSTITUTED_DOCUMENT_BYTES: usize = 4 * 1024 * 1024;
/// Most characters of a document's value quoted in an error or warning
/// message; longer values are cut and end with an ellipsis.
pub const MAX_QUOTED_CHARS: usize = 64;

/// `value` cut to [`MAX_QUOTED_CHARS`] characters (ending with `…` if cut),
/// so messages never echo huge attribute values.
pub fn clip(value: &str) -> std::borrow::Cow<'_, str> {
    match value.char_indices().nth(MAX_QUOTED_CHARS) {
        Some((cut, _)) => format!("{}…", &value[..cut]).into(),
        None => value.into(),
    }
}

/// [`clip`]ped `value` in double quotes (Rust string escapes), for messages.
pub fn quote(value: &str) -> String {
    format!("{:?}", clip(value))
}

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
                s.push_str(&format!(" {key}={}", quote(v)));
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
    let mut state = Convert {
        params: parameters.clone(),
        position: Position::new(text),
        substituted_bytes: 0,
    };
    let scene = convert(&mut state, root, 0)?;
    if scene.tag != "scene" {
        return Err(scene.error("", "the root element must be <scene>"));
    }
    Ok(scene)
}

/// State of one document's conversion.
struct Convert<'t> {
    /// `$name` values: the caller's, then the `<default>`s seen so far.
    params: BTreeMap<String, String>,
    position: Position<'t>,
    /// Bytes produced by substitution so far (see
    /// [`MAX_SUBSTITUTED_DOCUMENT_BYTES`]).
    substituted_bytes: usize,
}

/// Line and column of byte offsets visited in increasing order, found by
/// scanning the text once. (`roxmltree::Document::text_pos_at` rescans from
/// the start of the text on every call, which makes converting N elements on
/// one line cost O(N²).)
struct Position<'t> {
    text: &'t str,
    offset: usize,
    /// 1-based line and column (in characters, as roxmltree counts) of `offset`.
    line: u32,
    column: u32,
}

impl<'t> Position<'t> {
    fn new(text: &'t str) -> Self {
        Position {
            text,
            offset: 0,
            line: 1,
            column: 1,
        }
    }

    /// Line and column of byte `offset`, which must not precede the
    /// previous call's (elements are visited in document order).
    fn at(&mut self, offset: usize) -> (u32, u32) {
        let offset = offset.min(self.text.len());
        debug_assert!(offset >= self.offset, "positions must be visited in order");
        if offset > self.offset {
            for c in self.text[self.offset..offset].chars() {
                if c == '\n' {
                    self.line += 1;
                    self.column = 1;
                } else {
                    self.column += 1;
                }
            }
            self.offset = offset;
        }
        (self.line, self.column)
    }
}

fn convert(state: &mut Convert, node: roxmltree::Node, depth: usize) -> Result<Element, XmlError> {
    let (line, column) = state.position.at(node.range().start);
    let tag = node.tag_name().name().to_string();
    let mut element = Element {
        tag,
        attrs: Vec::new(),
        children: Vec::new(),
        line,
        column,
    };
    if depth >= MAX_DEPTH {
        return Err(element.error(
            "",
            format!("elements nested deeper than {MAX_DEPTH} levels"),
        ));
    }
    for a in node.attributes() {
        let value = substitute(a.value(), &state.params).map_err(|m| element.error(a.name(), m))?;
        if a.value().contains('$') {
            state.substituted_bytes += value.len();
            if state.substituted_bytes > MAX_SUBSTITUTED_DOCUMENT_BYTES {
                return Err(element.error(
                    a.name(),
                    format!(
                        "`$name` substitution produces more than {MAX_SUBSTITUTED_DOCUMENT_BYTES} bytes in this document"
                    ),
                ));
            }
        }
        element.attrs.push((a.name().to_string(), value));
    }
    if element.tag == "default" {
        let (Some(name), Some(value)) = (element.attr("name"), element.attr("value")) else {
            return Err(element.error("", "<default> needs `name` and `value`"));
        };
        // Values given by the caller win over the file's defaults.
        state
            .params
            .entry(name.to_string())
            .or_insert_with(|| value.to_string());
    }
    for child in node.children().filter(|c| c.is_element()) {
        element.children.push(convert(state, child, depth + 1)?);
    }
    Ok(element)
}

/// Replaces every `$name` (name = letters, digits, `_`) by its parameter.
/// The result may not exceed [`MAX_SUBSTITUTED_VALUE_BYTES`].
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
            Some(v) if !name.is_empty() => {
                if out.len() + v.len() > MAX_SUBSTITUTED_VALUE_BYTES {
                    return Err(format!(
                        "substituting `$` parameters makes the value longer than {MAX_SUBSTITUTED_VALUE_BYTES} bytes"
                    ));
                }
                out.push_str(v)
            }
            _ => {
                let name = clip(name);
                return Err(format!(
                    "parameter `${name}` has no value (declare <default name=\"{name}\" value=\"...\"/> before its use)"
                ));
            }
        }
        rest = &after[end..];
    }
    if out.len() + rest.len() > MAX_SUBSTITUTED_VALUE_BYTES {
        return Err(format!(
            "substituting `$` parameters makes the value longer than {MAX_SUBSTITUTED_VALUE_BYTES} bytes"
        ));
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
                        "duplicate id {} (first declared on line {})",
                        quote(id),
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

    /// `<default>`s `a0 = "x"`, `aK` = ten times `$a(K-1)`, up to `a{levels}`.
    fn chain(levels: usize) -> String {
        let mut xml = String::from("<default name=\"a0\" value=\"x\"/>");
        for k in 1..=levels {
            let value = format!("$a{}", k - 1).repeat(10);
            xml.push_str(&format!("<default name=\"a{k}\" value=\"{value}\"/>"));
        }
        xml
    }

    #[test]
    fn exponential_substitution_is_cut_at_the_value_that_grows_too_long() {
        // 655 bytes that would expand to 10⁹.
        let text = format!(
            "<scene version=\"3.0.0\">{}<integer name=\"n\" value=\"$a9\"/></scene>",
            chain(9)
        );
        let e = parse(&text, &BTreeMap::new()).unwrap_err();
        // a4 is 10⁴ bytes, a5 would be 10⁵ > 64 KiB.
        assert_eq!(e.field, "<default name=\"a5\">.value");
        assert!(
            e.message.contains(&MAX_SUBSTITUTED_VALUE_BYTES.to_string()),
            "{}",
            e.message
        );
        assert!(e.message.len() < 200, "{}", e.message);
        // Caller parameters are capped the same way.
        let big = "y".repeat(MAX_SUBSTITUTED_VALUE_BYTES);
        let text = "<scene version=\"3.0.0\"><integer name=\"n\" value=\"$p$p\"/></scene>";
        let e = parse(text, &params(&[("p", &big)])).unwrap_err();
        assert_eq!(e.field, "<integer name=\"n\">.value");
        // Exactly at the cap is fine.
        let text = "<scene version=\"3.0.0\"><integer name=\"n\" value=\"$p\"/></scene>";
        let scene = parse(text, &params(&[("p", &big)])).unwrap();
        assert_eq!(
            scene.children[0].attr("value").map(str::len),
            Some(big.len())
        );
    }

    #[test]
    fn substitution_over_the_whole_document_is_capped() {
        // Each use is 10⁴ bytes, under the per-value cap; 500 of them are not.
        let uses = "<float name=\"f\" value=\"$a4\"/>".repeat(500);
        let text = format!("<scene version=\"3.0.0\">{}{uses}</scene>", chain(4));
        let e = parse(&text, &BTreeMap::new()).unwrap_err();
        assert_eq!(e.field, "<float name=\"f\">.value");
        assert!(e.message.contains("in this document"), "{}", e.message);
        // The first uses are within the budget.
        let uses = "<float name=\"f\" value=\"$a4\"/>".repeat(400);
        let text = format!("<scene version=\"3.0.0\">{}{uses}</scene>", chain(4));
        assert_eq!(parse(&text, &BTreeMap::new()).unwrap().children.len(), 405);
    }

    #[test]
    fn quoted_values_are_cut_short() {
        assert_eq!(quote("ab"), "\"ab\"");
        let long = "é".repeat(1000);
        let q = quote(&long);
        assert_eq!(q.chars().count(), MAX_QUOTED_CHARS + 3);
        assert!(q.ends_with("…\""), "{q}");
        let name = "n".repeat(10_000);
        let text = format!(
            "<scene version=\"3.0.0\"><integer name=\"{name}\" value=\"${name}\"/></scene>"
        );
        let e = parse(&text, &BTreeMap::new()).unwrap_err();
        assert!(e.message.len() < 400, "{} bytes", e.message.len());
        assert!(e.field.len() < 200, "{} bytes", e.field.len());
    }

    #[test]
    fn positions_match_roxmltree() {
        let text =
            "<scene version=\"3.0.0\">\n  <a/><b/>\n\t<é x=\"ü\"/><c/>\n\n   <d>\n<e/></d></scene>";
        let doc = roxmltree::Document::parse(text).unwrap();
        let expected: Vec<(u32, u32)> = doc
            .descendants()
            .filter(|n| n.is_element())
            .map(|n| {
                let p = doc.text_pos_at(n.range().start);
                (p.row, p.col)
            })
            .collect();
        fn walk(e: &Element, out: &mut Vec<(u32, u32)>) {
            out.push((e.line, e.column));
            e.children.iter().for_each(|c| walk(c, out));
        }
        let mut got = Vec::new();
        walk(&parse(text, &BTreeMap::new()).unwrap(), &mut got);
        assert_eq!(got, expected);
    }

    #[test]
    fn hundreds_of_thousands_of_siblings_on_one_line_parse() {
        // Each element's position used to be found by rescanning the text
        // from its start: quadratic in the element count.
        let count = 200_000;
        let text = format!(
            "<scene version=\"3.0.0\">{}</scene>",
            "<foo/>".repeat(count)
        );
        let scene = parse(&text, &BTreeMap::new()).unwrap();
        assert_eq!(scene.children.len(), count);
        let last = scene.children.last().unwrap();
        assert_eq!((last.line, last.column), (1, 24 + 6 * (count as u32 - 1)));
    }

    #[test]
    fn root_must_be_scene() {
        let e = parse("<bsdf type=\"diffuse\"/>", &BTreeMap::new()).unwrap_err();
        assert!(e.message.contains("<scene>"));
    }
}
