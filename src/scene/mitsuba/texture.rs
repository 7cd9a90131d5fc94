//! Colour-valued properties (`reflectance`, `radiance`, ...) → one RGB
//! triple. The scene model has no textures: constant `<rgb>`, `<float>` and
//! single-valued `<spectrum>` are exact; with `lenient`, a `bitmap` becomes
//! its mean linear colour, a `checkerboard` the mean of its two colours, a
//! sampled spectrum the mean of its values, anything else mid grey.

use std::io::BufReader;
use std::path::Path;

use crate::scene::format::Rgb;
use crate::scene::{environment, read};

use super::parse::{Element, quote};
use super::props::{Props, numbers};
use super::{Ctx, XmlError};

/// Largest width or height of a PNG bitmap texture, pixels.
pub const MAX_BITMAP_SIDE: u32 = 16384;
/// Most pixels of a PNG bitmap texture (4096²). Only the mean colour is kept
/// and rows are streamed, so memory stays at one row, but decoding time grows
/// with the pixel count: a 16384² grey PNG compresses to ~260 KB and would
/// take seconds of CPU (and, decoded whole, 6 GiB).
pub const MAX_BITMAP_PIXELS: u64 = 4096 * 4096;
/// Largest PNG file read, bytes (a 4096² RGBA 16-bit image stored
/// uncompressed is 128 MiB).
pub const MAX_BITMAP_FILE_BYTES: u64 = 160 << 20;
/// Bytes the PNG decoder may allocate (row buffers, metadata chunks).
const MAX_BITMAP_DECODER_BYTES: usize = 16 << 20;

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
                &format!("texture type {} is not supported", quote(other)),
                "using mid grey",
            )?;
            return Ok(GREY);
        }
    };
    props.ignore(&["to_uv"]);
    props.finish(ctx)?;
    Ok(out)
}

/// Mean linear RGB of an image: EXR as stored; PNG decoded from sRGB
/// unless `raw` (Mitsuba's bitmap convention).
fn bitmap_mean(path: &Path, raw: bool) -> Result<Rgb, String> {
    let is_exr = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    if !is_exr {
        return png_mean(path, raw).map_err(|e| format!("{}: {e}", path.display()));
    }
    let (_, _, texels) = environment::read_exr(path, "filename").map_err(|e| e.to_string())?;
    if texels.is_empty() {
        return Err(format!("{}: empty image", path.display()));
    }
    let n = texels.len() as f64;
    Ok(std::array::from_fn(|i| {
        texels.iter().map(|t| f64::from(t[i])).sum::<f64>() / n
    }))
}

/// Mean linear RGB of a PNG, streamed row by row (alpha ignored). Refuses
/// images over [`MAX_BITMAP_SIDE`] or [`MAX_BITMAP_PIXELS`] before decoding.
fn png_mean(path: &Path, raw: bool) -> Result<Rgb, String> {
    let file =
        read::open_capped(path, MAX_BITMAP_FILE_BYTES).map_err(|e| format!("cannot open: {e}"))?;
    let limits = png::Limits {
        bytes: MAX_BITMAP_DECODER_BYTES,
    };
    let mut decoder = png::Decoder::new_with_limits(BufReader::new(file), limits);
    // Palettes and low bit depths become 8-bit grey or RGB (with alpha).
    decoder.set_transformations(png::Transformations::EXPAND);
    let mut reader = decoder
        .read_info()
        .map_err(|e| format!("not a readable PNG: {e}"))?;
    let (width, height) = (reader.info().width, reader.info().height);
    if width > MAX_BITMAP_SIDE
        || height > MAX_BITMAP_SIDE
        || u64::from(width) * u64::from(height) > MAX_BITMAP_PIXELS
    {
        return Err(format!(
            "image is {width}×{height}; each side must be at most {MAX_BITMAP_SIDE} and the area at most {MAX_BITMAP_PIXELS} pixels"
        ));
    }
    let (color, depth) = reader.output_color_type();
    let channels = color.samples();
    let sample_bytes = if depth == png::BitDepth::Sixteen {
        2
    } else {
        1
    };
    let lut: Vec<f64> = (0..256)
        .map(|v| {
            let c = f64::from(v) / 255.0;
            if raw { c } else { srgb_to_linear(c) }
        })
        .collect();
    let decode = |bytes: &[u8]| -> f64 {
        if sample_bytes == 2 {
            let c = f64::from(u16::from_be_bytes([bytes[0], bytes[1]])) / 65535.0;
            if raw { c } else { srgb_to_linear(c) }
        } else {
            lut[usize::from(bytes[0])]
        }
    };
    let mut sum = [0.0f64; 3];
    let mut pixels = 0u64;
    // Interlaced images come as the rows of each pass; every pixel appears
    // in exactly one, so sums and counts are still over the whole image.
    while let Some(row) = reader
        .next_row()
        .map_err(|e| format!("cannot decode PNG: {e}"))?
    {
        for pixel in row.data().chunks_exact(channels * sample_bytes) {
            let sample = |c: usize| decode(&pixel[c * sample_bytes..]);
            let rgb = if channels >= 3 {
                [sample(0), sample(1), sample(2)]
            } else {
                [sample(0); 3]
            };
            for (s, c) in sum.iter_mut().zip(rgb) {
                *s += c;
            }
            pixels += 1;
        }
    }
    if pixels == 0 {
        return Err("empty image".into());
    }
    Ok(sum.map(|s| s / pixels as f64))
}

/// The sRGB electro-optical transfer function (IEC 61966-2-1).
fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}
