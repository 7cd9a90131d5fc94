//! Rendered images: linear RGB radiance per pixel with an optional per-pixel
//! variance, their file and byte encodings (EXR, tone-mapped PNG, JSON),
//! the relative-RMSE comparison used for validation and a denoiser guided
//! by buffers the renderer hands it (`denoise`). Knows nothing of
//! scenes or HTTP.
//!
//! Pixels are row-major, top row first, (0, 0) the top-left corner — the
//! camera's raster convention ([`crate::scene::Camera::generate_ray`]).
//! Values are radiance in W/(m²·sr) per linear RGB channel, stored as f32.

mod compare;
mod denoise;
mod error;
pub(crate) mod exr_io;
mod false_colour;
#[cfg(feature = "oidn")]
pub mod oidn;
pub(crate) mod png_io;

use serde::Serialize;

pub use compare::{RelativeRmse, relative_rmse};
pub use denoise::{GuideBuffers, GuidePixel, denoise};
pub use error::ImageError;
pub use exr_io::{check_exr_parts, decode_exr, encode_exr, read_exr, write_exr};
pub use png_io::ToneMap;

/// Largest number of pixels an image may hold (8192², 1.3 GB with variance).
pub const MAX_PIXELS: u64 = 1 << 26;

/// A linear RGB image, optionally with the variance of each pixel's value.
///
/// Invariants (checked by every constructor): both sides ≥ 1, at most
/// [`MAX_PIXELS`] pixels, `rgb.len() == width·height`, and `variance`, when
/// present, has the same length as `rgb`.
///
/// `variance[i]` is the variance of the Monte Carlo estimate of pixel `i`
/// (the sample variance of its radiance samples divided by their number, or
/// the mean variance its shader reports for them over their number where
/// that is larger, docs/math.md §13.3), averaged over the three channels,
/// in (W/(m²·sr))². Its square root is the pixel's standard error.
///
/// Serialises (serde) as `{"width", "height", "rgb": [[r, g, b], …],
/// "variance": [v, …] | null}` — the JSON tile format.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Image {
    width: u32,
    height: u32,
    rgb: Vec<[f32; 3]>,
    variance: Option<Vec<f32>>,
}

/// The byte encodings an image can be delivered in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ImageEncoding {
    /// OpenEXR, f32 channels `R`, `G`, `B` and `variance` (when present).
    Exr,
    /// 8-bit sRGB PNG, tone-mapped by a [`ToneMap`].
    Png,
    /// The serde form of [`Image`] as JSON.
    Json,
}

impl ImageEncoding {
    /// MIME type of the encoded bytes.
    pub fn content_type(self) -> &'static str {
        match self {
            Self::Exr => "image/x-exr",
            Self::Png => "image/png",
            Self::Json => "application/json",
        }
    }
}

impl Image {
    /// A black image with zero variance.
    pub fn black(width: u32, height: u32) -> Result<Self, ImageError> {
        let n = check_size(width, height)?;
        Ok(Self {
            width,
            height,
            rgb: vec![[0.0; 3]; n],
            variance: Some(vec![0.0; n]),
        })
    }

    /// An image from its parts, checking the invariants.
    pub fn from_parts(
        width: u32,
        height: u32,
        rgb: Vec<[f32; 3]>,
        variance: Option<Vec<f32>>,
    ) -> Result<Self, ImageError> {
        let n = check_size(width, height)?;
        if rgb.len() != n {
            return Err(ImageError::invalid(
                "rgb",
                format!("{} pixels for a {width}×{height} image", rgb.len()),
            ));
        }
        if let Some(v) = &variance
            && v.len() != n
        {
            return Err(ImageError::invalid(
                "variance",
                format!("{} values for a {width}×{height} image", v.len()),
            ));
        }
        Ok(Self {
            width,
            height,
            rgb,
            variance,
        })
    }

    pub fn width(&self) -> u32 {
        self.width
    }

    pub fn height(&self) -> u32 {
        self.height
    }

    /// Pixels, row-major, top row first.
    pub fn rgb(&self) -> &[[f32; 3]] {
        &self.rgb
    }

    /// Per-pixel variance of the estimate (see the type's docs), if known.
    pub fn variance(&self) -> Option<&[f32]> {
        self.variance.as_deref()
    }

