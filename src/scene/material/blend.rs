//! `blendbsdf`: a linear blend of two materials, `f = (1 − w) f₀ + w f₁`
//! (Mitsuba 3's), e.g. dust over a metal or a painted pattern.
//!
//! Parameters: `weight` (w in [0, 1], a number or a texture whose
//! luminance is taken; default 0.5); `bsdf`: a list of exactly two nested
//! materials, `[f₀, f₁]`.
//!
//! Sampling picks `f₁`
//! with probability `w`; a direction from a spread lobe is then weighed by
//! the whole blend's value and density (so MIS sees the mixture), a delta
//! event by its component's share.

use glam::DVec3;

use std::sync::Arc;

use super::{Bsdf, BsdfFlags, LobeSample, Lookup, Material, Model, Params, Parameters, Plugin};
use crate::color::Rgb;
use crate::scene::error::SceneError;
use crate::scene::texture::{self, Texture};

/// The parameters of a `blendbsdf` material; see the module docs.
#[derive(Clone, Debug, PartialEq)]
pub struct BlendMaterial {
    /// `w`, its luminance taken.
    pub weight: Texture,
    pub bsdfs: [Arc<Material>; 2],
}

impl Plugin for BlendMaterial {
    type Model = Blend;
}

impl BlendMaterial {
    /// The parameters of a material document, each validated once.
    pub(crate) fn parse(params: &mut Params) -> Result<Self, SceneError> {
        let weight = texture::albedo(params, "weight", [0.5; 3])?;
        let nested: Vec<_> = Material::nested(params)?
            .into_iter()
            .map(|(_, m)| m)
            .collect();
        let Ok(bsdfs) = <[_; 2]>::try_from(nested) else {
            return Err(params.invalid("bsdf", "a blend needs exactly two nested materials"));
        };
        Ok(Self { weight, bsdfs })
    }
}

impl Parameters for BlendMaterial {
    fn textures(&self) -> Vec<&Texture> {
        vec![&self.weight]
    }

    fn nested(&self) -> Vec<&Arc<Material>> {
        vec![&self.bsdfs[0], &self.bsdfs[1]]
    }

    fn build(&self, lookup: Lookup, template: Option<&Bsdf>) -> Bsdf {
        let parts = match template {
            Some(Bsdf::Blend(b)) => [Some(&b.bsdfs[0]), Some(&b.bsdfs[1])],
            _ => [None, None],
        };
        Bsdf::Blend(Blend {
            weight: lookup.scalar(&self.weight).clamp(0.0, 1.0),
            bsdfs: Box::new([
                self.bsdfs[0].build(lookup, parts[0]),
                self.bsdfs[1].build(lookup, parts[1]),
            ]),
        })
    }
}

/// The blend's model: its weight valued and its components built.
#[derive(Clone, Debug, PartialEq)]
pub struct Blend {
    /// `w` in [0, 1].
    pub weight: f64,
    pub bsdfs: Box<[Bsdf; 2]>,
}

impl Blend {
    fn mix<T: std::ops::Add<Output = T> + std::ops::Mul<f64, Output = T>>(&self, a: T, b: T) -> T {
        a * (1.0 - self.weight) + b * self.weight
    }
}

impl Model for Blend {
    fn eval(&self, wo: DVec3, wi: DVec3) -> Rgb {
        self.mix(self.bsdfs[0].eval(wo, wi), self.bsdfs[1].eval(wo, wi))
    }

    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        self.mix(self.bsdfs[0].pdf(wo, wi), self.bsdfs[1].pdf(wo, wi))
    }

    fn sample(&self, wo: DVec3, u_lobe: f64, u: [f64; 2]) -> Option<LobeSample> {
        let w = self.weight;
        // The lobe number reused for the component's own choice.
        let (i, share, u_lobe) = if u_lobe < w {
            (1, w, u_lobe / w)
        } else {
            (0, 1.0 - w, (u_lobe - w) / (1.0 - w))
        };
        let s = self.bsdfs[i].sample(wo, u_lobe.min(1.0 - f64::EPSILON), u)?;
        if s.delta {
            return Some(LobeSample {
                value: s.value * share,
                pdf: s.pdf * share,
                ..s
            });
        }
        LobeSample::spread(s.wi, self.pdf(wo, s.wi), || self.eval(wo, s.wi))
    }

    fn flags(&self) -> BsdfFlags {
        self.bsdfs[0].flags().union(self.bsdfs[1].flags())
    }

    /// The components' parts, weighted as they are.
    fn lambertian(&self, wo: DVec3) -> Rgb {
        self.mix(self.bsdfs[0].lambertian(wo), self.bsdfs[1].lambertian(wo))
    }

    fn scatters_towards(&self, wo: DVec3) -> bool {
        self.bsdfs.iter().any(|b| b.scatters_towards(wo))
    }

    fn is_black(&self) -> bool {
        self.bsdfs.iter().all(Bsdf::is_black)
    }

    fn is_anisotropic(&self) -> bool {
        self.bsdfs.iter().any(Bsdf::is_anisotropic)
    }
}
