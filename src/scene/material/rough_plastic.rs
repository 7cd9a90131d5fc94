//! `roughplastic`: a diffuse base under a rough dielectric coating, Mitsuba
//! 3's model. The coating reflects as a microfacet surface with the
//! dielectric Fresnel term (Walter et al. 2007):
//!
//! `f_s = F(ω_i·m) D(m) G(ω_i, ω_o, m) / (4 cos θ_i cos θ_o)`;
//!
//! the base is seen through the coating's transmittance `T(μ)`, the share
//! of light arriving at cosine `μ` that the rough interface lets through
//! (single scattering):
//!
//! `f_d = ρ' / π · T(cos θ_i) T(cos θ_o) / η²`,
//!
//! with `ρ' = ρ/(1 − F_int)` (or `ρ/(1 − ρ F_int)` when `nonlinear`), `F_int`
//! the coating's diffuse reflectance from inside. `T` and `F_int` are
//! integrals over the visible microfacet normals, tabulated as Mitsuba does
//! (64 cosines, linear interpolation, `F_int` as the mean of `2 μ R(μ)`
//! over them) so values agree with it; the integrals themselves use a
//! Gauss–Legendre rule over this crate's normal samplers.
//!
//! Sampling picks the coating with probability `(1 − T(cos θ_o)) w /
//! ((1 − T) w + T (1 − w))`, `w` the specular over total mean reflectance,
//! and the base by the cosine otherwise.
//!
//! Parameters (Mitsuba 3's names): `distribution` (default `beckmann`)
//! and `alpha` (`optical_params::roughness`; one number, isotropic, as
//! Mitsuba's: the tables depend on it; default 0.1; below `MIN_ALPHA` the
//! coating is the smooth `plastic`'s); `diffuse_reflectance`,
//! `specular_reflectance`, `int_ior`, `ext_ior`, `nonlinear`: as
//! `plastic`'s.

use std::num::NonZeroUsize;
use std::sync::Arc;

use gauss_quad::legendre::GaussLegendre;
use glam::DVec3;

use super::plastic::{Plastic, coated_base};
use super::{
    Bsdf, BsdfFlags, LobeSample, Lookup, Model, Params, Parameters, Plugin, Roughness, ior, optical_params,
    reflect,
};
use crate::scene::error::SceneError;
use crate::scene::texture::{self, Texture};
use crate::color::Rgb;
use crate::optics::fresnel;
use crate::optics::microfacet::Microfacet;
use crate::optics::warp;

/// Cosines at which the coating's transmittance is tabulated (Mitsuba's
/// `MI_ROUGH_TRANSMITTANCE_RES`).
const TABLE: usize = 64;

/// A rough plastic; see the module docs.
#[derive(Clone, Debug, PartialEq)]
pub struct RoughPlastic {
    distribution: Microfacet,
    specular_reflectance: Rgb,
    eta: f64,
    /// `ρ'/π · 1/η²`: the base without its transmittance factors.
    diffuse: Rgb,
    /// `w` of the module docs.
    specular_weight: f64,
    /// `T(μ)` at `μ = k/(TABLE − 1)`, shared by the BSDFs a texture
    /// derives from one material ([`Self::retinted`]).
    transmittance: Arc<[f64; TABLE]>,
    /// The coating's diffuse reflectance seen from inside.
    internal: f64,
}

/// `E[g(m)]` over the normals `m` visible from `w` (density `G1(w, m)
/// max(0, w·m) D(m) / cos θ_w`), by an `n × n` Gauss–Legendre rule over the
/// unit square of the distribution's sampler, reweighted from the
/// sampler's density to the visible one.
fn visible_mean(distribution: &Microfacet, w: DVec3, n: usize, g: impl Fn(DVec3) -> f64) -> f64 {
    let rule = GaussLegendre::new(NonZeroUsize::new(n).expect("n > 0"));
    let nodes: Vec<(f64, f64)> = rule
        .iter()
        .map(|(x, weight)| (0.5 * (x + 1.0), 0.5 * weight))
        .collect();
    let mut sum = 0.0;
    for &(u, wu) in &nodes {
        for &(v, wv) in &nodes {
            let s = distribution.sample(w, [u, v]);
            if s.pdf <= 0.0 {
                continue;
            }
            let visible = distribution.g1(w, s.m) * w.dot(s.m).max(0.0) * distribution.d(s.m) / w.z;
            sum += wu * wv * g(s.m) * visible / s.pdf;
        }
    }
    sum
}

