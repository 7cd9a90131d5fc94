//! `roughconductor`: a rough metal, single scattering on a microfacet
//! surface (Walter et al. 2007, eq. 20) with the conductor's complex Fresnel
//! reflectance:
//!
//! `f(ω_o, ω_i) = F(ω_i·m) D(m) G(ω_i, ω_o, m) / (4 cos θ_i cos θ_o)`,
//! `m = (ω_i + ω_o)/|ω_i + ω_o|`,
//!
//! with `G` the separable Smith term (`microfacet`). Sampling draws `m` from the
//! distribution's own strategy (`microfacet`: GGX visible normals) and
//! reflects `ω_o` about it; the density of `ω_i` is that of `m` times the
//! Jacobian `1/(4 |ω_o·m|)` of the reflection (Walter et al. 2007, eq. 14).
//!
//! Parameters (Mitsuba 3's names):
//! - `distribution`: `beckmann` (default, as Mitsuba 3) or `ggx`;
//! - `alpha`, or `alpha_u` and `alpha_v` (anisotropic): roughness, default
//!   0.1, numbers or textures (`optical_params::roughness`); below
//!   `MIN_ALPHA` the surface is the smooth `conductor`;
//! - `eta`, `k`, `material`, `specular_reflectance`: as `conductor`'s.
//!
//! Single scattering loses the light that bounces more than once between
//! facets, so the albedo of a white (F = 1) surface falls below 1 as the
//! roughness grows, as in Mitsuba.

use glam::DVec3;

use super::conductor::Conductor;
use super::{
    Bsdf, BsdfFlags, LobeSample, Lookup, Model, Params, Parameters, Plugin, Roughness, optical_params,
    reflect,
};
use crate::color::{Rgb, RgbArray};
use crate::scene::error::SceneError;
use crate::scene::texture::{self, Texture};
use crate::optics::fresnel;
use crate::optics::microfacet::Microfacet;

/// A rough conductor lobe; see the module docs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RoughConductor {
    pub distribution: Microfacet,
    /// Real part of the relative index per channel.
    pub eta: Rgb,
    /// Imaginary part (absorption) per channel, ≥ 0.
    pub k: Rgb,
    pub specular_reflectance: Rgb,
}

impl RoughConductor {
    /// Fresnel reflectance per channel at `cos_i`, times `specular_reflectance`.
    fn fresnel(&self, cos_i: f64) -> Rgb {
        fresnel::conductor_rgb(cos_i, self.eta, self.k) * self.specular_reflectance
    }

    /// `f(ω_o, ω_i)`, sr⁻¹; zero unless both are above the surface.
    pub fn eval(&self, wo: DVec3, wi: DVec3) -> Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::BLACK;
        }
        let m = (wi + wo).normalize();
        let d = self.distribution.d(m);
        let g = self.distribution.g(wi, wo, m);
        if d == 0.0 || g == 0.0 {
            return Rgb::BLACK;
        }
        self.fresnel(wi.dot(m)) * (d * g / (4.0 * wi.z * wo.z))
    }

    /// Density (sr⁻¹) with which [`Self::sample`] draws `wi`.
    pub fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let m = (wi + wo).normalize();
        let cos_om = wo.dot(m);
        if cos_om <= 0.0 {
            return 0.0;
        }
        self.distribution.pdf(wo, m) / (4.0 * cos_om)
    }

    /// `ω_i` by reflecting `ω_o` about a sampled microfacet normal; `None`
    /// when `ω_o` is below the surface or the reflection goes below it
    /// (that mass has `f = 0`, so dropping it keeps estimates unbiased).
    pub fn sample(&self, wo: DVec3, u: [f64; 2]) -> Option<LobeSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let m = self.distribution.sample(wo, u).m;
        let wi = reflect(wo, m);
        if wi.z <= 0.0 {
            return None;
        }
        LobeSample::spread(wi, self.pdf(wo, wi), || self.eval(wo, wi))
    }
}

/// The parameters of a `roughconductor` material; see the module docs.
#[derive(Clone, Debug, PartialEq)]
pub struct RoughConductorMaterial {
    /// Real part `η` of the relative complex index, per channel.
    pub eta: RgbArray,
    /// Imaginary part `k` (absorption), per channel.
    pub k: RgbArray,
    /// A factor on the reflectance, in [0, 1].
    pub specular_reflectance: Texture,
    pub roughness: Roughness,
}

impl Plugin for RoughConductorMaterial {
    type Model = RoughConductor;
}

impl RoughConductorMaterial {
    /// The parameters of a material document, each validated once.
    pub(crate) fn parse(params: &mut Params) -> Result<Self, SceneError> {
        let (eta, k) = optical_params::metal(params)?;
        Ok(Self {
            eta,
            k,
            specular_reflectance: texture::albedo(params, "specular_reflectance", [1.0; 3])?,
            roughness: optical_params::roughness(params)?,
        })
    }
}

impl Parameters for RoughConductorMaterial {
    fn textures(&self) -> Vec<&Texture> {
        let mut all = vec![&self.specular_reflectance];
        all.extend(self.roughness.textures());
        all
    }

    fn build(&self, lookup: Lookup, _: Option<&Bsdf>) -> Bsdf {
        let (eta, k) = (Rgb::from_array(self.eta), Rgb::from_array(self.k));
        let specular_reflectance = lookup.rgb(&self.specular_reflectance);
        match self.roughness.microfacet(lookup) {
            Some(distribution) => Bsdf::RoughConductor(RoughConductor {
                distribution,
                eta,
                k,
                specular_reflectance,
            }),
            None => Bsdf::Conductor(Conductor {
                eta,
                k,
                specular_reflectance,
            }),
        }
    }
}

impl Model for RoughConductor {
    fn eval(&self, wo: DVec3, wi: DVec3) -> Rgb {
        RoughConductor::eval(self, wo, wi)
    }

    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        RoughConductor::pdf(self, wo, wi)
    }

    fn sample(&self, wo: DVec3, _: f64, u: [f64; 2]) -> Option<LobeSample> {
        RoughConductor::sample(self, wo, u)
    }

    fn flags(&self) -> BsdfFlags {
        BsdfFlags {
            glossy: true,
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
