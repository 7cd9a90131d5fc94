//! `mask`: a surface that is partly absent (leaves, fences, cut-outs): with
//! probability `1 − α` light passes straight through, otherwise the nested
//! material scatters it (Mitsuba 3's).
//!
//! Parameters: `opacity` (α in [0, 1], a number or a texture whose
//! luminance is taken, usually a bitmap with `raw`; default 0.5); `bsdf`:
//! the nested material.

use super::{Material, Params};
use crate::scene::error::SceneError;
use crate::scene::texture;

pub(super) fn parse(params: &mut Params) -> Result<Material, SceneError> {
    let opacity = texture::albedo(params, "opacity", [0.5; 3])?;
    let nested: Vec<_> = Material::nested(params)?
        .into_iter()
        .map(|(_, m)| m)
        .collect();
    let Ok([bsdf]) = <[_; 1]>::try_from(nested) else {
        return Err(params.invalid("bsdf", "a mask needs exactly one nested material"));
    };
    Ok(Material::Mask { opacity, bsdf })
}