/// The direction at cosine `mu` in the xz plane.
fn at_cosine(mu: f64) -> DVec3 {
    let mu = mu.max(1e-6);
    DVec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu)
}

/// Share of light arriving at `w` that a rough interface of relative
/// index `eta` transmits (single scattering).
fn transmittance(distribution: &Microfacet, w: DVec3, eta: f64) -> f64 {
    let n = if eta > 1.0 { 32 } else { 128 };
    visible_mean(distribution, w, n, |m| {
        let f = fresnel::dielectric(w.dot(m), eta);
        if f.reflectance >= 1.0 {
            return 0.0;
        }
        // Refraction about m: the tangential part scales by 1/η', the
        // normal part is cos θ_t along m (signed opposite to w).
        let cos_i = w.dot(m);
        let t = (-w / f.eta + m * (cos_i / f.eta + f.cos_t)).normalize();
        if t.z * w.z >= 0.0 {
            return 0.0;
        }
        distribution.g1(-t, m) * (1.0 - f.reflectance)
    })
}

/// Share of light arriving at `w` that a rough interface reflects.
fn reflectance(distribution: &Microfacet, w: DVec3, eta: f64) -> f64 {
    let n = if eta > 1.0 { 32 } else { 128 };
    visible_mean(distribution, w, n, |m| {
        let r = reflect(w, m);
        if r.z <= 0.0 {
            return 0.0;
        }
        distribution.g1(r, m) * fresnel::dielectric(w.dot(m), eta).reflectance
    })
}

impl RoughPlastic {
    /// The plastic with relative index `eta = int_ior / ext_ior > 0`.
    pub fn new(
        distribution: Microfacet,
        diffuse_reflectance: Rgb,
        specular_reflectance: Rgb,
        eta: f64,
        nonlinear: bool,
    ) -> Self {
        let mus = (0..TABLE).map(|k| k as f64 / (TABLE - 1) as f64);
        let table: Vec<f64> = mus
            .clone()
            .map(|mu| transmittance(&distribution, at_cosine(mu), eta))
            .collect();
        let internal = 2.0
            * mus
                .map(|mu| {
                    let w = at_cosine(mu);
                    reflectance(&distribution, w, 1.0 / eta) * w.z
                })
                .sum::<f64>()
            / TABLE as f64;
        let transmittance = Arc::new(table.try_into().expect("TABLE entries"));
        Self::coated(
            distribution,
            transmittance,
            internal,
            diffuse_reflectance,
            specular_reflectance,
            eta,
            nonlinear,
        )
    }

    /// The same coating over other reflectances (a texture's values at a
    /// surface point), without integrating its tables again.
    pub fn retinted(
        &self,
        diffuse_reflectance: Rgb,
        specular_reflectance: Rgb,
        nonlinear: bool,
    ) -> Self {
        Self::coated(
            self.distribution,
            self.transmittance.clone(),
            self.internal,
            diffuse_reflectance,
            specular_reflectance,
            self.eta,
            nonlinear,
        )
    }

    fn coated(
        distribution: Microfacet,
        transmittance: Arc<[f64; TABLE]>,
        internal: f64,
        diffuse_reflectance: Rgb,
        specular_reflectance: Rgb,
        eta: f64,
        nonlinear: bool,
    ) -> Self {
        let (diffuse, specular_weight) = coated_base(
            diffuse_reflectance,
            specular_reflectance,
            eta,
            nonlinear,
            internal,
        );
        Self {
            distribution,
            specular_reflectance,
            eta,
            diffuse,
            specular_weight,
            transmittance,
            internal,
        }
    }

    /// `T(μ)` interpolated linearly in the table, as Mitsuba's `lerp_gather`.
    fn transmittance_at(&self, mu: f64) -> f64 {
        let x = mu.clamp(0.0, 1.0) * (TABLE - 1) as f64;
        let i = (x as usize).min(TABLE - 2);
        let t = x - i as f64;
        self.transmittance[i] * (1.0 - t) + self.transmittance[i + 1] * t
    }

    fn specular_probability(&self, wo: DVec3) -> f64 {
        let t = self.transmittance_at(wo.z);
        let (s, d) = (
            (1.0 - t) * self.specular_weight,
            t * (1.0 - self.specular_weight),
        );
        if s + d > 0.0 { s / (s + d) } else { 0.0 }
    }

