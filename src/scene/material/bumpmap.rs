//! `bumpmap`: the nested BSDF under shading normals tilted by a height
//! field, Mitsuba 3's adapter. With `h` the texture's scalar value (its
//! luminance) times `scale`, the surface is taken to be displaced by `h`
//! along its shading normal `n`, the normal's own change ignored: the
//! tangents become `∂p/∂u + (∂h/∂u − n·∂p/∂u) n` and likewise in `v`, and
//! the tilted normal is their cross product, turned to the geometric
//! normal's side (docs/math.md §18.5). A constant offset of `h` changes
//! nothing; only bilinear bitmaps have a gradient (a checkerboard's or a
//! nearest-texel lookup's is zero, as in Mitsuba). The model is
//! [`Perturbed`].
//!
//! Parameters: one texture of any name (Mitsuba names it freely, so any
//! parameter not named below is it, and a second one is refused; a number
//! is a flat field); `scale` (default 1); `bsdf` (exactly one nested
//! material); `flip_invalid_normals`, `use_shadowing_function` (default
//! true), as [`Perturbed`] describes.

use std::sync::Arc;

use glam::DVec3;

use super::perturbed::{Perturbed, nested_template};
use super::{Bsdf, Lookup, Material, Params, Parameters, Plugin};
use crate::scene::error::SceneError;
use crate::scene::texture::{self, Texture};

/// The parameter names a `bumpmap` knows besides its height field's.
const NAMED: &[&str] = &["bsdf", "scale", "flip_invalid_normals", "use_shadowing_function"];

/// The parameters of a `bumpmap` material; see the module docs.
#[derive(Clone, Debug, PartialEq)]
pub struct BumpMapMaterial {
    /// The height field, world units (times `scale`), its luminance taken.
    pub height: Texture,
    pub scale: f64,
    pub bsdf: Arc<Material>,
    pub flip_invalid_normals: bool,
    pub shadowing: bool,
}

impl Plugin for BumpMapMaterial {
    type Model = Perturbed;
}

impl BumpMapMaterial {
    /// The parameters of a material document, each validated once.
    pub(crate) fn parse(params: &mut Params) -> Result<Self, SceneError> {
        let names: Vec<String> = params
            .remaining()
            .into_iter()
            .filter(|n| !NAMED.contains(&n.as_str()))
            .collect();
        // A second one is left for `Params::finish` to refuse by name.
        let height = match names.first() {
            Some(name) => texture::values(params, name)?.expect("present"),
            None => return Err(params.missing("texture")),
        };
        let scale = params.number("scale")?.unwrap_or(1.0);
        if !scale.is_finite() {
            return Err(params.invalid("scale", format!("{scale} is not finite")));
        }
        Ok(Self {
            height,
            scale,
            bsdf: Material::one_nested(params, "bumpmap")?,
            flip_invalid_normals: params.boolean("flip_invalid_normals", true)?,
            shadowing: params.boolean("use_shadowing_function", true)?,
        })
    }
}

impl Parameters for BumpMapMaterial {
    fn textures(&self) -> Vec<&Texture> {
        vec![&self.height]
    }

    fn nested(&self) -> Vec<&Arc<Material>> {
        vec![&self.bsdf]
    }

    fn may_be_a_side(&self) -> bool {
        self.bsdf.may_be_a_side()
    }

    /// At a surface point, the tilted normal of the module docs in the
    /// shading frame (z = n); as a whole, the surface untilted.
    fn build(&self, lookup: Lookup, template: Option<&Bsdf>) -> Bsdf {
        let (normal, tangent) = match lookup {
            Lookup::At(p) => {
                let g = self.height.gradient_scalar(p.uv) * self.scale;
                let du = DVec3::new(p.dp_du.x, p.dp_du.y, g.x);
                let dv = DVec3::new(p.dp_dv.x, p.dp_dv.y, g.y);
                let n = du.cross(dv).try_normalize().unwrap_or(DVec3::Z);
                let n = if n.dot(p.normal) < 0.0 { -n } else { n };
                (n, p.dp_du)
            }
            Lookup::Mean => (DVec3::Z, DVec3::X),
        };
        Bsdf::BumpMap(Perturbed {
            normal,
            tangent,
            flip_invalid_normals: self.flip_invalid_normals,
            shadowing: self.shadowing,
            bsdf: Box::new(self.bsdf.build(lookup, nested_template(template))),
        })
    }
}
