//! Images as textures read them: decoded from PNG (8/16-bit), JPEG,
//! Radiance HDR or OpenEXR to linear RGB texels, each file once per scene.

use std::collections::HashMap;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use super::environment::{MAX_ENVMAP_SIDE, MAX_ENVMAP_TEXELS, read_exr};
use super::error::SceneError;
use super::files::Files;
use super::read;

/// A linear RGB triple.
type Rgb = [f64; 3];

/// Largest image file read, bytes: a 16-bit RGBA PNG of the largest
/// accepted size stored uncompressed, plus headers.
pub const MAX_BITMAP_FILE_BYTES: u64 = (MAX_ENVMAP_TEXELS as u64) * 8 + (1 << 20);

/// Decoded linear RGB texels, top row first.
#[derive(Debug, PartialEq)]
pub struct Bitmap {
    width: usize,
    height: usize,
    texels: Vec<[f32; 3]>,
    mean: Rgb,
    max: f64,
}

impl Bitmap {
    /// An image of `width × height` texels, row-major from the top;
    /// `None` if the sizes disagree or a texel is negative or not finite.
    pub fn new(width: usize, height: usize, texels: Vec<[f32; 3]>) -> Option<Self> {
        if width == 0 || height == 0 || texels.len() != width * height {
            return None;
        }
        if texels.iter().flatten().any(|c| !c.is_finite() || *c < 0.0) {
            return None;
        }
        let mut sum = [0.0f64; 3];
        let mut max = 0.0f64;
        for t in &texels {
            for c in 0..3 {
                sum[c] += f64::from(t[c]);
                max = max.max(f64::from(t[c]));
            }
        }
        let n = texels.len() as f64;
        Some(Self {
            width,
            height,
            texels,
            mean: sum.map(|s| s / n),
            max,
        })
    }

    /// The mean of the texels.
    pub fn mean(&self) -> Rgb {
        self.mean
    }

    /// The largest texel channel.
    pub fn max(&self) -> f64 {
        self.max
    }

    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    /// `(width, height, texels)`, row-major from the top.
    pub fn into_parts(self) -> (usize, usize, Vec<[f32; 3]>) {
        (self.width, self.height, self.texels)
    }

    /// Texel `(x, y)`, row `y = 0` at the top.
    pub fn texel(&self, x: usize, y: usize) -> Rgb {
        self.texels[y * self.width + x].map(f64::from)
    }

    pub(crate) fn heap_bytes(&self) -> u64 {
        (self.texels.capacity() * std::mem::size_of::<[f32; 3]>()) as u64
    }
}

/// Most texels all the images of one scene may hold together: two of the
/// largest (768 MiB as f32 RGB). An image is checked once decoded, so a
/// load peaks at this plus one image.
pub const MAX_SCENE_TEXELS: usize = 2 * MAX_ENVMAP_TEXELS;

/// The bitmaps of one scene load, each file decoded once per `raw` setting
/// however many textures name it, and within [`MAX_SCENE_TEXELS`] in all.
pub(crate) struct Bitmaps<'a> {
    files: &'a Files,
    loaded: Mutex<HashMap<(PathBuf, bool), Arc<Bitmap>>>,
    max_texels: usize,
}

impl<'a> Bitmaps<'a> {
    pub(crate) fn new(files: &'a Files) -> Self {
        Self::with_limit(files, MAX_SCENE_TEXELS)
    }

    /// Bitmaps holding at most `max_texels` in all.
    pub(crate) fn with_limit(files: &'a Files, max_texels: usize) -> Self {
        Self {
            files,
            loaded: Mutex::new(HashMap::new()),
            max_texels,
        }
    }

    /// The image `name` (relative to the scene file), decoded to linear RGB.
    pub(crate) fn load(
        &self,
        name: &str,
        raw: bool,
        field: &str,
    ) -> Result<Arc<Bitmap>, SceneError> {
        let path = self.files.resolve(name, field)?;
        let key = (path.clone(), raw);
        if let Some(b) = self
            .loaded
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .get(&key)
        {
            return Ok(b.clone());
        }
        let bitmap = Arc::new(read_bitmap(&path, raw, field)?);
        let mut loaded = self.loaded.lock().unwrap_or_else(|p| p.into_inner());
        // A file read with and without `raw` counts twice: it is held twice.
        let held: usize = loaded.values().map(|b| b.texels.len()).sum();
        if held + bitmap.texels.len() > self.max_texels {
            return Err(SceneError::file(
                field,
                &path,
                format!(
                    "the scene's images would hold {} texels in all, more than {}",
                    held + bitmap.texels.len(),
                    self.max_texels
                ),
            ));
        }
        loaded.insert(key, bitmap.clone());
        Ok(bitmap)
    }
}