    /// `f_s + f_d`, sr⁻¹; zero unless both are above the surface.
    pub fn eval(&self, wo: DVec3, wi: DVec3) -> Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::BLACK;
        }
        let m = (wi + wo).normalize();
        let d = self.distribution.d(m);
        let g = self.distribution.g(wi, wo, m);
        let f = fresnel::dielectric(wo.dot(m), self.eta).reflectance;
        let specular = self.specular_reflectance * (f * d * g / (4.0 * wi.z * wo.z));
        let base = self.transmittance_at(wi.z) * self.transmittance_at(wo.z);
        specular + self.diffuse * base
    }

    /// Density (sr⁻¹) with which [`Self::sample`] draws `wi`.
    pub fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let p = self.specular_probability(wo);
        let m = (wi + wo).normalize();
        let cos_om = wo.dot(m);
        let specular = if cos_om > 0.0 {
            self.distribution.pdf(wo, m) / (4.0 * cos_om)
        } else {
            0.0
        };
        p * specular + (1.0 - p) * warp::cosine_hemisphere_pdf(wi)
    }

    /// A reflection about a sampled microfacet normal (when `u_event`
    /// falls under the coating's probability) or a cosine-distributed
    /// direction from the base.
    pub fn sample(&self, wo: DVec3, u_event: f64, u: [f64; 2]) -> Option<LobeSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let wi = if u_event < self.specular_probability(wo) {
            reflect(wo, self.distribution.sample(wo, u).m)
        } else {
            warp::cosine_hemisphere(u)
        };
        if wi.z <= 0.0 {
            return None;
        }
        LobeSample::spread(wi, self.pdf(wo, wi), || self.eval(wo, wi))
    }

    /// `ρ(ω_o)` with `ρ/π` the base's largest value for this `ω_o` over
    /// `ω_i` (see `Bsdf::lambertian`), for `cos_o > 0`.
    pub fn lambertian(&self, cos_o: f64) -> Rgb {
        let t_max = self.transmittance.iter().copied().fold(0.0, f64::max);
        self.diffuse * (std::f64::consts::PI * self.transmittance_at(cos_o) * t_max)
    }
}

/// The parameters of a `roughplastic` material; see the module docs.
#[derive(Clone, Debug, PartialEq)]
pub struct RoughPlasticMaterial {
    /// The coating's roughness (isotropic, no texture).
    pub roughness: Roughness,
    /// The base's albedo `ρ`, in [0, 1].
    pub diffuse_reflectance: Texture,
    /// A factor on the coating's reflection, in [0, 1].
    pub specular_reflectance: Texture,
    /// The coating's index over the outside's, `int_ior / ext_ior`.
    pub eta: f64,
    /// Whether inner bounces darken and saturate the base's colour.
    pub nonlinear: bool,
}

impl Plugin for RoughPlasticMaterial {
    type Model = RoughPlastic;
}

impl RoughPlasticMaterial {
    /// The parameters of a material document, each validated once.
    pub(crate) fn parse(params: &mut Params) -> Result<Self, SceneError> {
        // Its tables depend on the roughness, so it is one number, as in
        // Mitsuba (whose roughplastic takes no texture for it either).
        for name in ["alpha", "alpha_u", "alpha_v"] {
            if params.peek(name).is_some_and(serde_json::Value::is_object) {
                return Err(params.invalid(name, "roughplastic takes a number, not a texture"));
            }
        }
        let roughness = optical_params::roughness(params)?;
        if roughness.alpha_u != roughness.alpha_v {
            return Err(SceneError::invalid(
                params.field("alpha_u"),
                "roughplastic is isotropic (as Mitsuba's): give one `alpha`",
            ));
        }
        Ok(Self {
            roughness,
            diffuse_reflectance: texture::albedo(params, "diffuse_reflectance", [0.5; 3])?,
            specular_reflectance: texture::albedo(params, "specular_reflectance", [1.0; 3])?,
            eta: optical_params::relative_ior(params, ior::POLYPROPYLENE)?,
            nonlinear: params.boolean("nonlinear", false)?,
        })
    }
}

impl Parameters for RoughPlasticMaterial {
    fn textures(&self) -> Vec<&Texture> {
        vec![&self.diffuse_reflectance, &self.specular_reflectance]
    }

