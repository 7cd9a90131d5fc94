//! Reading a plugin's properties (`<float name="radius" value="2"/>`, nested
//! objects, `<ref>`s) with every child accounted for: whatever a plugin does
//! not read is reported as unsupported.

use super::parse::{Element, quote};
use super::{Ctx, XmlError};

/// The children of one plugin element, with a record of which were read.
pub(crate) struct Props<'a> {
    pub el: &'a Element,
    used: Vec<bool>,
}

/// Numbers of attribute `attr`, separated by commas and/or whitespace (as
/// Mitsuba accepts them); each must be finite.
pub(crate) fn numbers(el: &Element, attr: &str) -> Result<Vec<f64>, XmlError> {
    let text = el
        .attr(attr)
        .ok_or_else(|| el.error(attr, format!("missing attribute `{attr}`")))?;
    text.split(|c: char| c == ',' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .map(|s| {
            let x: f64 = s
                .parse()
                .map_err(|_| el.error(attr, format!("{} is not a number", quote(s))))?;
            if x.is_finite() {
                Ok(x)
            } else {
                Err(el.error(attr, format!("{} is not a finite number", quote(s))))
            }
        })
        .collect()
}

/// Exactly one number in `attr`.
pub(crate) fn number(el: &Element, attr: &str) -> Result<f64, XmlError> {
    match numbers(el, attr)?[..] {
        [x] => Ok(x),
        ref v => Err(el.error(attr, format!("expected one number, found {}", v.len()))),
    }
}

/// The `true` or `false` of a `<boolean>` element's `value`.
pub(crate) fn boolean_value(el: &Element) -> Result<bool, XmlError> {
    match el.attr("value").map(str::trim) {
        Some("true") => Ok(true),
        Some("false") => Ok(false),
        other => Err(el.error(
            "value",
            format!(
                "{} is not a boolean (true or false)",
                quote(other.unwrap_or_default())
            ),
        )),
    }
}

/// A 3-vector from `value="x, y, z"` or from `x`/`y`/`z` attributes, each
/// defaulting to `default` (Mitsuba's `<point>`, `<vector>`, `<translate>`,
/// `<scale>`, `<rotate>` axis).
pub(crate) fn vec3(el: &Element, default: f64) -> Result<[f64; 3], XmlError> {
    if el.attr("value").is_some() {
        return match numbers(el, "value")?[..] {
            [x, y, z] => Ok([x, y, z]),
            ref v => Err(el.error("value", format!("expected 3 numbers, found {}", v.len()))),
        };
    }
    let mut out = [default; 3];
    for (k, name) in ["x", "y", "z"].iter().enumerate() {
        if el.attr(name).is_some() {
            out[k] = number(el, name)?;
        }
    }
    Ok(out)
}

impl<'a> Props<'a> {
    pub fn new(el: &'a Element) -> Self {
        Props {
            el,
            used: vec![false; el.children.len()],
        }
    }

    /// The child property named `name`, if any (a second one is an error).
    pub fn get(&mut self, name: &str) -> Result<Option<&'a Element>, XmlError> {
        let mut found = None;
        for (i, c) in self.el.children.iter().enumerate() {
            if c.attr("name") == Some(name) {
                if found.is_some() {
                    return Err(c.error("name", format!("property {} given twice", quote(name))));
                }
                self.used[i] = true;
                found = Some(c);
            }
        }
        Ok(found)
    }

    /// Marks properties that are read but have no effect on the scene.
    pub fn ignore(&mut self, names: &[&str]) {
        for (i, c) in self.el.children.iter().enumerate() {
            if c.attr("name").is_some_and(|n| names.contains(&n)) {
                self.used[i] = true;
            }
        }
    }

    /// Marks unnamed children with these tags (e.g. `<sampler>`) as read.
    pub fn ignore_tags(&mut self, tags: &[&str]) {
        for (i, c) in self.el.children.iter().enumerate() {
            if tags.contains(&c.tag.as_str()) {
                self.used[i] = true;
            }
        }
    }

    fn typed(&mut self, name: &str, tags: &[&str]) -> Result<Option<&'a Element>, XmlError> {
        match self.get(name)? {
            Some(c) if !tags.contains(&c.tag.as_str()) => Err(c.error(
                "",
                format!("property {} must be <{}>", quote(name), tags.join("> or <")),
            )),
            other => Ok(other),
        }
    }

    pub fn opt_float(&mut self, name: &str) -> Result<Option<f64>, XmlError> {
        self.typed(name, &["float", "integer"])?
            .map(|c| number(c, "value"))
            .transpose()
    }

    /// An integer property in `range`.
    pub fn int(
        &mut self,
        name: &str,
        default: i64,
        range: std::ops::RangeInclusive<i64>,
    ) -> Result<i64, XmlError> {
        let Some(c) = self.typed(name, &["integer"])? else {
            return Ok(default);
        };
        let text = c
            .attr("value")
            .ok_or_else(|| c.error("value", "missing attribute `value`"))?;
        let v: i64 = text
            .trim()
            .parse()
            .map_err(|_| c.error("value", format!("{} is not an integer", quote(text))))?;
        if !range.contains(&v) {
            return Err(c.error(
                "value",
                format!("{v} is outside {}..={}", range.start(), range.end()),
            ));
        }
        Ok(v)
    }

    pub fn boolean(&mut self, name: &str, default: bool) -> Result<bool, XmlError> {
        match self.typed(name, &["boolean"])? {
            Some(c) => boolean_value(c),
            None => Ok(default),
        }
    }

    pub fn string(&mut self, name: &str) -> Result<Option<&'a str>, XmlError> {
        match self.typed(name, &["string"])? {
            Some(c) => c
                .attr("value")
                .map(Some)
                .ok_or_else(|| c.error("value", "missing attribute `value`")),
            None => Ok(None),
        }
    }

    /// Nested objects of kind `tag` (`<bsdf>`, `<emitter>`, ...), given
    /// inline or as `<ref id>` to one; refs are followed.
    pub fn nested(&mut self, ctx: &Ctx<'a>, tag: &str) -> Result<Vec<&'a Element>, XmlError> {
        let mut out = Vec::new();
        for (i, c) in self.el.children.iter().enumerate() {
            if self.used[i] || !(c.tag == tag || c.tag == "ref") {
                continue;
            }
            let target = ctx.deref(c)?;
            if target.tag == tag {
                self.used[i] = true;
                out.push(target);
            }
        }
        Ok(out)
    }

    /// Reports every child not read: an error, or with `lenient` a warning.
    pub fn finish(self, ctx: &mut Ctx<'a>) -> Result<(), XmlError> {
        let plugin = self.el.label();
        for (c, used) in self.el.children.iter().zip(&self.used) {
            if !used {
                let what = match c.attr("name") {
                    Some(n) => format!("{plugin} has no supported property {}", quote(n)),
                    None => format!("{plugin} does not support a nested <{}>", c.tag),
                };
                ctx.unsupported(c, "name", &what, "ignoring it")?;
            }
        }
        Ok(())
    }
}
