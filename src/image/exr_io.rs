//! OpenEXR encoding of [`Image`]: one layer of f32 channels `R`, `G`, `B`
//! (linear radiance) and, when the image has one, `variance` (the per-pixel
//! variance of the estimate, mean over the three channels — see [`Image`]).
//! Readers that only know RGB ignore the extra channel.

use std::io::Cursor;
use std::path::Path;

use exr::prelude::*;
// The prelude brings its own `Result` alias; keep the standard one.
use std::result::Result;

use super::{Image, ImageError, MAX_PIXELS};

/// Name of the per-pixel variance channel.
pub const VARIANCE_CHANNEL: &str = "variance";

fn exr_error(what: impl Into<String>, e: impl std::fmt::Display) -> ImageError {
    ImageError::Exr {
        what: what.into(),
        reason: e.to_string(),
    }
}

/// The image as EXR file bytes.
pub fn encode_exr(image: &Image) -> Result<Vec<u8>, ImageError> {
    let size = (image.width() as usize, image.height() as usize);
    let channel = |i: usize| FlatSamples::F32(image.rgb().iter().map(|p| p[i]).collect());
    let mut channels = SmallVec::from_vec(vec![
        AnyChannel::new("R", channel(0)),
        AnyChannel::new("G", channel(1)),
        AnyChannel::new("B", channel(2)),
    ]);
    if let Some(v) = image.variance() {
        channels.push(AnyChannel::new(
            VARIANCE_CHANNEL,
            FlatSamples::F32(v.to_vec()),
        ));
    }
    let layer = Layer::new(
        size,
        LayerAttributes::default(),
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(channels),
    );
    let mut bytes = Vec::new();
    exr::image::Image::from_layer(layer)
        .write()
        .to_buffered(Cursor::new(&mut bytes))
        .map_err(|e| exr_error("encoding", e))?;
    Ok(bytes)
}

/// Checks every part of an EXR file, from its headers, before any pixel
/// memory is allocated: `(width, height)` of each must be within
/// `1..=max_side` and its area at most `max_area` pixels. Every part, not
/// the first: the decoders take the first part that has the channels they
/// want, so a small part in front must not vouch for a large one behind
/// it. A part's largest resolution level is its data window, so mip and rip
/// levels need no check of their own. Returns the first part's size.
pub fn check_exr_parts(
    meta: &exr::meta::MetaData,
    max_side: usize,
    max_area: usize,
) -> Result<(usize, usize), String> {
    let first = meta.headers.first().ok_or("the file has no parts")?;
    for (i, header) in meta.headers.iter().enumerate() {
        let size = header.layer_size;
        let (width, height) = (size.width(), size.height());
        let area = width.checked_mul(height);
        if width == 0
            || height == 0
            || width > max_side
            || height > max_side
            || area.is_none_or(|a| a > max_area)
        {
            return Err(format!(
                "part {i} is {width}×{height}; each side must be in 1..={max_side} and the area at most {max_area} pixels"
            ));
        }
    }
    Ok((first.layer_size.width(), first.layer_size.height()))
}

/// Writes the image to an EXR file.
pub fn write_exr(image: &Image, path: &Path) -> Result<(), ImageError> {
    let bytes = encode_exr(image)?;
    std::fs::write(path, bytes).map_err(|e| exr_error(format!("writing {}", path.display()), e))
}

/// Reads an EXR file's first layer: channels `R`, `G`, `B` (required) and
/// `variance` (optional).
pub fn read_exr(path: &Path) -> Result<Image, ImageError> {
    let bytes =
        std::fs::read(path).map_err(|e| exr_error(format!("reading {}", path.display()), e))?;
    decode_exr(&bytes).map_err(|e| match e {
        ImageError::Exr { what, reason } => ImageError::Exr {
            what: format!("{what} {}", path.display()),
            reason,
        },
        other => other,
    })
}

/// Decodes EXR bytes (see [`read_exr`]). The size is checked from the
/// header before pixel memory is allocated.
pub fn decode_exr(bytes: &[u8]) -> Result<Image, ImageError> {
    let meta = exr::meta::MetaData::read_from_buffered(Cursor::new(bytes), false)
        .map_err(|e| exr_error("header", e))?;
    let max = MAX_PIXELS as usize;
    check_exr_parts(&meta, max, max).map_err(|e| exr_error("header", e))?;
    type Pixels = (usize, Vec<[f32; 3]>, Option<Vec<f32>>);
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .specific_channels()
        .required("R")
        .required("G")
        .required("B")
        .optional(VARIANCE_CHANNEL, 0.0f32)
        .collect_pixels(
            |resolution, (_, _, _, variance): &(_, _, _, Option<ChannelDescription>)| -> Pixels {
                let n = resolution.area();
                (
                    resolution.width(),
                    vec![[0.0; 3]; n],
                    variance.as_ref().map(|_| vec![0.0; n]),
                )
            },
            |pixels: &mut Pixels, position, (r, g, b, v): (f32, f32, f32, f32)| {
                let i = position.y() * pixels.0 + position.x();
                pixels.1[i] = [r, g, b];
                if let Some(variance) = &mut pixels.2 {
                    variance[i] = v;
                }
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_buffered(Cursor::new(bytes))
        .map_err(|e| exr_error("decoding", e))?;
    let layer = image.layer_data;
    let (_, rgb, variance) = layer.channel_data.pixels;
    Image::from_parts(
        layer.size.width() as u32,
        layer.size.height() as u32,
        rgb,
        variance,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_keeps_rgb_and_variance_bit_exact() {
        let rgb = (0..12)
            .map(|i| [i as f32 * 0.37, 1.0 / (i as f32 + 1.0), 1e-7 * i as f32])
            .collect();
        let variance = (0..12).map(|i| (i * i) as f32 * 1e-3).collect();
        let image = Image::from_parts(4, 3, rgb, Some(variance)).expect("valid");
        let back = decode_exr(&encode_exr(&image).expect("encodes")).expect("decodes");
        assert_eq!(back, image);

        let path = std::env::temp_dir().join(format!("bmc-exr-{}.exr", std::process::id()));
        write_exr(&image, &path).expect("writes");
        let from_file = read_exr(&path);
        let _ = std::fs::remove_file(&path);
        assert_eq!(from_file.expect("reads"), image);
    }

    #[test]
    fn images_without_variance_read_back_without_it() {
        let image =
            Image::from_parts(2, 1, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]], None).expect("valid");
        let back = decode_exr(&encode_exr(&image).expect("encodes")).expect("decodes");
        assert_eq!(back, image);
    }

    #[test]
    fn a_large_part_behind_a_small_one_is_refused_before_decoding() {
        // 200000² RGB f32 would be 480 GB: allocating it aborted the process.
        let err = decode_exr(&crate::testing::two_part_exr(200_000)).unwrap_err();
        assert!(err.to_string().contains("part 1 is 200000×200000"), "{err}");
    }

    #[test]
    fn garbage_is_an_error() {
        assert!(matches!(
            decode_exr(b"not an exr"),
            Err(ImageError::Exr { .. })
        ));
        assert!(read_exr(Path::new("/nonexistent/x.exr")).is_err());
    }
}
