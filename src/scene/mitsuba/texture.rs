//! Colour-valued properties. A BSDF's textured parameters become texture
//! documents (`scene::texture`: `bitmap` and `checkerboard` with their
//! Mitsuba parameters) through [`parameter`]; everything else that takes a
//! colour (emitters' radiance) becomes one RGB triple through [`value`].
//! Constant `<rgb>`, `<float>` and single-valued `<spectrum>` are exact;
//! with `lenient`, a texture where only a constant is supported becomes
//! its mean linear colour, a sampled spectrum the mean of its values,
//! anything else mid grey.

use serde_json::{Map, Value};

use crate::color::RgbArray;

use super::parse::{Element, quote};
use super::props::{Props, numbers};
use super::transform::Ops;
use super::{Ctx, XmlError};

/// Mitsuba's default for unspecified reflectances, used as the lenient
/// stand-in for textures that have no sensible mean.
const GREY: RgbArray = [0.5; 3];

/// The texture plugins the scene model has (`scene::texture`).
const TEXTURES: &[&str] = &["bitmap", "checkerboard"];

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
    if target.tag != "texture" || !TEXTURES.contains(&kind) {
        return Ok(Value::from(value(ctx, el)?.to_vec()));
    }
    ctx.enter(target)?;
    let mut props = Props::new(target);
    let mut doc = Map::new();
    doc.insert("type".into(), Value::from(kind));
    if kind == "bitmap" {
        let name = props
            .string("filename")?
            .ok_or_else(|| target.error("filename", "a bitmap needs a `filename`"))?;
        doc.insert("filename".into(), Value::from(name));
        doc.insert("raw".into(), Value::from(props.boolean("raw", false)?));
        for name in ["filter_type", "wrap_mode"] {
            if let Some(v) = props.string(name)? {
                doc.insert(name.into(), Value::from(v));
            }
        }
        // The storage format changes precision, not the picture.
        props.ignore(&["format"]);
    } else {
        for (name, default) in [("color0", [0.4; 3]), ("color1", [0.2; 3])] {
            let c = color(ctx, &mut props, name, default)?;
            doc.insert(name.into(), Value::from(c.to_vec()));
        }
    }
    if let Some(t) = props.get("to_uv")?
        && let Some(transform) = Ops::read(t)?.doc()
    {
        let ops = serde_json::to_value(&transform.ops)
            .map_err(|e| t.error("", format!("cannot translate: {e}")))?;
        doc.insert("to_uv".into(), ops);
    }
    props.finish(ctx)?;
    ctx.leave();
    Ok(Value::Object(doc))
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
            let supported = TEXTURES.contains(&kind);
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
/// lenient document: a bitmap's texels (each file decoded once for the
/// whole load, within its budget), a checkerboard's two colours; mid grey
/// for other types. A strict document fails where a stand-in is needed,
/// so it gets mid grey without any image being decoded.
pub(crate) fn mean<'a>(ctx: &mut Ctx<'a>, el: &'a Element) -> Result<RgbArray, XmlError> {
    if !ctx.lenient {
        return Ok(GREY);
    }
    let mut props = Props::new(el);
    let out = match el.attr("type").unwrap_or("") {
        "bitmap" => {
            let name = props
                .string("filename")?
                .ok_or_else(|| el.error("filename", "a bitmap needs a `filename`"))?;
            let raw = props.boolean("raw", false)?;
            ctx.bitmaps
                .load(name, raw, "filename")
                .map_err(|e| XmlError {
                    source: Some(Box::new(e)),
                    ..el.error("filename", "")
                })?
                .mean()
        }
        "checkerboard" => {
            let a = color(ctx, &mut props, "color0", [0.4; 3])?;
            let b = color(ctx, &mut props, "color1", [0.2; 3])?;
            std::array::from_fn(|i| 0.5 * (a[i] + b[i]))
        }
        _ => return Ok(GREY),
    };
    // Whatever else it holds does not change its mean.
    props.ignore(&["filter_type", "wrap_mode", "format", "to_uv"]);
    props.finish(ctx)?;
    Ok(out)
}