    /// The `width`×`height` rectangle whose top-left corner is (`x`, `y`),
    /// variance included.
    pub fn crop(&self, x: u32, y: u32, width: u32, height: u32) -> Result<Image, ImageError> {
        if x.saturating_add(width) > self.width || y.saturating_add(height) > self.height {
            return Err(ImageError::invalid(
                "crop",
                format!(
                    "{width}×{height} at ({x}, {y}) outside a {}×{} image",
                    self.width, self.height
                ),
            ));
        }
        let rows = (y..y + height).flat_map(|r| {
            let start = (r * self.width + x) as usize;
            start..start + width as usize
        });
        let rgb = rows.clone().map(|i| self.rgb[i]).collect();
        let variance = self.variance.as_ref().map(|v| rows.map(|i| v[i]).collect());
        Image::from_parts(width, height, rgb, variance)
    }

    /// Pixel at column `x`, row `y` (`None` outside the image).
    pub fn pixel(&self, x: u32, y: u32) -> Option<[f32; 3]> {
        (x < self.width && y < self.height)
            .then(|| self.rgb[y as usize * self.width as usize + x as usize])
    }

    /// Copies `tile` into this image with its top-left corner at (x, y).
    /// The variance is kept only if both images have one.
    pub fn insert(&mut self, tile: &Image, x: u32, y: u32) -> Result<(), ImageError> {
        let fits =
            |start: u32, len: u32, side: u32| u64::from(start) + u64::from(len) <= u64::from(side);
        if !fits(x, tile.width, self.width) || !fits(y, tile.height, self.height) {
            return Err(ImageError::invalid(
                "tile",
                format!(
                    "{}×{} at ({x}, {y}) does not fit in {}×{}",
                    tile.width, tile.height, self.width, self.height
                ),
            ));
        }
        let (w, tw) = (self.width as usize, tile.width as usize);
        for row in 0..tile.height as usize {
            let dst = (y as usize + row) * w + x as usize;
            let src = row * tw;
            self.rgb[dst..dst + tw].copy_from_slice(&tile.rgb[src..src + tw]);
            match (&mut self.variance, &tile.variance) {
                (Some(v), Some(tv)) => v[dst..dst + tw].copy_from_slice(&tv[src..src + tw]),
                (v, None) => *v = None,
                (None, Some(_)) => {}
            }
        }
        Ok(())
    }

    /// The per-pixel standard error `√variance` as a grey image (every
    /// channel the same, no variance of its own); `None` without a variance.
    pub fn std_dev(&self) -> Option<Image> {
        let variance = self.variance.as_ref()?;
        let rgb = variance.iter().map(|&v| [v.max(0.0).sqrt(); 3]).collect();
        Some(Image {
            width: self.width,
            height: self.height,
            rgb,
            variance: None,
        })
    }

    /// Per pixel, the relative standard error `√variance / m` with `m` the
    /// mean of the three channels (the variance is a channel mean too;
    /// docs/math.md §16.2);
    /// 0 where both are 0, infinite where only `m` is. `None` without a
    /// variance.
    pub fn relative_std_error(&self) -> Option<Vec<f64>> {
        let variance = self.variance.as_ref()?;
        Some(
            self.rgb
                .iter()
                .zip(variance)
                .map(|(p, &v)| {
                    let sigma = f64::from(v.max(0.0)).sqrt();
                    let mean = p.iter().map(|&c| f64::from(c)).sum::<f64>() / 3.0;
                    if sigma == 0.0 {
                        0.0
                    } else {
                        sigma / mean.abs()
                    }
                })
                .collect(),
        )
    }

    /// The relative standard error as a false-colour PNG: `0` at the
    /// bottom of the viridis colour map, `scale` (e.g. 0.2 = 20 %) and
    /// above at the top.
    pub fn relative_std_error_png(&self, scale: f64) -> Result<Vec<u8>, ImageError> {
        if !(scale.is_finite() && scale > 0.0) {
            return Err(ImageError::invalid(
                "scale",
                format!("{scale} is not a positive number"),
            ));
        }
        let relative = self
            .relative_std_error()
            .ok_or_else(|| ImageError::invalid("variance", "the image has no variance"))?;
        let pixels: Vec<u8> = relative
            .iter()
            .flat_map(|&r| false_colour::viridis(r / scale))
            .collect();
        png_io::encode_png8(&pixels, self.width, self.height, false)
    }

    /// The image in `encoding` as bytes (the body of a tile response).
    /// `tone_map` applies to PNG only.
    pub fn encode(
        &self,
        encoding: ImageEncoding,
        tone_map: ToneMap,
    ) -> Result<Vec<u8>, ImageError> {
        match encoding {
            ImageEncoding::Exr => exr_io::encode_exr(self),
            ImageEncoding::Png => png_io::encode_png(self, tone_map),
            ImageEncoding::Json => serde_json::to_vec(self)
                .map_err(|e| ImageError::invalid("rgb", format!("cannot serialise as JSON: {e}"))),
        }
    }
}

