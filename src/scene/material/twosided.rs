//! `twosided`: a material for both sides of a surface. One nested BSDF
//! (`"bsdf": {…}`) serves both sides; two (`"bsdf": [front, back]`) give
//! the side the normal points to and the other. On the back side the
//! nested BSDF is evaluated as if the surface were turned around, as
//! Mitsuba 3 does. Nested BSDFs may not transmit (a two-sided glass is
//! just glass) nor be two-sided themselves.

use std::sync::Arc;

use glam::DVec3;

use super::{
    Bsdf, BsdfFlags, LobeSample, Lookup, Material, Model, Params, Parameters, Plugin, flip,
};
use crate::color::Rgb;
use crate::scene::error::SceneError;
use crate::scene::texture::Texture;

/// The parameters of a `twosided` material; see the module docs.
#[derive(Clone, Debug, PartialEq)]
pub struct TwoSidedMaterial {
    /// The material on the side the normal points to.
    pub front: Arc<Material>,
    /// The material on the other side.
    pub back: Arc<Material>,
}

impl Plugin for TwoSidedMaterial {
    type Model = TwoSided;
}

impl TwoSidedMaterial {
    /// The parameters of a material document, each validated once.
    pub(crate) fn parse(params: &mut Params) -> Result<Self, SceneError> {
        let mut sides = Vec::new();
        for (field, material) in Material::nested(params)? {
            if !material.may_be_a_side() {
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
        Ok(Self { front, back })
    }
}

impl Parameters for TwoSidedMaterial {
    fn textures(&self) -> Vec<&Texture> {
        Vec::new()
    }

    fn nested(&self) -> Vec<&Arc<Material>> {
        vec![&self.front, &self.back]
    }

    /// A two-sided material is one already.
    fn may_be_a_side(&self) -> bool {
        false
    }

    fn build(&self, lookup: Lookup, template: Option<&Bsdf>) -> Bsdf {
        let sides = match template {
            Some(Bsdf::TwoSided(t)) => [Some(&t.sides[0]), Some(&t.sides[1])],
            _ => [None, None],
        };
        Bsdf::TwoSided(TwoSided {
            sides: Box::new([
                self.front.build(lookup, sides[0]),
                self.back.build(lookup, sides[1]),
            ]),
        })
    }
}

/// The two-sided model: each side's BSDF, the back one evaluated with the
/// directions turned to its side (`z` negated).
#[derive(Clone, Debug, PartialEq)]
pub struct TwoSided {
    /// `[front, back]`.
    pub sides: Box<[Bsdf; 2]>,
}

impl TwoSided {
    /// The side `wo` sees and whether directions must be turned around for it.
    fn side(&self, wo: DVec3) -> (&Bsdf, bool) {
        if wo.z < 0.0 {
            (&self.sides[1], true)
        } else {
            (&self.sides[0], false)
        }
    }
}

impl Model for TwoSided {
    fn eval(&self, wo: DVec3, wi: DVec3) -> Rgb {
        match self.side(wo) {
            (side, true) => side.eval(flip(wo), flip(wi)),
            (side, false) => side.eval(wo, wi),
        }
    }

    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        match self.side(wo) {
            (side, true) => side.pdf(flip(wo), flip(wi)),
            (side, false) => side.pdf(wo, wi),
        }
    }

    fn sample(&self, wo: DVec3, u_lobe: f64, u: [f64; 2]) -> Option<LobeSample> {
        match self.side(wo) {
            (side, true) => side.sample(flip(wo), u_lobe, u).map(|s| LobeSample {
                wi: flip(s.wi),
                ..s
            }),
            (side, false) => side.sample(wo, u_lobe, u),
        }
    }

    fn flags(&self) -> BsdfFlags {
        self.sides[0].flags().union(self.sides[1].flags())
    }

    fn lambertian(&self, wo: DVec3) -> Rgb {
        match self.side(wo) {
            (side, true) => side.lambertian(flip(wo)),
            (side, false) => side.lambertian(wo),
        }
    }

    /// The back side always scatters: it is a plain BSDF turned around.
    fn scatters_towards(&self, wo: DVec3) -> bool {
        match self.side(wo) {
            (_, true) => true,
            (side, false) => side.scatters_towards(wo),
        }
    }

    fn is_anisotropic(&self) -> bool {
        self.sides.iter().any(Bsdf::is_anisotropic)
    }
}
