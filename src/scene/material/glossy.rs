//! `glossy` (this project's own, not Mitsuba's): a Lambertian base plus a
//! normalised Phong lobe (Lafortune & Willems, "Using the modified Phong
//! reflectance model for physically based rendering", 1994):
//! `f_r(ω_o, ω_i) = k_d/π + k_s (m+2)/(2π) cos^m α`, with `α` the angle
//! between `ω_i` and the mirror direction of `ω_o` (docs/math.md §1). A
//! purely diffuse material (`diffuse`) is this model with `k_s = 0`.
//!
//! Parameters (all required): `diffuse` (`k_d`), `specular` (`k_s`), each
//! in [0, 1] with `k_d + k_s ≤ 1` per channel so no energy is created;
//! `exponent` (`m`, 0 or in `[1, MAX_PHONG_EXPONENT]`). Between 0 and 1
//! the lobe `cosᵐ α` has an infinite slope at its edge, where the cache
//! integrator's BMC weights integrate it: their exact kernel means then
//! take seconds per node instead of a fraction (measured: 2.5 s at
//! `m` = 0.5 against 0.3 s at 20), so such lobes are refused rather than
//! left to hold a worker.
//!
//! All directions are unit vectors in the **local frame** (z = the geometric
//! normal as authored) and both point away from the surface.
//!
//! **One-sided**, like Mitsuba 3's `diffuse` and `phong`-style BSDFs: when
//! `ω_o` or `ω_i` lies below the surface (`z ≤ 0`) the BSDF is zero, so the
//! back of a surface is black. Matching this convention is what makes our
//! numbers comparable with Mitsuba's (docs/VALIDATION.md).

use glam::DVec3;

use super::{
    Bsdf, BsdfFlags, LobeSample, Lookup, MAX_PHONG_EXPONENT, Model, Params, Parameters, Plugin,
};
use crate::color::{Rgb, RgbArray};
use crate::scene::error::SceneError;
use crate::scene::texture::Texture;
use crate::optics::warp;
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

/// The parameters of a `glossy` material; see the module docs.
#[derive(Clone, Debug, PartialEq)]
pub struct GlossyMaterial {
    /// `k_d`, linear RGB.
    pub diffuse: RgbArray,
    /// `k_s` (the lobe's albedo at normal incidence), linear RGB.
    pub specular: RgbArray,
    /// `m ≥ 0`.
    pub exponent: f64,
}

impl Plugin for GlossyMaterial {
    type Model = Phong;
}

impl GlossyMaterial {
    /// The parameters of a material document, each validated once.
    pub(crate) fn parse(params: &mut Params) -> Result<Self, SceneError> {
    let diffuse = params.required_albedo("diffuse")?;
    let specular = params.required_albedo("specular")?;
    if let Some(i) = (0..3).find(|&i| diffuse[i] + specular[i] > 1.0) {
        return Err(SceneError::invalid(
            format!("{}[{i}]", params.field("specular")),
            "diffuse + specular exceeds 1: the material would create energy",
        ));
    }
    let exponent = match params.number("exponent")? {
        Some(x) if x == 0.0 || (1.0..=MAX_PHONG_EXPONENT).contains(&x) => x,
        Some(x) => {
            return Err(SceneError::invalid(
                params.field("exponent"),
                format!("{x} is neither 0 nor in [1, {MAX_PHONG_EXPONENT:e}]"),
            ));
        }
        None => return Err(params.missing("exponent")),
    };
        Ok(Self {
            diffuse,
            specular,
            exponent,
        })
    }
}

impl Parameters for GlossyMaterial {
    fn textures(&self) -> Vec<&Texture> {
        Vec::new()
    }

    fn build(&self, _: Lookup, _: Option<&Bsdf>) -> Bsdf {
        let rgb = Rgb::from_array;
        Bsdf::Glossy(Phong::new(rgb(self.diffuse), rgb(self.specular), self.exponent))
    }
}

impl Model for Phong {
    fn eval(&self, wo: DVec3, wi: DVec3) -> Rgb {
        Phong::eval(self, wo, wi)
    }

    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        Phong::pdf(self, wo, wi)
    }

    fn sample(&self, wo: DVec3, u_lobe: f64, u: [f64; 2]) -> Option<LobeSample> {
        Phong::sample(self, wo, u_lobe, u)
    }

    fn flags(&self) -> BsdfFlags {
        BsdfFlags {
            diffuse: !self.diffuse.is_black(),
            glossy: !self.specular.is_black(),
            ..BsdfFlags::default()
        }
    }

    /// The diffuse albedo; the rest `r` is the Phong lobe.
    fn lambertian(&self, wo: DVec3) -> Rgb {
        if wo.z > 0.0 {
            self.diffuse
        } else {
            Rgb::BLACK
        }
    }

    fn is_black(&self) -> bool {
        Phong::is_black(self)
    }

    fn phong(&self) -> Option<&Phong> {
        Some(self)
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
