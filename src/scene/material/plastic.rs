//! `plastic`: a diffuse base under a smooth dielectric coating (Mitsuba
//! 3's smooth plastic). Light either reflects off the coating, a Dirac delta
//! in the mirror direction weighted by the Fresnel reflectance `F(θ_o)`, or
//! enters, scatters in the base any number of times (the coating sending
//! back a fraction `F_dr` of what tries to leave) and leaves:
//!
//! `f_d(ω_o, ω_i) = ρ' / π · (1 − F(θ_i)) (1 − F(θ_o)) / η²`,
//!
//! with `ρ' = ρ / (1 − F_dr)` (the base's colour kept, the default) or
//! `ρ / (1 − ρ F_dr)` (`nonlinear`: the inner bounces darken and saturate
//! it, as varnish does), `F_dr` the coating's diffuse reflectance from
//! inside, `2 ∫ F(μ, 1/η) μ dμ` (Weidlich & Wilkie 2007; Mitsuba fits it by
//! a polynomial, this integrates it). Sampling picks the coating with
//! probability `F w / (F w + (1 − F)(1 − w))`, `w` the specular over total
//! mean reflectance, and the base by the cosine otherwise.
//!
//! Parameters (Mitsuba 3's names): `diffuse_reflectance` (default 0.5),
//! `specular_reflectance` (default 1), both in [0, 1], colours or
//! textures; `int_ior` (default polypropylene, 1.49) and `ext_ior`
//! (default air), numbers or named media ([`super::ior`]); `nonlinear`
//! (default false: whether inner bounces darken and saturate the base's
//! colour).

use std::f64::consts::FRAC_1_PI;
use std::num::NonZeroUsize;

use glam::DVec3;

use super::{Bsdf, BsdfFlags, LobeSample, Lookup, Model, Params, Parameters, Plugin, ior, optical_params};
use gauss_quad::legendre::GaussLegendre;

use crate::color::Rgb;
use crate::optics::fresnel;
use crate::optics::warp;
use crate::scene::error::SceneError;
use crate::scene::texture::{self, Texture};

/// A smooth plastic; see the module docs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plastic {
    diffuse_reflectance: Rgb,
    specular_reflectance: Rgb,
    eta: f64,
    /// `ρ'/π · 1/η²`: the diffuse lobe without its Fresnel factors.
    diffuse: Rgb,
    /// `w` of the module docs.
    specular_weight: f64,
    /// The coating's diffuse Fresnel reflectance seen from inside (an
    /// integral computed once per material, reused by [`Self::retinted`]).
    internal: f64,
}

/// `2 ∫₀¹ F(μ, η) μ dμ`: the Fresnel reflectance of an interface of
/// relative index `eta` averaged over cosine-distributed directions.
pub fn diffuse_fresnel_reflectance(eta: f64) -> f64 {
    let rule = GaussLegendre::new(NonZeroUsize::new(64).expect("64 is non-zero"));
    let f = |mu: f64| 2.0 * mu * fresnel::dielectric(mu, eta).reflectance;
    if eta >= 1.0 {
        return rule.integrate(0.0, 1.0, f);
    }
    // Below the critical cosine every direction is reflected. Above it the
    // transmitted cosine grows as √(μ − μ_c), which μ = μ_c + (1 − μ_c) t²
    // makes smooth in t for the rule.
    let critical = (1.0 - eta * eta).sqrt();
    let span = 1.0 - critical;
    let smooth = rule.integrate(0.0, 1.0, |t: f64| {
        f(critical + span * t * t) * 2.0 * span * t
    });
    critical * critical + smooth
}

