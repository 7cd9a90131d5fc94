//! `diffuse`: a Lambertian reflector, `f = ρ/π`, built as the Phong model
//! of `glossy` without its lobe (so the cache integrates it by BMC alike).
//!
//! Parameters: `reflectance` (the albedo `ρ`, in [0, 1] per channel, a
//! colour or a texture; required in JSON scenes, Mitsuba's 0.5 in
//! translated ones).

use super::glossy::Phong;
use super::{Bsdf, Lookup, Params, Parameters, Plugin};
use crate::scene::error::SceneError;
use crate::scene::texture::{self, Texture};

/// The parameters of a `diffuse` material; see the module docs.
#[derive(Clone, Debug, PartialEq)]
pub struct DiffuseMaterial {
    /// The albedo `ρ`, in [0, 1] per channel.
    pub reflectance: Texture,
}

impl Plugin for DiffuseMaterial {
    type Model = Phong;
}

impl DiffuseMaterial {
    /// The parameters of a material document, each validated once.
    pub(crate) fn parse(params: &mut Params) -> Result<Self, SceneError> {
        Ok(Self {
            reflectance: texture::required_albedo(params, "reflectance")?,
        })
    }
}

impl Parameters for DiffuseMaterial {
    fn textures(&self) -> Vec<&Texture> {
        vec![&self.reflectance]
    }

    fn build(&self, lookup: Lookup, _: Option<&Bsdf>) -> Bsdf {
        Bsdf::Diffuse(Phong::lambert(lookup.rgb(&self.reflectance)))
    }
}
