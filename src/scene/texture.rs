//! Textures: colours that vary over a surface with its texture coordinates
//! `(u, v)` (`SurfaceHit::uv`, Mitsuba 3's conventions per shape, see
//! `docs/scene-format.md`, "Texture coordinates").
//!
//! A textured parameter is written as a constant (a number or `[r, g, b]`)
//! or as a texture document `{"type": PLUGIN, PARAMETER: value, …}` with
//! Mitsuba 3's plugin and parameter names, so a Mitsuba `<texture>`
//! translates into one by copying its properties. Each plugin has its own
//! file below holding its parameters' docs, their parsing and validation
//! through `Params`, and its lookups ([`Plugin`]: `eval` at `(u, v)`,
//! `mean`, `max`); the `plugins!` invocation below is the registry: each
//! line declares the plugin's module and generates its [`Texture`]
//! variant, its parser entry and its dispatch arm. Every plugin takes
//! `to_uv`, an affine
//! transform of the texture coordinates written like a `to_world` (its
//! x and y rows act on `(u, v)`; Mitsuba's `to_uv`).

use std::sync::Arc;

use glam::{DAffine2, DVec2};
use serde_json::{Map, Value};

pub use super::bitmap::Bitmap;

use super::error::SceneError;
use super::format::TransformDoc;
use super::params::Params;

/// A linear RGB triple.
use crate::color::{RgbArray, luminance};

/// What a texture plugin offers: its lookups over the texture coordinates.
pub trait Plugin {
    /// The colour at texture coordinates `uv`, linear RGB.
    fn eval(&self, uv: DVec2) -> RgbArray;

    /// The texture as a number at `uv` (Mitsuba 3's `eval_1`): the
    /// luminance of the colour unless the plugin says otherwise.
    fn eval_scalar(&self, uv: DVec2) -> f64 {
        luminance(self.eval(uv))
    }

    /// `(∂/∂u, ∂/∂v)` of [`Self::eval_scalar`] at `uv` (Mitsuba 3's
    /// `eval_1_grad`, which bump maps tilt the normal by): zero unless the
    /// plugin says otherwise, as for textures constant between jumps.
    fn gradient_scalar(&self, _uv: DVec2) -> DVec2 {
        DVec2::ZERO
    }

    /// The mean colour over the unit square of texture coordinates.
    fn mean(&self) -> RgbArray;

    /// The largest channel value anywhere.
    fn max(&self) -> f64;
}

/// The texture plugins: `Variant(file::Type) = "name"`, one line each.
/// For each line the macro declares `pub mod file;` (the plugin's file),
/// the variant `Texture::Variant(Type)`, the parser of `"name"` (the
/// type's `parse(&mut Params)`) and the arm dispatching to its [`Plugin`]
/// implementation.
macro_rules! plugins {
    ($($variant:ident($file:ident::$plugin:ident) = $name:literal,)*) => {
        $(pub mod $file;)*

        /// A colour over a surface: linear RGB as a function of `(u, v)`.
        #[derive(Clone, Debug, PartialEq)]
        pub enum Texture {
            Constant(RgbArray),
            $($variant($file::$plugin),)*
        }

        /// Every texture plugin, by its `type`.
        const PLUGINS: &[(&str, Parse)] = &[$(($name, $file::$plugin::parse),)*];

        impl Texture {
            /// The parameters a translated document of plugin `kind`
            /// states even at their defaults, so that its canonical form
            /// (which the scene digest hashes) stays what it was.
            pub(crate) fn stated_defaults(kind: &str) -> Map<String, Value> {
                match kind {
                    $($name => $file::$plugin::stated_defaults(),)*
                    _ => Map::new(),
                }
            }

            /// The plugin behind a texture that varies, for dispatch, or
            /// the value of a constant.
            fn plugin(&self) -> Result<&dyn Plugin, RgbArray> {
                match self {
                    Texture::Constant(c) => Err(*c),
                    $(Texture::$variant(t) => Ok(t),)*
                }
            }
        }
    };
}

plugins! {
    Bitmap(bitmap::BitmapTexture) = "bitmap",
    Checkerboard(checkerboard::CheckerboardTexture) = "checkerboard",
}

/// The largest of a colour's channels (0 for black).
pub(crate) fn max_channel(c: RgbArray) -> f64 {
    c.into_iter().fold(0.0, f64::max)
}

impl From<RgbArray> for Texture {
    fn from(rgb: RgbArray) -> Self {
        Texture::Constant(rgb)
    }
}

impl Texture {
    /// The colour at texture coordinates `uv`.
    pub fn eval(&self, uv: DVec2) -> RgbArray {
        match self.plugin() {
            Ok(p) => p.eval(uv),
            Err(c) => c,
        }
    }

    /// The texture as a number at `uv` (a blend weight, an opacity), as
    /// Mitsuba 3's `eval_1` gives it: the luminance of the colour, except
    /// where a plugin says otherwise (the checkerboard's swaps its colours).
    pub fn eval_scalar(&self, uv: DVec2) -> f64 {
        match self.plugin() {
            Ok(p) => p.eval_scalar(uv),
            Err(c) => luminance(c),
        }
    }

    /// [`Plugin::gradient_scalar`]: `(∂/∂u, ∂/∂v)` of [`Self::eval_scalar`].
    pub fn gradient_scalar(&self, uv: DVec2) -> DVec2 {
        match self.plugin() {
            Ok(p) => p.gradient_scalar(uv),
            Err(_) => DVec2::ZERO,
        }
    }

