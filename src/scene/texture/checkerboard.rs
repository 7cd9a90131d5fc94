//! `checkerboard`: two colours alternating over the unit square of texture
//! coordinates in a 2 × 2 pattern (Mitsuba 3's): `color0` where the
//! fractional parts of `u` and `v` are both below ½ or both above,
//! `color1` elsewhere.
//!
//! Parameters: `color0` (default 0.4), `color1` (default 0.2), constant
//! colours; `to_uv` (`super`), e.g. a scale to repeat the pattern.

use glam::{DAffine2, DVec2};

use super::Texture;
use crate::color::RgbArray;
use crate::scene::error::SceneError;
use crate::scene::params::Params;

#[derive(Clone, Debug, PartialEq)]
pub struct Checkerboard {
    pub color0: RgbArray,
    pub color1: RgbArray,
    pub to_uv: DAffine2,
}

impl Checkerboard {
    pub fn eval(&self, uv: DVec2) -> RgbArray {
        if self.is_color0(uv) {
            self.color0
        } else {
            self.color1
        }
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

    /// Both colours cover half of every period.
    pub fn mean(&self) -> RgbArray {
        std::array::from_fn(|i| 0.5 * (self.color0[i] + self.color1[i]))
    }
}

pub(super) fn parse(params: &mut Params) -> Result<Texture, SceneError> {
    Ok(Texture::Checkerboard(Checkerboard {
        color0: params.color("color0")?.unwrap_or([0.4; 3]),
        color1: params.color("color1")?.unwrap_or([0.2; 3]),
        to_uv: super::to_uv(params)?,
    }))
}
