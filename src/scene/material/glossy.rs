//! `glossy` (this project's own, not Mitsuba's): a Lambertian base plus a
//! normalised Phong lobe (Lafortune & Willems, "Using the modified Phong
//! reflectance model for physically based rendering", 1994):
//! `f = ρ_d/π + ρ_s·(n+2)/(2π)·max(0, cos α)ⁿ`, α the angle between the
//! outgoing direction and the mirror direction of the incoming one.
//!
//! Parameters (all required): `diffuse` (`ρ_d`), `specular` (`ρ_s`), each
//! in [0, 1] with `ρ_d + ρ_s ≤ 1` per channel so no energy is created;
//! `exponent` (`n`, 0 or in `[1, MAX_PHONG_EXPONENT]`). Between 0 and 1
//! the lobe `cosⁿ α` has an infinite slope at its edge, where the cache
//! integrator's BMC weights integrate it: their exact kernel means then
//! take seconds per node instead of a fraction (measured: 2.5 s at
//! `n` = 0.5 against 0.3 s at 20), so such lobes are refused rather than
//! left to hold a worker.

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
        Some(x) if x == 0.0 || (1.0..=MAX_PHONG_EXPONENT).contains(&x) => x,
        Some(x) => {
            return Err(SceneError::invalid(
                params.field("exponent"),
                format!("{x} is neither 0 nor in [1, {MAX_PHONG_EXPONENT:e}]"),
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
