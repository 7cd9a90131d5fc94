//! `roughdielectric`: a rough interface between two dielectrics (glass,
//! water), reflecting and refracting by single scattering on microfacets
//! (Walter et al. 2007, eqs. 20–21), in the radiance convention:
//!
//! - reflection (`ω_i`, `ω_o` on one side): `F D G / (4 |cos θ_i| |cos θ_o|)`
//!   with `m` the half vector;
//! - refraction: `|ω_i·m| |ω_o·m| (1 − F) D G / (|cos θ_i| |cos θ_o|
//!   (ω_i·m + ω_o·m / η')²) / η'²`, with `η'` the index of `ω_i`'s side over
//!   `ω_o`'s and `m ∝ η' ω_i + ω_o` the generalised half vector;
//!
//! `F` the dielectric Fresnel reflectance at `ω_o·m` and `G` the separable
//! Smith term (`microfacet`). The `1/η'²` makes radiance, not importance,
//! cross the interface: `f(a, b) / n(a)² = f(b, a) / n(b)²` (generalised
//! reciprocity, Veach 1997 §5.2), which the tests check.
//!
//! Sampling draws `m` from the distribution's strategy as seen from `ω_o`,
//! then reflects with probability `F` and refracts otherwise; the density
//! carries the Jacobians of both maps (Walter et al. 2007, eqs. 14 and 17).
//! A view from inside (`cos θ_o < 0`) is the same interface seen from
//! outside with `η` inverted, so every formula runs with `ω_o` above.
//!
//! Parameters (Mitsuba 3's names): `distribution` (`beckmann` default,
//! or `ggx`); `alpha` or `alpha_u`/`alpha_v`, default 0.1, numbers or
//! textures (`optical_params::roughness`; below `MIN_ALPHA` the interface
//! is the smooth `dielectric`); `int_ior`, `ext_ior`,
//! `specular_reflectance`, `specular_transmittance`: as `dielectric`'s.

use glam::DVec3;

use super::dielectric::Dielectric;
use super::Interface;
use super::{
    Bsdf, BsdfFlags, LobeSample, Lookup, Model, Params, Parameters, Plugin, Roughness, optical_params,
    reflect,
};
use crate::color::Rgb;
use crate::scene::error::SceneError;
use crate::scene::texture::Texture;
use crate::optics::fresnel;
use crate::optics::microfacet::Microfacet;

/// A rough dielectric interface; see the module docs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RoughDielectric {
    pub distribution: Microfacet,
    /// Interior over exterior index of refraction, > 0 and ≠ 1.
    pub eta: f64,
    pub specular_reflectance: Rgb,
    pub specular_transmittance: Rgb,
}

/// The configuration seen with `ω_o` above the surface.
struct Canonical {
    wo: DVec3,
    wi: DVec3,
    /// Index of the far side (below) over the near side (above).
    eta: f64,
}

impl RoughDielectric {
    fn canonical(&self, wo: DVec3, wi: DVec3) -> Canonical {
        if wo.z >= 0.0 {
            Canonical {
                wo,
                wi,
                eta: self.eta,
            }
        } else {
            Canonical {
                wo: -wo,
                wi: -wi,
                eta: 1.0 / self.eta,
            }
        }
    }

    /// Smith's separable masking-shadowing (`microfacet`) for directions
    /// on either side: Λ depends on a direction's slope only, and the side
    /// conditions are checked with the half vector.
    fn g(&self, a: DVec3, b: DVec3) -> f64 {
        let g1 = |w: DVec3| 1.0 / (1.0 + self.distribution.lambda(w));
        g1(a) * g1(b)
    }

    /// The generalised half vector of a refraction, facing up, if both
    /// directions lie on the sides of it their hemispheres say.
    fn refraction_normal(c: &Canonical) -> Option<DVec3> {
        let m = (c.wi * c.eta + c.wo).normalize();
        let m = if m.z < 0.0 { -m } else { m };
        let consistent = c.wi.dot(m) * c.wi.z > 0.0 && c.wo.dot(m) * c.wo.z > 0.0;
        (consistent && m.is_finite()).then_some(m)
    }

    /// `f(ω_o, ω_i)`, sr⁻¹ (module docs).
    pub fn eval(&self, wo: DVec3, wi: DVec3) -> Rgb {
        let c = self.canonical(wo, wi);
        if c.wo.z == 0.0 || c.wi.z == 0.0 {
            return Rgb::BLACK;
        }
        if c.wi.z > 0.0 {
            let m = (c.wi + c.wo).normalize();
            let f = fresnel::dielectric(c.wo.dot(m), c.eta).reflectance;
            let d = self.distribution.d(m);
            return self.specular_reflectance
                * (f * d * self.g(c.wi, c.wo) / (4.0 * c.wi.z * c.wo.z));
        }
        let Some(m) = Self::refraction_normal(&c) else {
            return Rgb::BLACK;
        };
        let (im, om) = (c.wi.dot(m), c.wo.dot(m));
        let f = fresnel::dielectric(om, c.eta).reflectance;
        let denom = (im + om / c.eta).powi(2);
        let value = (im * om).abs() * (1.0 - f) * self.distribution.d(m) * self.g(c.wi, c.wo)
            / ((c.wi.z * c.wo.z).abs() * denom)
            / (c.eta * c.eta);
        self.specular_transmittance * value
    }