/// What a coated base needs of its reflectances, for smooth and rough
/// coatings alike: the base's lobe without its coating factors, `ρ'/π ·
/// 1/η²` with `ρ' = ρ/(1 − ρ_i)` (the inner bounces: `ρ_i` is `internal`,
/// the coating's diffuse reflectance from inside, times `ρ` if
/// `nonlinear`), and the weight `w` of the module docs.
pub(super) fn coated_base(
    diffuse_reflectance: Rgb,
    specular_reflectance: Rgb,
    eta: f64,
    nonlinear: bool,
    internal: f64,
) -> (Rgb, f64) {
    let kept = diffuse_reflectance.map(|rho| {
        let lost = if nonlinear { rho * internal } else { internal };
        rho / (1.0 - lost)
    });
    let mean = |c: Rgb| (c.r + c.g + c.b) / 3.0;
    let (d, s) = (mean(diffuse_reflectance), mean(specular_reflectance));
    let weight = if d + s > 0.0 { s / (d + s) } else { 0.0 };
    (kept * (FRAC_1_PI / (eta * eta)), weight)
}

impl Plastic {
    /// The plastic with relative index `eta = int_ior / ext_ior > 0`.
    pub fn new(
        diffuse_reflectance: Rgb,
        specular_reflectance: Rgb,
        eta: f64,
        nonlinear: bool,
    ) -> Self {
        let internal = diffuse_fresnel_reflectance(1.0 / eta);
        Self::coated(
            diffuse_reflectance,
            specular_reflectance,
            eta,
            nonlinear,
            internal,
        )
    }

    /// The same coating over other reflectances (a texture's values at a
    /// surface point), without integrating the Fresnel term again.
    pub fn retinted(
        &self,
        diffuse_reflectance: Rgb,
        specular_reflectance: Rgb,
        nonlinear: bool,
    ) -> Self {
        Self::coated(
            diffuse_reflectance,
            specular_reflectance,
            self.eta,
            nonlinear,
            self.internal,
        )
    }

    fn coated(
        diffuse_reflectance: Rgb,
        specular_reflectance: Rgb,
        eta: f64,
        nonlinear: bool,
        internal: f64,
    ) -> Self {
        let (diffuse, specular_weight) = coated_base(
            diffuse_reflectance,
            specular_reflectance,
            eta,
            nonlinear,
            internal,
        );
        Self {
            diffuse_reflectance,
            specular_reflectance,
            eta,
            diffuse,
            specular_weight,
            internal,
        }
    }

    fn fresnel(&self, cos: f64) -> f64 {
        fresnel::dielectric(cos, self.eta).reflectance
    }

    /// Probability of sampling the coating for a view with Fresnel `f`.
    fn specular_probability(&self, f: f64) -> f64 {
        let (s, d) = (
            f * self.specular_weight,
            (1.0 - f) * (1.0 - self.specular_weight),
        );
        if s + d > 0.0 { s / (s + d) } else { 0.0 }
    }

    /// The diffuse lobe `f_d(ω_o, ω_i)`, sr⁻¹ (the coating's delta is
    /// reached by [`Self::sample`] only); zero unless both are above.
    pub fn eval(&self, wo: DVec3, wi: DVec3) -> Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::BLACK;
        }
        self.diffuse * ((1.0 - self.fresnel(wo.z)) * (1.0 - self.fresnel(wi.z)))
    }

    /// Density with which [`Self::sample`] draws `wi` from the base.
    pub fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        (1.0 - self.specular_probability(self.fresnel(wo.z))) * warp::cosine_hemisphere_pdf(wi)
    }

    /// The coating's mirror direction (when `u_event` falls under its
    /// probability) or a cosine-distributed direction from the base.
    pub fn sample(&self, wo: DVec3, u_event: f64, u: [f64; 2]) -> Option<LobeSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let f = self.fresnel(wo.z);
        let p = self.specular_probability(f);
        if u_event < p {
            let wi = DVec3::new(-wo.x, -wo.y, wo.z);
            return Some(LobeSample {
                wi,
                value: self.specular_reflectance * (f / wi.z),
                pdf: p,
                delta: true,
            });
        }
        let wi = warp::cosine_hemisphere(u);
        LobeSample::spread(wi, self.pdf(wo, wi), || self.eval(wo, wi))
    }

    /// `ρ(ω_o)` with `ρ/π = f_d(ω_o, ω_i)` at normal `ω_i`, the base's
    /// largest value for a given `ω_o` (`F` grows towards grazing), for an
    /// `ω_o` at `cos_o > 0` (see `Bsdf::lambertian`).
    pub fn lambertian(&self, cos_o: f64) -> Rgb {
        self.diffuse
            * (std::f64::consts::PI * (1.0 - self.fresnel(cos_o)) * (1.0 - self.fresnel(1.0)))
    }

    pub fn diffuse_reflectance(&self) -> Rgb {
        self.diffuse_reflectance
    }
}

