//! Colour-valued properties. A BSDF's textured parameters become texture
//! documents (`scene::texture`, whose plugins take Mitsuba's names) through
//! [`parameter`], which copies the `<texture>`'s properties for the
//! plugin's own parser to read; everything else that takes a
//! colour (emitters' radiance) becomes one RGB triple through [`value`].
//! Constant `<rgb>`, `<float>` and single-valued `<spectrum>` are exact;
//! with `lenient`, a texture where only a constant is supported becomes
//! its mean linear colour, a sampled spectrum the mean of its values,
//! anything else mid grey.

use serde_json::{Map, Value};

use crate::color::RgbArray;
use crate::scene::params::Params;
use crate::scene::texture::{Texture, plugin_names};

use super::parse::{Element, quote};
use super::props::{Props, numbers};
use super::transform::Ops;
use super::{Ctx, XmlError};

/// Mitsuba's default for unspecified reflectances, used as the lenient
/// stand-in for textures that have no sensible mean.
const GREY: RgbArray = [0.5; 3];

/// The RGB value of property `name` of `props`, or `default` if absent.
pub(crate) fn color<'a>(
    ctx: &mut Ctx<'a>,
    props: &mut Props<'a>,
    name: &str,
    default: RgbArray,
) -> Result<RgbArray, XmlError> {
    match props.get(name)? {
        Some(el) => value(ctx, el),
        None => Ok(default),
    }
}

/// The document value of a BSDF's colour property `el` (following
/// `<ref>`s): `[r, g, b]`, or a texture document for a supported texture.
pub(crate) fn parameter<'a>(ctx: &mut Ctx<'a>, el: &'a Element) -> Result<Value, XmlError> {
    let target = ctx.deref(el)?;
    let kind = target.attr("type").unwrap_or("");
    if target.tag != "texture" || !plugin_names().contains(&kind) {
        return Ok(Value::from(value(ctx, el)?.to_vec()));
    }
    ctx.enter(target)?;
    let mut doc = document(ctx, target, kind)?;
    doc.insert("type".into(), Value::from(kind));
    ctx.leave();
    Ok(Value::Object(doc))
}

/// The parameters of `<texture>` element `el` of plugin `kind`, which the
/// scene model has: its properties copied under their names (strings and
/// booleans as they are, colours as `[r, g, b]`, `to_uv` as a transform
/// document) with the defaults the plugin's documents state. Those the
/// plugin does not take are reported as unsupported; `format`, the
/// storage precision, changes nothing in the picture and is dropped.
fn document<'a>(
    ctx: &mut Ctx<'a>,
    el: &'a Element,
    kind: &str,
) -> Result<Map<String, Value>, XmlError> {
    let mut props = Props::new(el);
    props.ignore(&["format"]);
    let mut doc = Texture::stated_defaults(kind);
    for child in &el.children {
        let Some(name) = child.attr("name").filter(|n| *n != "format") else {
            continue;
        };
        let target = ctx.deref(child)?;
        let value = match target.tag.as_str() {
            "string" => Value::from(
                target
                    .attr("value")
                    .ok_or_else(|| target.error("value", "missing attribute `value`"))?,
            ),
            "boolean" => Value::Bool(super::props::boolean_value(target)?),
            "transform" => match Ops::read(child)?.doc() {
                Some(transform) => serde_json::to_value(&transform.ops)
                    .map_err(|e| child.error("", format!("cannot translate: {e}")))?,
                None => continue,
            },
            _ => Value::from(value(ctx, child)?.to_vec()),
        };
        doc.insert(name.to_string(), value);
    }
    for name in Texture::unknown_parameters(kind, &doc) {
        doc.remove(&name);
    }
    let names: Vec<String> = doc.keys().cloned().collect();
    for name in names {
        props.get(&name)?;
    }
    props.finish(ctx)?;
    Ok(doc)
}

/// The RGB value of a colour element (following `<ref>`s).
pub(crate) fn value<'a>(ctx: &mut Ctx<'a>, el: &'a Element) -> Result<RgbArray, XmlError> {
    let target = ctx.deref(el)?;
    ctx.enter(target)?;
    let out = match target.tag.as_str() {
        "rgb" => match numbers(target, "value")?[..] {
            [g] => Ok([g; 3]),
            [r, g, b] => Ok([r, g, b]),
            ref v => Err(target.error(
                "value",
                format!("expected 1 or 3 numbers, found {}", v.len()),
            )),
        },
        "float" => Ok([super::props::number(target, "value")?; 3]),
        "spectrum" => spectrum(ctx, target),
        "texture" => {
            let kind = target.attr("type").unwrap_or("");
            let supported = plugin_names().contains(&kind);
            ctx.unsupported(
                target,
                "type",
                &if supported {
                    format!("a {} texture is not supported here", quote(kind))
                } else {
                    format!("texture type {} is not supported", quote(kind))
                },
                if supported {
                    "using its mean linear colour"
                } else {
                    "using mid grey"
                },
            )?;
            mean(ctx, target)
        }
        other => Err(target.error(
            "",
            format!("<{other}> is not a colour (rgb, float, spectrum or texture)"),
        )),
    };
    ctx.leave();
    out
}

fn spectrum(ctx: &mut Ctx, el: &Element) -> Result<RgbArray, XmlError> {
    if el.attr("filename").is_some() {
        ctx.unsupported(
            el,
            "filename",
            "spectra read from files are not supported",
            "using mid grey",
        )?;
        return Ok(GREY);
    }
    let text = el
        .attr("value")
        .ok_or_else(|| el.error("value", "missing attribute `value`"))?;
    if !text.contains(':') {
        return Ok([super::props::number(el, "value")?; 3]);
    }
    // Sampled spectrum "λ1:v1, λ2:v2, ...".
    let mut values = Vec::new();
    for pair in text.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let v = pair
            .split_once(':')
            .and_then(|(_, v)| v.trim().parse::<f64>().ok())
            .filter(|v| v.is_finite())
            .ok_or_else(|| {
                el.error(
                    "value",
                    format!("{} is not `wavelength:value`", quote(pair)),
                )
            })?;
        values.push(v);
    }
    ctx.unsupported(
        el,
        "value",
        "sampled spectra are not supported (the scene model is RGB)",
        "using the mean of the sampled values as grey",
    )?;
    let mean = values.iter().sum::<f64>() / values.len().max(1) as f64;
    Ok([mean; 3])
}

/// The mean linear colour of texture element `el`, the stand-in of a
/// lenient document: the plugin's own mean of the texture its properties
/// make (a bitmap's image decoded once for the whole load, within its
/// budget); mid grey for types the scene model lacks. A strict document
/// fails where a stand-in is needed, so it gets mid grey without any image
/// being decoded.
pub(crate) fn mean<'a>(ctx: &mut Ctx<'a>, el: &'a Element) -> Result<RgbArray, XmlError> {
    let kind = el.attr("type").unwrap_or("");
    if !ctx.lenient || !plugin_names().contains(&kind) {
        return Ok(GREY);
    }
    let mut doc = document(ctx, el, kind)?;
    // The mean is over the unit square, whatever maps onto it.
    doc.remove("to_uv");
    doc.insert("type".into(), Value::from(kind));
    let params = Params::new("", Map::new()).with_bitmaps(ctx.bitmaps);
    let texture = Texture::parse(&params, "", Value::Object(doc)).map_err(|e| XmlError {
        source: Some(Box::new(e)),
        ..el.error("", "")
    })?;
    Ok(texture.mean())
}
