//! `phong`: the project's own reflection model, Lambert plus an optional
//! normalised modified-Phong lobe (the JSON format's `diffuse` and `glossy`).
//!
//! `f_r(ω_o, ω_i) = k_d/π + k_s (m+2)/(2π) cos^m α`, with `α` the angle
//! between `ω_i` and the mirror direction of `ω_o` (docs/math.md §1;
//! Lafortune & Willems 1994). A purely diffuse material has `k_s = 0`.
//!
//! All directions are unit vectors in the **local frame** (z = the geometric
//! normal as authored) and both point away from the surface.
//!
//! **One-sided**, like Mitsuba 3's `diffuse` and `phong`-style BSDFs: when
//! `ω_o` or `ω_i` lies below the surface (`z ≤ 0`) the BSDF is zero, so the
//! back of a surface is black. Matching this convention is what makes our
//! numbers comparable with Mitsuba's (docs/VALIDATION.md).

use glam::DVec3;

use super::LobeSample;
use crate::color::Rgb;
use crate::render::warp;
use crate::sphere::Frame;
use std::f64::consts::{FRAC_1_PI, TAU};

/// Lambert + normalised Phong reflection; see the module docs.
///
/// Invariant (checked by the scene loader, which builds every [`Phong`]):
/// reflectances are finite and non-negative and `exponent ≥ 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Phong {
    /// Diffuse reflectance `k_d` (the diffuse albedo).
    pub diffuse: Rgb,
    /// Specular reflectance `k_s`: the lobe's albedo when it lies entirely
    /// above the surface.
    pub specular: Rgb,
    /// Phong exponent `m`; larger is shinier.
    pub exponent: f64,
    /// Probability of sampling the Phong lobe rather than the cosine lobe,
    /// proportional to the lobes' luminance-weighted albedos.
    specular_probability: f64,
}

impl Phong {
    pub fn new(diffuse: Rgb, specular: Rgb, exponent: f64) -> Self {
        let (d, s) = (diffuse.luminance().max(0.0), specular.luminance().max(0.0));
        let specular_probability = if d + s > 0.0 { s / (d + s) } else { 0.0 };
        Self {
            diffuse,
            specular,
            exponent,
            specular_probability,
        }
    }

    pub fn lambert(reflectance: Rgb) -> Self {
        Self::new(reflectance, Rgb::BLACK, 0.0)
    }

    /// True when the material reflects nothing, so paths can stop here.
    pub fn is_black(&self) -> bool {
        self.diffuse.is_black() && self.specular.is_black()
    }

    /// `f_r(ω_o, ω_i)`, sr⁻¹; zero unless both directions are above the surface.
    pub fn eval(&self, wo: DVec3, wi: DVec3) -> Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::BLACK;
        }
        let mut f = self.diffuse * FRAC_1_PI;
        if self.specular_probability > 0.0 {
            let cos_alpha = wi.dot(mirror(wo));
            if cos_alpha > 0.0 {
                let lobe = (self.exponent + 2.0) / TAU * cos_alpha.powf(self.exponent);
                f += self.specular * lobe;
            }
        }
        f
    }

    /// Density (sr⁻¹) with which [`Phong::sample`] draws `wi`; zero below the
    /// surface, where the sampler returns no direction.
    pub fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let ps = self.specular_probability;
        let mut pdf = (1.0 - ps) * warp::cosine_hemisphere_pdf(wi);
        if ps > 0.0 {
            pdf += ps * warp::power_cosine_pdf(wi.dot(mirror(wo)), self.exponent);
        }
        pdf
    }

    /// Draws `wi` from the mixture of a cosine lobe and the Phong lobe.
    ///
    /// `u_lobe` picks the lobe, `u` drives the warp. Returns `None` when `ω_o`
    /// is below the surface or the Phong lobe produced a direction below it
    /// (that mass has `f_r = 0`, so dropping it keeps the estimate unbiased).
    pub fn sample(&self, wo: DVec3, u_lobe: f64, u: [f64; 2]) -> Option<LobeSample> {
        if wo.z <= 0.0 || self.is_black() {
            return None;
        }
        let wi = if u_lobe < self.specular_probability {
            let r = mirror(wo);
            Frame::from_normal(r).to_world(warp::power_cosine(u, self.exponent))
        } else {
            warp::cosine_hemisphere(u)
        };
        if wi.z <= 0.0 {
            return None;
        }
        LobeSample::spread(wi, self.pdf(wo, wi), || self.eval(wo, wi))
    }
}

