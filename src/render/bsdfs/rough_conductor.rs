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
//! - `alpha`, or `alpha_u` and `alpha_v` (anisotropic): roughness, default 0.1;
//! - `eta`, `k`: the conductor's complex index of refraction per RGB
//!   channel, relative to the outside;
//! - `specular_reflectance`: a factor on the reflectance, default 1.
//!
//! Single scattering loses the light that bounces more than once between
//! facets, so the albedo of a white (F = 1) surface falls below 1 as the
//! roughness grows, as in Mitsuba.

use glam::DVec3;

use super::{LobeSample, reflect};
use crate::color::Rgb;
use crate::render::fresnel;
use crate::render::microfacet::Microfacet;

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

#[cfg(test)]
mod tests;
