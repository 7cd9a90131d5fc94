//! `checkerboard`: two colours alternating over the unit square of texture
//! coordinates in a 2 × 2 pattern (Mitsuba 3's): `color0` where the
//! fractional parts of `u` and `v` are both below ½ or both above,
//! `color1` elsewhere.
//!
//! Parameters: `color0` (default 0.4), `color1` (default 0.2), constant
//! colours; `to_uv` (`super`), e.g. a scale to repeat the pattern.

use glam::{DAffine2, DVec2};
use serde_json::{Map, Value};

use super::{Plugin, Texture, max_channel, to_uv};
use crate::color::{RgbArray, luminance};
use crate::scene::error::SceneError;
use crate::scene::params::Params;

/// A checkerboard; see the module docs.
#[derive(Clone, Debug, PartialEq)]
pub struct CheckerboardTexture {
    /// Linear RGB.
    pub color0: RgbArray,
    pub color1: RgbArray,
    pub to_uv: DAffine2,
}

/// Mitsuba's colours where none is given.
const COLOR0: RgbArray = [0.4; 3];
const COLOR1: RgbArray = [0.2; 3];

impl CheckerboardTexture {
    /// The parameters of a texture document, each validated once.
    pub(crate) fn parse(params: &mut Params) -> Result<Texture, SceneError> {
        Ok(Texture::Checkerboard(CheckerboardTexture {
            color0: params.color("color0")?.unwrap_or(COLOR0),
            color1: params.color("color1")?.unwrap_or(COLOR1),
            to_uv: to_uv(params)?,
        }))
    }

    /// The defaults a translated document states: both colours.
    pub(crate) fn stated_defaults() -> Map<String, Value> {
        let mut doc = Map::new();
        doc.insert("color0".into(), Value::from(COLOR0.to_vec()));
        doc.insert("color1".into(), Value::from(COLOR1.to_vec()));
        doc
    }

    /// The pattern with its colours swapped (Mitsuba's scalar lookup).
    pub fn eval_swapped(&self, uv: DVec2) -> RgbArray {
        if self.is_color0(uv) {
            self.color1
        } else {
            self.color0
        }
    }

    fn is_color0(&self, uv: DVec2) -> bool {
        let uv = self.to_uv.transform_point2(uv);
        let upper = |x: f64| x - x.floor() > 0.5;
        upper(uv.x) == upper(uv.y)
    }

}

impl Plugin for CheckerboardTexture {
    fn eval(&self, uv: DVec2) -> RgbArray {
        if self.is_color0(uv) {
            self.color0
        } else {
            self.color1
        }
    }

    /// Mitsuba's `checkerboard` swaps its colours in its scalar lookup,
    /// and scenes are authored against it.
    fn eval_scalar(&self, uv: DVec2) -> f64 {
        luminance(self.eval_swapped(uv))
    }

    /// Both colours cover half of every period.
    fn mean(&self) -> RgbArray {
        std::array::from_fn(|i| 0.5 * (self.color0[i] + self.color1[i]))
    }

    fn max(&self) -> f64 {
        max_channel(self.color0).max(max_channel(self.color1))
    }
}
