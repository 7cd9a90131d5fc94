//! `dielectric`, `thindielectric` and `roughdielectric`: interfaces between
//! two dielectrics (glass, water), smooth, as a thin slab, or microfacet
//! (`render::bsdfs::{dielectric, thin_dielectric, rough_dielectric}`).
//!
//! Parameters (Mitsuba 3's): `int_ior` (default BK7, 1.5046) and `ext_ior`
//! (default air), numbers or named media ([`super::ior`]);
//! `specular_reflectance` and `specular_transmittance` (factors in [0, 1],
//! default 1); rough only: `distribution`, `alpha` or `alpha_u`/`alpha_v`
//! ([`super::optics::roughness`]).

use super::{Material, Params, optics};
use crate::scene::error::SceneError;
use crate::scene::texture;

/// Mitsuba's default interior: BK7 glass.
const BK7: f64 = 1.5046;

pub(super) fn parse_smooth(params: &mut Params) -> Result<Material, SceneError> {
    parse(params, false, false)
}

pub(super) fn parse_thin(params: &mut Params) -> Result<Material, SceneError> {
    parse(params, false, true)
}

pub(super) fn parse_rough(params: &mut Params) -> Result<Material, SceneError> {
    parse(params, true, false)
}

fn parse(params: &mut Params, rough: bool, thin: bool) -> Result<Material, SceneError> {
    Ok(Material::Dielectric {
        eta: optics::relative_ior(params, BK7)?,
        specular_reflectance: texture::albedo(params, "specular_reflectance", [1.0; 3])?,
        specular_transmittance: texture::albedo(params, "specular_transmittance", [1.0; 3])?,
        roughness: if rough {
            Some(optics::roughness(params)?)
        } else {
            None
        },
        thin,
    })
}