/// Mirror direction of `wo` about the local normal z.
fn mirror(wo: DVec3) -> DVec3 {
    DVec3::new(-wo.x, -wo.y, wo.z)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64;

    fn integrate_hemisphere(f: impl Fn(DVec3) -> f64) -> f64 {
        warp::integrate_directions(f, 0.0, 2000, 256)
    }

    fn glossy() -> Phong {
        Phong::new(Rgb::new(0.3, 0.2, 0.1), Rgb::new(0.4, 0.5, 0.6), 20.0)
    }

    #[test]
    fn albedo_at_normal_incidence_is_kd_plus_ks() {
        // ∫ f cos dω with ω_o = n: the Phong lobe is centred on n, and
        // (m+2)/(2π) ∫ cos^{m+1} θ dω = 1 exactly.
        for bsdf in [Phong::lambert(Rgb::new(0.8, 0.5, 0.2)), glossy()] {
            let expected = bsdf.diffuse + bsdf.specular;
            let got = [0, 1, 2]
                .map(|c| integrate_hemisphere(|wi| bsdf.eval(DVec3::Z, wi).to_array()[c] * wi.z));
            for c in 0..3 {
                assert!(
                    (got[c] - expected.to_array()[c]).abs() < 1e-4,
                    "{got:?} vs {expected:?}"
                );
            }
        }
    }

    #[test]
    fn sampling_density_integrates_to_one_at_normal_incidence() {
        let total = integrate_hemisphere(|wi| glossy().pdf(DVec3::Z, wi));
        assert!((total - 1.0).abs() < 1e-4, "{total}");
        // At grazing incidence part of the lobe falls below the surface.
        let wo = DVec3::new(0.9, 0.0, 0.1f64).normalize();
        let total = integrate_hemisphere(|wi| glossy().pdf(wo, wi));
        assert!(total < 1.0 && total > 0.5, "{total}");
    }

    #[test]
    fn importance_sampling_reproduces_the_albedo() {
        let bsdf = glossy();
        let wo = DVec3::new(0.5, -0.2, 0.8).normalize();
        let reference = integrate_hemisphere(|wi| bsdf.eval(wo, wi).g * wi.z);
        let mut rng = Pcg64::seed_from_u64(7);
        let n = 200_000;
        let mut sum = 0.0;
        for _ in 0..n {
            if let Some(s) = bsdf.sample(wo, rng.random(), [rng.random(), rng.random()]) {
                assert!((s.pdf - bsdf.pdf(wo, s.wi)).abs() < 1e-9 * s.pdf);
                sum += s.value.g * s.wi.z / s.pdf;
            }
        }
        let estimate = sum / n as f64;
        assert!(
            (estimate - reference).abs() < 0.01 * reference,
            "{estimate} vs {reference}"
        );
    }

    #[test]
    fn back_side_is_black() {
        let below = DVec3::new(0.0, 0.6, -0.8);
        let above = DVec3::new(0.0, 0.6, 0.8);
        let bsdf = glossy();
        assert!(bsdf.eval(below, above).is_black());
        assert!(bsdf.eval(above, below).is_black());
        assert_eq!(bsdf.pdf(above, below), 0.0);
        assert!(bsdf.sample(below, 0.5, [0.3, 0.3]).is_none());
    }
}
