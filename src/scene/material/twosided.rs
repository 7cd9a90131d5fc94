//! `twosided`: a material for both sides of a surface. One nested BSDF
//! (`"bsdf": {…}`) serves both sides; two (`"bsdf": [front, back]`) give
//! the side the normal points to and the other. On the back side the
//! nested BSDF is evaluated as if the surface were turned around, as
//! Mitsuba 3 does. Nested BSDFs may not transmit (a two-sided glass is
//! just glass) nor be two-sided themselves.

use super::{Material, Params};
use crate::scene::error::SceneError;

pub(super) fn parse(params: &mut Params) -> Result<Material, SceneError> {
    let mut sides = Vec::new();
    for (field, material) in Material::nested(params)? {
        if matches!(
            *material,
            Material::TwoSided { .. } | Material::Dielectric { .. }
        ) {
            return Err(SceneError::invalid(
                format!("{field}.type"),
                "a dielectric or twosided material cannot be one side of a twosided one",
            ));
        }
        sides.push(material);
    }
    let (front, back) = match <[_; 2]>::try_from(sides) {
        Ok([front, back]) => (front, back),
        Err(sides) if sides.len() == 1 => (sides[0].clone(), sides[0].clone()),
        Err(sides) => {
            return Err(SceneError::invalid(
                params.field("bsdf"),
                format!("needs 1 or 2 nested materials, found {}", sides.len()),
            ));
        }
    };
    Ok(Material::TwoSided { front, back })
}