    /// [`Self::eval_scalar`]'s mean.
    pub fn mean_scalar(&self) -> f64 {
        luminance(self.mean())
    }

    /// The mean colour over the unit square of texture coordinates (what
    /// stands for the texture where no surface point is at hand).
    pub fn mean(&self) -> RgbArray {
        match self.plugin() {
            Ok(p) => p.mean(),
            Err(c) => c,
        }
    }

    /// The largest channel value anywhere.
    pub fn max(&self) -> f64 {
        match self.plugin() {
            Ok(p) => p.max(),
            Err(c) => max_channel(c),
        }
    }

    /// The value if it does not vary.
    pub fn constant(&self) -> Option<RgbArray> {
        match self {
            Texture::Constant(c) => Some(*c),
            _ => None,
        }
    }

    /// The parameters of a `kind` document that its plugin does not take,
    /// when the others parse (none otherwise: the loader then reports the
    /// error), so that a translator can drop them with a warning.
    pub(crate) fn unknown_parameters(kind: &str, params: &Map<String, Value>) -> Vec<String> {
        let Some((_, parse)) = PLUGINS.iter().find(|(n, _)| *n == kind) else {
            return Vec::new();
        };
        let mut params = Params::new("", params.clone());
        match parse(&mut params) {
            Ok(_) => params.remaining(),
            Err(_) => Vec::new(),
        }
    }

    /// Parses a texture document given to parameter `params.field(name)`:
    /// `doc` must be an object with a `type` among [`PLUGINS`].
    pub(crate) fn parse(params: &Params, name: &str, doc: Value) -> Result<Self, SceneError> {
        let field = params.field(name);
        let Value::Object(map) = doc else {
            return Err(SceneError::invalid(field, "is not a colour or a texture"));
        };
        let mut inner = params.nested_params(&field, map);
        let kind = match inner.string("type")? {
            Some(kind) => kind,
            None => return Err(inner.missing("type")),
        };
        let Some((_, parse)) = PLUGINS.iter().find(|(n, _)| *n == kind) else {
            return Err(SceneError::invalid(
                format!("{field}.type"),
                format!(
                    "unknown texture type {kind:?} (known: {})",
                    PLUGINS
                        .iter()
                        .map(|(n, _)| *n)
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ));
        };
        let texture = parse(&mut inner)?;
        inner.finish()?;
        Ok(texture)
    }
}

/// Parameter `name` of `params` as a colour that scales reflected or
/// transmitted light, constant or a texture: in [0, 1] everywhere,
/// `default` when absent.
pub(crate) fn albedo(
    params: &mut Params,
    name: &str,
    default: RgbArray,
) -> Result<Texture, SceneError> {
    if !params.peek(name).is_some_and(Value::is_object) {
        return Ok(Texture::Constant(params.albedo(name, default)?));
    }
    let doc = params.take(name).expect("present");
    let texture = Texture::parse(params, name, doc)?;
    match texture.max() {
        m if m > 1.0 => Err(params.invalid(
            name,
            format!("the texture reaches {m}, not an albedo in [0, 1]"),
        )),
        _ => Ok(texture),
    }
}

/// Parameter `name` of `params` as a number, a colour or a texture of any
/// non-negative values (a height field), `None` when absent.
pub(crate) fn values(params: &mut Params, name: &str) -> Result<Option<Texture>, SceneError> {
    if !params.peek(name).is_some_and(Value::is_object) {
        return Ok(params.color(name)?.map(Texture::Constant));
    }
    let doc = params.take(name).expect("present");
    Texture::parse(params, name, doc).map(Some)
}

/// [`albedo`] that must be given.
pub(crate) fn required_albedo(params: &mut Params, name: &str) -> Result<Texture, SceneError> {
    if params.peek(name).is_none() {
        return Err(params.missing(name));
    }
    albedo(params, name, [0.0; 3])
}

/// A plugin's parser: its parameters to a texture.
type Parse = fn(&mut Params) -> Result<Texture, SceneError>;

/// The texture plugin names a texture document's `type` accepts, for messages and docs.
pub fn plugin_names() -> Vec<&'static str> {
    PLUGINS.iter().map(|(name, _)| *name).collect()
}

/// The `to_uv` parameter: the identity if absent.
pub(crate) fn to_uv(params: &mut Params) -> Result<DAffine2, SceneError> {
    let Some(value) = params.take("to_uv") else {
        return Ok(DAffine2::IDENTITY);
    };
    let field = params.field("to_uv");
    let doc: TransformDoc = serde_json::from_value(value)
        .map_err(|e| SceneError::invalid(field.clone(), e.to_string()))?;
    let t = super::transform::build(&doc, &field)?;
    let affine = DAffine2::from_cols(
        t.matrix3.x_axis.truncate(),
        t.matrix3.y_axis.truncate(),
        t.translation.truncate(),
    );
    if affine.matrix2.determinant() == 0.0 {
        return Err(SceneError::invalid(field, "maps (u, v) onto a line"));
    }
    Ok(affine)
}

/// An image shared by every texture that reads it.
pub(crate) type SharedBitmap = Arc<Bitmap>;

#[cfg(test)]
mod tests;