    /// Density (sr⁻¹) with which [`Self::sample`] draws `wi`.
    pub fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        let c = self.canonical(wo, wi);
        if c.wo.z == 0.0 || c.wi.z == 0.0 {
            return 0.0;
        }
        if c.wi.z > 0.0 {
            let m = (c.wi + c.wo).normalize();
            let om = c.wo.dot(m);
            if om <= 0.0 {
                return 0.0;
            }
            let f = fresnel::dielectric(om, c.eta).reflectance;
            return f * self.distribution.pdf(c.wo, m) / (4.0 * om);
        }
        let Some(m) = Self::refraction_normal(&c) else {
            return 0.0;
        };
        let (im, om) = (c.wi.dot(m), c.wo.dot(m));
        let f = fresnel::dielectric(om, c.eta).reflectance;
        // dω_m / dω_i for refraction (Walter et al. 2007, eq. 17).
        let jacobian = im.abs() / (im + om / c.eta).powi(2);
        (1.0 - f) * self.distribution.pdf(c.wo, m) * jacobian
    }

    /// `ω_i` by reflection (probability `F`) or refraction about a sampled
    /// microfacet normal; `None` where the sample leaves the side its
    /// event requires (that mass has `f = 0`).
    pub fn sample(&self, wo: DVec3, u_event: f64, u: [f64; 2]) -> Option<LobeSample> {
        let flip = wo.z < 0.0;
        let c = self.canonical(wo, wo);
        if c.wo.z == 0.0 {
            return None;
        }
        let m = self.distribution.sample(c.wo, u).m;
        let om = c.wo.dot(m);
        if om <= 0.0 {
            return None;
        }
        let fresnel = fresnel::dielectric(om, c.eta);
        let wi = if u_event < fresnel.reflectance {
            let wi = reflect(c.wo, m);
            (wi.z > 0.0).then_some(wi)?
        } else {
            // Refraction about m: ω_t = −ω_o/η + (cos θ_o/η + cos θ_t) m,
            // with `cos_t` negative (the transmitted side of m).
            let wi = -c.wo / c.eta + (om / c.eta + fresnel.cos_t) * m;
            (wi.z < 0.0).then_some(wi.normalize())?
        };
        let wi = if flip { -wi } else { wi };
        LobeSample::spread(wi, self.pdf(wo, wi), || self.eval(wo, wi))
    }
}

/// The parameters of a `roughdielectric` material; see the module docs.
#[derive(Clone, Debug, PartialEq)]
pub struct RoughDielectricMaterial {
    pub interface: Interface,
    pub roughness: Roughness,
}

impl Plugin for RoughDielectricMaterial {
    type Model = RoughDielectric;
}

impl RoughDielectricMaterial {
    /// The parameters of a material document, each validated once.
    pub(crate) fn parse(params: &mut Params) -> Result<Self, SceneError> {
        Ok(Self {
            interface: Interface::parse(params)?,
            roughness: optical_params::roughness(params)?,
        })
    }
}

impl Parameters for RoughDielectricMaterial {
    fn textures(&self) -> Vec<&Texture> {
        let mut all = self.interface.textures();
        all.extend(self.roughness.textures());
        all
    }

    /// A dielectric is the same from both sides.
    fn may_be_a_side(&self) -> bool {
        false
    }

    fn build(&self, lookup: Lookup, _: Option<&Bsdf>) -> Bsdf {
        let (eta, specular_reflectance, specular_transmittance) = self.interface.at(lookup);
        match self.roughness.microfacet(lookup) {
            Some(distribution) => Bsdf::RoughDielectric(RoughDielectric {
                distribution,
                eta,
                specular_reflectance,
                specular_transmittance,
            }),
            None => Bsdf::Dielectric(Dielectric {
                eta,
                specular_reflectance,
                specular_transmittance,
            }),
        }
    }
}

impl Model for RoughDielectric {
    fn eval(&self, wo: DVec3, wi: DVec3) -> Rgb {
        RoughDielectric::eval(self, wo, wi)
    }

    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        RoughDielectric::pdf(self, wo, wi)
    }

    fn sample(&self, wo: DVec3, u_lobe: f64, u: [f64; 2]) -> Option<LobeSample> {
        RoughDielectric::sample(self, wo, u_lobe, u)
    }

    fn flags(&self) -> BsdfFlags {
        BsdfFlags {
            glossy: true,
            transmission: true,
            ..BsdfFlags::default()
        }
    }

    fn is_anisotropic(&self) -> bool {
        let (u, v) = self.distribution.alpha();
        u != v
    }
}

#[cfg(test)]
mod tests;
