//! `mask`: with probability `α` (the opacity) the nested BSDF scatters,
//! otherwise light passes straight through (`ω_i = −ω_o`, a delta
//! transmission of weight `1 − α`), Mitsuba 3's. Shadow rays stop at the
//! surface as at any other (as in Mitsuba); light crossing it is reached
//! by sampling the pass-through. For leaves, fences, cut-outs.
//!
//! Parameters: `opacity` (α in [0, 1], a number or a texture whose
//! luminance is taken, usually a bitmap with `raw`; default 0.5); `bsdf`:
//! the nested material.

use glam::DVec3;

use std::sync::Arc;

use super::{Bsdf, BsdfFlags, LobeSample, Lookup, Material, Model, Params, Parameters, Plugin};
use crate::color::Rgb;
use crate::scene::error::SceneError;
use crate::scene::texture::{self, Texture};

/// The parameters of a `mask` material; see the module docs.
#[derive(Clone, Debug, PartialEq)]
pub struct MaskMaterial {
    /// `α`, its luminance taken.
    pub opacity: Texture,
    pub bsdf: Arc<Material>,
}

impl Plugin for MaskMaterial {
    type Model = Mask;
}

impl MaskMaterial {
    /// The parameters of a material document, each validated once.
    pub(crate) fn parse(params: &mut Params) -> Result<Self, SceneError> {
        let opacity = texture::albedo(params, "opacity", [0.5; 3])?;
        let bsdf = Material::one_nested(params, "mask")?;
        Ok(Self { opacity, bsdf })
    }
}

impl Parameters for MaskMaterial {
    fn textures(&self) -> Vec<&Texture> {
        vec![&self.opacity]
    }

    fn nested(&self) -> Vec<&Arc<Material>> {
        vec![&self.bsdf]
    }

    fn build(&self, lookup: Lookup, template: Option<&Bsdf>) -> Bsdf {
        let inner = match template {
            Some(Bsdf::Mask(m)) => Some(&*m.bsdf),
            _ => None,
        };
        Bsdf::Mask(Mask {
            opacity: lookup.scalar(&self.opacity).clamp(0.0, 1.0),
            bsdf: Box::new(self.bsdf.build(lookup, inner)),
        })
    }
}

/// The mask's model: its opacity valued and its material built.
#[derive(Clone, Debug, PartialEq)]
pub struct Mask {
    /// `α` in [0, 1].
    pub opacity: f64,
    pub bsdf: Box<Bsdf>,
}

impl Model for Mask {
    fn eval(&self, wo: DVec3, wi: DVec3) -> Rgb {
        self.bsdf.eval(wo, wi) * self.opacity
    }

    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        self.bsdf.pdf(wo, wi) * self.opacity
    }

    fn sample(&self, wo: DVec3, u_lobe: f64, u: [f64; 2]) -> Option<LobeSample> {
        let alpha = self.opacity;
        // Where the nested BSDF scatters nothing (a one-sided one seen
        // from below) passing through is the only event.
        let scatters = self.bsdf.scatters_towards(wo);
        if u_lobe >= alpha || !scatters {
            let wi = -wo;
            if wi.z == 0.0 || alpha >= 1.0 {
                return None;
            }
            let pass = 1.0 - alpha;
            return Some(LobeSample {
                wi,
                value: Rgb::WHITE * (pass / wi.z.abs()),
                pdf: if scatters { pass } else { 1.0 },
                delta: true,
            });
        }
        let s = self.bsdf.sample(wo, u_lobe / alpha, u)?;
        Some(LobeSample {
            value: s.value * alpha,
            pdf: s.pdf * alpha,
            ..s
        })
    }

    fn flags(&self) -> BsdfFlags {
        let pass = BsdfFlags {
            delta: self.opacity < 1.0,
            transmission: self.opacity < 1.0,
            ..BsdfFlags::default()
        };
        self.bsdf.flags().union(pass)
    }

    fn lambertian(&self, wo: DVec3) -> Rgb {
        self.bsdf.lambertian(wo) * self.opacity
    }

    fn scatters_towards(&self, wo: DVec3) -> bool {
        self.opacity < 1.0 || self.bsdf.scatters_towards(wo)
    }

    fn is_anisotropic(&self) -> bool {
        self.bsdf.is_anisotropic()
    }
}
