//! `diffuse`: a Lambertian reflector, `f = ρ/π`.
//!
//! Parameters: `reflectance` (the albedo `ρ`, in [0, 1] per channel, a
//! colour or a texture; required in JSON scenes, Mitsuba's 0.5 in
//! translated ones).

use super::{Material, Params};
use crate::scene::error::SceneError;
use crate::scene::texture;

pub(super) fn parse(params: &mut Params) -> Result<Material, SceneError> {
    Ok(Material::Diffuse {
        reflectance: texture::required_albedo(params, "reflectance")?,
    })
}
