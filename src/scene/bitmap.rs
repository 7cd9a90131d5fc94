//! Images as textures read them: decoded from PNG (8/16-bit), JPEG,
//! Radiance HDR or OpenEXR to linear RGB texels, each file once per scene.

use std::collections::HashMap;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use super::budget::Budget;
use super::environment::{MAX_ENVMAP_SIDE, MAX_ENVMAP_TEXELS, read_exr};
use super::error::SceneError;
use super::files::Files;
use super::read;

/// A linear RGB triple.
use crate::color::RgbArray;

/// Largest image file read, bytes: a 16-bit RGBA PNG of the largest
/// accepted size stored uncompressed, plus headers.
pub const MAX_BITMAP_FILE_BYTES: u64 = (MAX_ENVMAP_TEXELS as u64) * 8 + (1 << 20);

/// Decoded linear RGB texels, top row first.
#[derive(Debug, PartialEq)]
pub struct Bitmap {
    width: usize,
    height: usize,
    texels: Vec<[f32; 3]>,
    mean: RgbArray,
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
    pub fn mean(&self) -> RgbArray {
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
    pub fn texel(&self, x: usize, y: usize) -> RgbArray {
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
/// however many textures name it (material, emitter and the translator's
/// texture means alike), within [`MAX_SCENE_TEXELS`] in all and each
/// reserved from the load's budget before it is decoded.
pub(crate) struct Bitmaps<'a> {
    files: &'a Files,
    budget: &'a Budget,
    loaded: Mutex<HashMap<(PathBuf, bool), Arc<Bitmap>>>,
    max_texels: usize,
}

impl<'a> Bitmaps<'a> {
    pub(crate) fn new(files: &'a Files, budget: &'a Budget) -> Self {
        Self::with_limit(files, budget, MAX_SCENE_TEXELS)
    }

    /// Bitmaps holding at most `max_texels` in all.
    pub(crate) fn with_limit(files: &'a Files, budget: &'a Budget, max_texels: usize) -> Self {
        Self {
            files,
            budget,
            loaded: Mutex::new(HashMap::new()),
            max_texels,
        }
    }

    /// The scene's file names, which the scene's other readers resolve
    /// through too.
    pub(crate) fn files(&self) -> &'a Files {
        self.files
    }

    /// The load's budget, which the scene's other readers share.
    pub(crate) fn budget(&self) -> &'a Budget {
        self.budget
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
        self.budget.check_cancel()?;
        let bitmap = Arc::new(read_bitmap(&path, raw, field, self.budget)?);
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

/// Most texels an image may decode to per byte of its file. Deflate (PNG)
/// inflates at most 1032 times; a JPEG of one flat colour takes about a
/// bit per 8×8 block and channel, some 150 texels a byte. A file far
/// smaller than its header's size claims is a truncated or crafted one,
/// whose decoding would cost the memory and time of the claim.
pub const MAX_TEXELS_PER_FILE_BYTE: u64 = 1024;

/// Bytes a decoded texel is held in ([`Bitmap`]'s `[f32; 3]`).
const TEXEL_BYTES: u64 = std::mem::size_of::<[f32; 3]>() as u64;
/// Bytes a texel takes while a PNG, JPEG or HDR file of `color` is
/// decoded, beside the one it is kept in: the image in its own format and,
/// unless that is already f32 RGB, the f32 RGB copy made from it.
fn decoding_bytes(color: image::ColorType) -> u64 {
    let copy = if color == image::ColorType::Rgb32F {
        0
    } else {
        TEXEL_BYTES
    };
    u64::from(color.bytes_per_pixel()) + copy
}

/// Decodes an image file to linear RGB: EXR and HDR as stored, 8- and
/// 16-bit formats from sRGB unless `raw` (alpha is ignored). Its texels are
/// reserved from `budget` once the header has given its size, before any
/// pixel memory is allocated (with what decoding holds on the way, given
/// back after).
pub(crate) fn read_bitmap(
    path: &Path,
    raw: bool,
    field: &str,
    budget: &Budget,
) -> Result<Bitmap, SceneError> {
    let err = |message: String| SceneError::file(field, path, message);
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let reserve = |width: usize, height: usize, bytes_per_texel: u64| {
        let texels = (width as u64) * (height as u64);
        budget.reserve(
            texels * bytes_per_texel,
            field,
            &format!("its {width}×{height} texels"),
        )
    };
    if extension.as_deref() == Some("exr") {
        let (width, height, texels) = read_exr(path, field, &|w, h| reserve(w, h, TEXEL_BYTES))?;
        return Bitmap::new(width, height, texels).ok_or_else(|| err("empty image".into()));
    }
    let file = read::open_regular(path).map_err(|e| err(format!("cannot open: {e}")))?;
    let file_bytes = file
        .metadata()
        .map_err(|e| err(format!("cannot read: {e}")))?
        .len();
    let mut file = BufReader::new(read::Capped::new(file, MAX_BITMAP_FILE_BYTES));
    let radiance = file
        .fill_buf()
        .map_err(|e| err(format!("cannot read: {e}")))?
        .starts_with(b"#?");
    let admit = |width: u32, height: u32, color| -> Result<Result<(), String>, SceneError> {
        if let Err(why) = check_claimed_size(width, height, file_bytes) {
            return Ok(Err(why));
        }
        let bytes_per_texel = TEXEL_BYTES + decoding_bytes(color);
        reserve(width as usize, height as usize, bytes_per_texel).map(Ok)
    };
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
        decode(decoder, &admit)?.map_err(err)?
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
        decode(decoder, &admit)?.map_err(err)?
    };
    let (width, height, color) = (decoded.width(), decoded.height(), decoded.color());
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
    drop(rgb);
    budget.release(u64::from(width) * u64::from(height) * decoding_bytes(color));
    Bitmap::new(width as usize, height as usize, texels)
        .ok_or_else(|| err("an empty image or a texel that is negative or not finite".into()))
}

/// Whether an image file of `file_bytes` bytes may decode to `width ×
/// height` texels: within the sides and area every image keeps to, and
/// at most [`MAX_TEXELS_PER_FILE_BYTE`] texels a byte.
fn check_claimed_size(width: u32, height: u32, file_bytes: u64) -> Result<(), String> {
    let texels = u64::from(width) * u64::from(height);
    if width as usize > MAX_ENVMAP_SIDE
        || height as usize > MAX_ENVMAP_SIDE
        || texels > MAX_ENVMAP_TEXELS as u64
    {
        return Err(format!(
            "image is {width}×{height}; each side must be at most {MAX_ENVMAP_SIDE} and the area at most {MAX_ENVMAP_TEXELS} texels"
        ));
    }
    if texels > file_bytes.saturating_mul(MAX_TEXELS_PER_FILE_BYTE) {
        return Err(format!(
            "image claims {width}×{height} texels in a file of {file_bytes} bytes, more than {MAX_TEXELS_PER_FILE_BYTE} a byte: a truncated or crafted file"
        ));
    }
    Ok(())
}

/// Decodes an image once `admit` has accepted the size its header gives
/// (and reserved its memory), before any pixel memory is allocated. The
/// outer error is the budget's refusal, the inner one the file's.
fn decode(
    mut decoder: impl image::ImageDecoder,
    admit: &dyn Fn(u32, u32, image::ColorType) -> Result<Result<(), String>, SceneError>,
) -> Result<Result<image::DynamicImage, String>, SceneError> {
    let (width, height) = decoder.dimensions();
    if let Err(why) = admit(width, height, decoder.color_type())? {
        return Ok(Err(why));
    }
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(width);
    limits.max_image_height = Some(height);
    // The image in its own format plus what the decoder holds beside it.
    limits.max_alloc = Some(u64::from(width) * u64::from(height) * 16 * 2 + (1 << 20));
    let decoded = decoder
        .set_limits(limits)
        .map_err(|e| format!("too large to decode: {e}"))
        .and_then(|()| {
            image::DynamicImage::from_decoder(decoder).map_err(|e| format!("cannot decode: {e}"))
        });
    Ok(decoded)
}

/// The sRGB electro-optical transfer function (IEC 61966-2-1).
pub(crate) fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}
