//! `normalmap`: the nested BSDF under shading normals read from an RGB
//! texture, Mitsuba 3's adapter. A texel `(r, g, b)` is the normal
//! `2 (r, g, b) − 1` in the surface's tangent frame (x along ∂p/∂u made
//! orthogonal to the shading normal, y = n × x, turned where the texture
//! coordinates are mirrored; z the shading normal), normalised: the
//! tangent-space normal maps of game and film assets, stored `raw`.
//! The model is [`Perturbed`] (docs/math.md §18.5).
//!
//! Parameters: `normalmap` (a texture, required; usually a `bitmap` with
//! `raw: true`); `bsdf` (the nested material, exactly one);
//! `flip_invalid_normals` (default true) and `use_shadowing_function`
//! (default true), as [`Perturbed`] describes.

use std::sync::Arc;

use glam::DVec3;

use super::perturbed::{Perturbed, nested_template};
use super::{Bsdf, Lookup, Material, Params, Parameters, Plugin};
use crate::scene::error::SceneError;
use crate::scene::texture::{self, Texture};

/// The parameters of a `normalmap` material; see the module docs.
#[derive(Clone, Debug, PartialEq)]
pub struct NormalMapMaterial {
    /// Encoded normals, `(n + 1)/2` per channel.
    pub normalmap: Texture,
    pub bsdf: Arc<Material>,
    pub flip_invalid_normals: bool,
    pub shadowing: bool,
}

impl Plugin for NormalMapMaterial {
    type Model = Perturbed;
}

impl NormalMapMaterial {
    /// The parameters of a material document, each validated once.
    pub(crate) fn parse(params: &mut Params) -> Result<Self, SceneError> {
        let normalmap = texture::values(params, "normalmap")?.ok_or_else(|| params.missing("normalmap"))?;
        Ok(Self {
            normalmap,
            bsdf: Material::one_nested(params, "normalmap")?,
            flip_invalid_normals: params.boolean("flip_invalid_normals", true)?,
            shadowing: params.boolean("use_shadowing_function", true)?,
        })
    }
}

impl Parameters for NormalMapMaterial {
    fn textures(&self) -> Vec<&Texture> {
        vec![&self.normalmap]
    }

    fn nested(&self) -> Vec<&Arc<Material>> {
        vec![&self.bsdf]
    }

    fn may_be_a_side(&self) -> bool {
        self.bsdf.may_be_a_side()
    }

    fn build(&self, lookup: Lookup, template: Option<&Bsdf>) -> Bsdf {
        let encoded = lookup.rgb(&self.normalmap);
        let normal = (DVec3::new(encoded.r, encoded.g, encoded.b) * 2.0 - 1.0)
            .try_normalize()
            .unwrap_or(DVec3::Z);
        Bsdf::NormalMap(Perturbed {
            normal,
            tangent: DVec3::X,
            flip_invalid_normals: self.flip_invalid_normals,
            shadowing: self.shadowing,
            bsdf: Box::new(self.bsdf.build(lookup, nested_template(template))),
        })
    }
}
