//! `plastic` and `roughplastic`: a diffuse base under a smooth or rough
//! dielectric coating, Mitsuba 3's coated-diffuse models
//! (`render::bsdfs::{plastic, rough_plastic}`).
//!
//! Parameters (Mitsuba 3's): `diffuse_reflectance` (default 0.5),
//! `specular_reflectance` (default 1), both in [0, 1]; `int_ior` (default
//! polypropylene, 1.49) and `ext_ior` (default air); `nonlinear` (default
//! false: whether inner bounces darken and saturate the base's colour);
//! rough only: `distribution` and `alpha` ([`super::optics::roughness`]; isotropic,
//! as Mitsuba's).

use super::{Material, Params, optics};
use crate::scene::error::SceneError;
use crate::scene::texture;

/// Mitsuba's default coating: polypropylene.
const POLYPROPYLENE: f64 = 1.49;

pub(super) fn parse_smooth(params: &mut Params) -> Result<Material, SceneError> {
    parse(params, false)
}

pub(super) fn parse_rough(params: &mut Params) -> Result<Material, SceneError> {
    parse(params, true)
}

fn parse(params: &mut Params, rough: bool) -> Result<Material, SceneError> {
    let roughness = if rough {
        // Its tables depend on the roughness, so it is one number, as in
        // Mitsuba (whose roughplastic takes no texture for it either).
        for name in ["alpha", "alpha_u", "alpha_v"] {
            if params.peek(name).is_some_and(serde_json::Value::is_object) {
                return Err(params.invalid(name, "roughplastic takes a number, not a texture"));
            }
        }
        let r = optics::roughness(params)?;
        if r.alpha_u != r.alpha_v {
            return Err(SceneError::invalid(
                params.field("alpha_u"),
                "roughplastic is isotropic (as Mitsuba's): give one `alpha`",
            ));
        }
        Some(r)
    } else {
        None
    };
    Ok(Material::Plastic {
        roughness,
        diffuse_reflectance: texture::albedo(params, "diffuse_reflectance", [0.5; 3])?,
        specular_reflectance: texture::albedo(params, "specular_reflectance", [1.0; 3])?,
        eta: optics::relative_ior(params, POLYPROPYLENE)?,
        nonlinear: params.boolean("nonlinear", false)?,
    })
}