/// Decodes an image file to linear RGB: EXR and HDR as stored, 8- and
/// 16-bit formats from sRGB unless `raw` (alpha is ignored).
pub(crate) fn read_bitmap(path: &Path, raw: bool, field: &str) -> Result<Bitmap, SceneError> {
    let err = |message: String| SceneError::file(field, path, message);
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if extension.as_deref() == Some("exr") {
        let (width, height, texels) = read_exr(path, field)?;
        return Bitmap::new(width, height, texels).ok_or_else(|| err("empty image".into()));
    }
    let file = read::open_capped(path, MAX_BITMAP_FILE_BYTES)
        .map_err(|e| err(format!("cannot open: {e}")))?;
    let mut file = BufReader::new(file);
    let radiance = file
        .fill_buf()
        .map_err(|e| err(format!("cannot read: {e}")))?
        .starts_with(b"#?");
    let decoded = if radiance {
        // A Radiance file opens with `#?` and the writing program's name;
        // the decoder wants `#?RADIANCE` (Mitsuba, for one, writes `#?RGBE`).
        let mut first = Vec::new();
        (&mut file)
            .take(256)
            .read_until(b'\n', &mut first)
            .map_err(|e| err(format!("cannot read: {e}")))?;
        let reader = BufReader::new(std::io::Cursor::new(&b"#?RADIANCE\n"[..]).chain(file));
        let decoder = image::codecs::hdr::HdrDecoder::new(reader)
            .map_err(|e| err(format!("not a readable Radiance HDR image: {e}")))?;
        decode(decoder).map_err(err)?
    } else {
        let reader = image::ImageReader::new(file)
            .with_guessed_format()
            .map_err(|e| err(format!("cannot read: {e}")))?;
        if reader.format().is_none() {
            return Err(err("not a PNG, JPEG, Radiance HDR or OpenEXR image".into()));
        }
        let decoder = reader
            .into_decoder()
            .map_err(|e| err(format!("not a readable image: {e}")))?;
        decode(decoder).map_err(err)?
    };
    let (width, height) = (decoded.width(), decoded.height());
    let linear_file = matches!(
        decoded,
        image::DynamicImage::ImageRgb32F(_) | image::DynamicImage::ImageRgba32F(_)
    );
    let rgb = decoded.into_rgb32f();
    let decode = |c: f32| {
        if raw || linear_file {
            c
        } else {
            srgb_to_linear(f64::from(c)) as f32
        }
    };
    let texels: Vec<[f32; 3]> = rgb.pixels().map(|p| p.0.map(decode)).collect();
    Bitmap::new(width as usize, height as usize, texels)
        .ok_or_else(|| err("an empty image or a texel that is negative or not finite".into()))
}

/// Decodes an image whose size, read from its header, is checked first.
fn decode(mut decoder: impl image::ImageDecoder) -> Result<image::DynamicImage, String> {
    let (width, height) = decoder.dimensions();
    if width as usize > MAX_ENVMAP_SIDE
        || height as usize > MAX_ENVMAP_SIDE
        || (width as usize) * (height as usize) > MAX_ENVMAP_TEXELS
    {
        return Err(format!(
            "image is {width}×{height}; each side must be at most {MAX_ENVMAP_SIDE} and the area at most {MAX_ENVMAP_TEXELS} texels"
        ));
    }
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(width);
    limits.max_image_height = Some(height);
    // The image in its own format plus the f32 copy made from it.
    limits.max_alloc = Some(u64::from(width) * u64::from(height) * 16 * 2 + (1 << 20));
    decoder
        .set_limits(limits)
        .map_err(|e| format!("too large to decode: {e}"))?;
    image::DynamicImage::from_decoder(decoder).map_err(|e| format!("cannot decode: {e}"))
}

/// The sRGB electro-optical transfer function (IEC 61966-2-1).
pub(crate) fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}
