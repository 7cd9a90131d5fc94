//! Colour-valued properties. A BSDF's textured parameters become texture
//! documents (`scene::texture`, whose plugins take Mitsuba's names) through
//! [`parameter`], which copies the `<texture>`'s properties for the
//! plugin's own parser to read; everything else that takes a
//! colour (emitters' radiance) becomes one RGB triple through [`value`].
//! Constant `<rgb>` and `<float>` are exact, and so is `<spectrum>` (one
//! value, `λ:v` pairs or a spectrum file), read into RGB as Mitsuba 3's
//! RGB variants read it for what the property describes
//! ([`SpectrumUse`]); with `lenient`, a texture where only a constant is
//! supported becomes its mean linear colour, anything else mid grey.

use serde_json::{Map, Value};

use crate::color::RgbArray;
use crate::color::spectrum::{SampledSpectrum, SpectrumUse, uniform_to_rgb};
use crate::scene::params::Params;
use crate::scene::read::read_to_string;
use crate::scene::texture::{Texture, plugin_names};

use super::parse::{Element, quote};
use super::props::{Props, numbers};
use super::transform::Ops;
use super::{Ctx, XmlError};

/// Mitsuba's default for unspecified reflectances, used as the lenient
/// stand-in for textures that have no sensible mean.
const GREY: RgbArray = [0.5; 3];

/// Largest spectrum file read, in bytes (a 1-nm table over 300–1000 nm is
/// about 10 kB).
const MAX_SPECTRUM_FILE_BYTES: u64 = 1 << 20;

/// The RGB value of property `name` of `props`, describing `usage`, or
/// `default` if absent.
pub(crate) fn color<'a>(
    ctx: &mut Ctx<'a>,
    props: &mut Props<'a>,
    name: &str,
    default: RgbArray,
    usage: SpectrumUse,
) -> Result<RgbArray, XmlError> {
    match props.get(name)? {
        Some(el) => value(ctx, el, usage),
        None => Ok(default),
    }
}

/// The document value of a colour property `el` describing `usage`
/// (following `<ref>`s): `[r, g, b]`, or a texture document for a
/// supported texture.
pub(crate) fn parameter<'a>(
    ctx: &mut Ctx<'a>,
    el: &'a Element,
    usage: SpectrumUse,
) -> Result<Value, XmlError> {
    let target = ctx.deref(el)?;
    let kind = target.attr("type").unwrap_or("");
    if target.tag != "texture" || !plugin_names().contains(&kind) {
        return Ok(Value::from(value(ctx, el, usage)?.to_vec()));
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
            // A texture's own colours are reflectance-like whatever uses
            // the texture, as Mitsuba's texture plugins read them.
            _ => Value::from(value(ctx, child, SpectrumUse::Reflectance)?.to_vec()),
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

/// The RGB value of a colour element describing `usage` (following
/// `<ref>`s).
pub(crate) fn value<'a>(
    ctx: &mut Ctx<'a>,
    el: &'a Element,
    usage: SpectrumUse,
) -> Result<RgbArray, XmlError> {
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
        "spectrum" => spectrum(ctx, target, usage),
        "texture" if target.attr("type") == Some("rawconstant") => raw_constant(ctx, target),
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

/// A `<spectrum>` property as Mitsuba 3's RGB variants read it for
/// `usage`: one value, `λ:v` pairs, or a spectrum file (relative to the
/// scene file, within the scenes directory), exactly one of them.
fn spectrum<'a>(
    ctx: &mut Ctx<'a>,
    el: &'a Element,
    usage: SpectrumUse,
) -> Result<RgbArray, XmlError> {
    match el.attr("type") {
        // A `uniform` spectrum plugin is its value in every channel: as a
        // texture object it is not converted for emitters.
        Some("uniform") => return raw_constant(ctx, el),
        Some(kind) => {
            ctx.unsupported(
                el,
                "type",
                &format!("spectrum plugin {} is not supported", quote(kind)),
                "using mid grey",
            )?;
            return Ok(GREY);
        }
        None => {}
    }
    let sampled = match (el.attr("value"), el.attr("filename")) {
        (Some(text), None) if !text.contains(':') => {
            return Ok(uniform_to_rgb(super::props::number(el, "value")?, usage));
        }
        (Some(text), None) => {
            SampledSpectrum::parse_pairs(text).map_err(|e| el.error("value", e))?
        }
        (None, Some(name)) => {
            let path = ctx
                .bitmaps
                .files()
                .resolve(name, "filename")
                .map_err(|e| el.error("filename", e.to_string()))?;
            let text = read_to_string(&path, MAX_SPECTRUM_FILE_BYTES)
                .map_err(|e| el.error("filename", format!("cannot read {}: {e}", quote(name))))?;
            SampledSpectrum::parse_file(&text)
                .map_err(|e| el.error("filename", format!("{}: {e}", quote(name))))?
        }
        _ => {
            return Err(el.error(
                "value",
                "a <spectrum> takes `value` or `filename`, exactly one of them",
            ));
        }
    };
    Ok(sampled.to_rgb(usage).to_array())
}

/// The constant of a `<texture type="rawconstant">` or a `<spectrum
/// type="uniform">`: its `value`, a `<float>` in every channel or a
/// `<vector>`/`<point>` per channel, used as it is (Mitsuba converts
/// neither).
fn raw_constant<'a>(ctx: &mut Ctx<'a>, el: &'a Element) -> Result<RgbArray, XmlError> {
    let mut props = Props::new(el);
    let value = props
        .get("value")?
        .ok_or_else(|| el.error("value", "missing property `value`"))?;
    let value = ctx.deref(value)?;
    let rgb = match value.tag.as_str() {
        "float" => [super::props::number(value, "value")?; 3],
        "vector" | "point" => super::props::vec3(value, 0.0)?,
        other => {
            return Err(value.error(
                "",
                format!("a constant's `value` is a <float> or a <vector>, not a <{other}>"),
            ));
        }
    };
    props.finish(ctx)?;
    Ok(rgb)
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