/// The parameters of a `plastic` material; see the module docs.
#[derive(Clone, Debug, PartialEq)]
pub struct PlasticMaterial {
    /// The base's albedo `ρ`, in [0, 1].
    pub diffuse_reflectance: Texture,
    /// A factor on the coating's reflection, in [0, 1].
    pub specular_reflectance: Texture,
    /// The coating's index over the outside's, `int_ior / ext_ior`.
    pub eta: f64,
    /// Whether inner bounces darken and saturate the base's colour.
    pub nonlinear: bool,
}

impl Plugin for PlasticMaterial {
    type Model = Plastic;
}

impl PlasticMaterial {
    /// The parameters of a material document, each validated once.
    pub(crate) fn parse(params: &mut Params) -> Result<Self, SceneError> {
        Ok(Self {
            diffuse_reflectance: texture::albedo(params, "diffuse_reflectance", [0.5; 3])?,
            specular_reflectance: texture::albedo(params, "specular_reflectance", [1.0; 3])?,
            eta: optical_params::relative_ior(params, ior::POLYPROPYLENE)?,
            nonlinear: params.boolean("nonlinear", false)?,
        })
    }
}

impl Parameters for PlasticMaterial {
    fn textures(&self) -> Vec<&Texture> {
        vec![&self.diffuse_reflectance, &self.specular_reflectance]
    }

    fn build(&self, lookup: Lookup, template: Option<&Bsdf>) -> Bsdf {
        let diffuse = lookup.rgb(&self.diffuse_reflectance);
        let specular = lookup.rgb(&self.specular_reflectance);
        match template {
            Some(Bsdf::Plastic(t)) => Bsdf::Plastic(t.retinted(diffuse, specular, self.nonlinear)),
            _ => Bsdf::Plastic(Plastic::new(diffuse, specular, self.eta, self.nonlinear)),
        }
    }
}

