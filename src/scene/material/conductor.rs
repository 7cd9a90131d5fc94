//! `conductor` and `roughconductor`: metals. The smooth one is a mirror,
//! the rough one a microfacet surface (`render::bsdfs::rough_conductor`),
//! both weighted by the complex Fresnel reflectance of `η + i k`.
//!
//! Parameters (Mitsuba 3's): `eta` and `k` (colours, the index relative to
//! the outside) or `material` (a named metal, [`super::metals`]; default
//! `none`, a perfect mirror); `specular_reflectance` (a factor in [0, 1],
//! default 1); rough only: `distribution`, `alpha` or `alpha_u`/`alpha_v`
//! ([`super::optics::roughness`]).

use super::{Material, Params, optics};
use crate::scene::error::SceneError;
use crate::scene::texture;

pub(super) fn parse_smooth(params: &mut Params) -> Result<Material, SceneError> {
    parse(params, false)
}

pub(super) fn parse_rough(params: &mut Params) -> Result<Material, SceneError> {
    parse(params, true)
}

fn parse(params: &mut Params, rough: bool) -> Result<Material, SceneError> {
    let (eta, k) = optics::metal(params)?;
    Ok(Material::Conductor {
        eta,
        k,
        specular_reflectance: texture::albedo(params, "specular_reflectance", [1.0; 3])?,
        roughness: if rough {
            Some(optics::roughness(params)?)
        } else {
            None
        },
    })
}
