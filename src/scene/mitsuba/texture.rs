//! Colour-valued properties (`reflectance`, `radiance`, ...) → one RGB
//! triple. The scene model has no textures: constant `<rgb>`, `<float>` and
//! single-valued `<spectrum>` are exact; with `lenient`, a `bitmap` becomes
//! its mean linear colour, a `checkerboard` the mean of its two colours, a
//! sampled spectrum the mean of its values, anything else mid grey.

use std::path::Path;

use crate::scene::environment;
use crate::scene::format::Rgb;

use super::parse::Element;
use super::props::{Props, numbers};
use super::{Ctx, XmlError};

/// Mitsuba's default for unspecified reflectances, used as the lenient
/// stand-in for textures that have no sensible mean.
const GREY: Rgb = [0.5; 3];

/// The RGB value of property `name` of `props`, or `default` if absent.
pub(crate) fn color<'a>(
    ctx: &mut Ctx<'a>,
    props: &mut Props<'a>,
    name: &str,
    default: Rgb,
) -> Result<Rgb, XmlError> {
    match props.get(name)? {
        Some(el) => value(ctx, el),
        None => Ok(default),
    }
}

/// The RGB value of a colour element (following `<ref>`s).
pub(crate) fn value<'a>(ctx: &mut Ctx<'a>, el: &'a Element) -> Result<Rgb, XmlError> {
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
        "texture" => texture(ctx, target),
        other => Err(target.error(
            "",
            format!("<{other}> is not a colour (rgb, float, spectrum or texture)"),
        )),
    };
    ctx.leave();
    out
}

fn spectrum(ctx: &mut Ctx, el: &Element) -> Result<Rgb, XmlError> {
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
            .ok_or_else(|| el.error("value", format!("{pair:?} is not `wavelength:value`")))?;
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

fn texture<'a>(ctx: &mut Ctx<'a>, el: &'a Element) -> Result<Rgb, XmlError> {
    let kind = el.attr("type").unwrap_or("");
    let mut props = Props::new(el);
    let out = match kind {
        "bitmap" => {
            let name = props
                .string("filename")?
                .ok_or_else(|| el.error("filename", "a bitmap needs a `filename`"))?;
            let raw = props.boolean("raw", false)?;
            props.ignore(&["filter_type", "wrap_mode", "format"]);
            ctx.unsupported(
                el,
                "",
                "bitmap textures are not supported (the scene model has no textures)",
                "using the image's mean linear colour",
            )?;
            let path = ctx.resolve(el, "filename", name)?;
            bitmap_mean(&path, raw).map_err(|m| el.error("filename", m))?
        }
        "checkerboard" => {
            let a = color(ctx, &mut props, "color0", [0.4; 3])?;
            let b = color(ctx, &mut props, "color1", [0.2; 3])?;
            ctx.unsupported(
                el,
                "",
                "checkerboard textures are not supported",
                "using the mean of color0 and color1",
            )?;
            std::array::from_fn(|i| 0.5 * (a[i] + b[i]))
        }
        other => {
            ctx.unsupported(
                el,
                "type",
                &format!("texture type {other:?} is not supported"),
                "using mid grey",
            )?;
            return Ok(GREY);
        }
    };
    props.ignore(&["to_uv"]);
    props.finish(ctx)?;
    Ok(out)
}

/// Mean linear RGB of an image: EXR as stored; 8/16-bit images decoded from
/// sRGB unless `raw` (Mitsuba's bitmap convention).
fn bitmap_mean(path: &Path, raw: bool) -> Result<Rgb, String> {
    let is_exr = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    let texels: Vec<[f64; 3]> = if is_exr {
        let (_, _, texels) = environment::read_exr(path, "filename").map_err(|e| e.to_string())?;
        texels.iter().map(|t| t.map(f64::from)).collect()
    } else {
        let image = image::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let decode = |c: f32| {
            let c = f64::from(c);
            if raw { c } else { srgb_to_linear(c) }
        };
        image
            .to_rgb32f()
            .pixels()
            .map(|p| p.0.map(decode))
            .collect()
    };
    if texels.is_empty() {
        return Err(format!("{}: empty image", path.display()));
    }
    let n = texels.len() as f64;
    Ok(std::array::from_fn(|i| {
        texels.iter().map(|t| t[i]).sum::<f64>() / n
    }))
}

/// The sRGB electro-optical transfer function (IEC 61966-2-1).
fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}