impl Model for Plastic {
    fn eval(&self, wo: DVec3, wi: DVec3) -> Rgb {
        Plastic::eval(self, wo, wi)
    }

    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        Plastic::pdf(self, wo, wi)
    }

    fn sample(&self, wo: DVec3, u_lobe: f64, u: [f64; 2]) -> Option<LobeSample> {
        Plastic::sample(self, wo, u_lobe, u)
    }

    fn flags(&self) -> BsdfFlags {
        BsdfFlags {
            diffuse: true,
            delta: true,
            ..BsdfFlags::default()
        }
    }

    /// `(1 − F(θ_o))(1 − F(0)) ρ'/η²` (the base with the coating's
    /// transmission at normal incidence, its largest): `r = −(1 − F(θ_o))
    /// (F(θ_i) − F(0)) ρ'/(π η²) ≤ 0` is small except at grazing `θ_i`.
    fn lambertian(&self, wo: DVec3) -> Rgb {
        if wo.z > 0.0 {
            Plastic::lambertian(self, wo.z)
        } else {
            Rgb::BLACK
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn blue() -> [Plastic; 2] {
        let rho = Rgb::new(0.2, 0.5, 0.8);
        [false, true].map(|nonlinear| Plastic::new(rho, Rgb::WHITE, 1.5, nonlinear))
    }

    #[test]
    fn the_inner_diffuse_reflectance_follows_from_the_outer_one() {
        // Light from a diffuse inside source: what the outside reflects of
        // diffuse light, 1 − (1 − F_dr(η))/η² (Stokes and étendue).
        let (outer, inner) = (
            diffuse_fresnel_reflectance(1.5),
            diffuse_fresnel_reflectance(1.0 / 1.5),
        );
        assert!(
            (inner - (1.0 - (1.0 - outer) / 2.25)).abs() < 1e-9,
            "{outer} {inner}"
        );
        // Mitsuba's polynomial fits give 0.0917743 and 0.596811.
        assert!((outer - 0.091_774_3).abs() < 5e-4 && (inner - 0.596_811).abs() < 1e-3);
    }

    #[test]
    fn agrees_with_mitsuba() {
        // Mitsuba 3.9.1's `plastic` (diffuse (0.2, 0.5, 0.8), int_ior 1.5):
        // f without the cosine and pdf from ω_o = (0.6, 0, 0.8) towards
        // (−0.3, 0.2, 0.932738), then from the normal towards (0.8, 0, 0.6).
        let cases = [
            (
                false,
                [0.064_389_35, 0.160_973_4, 0.257_557_4],
                [0.063_022_04, 0.157_555_1, 0.252_088_2],
            ),
            (
                true,
                [0.029_479_86, 0.092_507_40, 0.198_725_6],
                [0.028_853_85, 0.090_543_01, 0.194_505_7],
            ),
        ];
        let pairs = [
            (
                DVec3::new(0.6, 0.0, 0.8),
                DVec3::new(-0.3, 0.2, 0.87f64.sqrt()),
            ),
            (DVec3::Z, DVec3::new(0.8, 0.0, 0.6)),
        ];
        for (plastic, (nonlinear, first, second)) in blue().iter().zip(cases) {
            for ((wo, wi), theirs) in pairs.iter().zip([first, second]) {
                let ours = plastic.eval(*wo, *wi).to_array();
                for c in 0..3 {
                    // Mitsuba's fitted F_dr is within 0.1 % of the integral.
                    assert!(
                        (ours[c] - theirs[c]).abs() < 3e-3 * theirs[c],
                        "nonlinear {nonlinear}: {ours:?} vs {theirs:?}"
                    );
                }
            }
            let (wo, wi) = pairs[0];
            assert!((plastic.pdf(wo, wi) - 0.271_931).abs() < 1e-5);
            assert!((plastic.pdf(pairs[1].0, pairs[1].1) - 0.176_294_7).abs() < 1e-5);
            // The coating: probability 0.0840980, throughput 0.521947.
            let s = plastic.sample(wo, 0.0, [0.5, 0.5]).unwrap();
            assert!(s.delta && (s.pdf - 0.084_098).abs() < 1e-5);
            assert!((s.value.g * s.wi.z / s.pdf - 0.521_947).abs() < 1e-5);
        }
    }

    #[test]
    fn energy_is_at_most_one() {
        // Coating plus base, by the midpoint rule over the hemisphere.
        let white = Plastic::new(Rgb::WHITE, Rgb::WHITE, 1.5, false);
        for wo in [DVec3::Z, DVec3::new(0.8, 0.0, 0.6)] {
            let n = 400;
            let mut base = 0.0;
            for i in 0..n {
                let mu = (i as f64 + 0.5) / n as f64;
                let s = (1.0 - mu * mu).sqrt();
                for j in 0..n {
                    let phi = (j as f64 + 0.5) / n as f64 * std::f64::consts::TAU;
                    let wi = DVec3::new(s * phi.cos(), s * phi.sin(), mu);
                    base += white.eval(wo, wi).g * mu / (n * n) as f64 * std::f64::consts::TAU;
                }
            }
            let albedo = base + fresnel::dielectric(wo.z, 1.5).reflectance;
            assert!(albedo <= 1.0 + 1e-9 && albedo > 0.95, "{wo}: {albedo}");
        }
    }
}
