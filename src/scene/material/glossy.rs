//! `glossy` (this project's own, not Mitsuba's): a Lambertian base plus a
//! normalised Phong lobe (Lafortune & Willems, "Using the modified Phong
//! reflectance model for physically based rendering", 1994):
//! `f = ρ_d/π + ρ_s·(n+2)/(2π)·max(0, cos α)ⁿ`, α the angle between the
//! outgoing direction and the mirror direction of the incoming one.
//!
//! Parameters (all required): `diffuse` (`ρ_d`), `specular` (`ρ_s`), each
//! in [0, 1] with `ρ_d + ρ_s ≤ 1` per channel so no energy is created;
//! `exponent` (`n`, in `[0, MAX_PHONG_EXPONENT]`).

use super::{MAX_PHONG_EXPONENT, Material, Params};
use crate::scene::error::SceneError;

pub(super) fn parse(params: &mut Params) -> Result<Material, SceneError> {
    let diffuse = params.required_albedo("diffuse")?;
    let specular = params.required_albedo("specular")?;
    if let Some(i) = (0..3).find(|&i| diffuse[i] + specular[i] > 1.0) {
        return Err(SceneError::invalid(
            format!("{}[{i}]", params.field("specular")),
            "diffuse + specular exceeds 1: the material would create energy",
        ));
    }
    let exponent = match params.number("exponent")? {
        Some(x) if (0.0..=MAX_PHONG_EXPONENT).contains(&x) => x,
        Some(x) => {
            return Err(SceneError::invalid(
                params.field("exponent"),
                format!("{x} is outside [0, {MAX_PHONG_EXPONENT:e}]"),
            ));
        }
        None => return Err(params.missing("exponent")),
    };
    Ok(Material::Glossy {
        diffuse,
        specular,
        exponent,
    })
}
