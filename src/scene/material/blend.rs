//! `blendbsdf`: a linear blend of two materials, `f = (1 − w) f₀ + w f₁`
//! (Mitsuba 3's), e.g. dust over a metal or a painted pattern.
//!
//! Parameters: `weight` (w in [0, 1], a number or a texture whose
//! luminance is taken; default 0.5); `bsdf`: a list of exactly two nested
//! materials, `[f₀, f₁]`.

use super::{Material, Params};
use crate::scene::error::SceneError;
use crate::scene::texture;

pub(super) fn parse(params: &mut Params) -> Result<Material, SceneError> {
    let weight = texture::albedo(params, "weight", [0.5; 3])?;
    let nested: Vec<_> = Material::nested(params)?
        .into_iter()
        .map(|(_, m)| m)
        .collect();
    let Ok(bsdfs) = <[_; 2]>::try_from(nested) else {
        return Err(params.invalid("bsdf", "a blend needs exactly two nested materials"));
    };
    Ok(Material::Blend { weight, bsdfs })
}