/// Checks the sides and returns the pixel count.
fn check_size(width: u32, height: u32) -> Result<usize, ImageError> {
    for (field, side) in [("width", width), ("height", height)] {
        if side == 0 {
            return Err(ImageError::invalid(field, "must be at least 1"));
        }
    }
    let n = u64::from(width) * u64::from(height);
    if n > MAX_PIXELS {
        return Err(ImageError::invalid(
            "width",
            format!("{width}×{height} exceeds {MAX_PIXELS} pixels"),
        ));
    }
    Ok(n as usize)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(width: u32, height: u32, offset: f32) -> Image {
        let n = (width * height) as usize;
        let rgb = (0..n).map(|i| [i as f32 + offset, 1.0, 2.0]).collect();
        let variance = (0..n).map(|i| i as f32 * 0.5).collect();
        Image::from_parts(width, height, rgb, Some(variance)).expect("valid")
    }

    #[test]
    fn bad_parts_name_the_field() {
        let field = |r: Result<Image, ImageError>| match r {
            Err(ImageError::Invalid { field, .. }) => field,
            other => panic!("{other:?}"),
        };
        assert_eq!(field(Image::black(0, 4)), "width");
        assert_eq!(field(Image::black(4, 0)), "height");
        assert_eq!(field(Image::black(u32::MAX, u32::MAX)), "width");
        assert_eq!(
            field(Image::from_parts(2, 2, vec![[0.0; 3]; 3], None)),
            "rgb"
        );
        assert_eq!(
            field(Image::from_parts(
                2,
                2,
                vec![[0.0; 3]; 4],
                Some(vec![0.0; 5])
            )),
            "variance"
        );
    }

    #[test]
    fn insert_places_tiles_and_rejects_overhangs() {
        let mut image = Image::black(4, 3).expect("valid");
        let tile = ramp(2, 2, 10.0);
        image.insert(&tile, 2, 1).expect("fits");
        assert_eq!(image.pixel(2, 1), Some([10.0, 1.0, 2.0]));
        assert_eq!(image.pixel(3, 2), Some([13.0, 1.0, 2.0]));
        assert_eq!(image.pixel(1, 1), Some([0.0; 3]));
        assert_eq!(image.variance().expect("kept")[2 * 4 + 3], 1.5);
        assert_eq!(image.pixel(4, 0), None);
        assert!(image.insert(&tile, 3, 0).is_err());
        assert!(image.insert(&tile, 0, u32::MAX).is_err());
    }

    #[test]
    fn crop_undoes_insert() {
        let tile = ramp(2, 3, 10.0);
        let mut image = ramp(5, 4, 0.0);
        image.insert(&tile, 3, 1).expect("fits");
        assert_eq!(image.crop(3, 1, 2, 3).expect("inside"), tile);
        assert_eq!(image.crop(0, 0, 5, 4).expect("inside"), image);
        assert!(image.crop(4, 0, 2, 1).is_err());
        assert!(image.crop(0, u32::MAX, 1, 2).is_err());
    }

    #[test]
    fn standard_errors_follow_the_variance() {
        let image = Image::from_parts(2, 1, vec![[2.0; 3], [0.0; 3]], Some(vec![0.25, 0.0]))
            .expect("valid");
        assert_eq!(
            image.std_dev().expect("has variance").pixel(0, 0),
            Some([0.5; 3])
        );
        assert_eq!(
            image.relative_std_error().expect("has variance"),
            vec![0.25, 0.0]
        );
        let png = image.relative_std_error_png(0.5).expect("encodes");
        assert_eq!(&png[1..4], b"PNG");
        assert!(image.relative_std_error_png(0.0).is_err());
        let bare = Image::from_parts(1, 1, vec![[1.0; 3]], None).expect("valid");
        assert!(bare.std_dev().is_none() && bare.relative_std_error_png(1.0).is_err());
    }

    #[test]
    fn json_form_lists_pixels_and_variance() {
        let bytes = ramp(2, 1, 0.0)
            .encode(ImageEncoding::Json, ToneMap::default())
            .expect("encodes");
        let value: serde_json::Value = serde_json::from_slice(&bytes).expect("JSON");
        assert_eq!(value["width"], 2);
        assert_eq!(value["rgb"][1], serde_json::json!([1.0, 1.0, 2.0]));
        assert_eq!(value["variance"], serde_json::json!([0.0, 0.5]));
    }
}
