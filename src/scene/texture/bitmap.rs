//! `bitmap`: an image looked up at the texture coordinates.
//!
//! Parameters (Mitsuba 3's): `filename` (PNG 8/16-bit, JPEG, Radiance HDR
//! or OpenEXR, relative to the scene file); `raw` (default false: 8- and
//! 16-bit images are sRGB-encoded and decoded to linear values, as
//! Mitsuba's; true keeps the stored values, e.g. for roughness maps; HDR
//! and EXR are linear either way); `filter_type` (`bilinear`, the default,
//! or `nearest`); `wrap_mode` (`repeat`, the default, `mirror` or `clamp`);
//! `to_uv` (`super`).
//!
//! Lookup follows Mitsuba 3 (Dr.Jit's texture): `v = 0` is the image's top
//! row, texel `(i, j)` is centred on `((i + ½)/w, (j + ½)/h)`, and bilinear
//! filtering blends the four texels around `uv·(w, h) − ½`, each index
//! wrapped by the wrap mode.

use glam::{DAffine2, DVec2};
use serde_json::{Map, Value};

use super::{Plugin, SharedBitmap, Texture, to_uv};
use crate::color::RgbArray;
use crate::scene::error::SceneError;
use crate::scene::params::Params;

/// How texels are blended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Filter {
    Nearest,
    Bilinear,
}

/// Where texel indices outside the image go.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wrap {
    /// Periodic: index `i mod n`.
    Repeat,
    /// Reflected at each edge (period `2n`).
    Mirror,
    /// The nearest edge texel.
    Clamp,
}

impl Wrap {
    /// Index `i` of an axis with `n` texels, inside `0..n`.
    fn index(self, i: i64, n: usize) -> usize {
        let n = n as i64;
        let j = match self {
            Wrap::Repeat => i.rem_euclid(n),
            Wrap::Clamp => i.clamp(0, n - 1),
            Wrap::Mirror => {
                let k = i.rem_euclid(2 * n);
                if k >= n { 2 * n - 1 - k } else { k }
            }
        };
        j as usize
    }
}

/// A [`Bitmap`](super::Bitmap) with its lookup settings.
#[derive(Clone, Debug, PartialEq)]
pub struct BitmapTexture {
    pub bitmap: SharedBitmap,
    pub filter: Filter,
    pub wrap: Wrap,
    pub to_uv: DAffine2,
}

impl Plugin for BitmapTexture {
    /// The filtered colour at texture coordinates `uv`.
    fn eval(&self, uv: DVec2) -> RgbArray {
        let b = &*self.bitmap;
        let (width, height) = (b.width(), b.height());
        let uv = self.to_uv.transform_point2(uv);
        let p = uv * DVec2::new(width as f64, height as f64);
        if !p.is_finite() {
            return b.mean();
        }
        let (x, y) = (
            |i: f64| self.wrap.index(i as i64, width),
            |j: f64| self.wrap.index(j as i64, height),
        );
        match self.filter {
            Filter::Nearest => b.texel(x(p.x.floor()), y(p.y.floor())),
            Filter::Bilinear => {
                let p = p - 0.5;
                let (fx, fy) = (p.x.floor(), p.y.floor());
                let (x0, x1, y0, y1) = (x(fx), x(fx + 1.0), y(fy), y(fy + 1.0));
                let corners = [(x0, y0), (x1, y0), (x0, y1), (x1, y1)].map(|(i, j)| b.texel(i, j));
                crate::scene::bilinear::blend(corners, DVec2::new(p.x - fx, p.y - fy))
            }
        }
    }

    /// The derivative of the bilinear blend of the texels' luminances
    /// (zero for `nearest`, constant between texel centres), through
    /// `to_uv`'s linear part: Mitsuba 3's `eval_1_grad`.
    fn gradient_scalar(&self, uv: DVec2) -> DVec2 {
        let b = &*self.bitmap;
        let (width, height) = (b.width(), b.height());
        let size = DVec2::new(width as f64, height as f64);
        let p = self.to_uv.transform_point2(uv) * size - 0.5;
        if self.filter == Filter::Nearest || !p.is_finite() {
            return DVec2::ZERO;
        }
        let (fx, fy) = (p.x.floor(), p.y.floor());
        let (x0, x1) = (self.wrap.index(fx as i64, width), self.wrap.index(fx as i64 + 1, width));
        let (y0, y1) = (self.wrap.index(fy as i64, height), self.wrap.index(fy as i64 + 1, height));
        let f = |i, j| crate::color::luminance(b.texel(i, j));
        let (f00, f10, f01, f11) = (f(x0, y0), f(x1, y0), f(x0, y1), f(x1, y1));
        let (tx, ty) = (p.x - fx, p.y - fy);
        // ∂/∂x and ∂/∂y in texels, then to (u, v) by the transpose of to_uv.
        let texels = DVec2::new(
            (1.0 - ty) * (f10 - f00) + ty * (f11 - f01),
            (1.0 - tx) * (f01 - f00) + tx * (f11 - f10),
        ) * size;
        self.to_uv.matrix2.transpose() * texels
    }

    /// The mean of the texels.
    fn mean(&self) -> RgbArray {
        self.bitmap.mean()
    }

    /// The largest texel channel.
    fn max(&self) -> f64 {
        self.bitmap.max()
    }
}

impl BitmapTexture {
    /// The defaults a translated document states: `raw`.
    pub(crate) fn stated_defaults() -> Map<String, Value> {
        let mut doc = Map::new();
        doc.insert("raw".into(), Value::from(false));
        doc
    }

    /// The parameters of a texture document, each validated once (the
    /// image read through the document's bitmaps).
    pub(crate) fn parse(params: &mut Params) -> Result<Texture, SceneError> {
        let filename = params
            .string("filename")?
            .ok_or_else(|| params.missing("filename"))?;
        let raw = params.boolean("raw", false)?;
        let filter = match params.string("filter_type")?.as_deref() {
            None | Some("bilinear") => Filter::Bilinear,
            Some("nearest") => Filter::Nearest,
            Some(other) => {
                return Err(params.invalid(
                    "filter_type",
                    format!("{other:?} is not `bilinear` or `nearest`"),
                ));
            }
        };
        let wrap = match params.string("wrap_mode")?.as_deref() {
            None | Some("repeat") => Wrap::Repeat,
            Some("mirror") => Wrap::Mirror,
            Some("clamp") => Wrap::Clamp,
            Some(other) => {
                return Err(params.invalid(
                    "wrap_mode",
                    format!("{other:?} is not `repeat`, `mirror` or `clamp`"),
                ));
            }
        };
        let to_uv = to_uv(params)?;
        let field = params.field("filename");
        let Some(bitmaps) = params.bitmaps() else {
            // Only the parameter names are wanted (`Material::unknown_parameters`).
            return Ok(Texture::Constant([0.5; 3]));
        };
        let bitmap = bitmaps.load(&filename, raw, &field)?;
        Ok(Texture::Bitmap(BitmapTexture {
            bitmap,
            filter,
            wrap,
            to_uv,
        }))
    }
}
