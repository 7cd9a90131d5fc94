//! Display encoding: linear radiance → 8-bit sRGB PNG.
//!
//! Tone mapping is deliberately simple, the same as Mitsuba 3's PNG output
//! of the reference image: scale by `2^exposure`, clamp to [0, 1], apply the
//! sRGB transfer function (IEC 61966-2-1) and round to 8 bits. Nothing is
//! compressed, so a bright emitter saturates to white.

use std::path::Path;

use image::ImageEncoder;
use image::codecs::png::PngEncoder;

use super::{Image, ImageError};

/// Linear → display mapping applied before 8-bit quantisation.
#[derive(Clone, Copy, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct ToneMap {
    /// Exposure in stops: values are multiplied by `2^exposure`.
    pub exposure: f32,
}

impl Default for ToneMap {
    fn default() -> Self {
        Self { exposure: 0.0 }
    }
}

impl ToneMap {
    /// 8-bit sRGB code of one linear channel value. NaN maps to 0.
    pub fn to_srgb8(self, linear: f32) -> u8 {
        let x = (linear * self.exposure.exp2()).clamp(0.0, 1.0);
        let x = if x.is_nan() { 0.0 } else { x };
        let encoded = if x <= 0.003_130_8 {
            12.92 * x
        } else {
            1.055 * x.powf(1.0 / 2.4) - 0.055
        };
        (encoded * 255.0).round() as u8
    }
}

/// The image as PNG bytes (8-bit RGB, sRGB).
pub fn encode_png(image: &Image, tone_map: ToneMap) -> Result<Vec<u8>, ImageError> {
    if !tone_map.exposure.is_finite() {
        return Err(ImageError::invalid(
            "exposure",
            format!("{} is not a finite number of stops", tone_map.exposure),
        ));
    }
    let pixels: Vec<u8> = image
        .rgb()
        .iter()
        .flat_map(|p| p.map(|c| tone_map.to_srgb8(c)))
        .collect();
    encode_png8(&pixels, image.width(), image.height(), false)
}

/// 8-bit pixels, row-major, as PNG: RGB, or RGBA with `alpha` (straight,
/// not premultiplied). The length must match the size.
pub fn encode_png8(
    pixels: &[u8],
    width: u32,
    height: u32,
    alpha: bool,
) -> Result<Vec<u8>, ImageError> {
    let colour = if alpha {
        image::ExtendedColorType::Rgba8
    } else {
        image::ExtendedColorType::Rgb8
    };
    let mut bytes = Vec::new();
    PngEncoder::new(&mut bytes)
        .write_image(pixels, width, height, colour)
        .map_err(|e| ImageError::Png {
            what: "encoding".into(),
            reason: e.to_string(),
        })?;
    Ok(bytes)
}

/// Writes the image as a tone-mapped PNG file.
pub fn write_png(image: &Image, tone_map: ToneMap, path: &Path) -> Result<(), ImageError> {
    let bytes = encode_png(image, tone_map)?;
    std::fs::write(path, bytes).map_err(|e| ImageError::Png {
        what: format!("writing {}", path.display()),
        reason: e.to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_curve_hits_its_anchor_points() {
        let t = ToneMap::default();
        assert_eq!(t.to_srgb8(0.0), 0);
        assert_eq!(t.to_srgb8(1.0), 255);
        assert_eq!(t.to_srgb8(7.0), 255);
        assert_eq!(t.to_srgb8(-1.0), 0);
        assert_eq!(t.to_srgb8(f32::NAN), 0);
        // Code 128 (sRGB 0.502) is linear 0.2159.
        assert_eq!(t.to_srgb8(0.2159), 128);
        // One stop up doubles the linear value.
        assert_eq!(ToneMap { exposure: 1.0 }.to_srgb8(0.108), t.to_srgb8(0.216));
    }

    #[test]
    fn png_has_the_image_size_and_pixels() {
        let rgb = vec![[0.0, 0.2159, 1.0], [1.0, 0.0, 0.0], [0.5, 0.5, 0.5]];
        let image = Image::from_parts(3, 1, rgb, None).expect("valid");
        let bytes = encode_png(&image, ToneMap::default()).expect("encodes");
        let decoded = image::load_from_memory_with_format(&bytes, image::ImageFormat::Png)
            .expect("decodes")
            .to_rgb8();
        assert_eq!(decoded.dimensions(), (3, 1));
        assert_eq!(decoded.get_pixel(0, 0).0, [0, 128, 255]);
        assert_eq!(decoded.get_pixel(1, 0).0, [255, 0, 0]);
        assert!(encode_png(&image, ToneMap { exposure: f32::NAN }).is_err());
    }
}