    fn build(&self, lookup: Lookup, template: Option<&Bsdf>) -> Bsdf {
        let diffuse = lookup.rgb(&self.diffuse_reflectance);
        let specular = lookup.rgb(&self.specular_reflectance);
        let (eta, nonlinear) = (self.eta, self.nonlinear);
        match (self.roughness.microfacet(Lookup::Mean), template) {
            (Some(_), Some(Bsdf::RoughPlastic(t))) => {
                Bsdf::RoughPlastic(t.retinted(diffuse, specular, nonlinear))
            }
            (Some(distribution), _) => Bsdf::RoughPlastic(RoughPlastic::new(
                distribution,
                diffuse,
                specular,
                eta,
                nonlinear,
            )),
            (None, Some(Bsdf::Plastic(t))) => Bsdf::Plastic(t.retinted(diffuse, specular, nonlinear)),
            (None, _) => Bsdf::Plastic(Plastic::new(diffuse, specular, eta, nonlinear)),
        }
    }
}

impl Model for RoughPlastic {
    fn eval(&self, wo: DVec3, wi: DVec3) -> Rgb {
        RoughPlastic::eval(self, wo, wi)
    }

    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        RoughPlastic::pdf(self, wo, wi)
    }

    fn sample(&self, wo: DVec3, u_lobe: f64, u: [f64; 2]) -> Option<LobeSample> {
        RoughPlastic::sample(self, wo, u_lobe, u)
    }

    fn flags(&self) -> BsdfFlags {
        BsdfFlags {
            diffuse: true,
            glossy: true,
            ..BsdfFlags::default()
        }
    }

    /// As the smooth plastic's, with the rough coating's transmittance
    /// `T(θ_o) max T`; `r` is the coating's lobe plus the base's loss
    /// towards grazing.
    fn lambertian(&self, wo: DVec3) -> Rgb {
        if wo.z > 0.0 {
            RoughPlastic::lambertian(self, wo.z)
        } else {
            Rgb::BLACK
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optics::microfacet::MicrofacetKind;

    #[test]
    fn the_coating_transmits_what_it_does_not_reflect_when_smooth_enough() {
        // For a nearly smooth coating, T(μ) ≈ 1 − F(μ) and the internal
        // reflectance approaches the smooth plastic's F_dr.
        let distribution = Microfacet::new(MicrofacetKind::Ggx, 0.01, 0.01).unwrap();
        let plastic = RoughPlastic::new(
            distribution,
            Rgb::new(0.5, 0.5, 0.5),
            Rgb::WHITE,
            1.5,
            false,
        );
        for mu in [0.2, 0.5, 0.9] {
            let smooth = 1.0 - fresnel::dielectric(mu, 1.5).reflectance;
            let t = plastic.transmittance_at(mu);
            assert!((t - smooth).abs() < 5e-3, "T({mu}) = {t} vs {smooth}");
        }
    }

    /// Mitsuba 3.9.1's `roughplastic` (`int_ior` 1.5, `ext_ior` 1,
    /// `diffuse_reflectance` (0.2, 0.5, 0.8)), its `eval` over `cos θ_i`,
    /// at three direction pairs (`θ`, `φ` in radians), printed by a few
    /// lines of its Python API.
    #[test]
    fn values_agree_with_mitsuba() {
        let d = |t: f64, p: f64| DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
        let pi = std::f64::consts::PI;
        let pairs = [
            (d(0.3, 0.0), d(0.5, 2.9)),
            (d(1.2, 0.4), d(1.0, -2.6)),
            (d(0.7, 1.0), d(0.75, 1.0 + pi)),
        ];
        let cases = [
            (
                MicrofacetKind::Beckmann,
                0.2,
                [
                    [0.131269, 0.220204, 0.309138],
                    [0.590625, 0.665565, 0.740506],
                    [0.222582, 0.310015, 0.397448],
                ],
            ),
            (
                MicrofacetKind::Ggx,
                0.3,
                [
                    [0.076940, 0.142221, 0.207502],
                    [0.275612, 0.330408, 0.385204],
                    [0.112785, 0.175966, 0.239147],
                ],
            ),
        ];
        for (kind, alpha, expected) in cases {
            let distribution = Microfacet::new(kind, alpha, alpha).unwrap();
            let plastic = RoughPlastic::new(
                distribution,
                Rgb::new(0.2, 0.5, 0.8),
                Rgb::WHITE,
                1.5,
                false,
            );
            for ((wo, wi), theirs) in pairs.iter().zip(expected) {
                let ours = plastic.eval(*wo, *wi).to_array();
                for c in 0..3 {
                    // Beckmann's G1 is a rational fit in Mitsuba (0.4 %).
                    let tolerance = 5e-3 * theirs[c];
                    assert!(
                        (ours[c] - theirs[c]).abs() < tolerance,
                        "{kind:?} {wo} {wi}: {ours:?} vs {theirs:?}"
                    );
                }
            }
        }
    }
}
