//! `principled`: Mitsuba 3's Disney-style BSDF (Burley 2012, 2015), the
//! material of Blender's and other tools' exports: a diffuse base with
//! retro-reflection, a fake subsurface (`flatness`) and sheen, a GGX
//! specular lobe whose Fresnel mixes a dielectric's, a metal's (tinted by
//! the base colour) and a tinted Schlick term, a rough transmission lobe
//! (`spec_trans`), and a GTR1 clearcoat (docs/math.md §18.6).
//!
//! Mitsuba's value for light from `ω_i` seen from `ω_o` (θ from the
//! normal, `h` the half vector turned outwards, `F` the dielectric Fresnel
//! at `ω_o·h`, `S(c) = (1 − c)⁵`, `brdf = (1 − metallic)(1 − spec_trans)`,
//! `bsdf = (1 − metallic) spec_trans`), each term only where it applies
//! (reflection on the front side, transmission through the surface):
//!
//! - specular: `F_p D G / (4 |cos θ_o| |cos θ_i|)`, with
//!   `F_p = (1 − metallic)(1 − spec_tint) F + metallic Schlick(base, ω_o·h)
//!   + (1 − metallic) spec_tint Schlick(tint R₀(η), ω_o·h)` on the front
//!   side and `bsdf · F` from inside;
//! - transmission: `√base · bsdf (1 − F) D G η² |ω_o·h| |ω_i·h| /
//!   (|cos θ_o| |cos θ_i| (ω_o·h + η ω_i·h)²)`, times `1/η²` in the
//!   radiance convention (`η` the path's relative index);
//! - clearcoat: `clearcoat/4 · Schlick(0.04, ω_o·h) D₁(h) G₁(ω_o) G₁(ω_i)`
//!   with GTR1 of α = lerp(0.1, 0.001, clearcoat_gloss) and Smith GGX of
//!   α = 0.25 (no `1/(4 cos cos)`, as Mitsuba has it);
//! - diffuse: `brdf · base/π · lerp((1 − S_o/2)(1 − S_i/2) + R (S_o + S_i +
//!   S_o S_i (R − 1)), f_ss, flatness)`, `R = 2 roughness (ω_i·h)²`, `f_ss`
//!   Hanrahan–Krueger's flattened form; sheen `sheen (1 − metallic)
//!   S(ω_i·h) lerp(1, base/lum, sheen_tint) / |cos θ_i|`.
//!
//! Sampling picks the diffuse, clearcoat, transmission or specular lobe
//! with Mitsuba's weights (`brdf`, `clearcoat/4`, `bsdf (1 − F)`,
//! `1 − bsdf (1 − F)`, each times its sampling rate) and draws cosine
//! directions, GTR1 normals or GGX visible normals. Mitsuba takes `F` in
//! those weights at the normal it draws, so its density is not the one it
//! reports where `spec_trans > 0`; here `F` is taken at `ω_o`'s angle to
//! the surface normal, so the reported density is exact (same lobes, same
//! value; only the variance differs).
//!
//! The Lambertian part the cache serves (§18.3) is `brdf (1 − flatness)
//! base (1 − S_o/2)(41/42)`: the diffuse term with its `ω_i` factor at its
//! cosine-weighted mean; the rest (retro-reflection, sheen, lobes) is
//! sampled.
//!
//! Parameters (Mitsuba's names and defaults): `base_color` (0.5, a colour
//! or texture in [0, 1]); `roughness` (0.5), `metallic`, `spec_trans`,
//! `spec_tint`, `sheen`, `sheen_tint`, `flatness`, `clearcoat`,
//! `clearcoat_gloss`, `anisotropic` (0): numbers or textures in [0, 1];
//! `specular` (0.5, giving `η = 2/(1 − √(0.08 specular)) − 1`) or `eta`,
//! not both; `main_specular_sampling_rate`, `clearcoat_sampling_rate`,
//! `diffuse_reflectance_sampling_rate` (1, ≥ 0).

use std::f64::consts::{FRAC_1_PI, PI};

use glam::DVec3;

use super::{Bsdf, BsdfFlags, LobeSample, Lookup, Model, Params, Parameters, Plugin, reflect};
use crate::color::{Rgb, luminance};
use crate::optics::fresnel;
use crate::optics::microfacet::{Microfacet, MicrofacetKind};
use crate::optics::warp;
use crate::scene::error::SceneError;
use crate::scene::texture::{self, Texture};

/// The scalar parameters, in the order of [`PrincipledMaterial::weights`].
const WEIGHTS: [(&str, f64); 10] = [
    ("roughness", 0.5),
    ("metallic", 0.0),
    ("spec_trans", 0.0),
    ("spec_tint", 0.0),
    ("sheen", 0.0),
    ("sheen_tint", 0.0),
    ("flatness", 0.0),
    ("clearcoat", 0.0),
    ("clearcoat_gloss", 0.0),
    ("anisotropic", 0.0),
];

/// The parameters of a `principled` material; see the module docs.
#[derive(Clone, Debug, PartialEq)]
pub struct PrincipledMaterial {
    pub base_color: Texture,
    /// The textures of [`WEIGHTS`], in its order (scalar lookups).
    pub weights: Vec<Texture>,
    /// The specular lobe's relative index of refraction.
    pub eta: f64,
    /// Sampling rates of the specular, clearcoat and diffuse lobes.
    pub rates: [f64; 3],
}

impl Plugin for PrincipledMaterial {
    type Model = Principled;
}

impl PrincipledMaterial {
    /// The parameters of a material document, each validated once.
    pub(crate) fn parse(params: &mut Params) -> Result<Self, SceneError> {
        let base_color = texture::albedo(params, "base_color", [0.5; 3])?;
        // Mitsuba nudges the index off 1 where light may pass (`spec_trans`
        // given and not a zero number), so that refraction stays defined.
        let transmits = params
            .peek("spec_trans")
            .is_some_and(|v| v.as_f64() != Some(0.0));
        let weights = weights(params, &WEIGHTS)?;
        let eta = match (params.number("eta")?, params.number("specular")?) {
            (Some(_), Some(_)) => {
                return Err(params.invalid("specular", "give `eta` or `specular`, not both"));
            }
            (Some(eta), None) if eta.is_finite() && eta > 0.0 => {
                if transmits && eta == 1.0 { 1.001 } else { eta }
            }
            (Some(eta), None) => {
                return Err(params.invalid("eta", format!("{eta} is not a positive index")));
            }
            (None, specular) => {
                let s = specular.unwrap_or(0.5);
                if !(0.0..12.5).contains(&s) {
                    return Err(params.invalid("specular", format!("{s} is not in [0, 12.5)")));
                }
                let s = if transmits && s == 0.0 { 1e-3 } else { s };
                2.0 / (1.0 - (0.08 * s).sqrt()) - 1.0
            }
        };
        let rates = rates(
            params,
            [
                "main_specular_sampling_rate",
                "clearcoat_sampling_rate",
                "diffuse_reflectance_sampling_rate",
            ],
        )?;
        Ok(Self {
            base_color,
            weights,
            eta,
            rates,
        })
    }
}

impl Parameters for PrincipledMaterial {
    fn textures(&self) -> Vec<&Texture> {
        std::iter::once(&self.base_color).chain(&self.weights).collect()
    }

    fn may_be_a_side(&self) -> bool {
        self.weights[2].constant() == Some([0.0; 3])
    }

    fn build(&self, lookup: Lookup, _: Option<&Bsdf>) -> Bsdf {
        let w: Vec<f64> = self.weights.iter().map(|t| lookup.scalar(t)).collect();
        let [roughness, metallic, spec_trans, spec_tint, sheen, sheen_tint, flatness, clearcoat, clearcoat_gloss, anisotropic] =
            <[f64; 10]>::try_from(w).expect("ten weights");
        let specular = ggx(roughness, anisotropic);
        Bsdf::Principled(Principled {
            base_color: lookup.rgb(&self.base_color),
            roughness,
            metallic,
            spec_trans,
            spec_tint,
            sheen,
            sheen_tint,
            flatness,
            clearcoat,
            clearcoat_alpha: 0.1 + (0.001 - 0.1) * clearcoat_gloss,
            specular,
            eta: self.eta,
            rates: self.rates,
        })
    }
}

/// The principled model with its parameters valued; see the module docs.
#[derive(Clone, Debug, PartialEq)]
pub struct Principled {
    pub base_color: Rgb,
    pub roughness: f64,
    pub metallic: f64,
    pub spec_trans: f64,
    pub spec_tint: f64,
    pub sheen: f64,
    pub sheen_tint: f64,
    pub flatness: f64,
    pub clearcoat: f64,
    /// GTR1's α of the clearcoat.
    pub clearcoat_alpha: f64,
    /// The specular and transmission lobes' GGX distribution.
    pub specular: Microfacet,
    pub eta: f64,
    pub rates: [f64; 3],
}

/// The textures of scalar parameters in [0, 1] (`(name, default)`), in order.
pub(super) fn weights(params: &mut Params, names: &[(&str, f64)]) -> Result<Vec<Texture>, SceneError> {
    names
        .iter()
        .map(|&(name, default)| texture::albedo(params, name, [default; 3]))
        .collect()
}

/// Lobe sampling rates named `names` (default 1, finite and ≥ 0).
pub(super) fn rates<const N: usize>(params: &mut Params, names: [&str; N]) -> Result<[f64; N], SceneError> {
    let mut rates = [1.0; N];
    for (rate, name) in rates.iter_mut().zip(names) {
        if let Some(r) = params.number(name)? {
            if !(r.is_finite() && r >= 0.0) {
                return Err(params.invalid(name, format!("{r} is not a finite rate ≥ 0")));
            }
            *rate = r;
        }
    }
    Ok(rates)
}

/// GGX of a principled roughness and anisotropy (Mitsuba's
/// `calc_dist_params`): `α = max(0.001, r²/a)` and `max(0.001, r² a)`,
/// `a = √(1 − 0.9 anisotropic)`.
pub(super) fn ggx(roughness: f64, anisotropic: f64) -> Microfacet {
    let aspect = (1.0 - 0.9 * anisotropic).sqrt();
    let r2 = roughness * roughness;
    Microfacet::new(MicrofacetKind::Ggx, (r2 / aspect).max(0.001), (r2 * aspect).max(0.001))
        .expect("roughness at least 0.001")
}

/// The base colour over its luminance (white for black), the tint of the
/// specular and sheen lobes.
pub(super) fn tint(base: Rgb) -> Rgb {
    let lum = luminance(base.to_array());
    if lum > 0.0 { base * (1.0 / lum) } else { Rgb::WHITE }
}

/// The Disney diffuse lobe (Burley 2012) per unit base colour and weight,
/// cosine included: `lerp((1 − S_o/2)(1 − S_i/2) + R(S_o + S_i + S_o S_i
/// (R − 1)), f_ss, flatness) |cos θ_i| / π` for light from `wi` reflected
/// to `wo` about the half vector `h` (module docs).
pub(super) fn disney_diffuse(roughness: f64, flatness: f64, wo: DVec3, wi: DVec3, h: DVec3) -> f64 {
    let (so, si) = (schlick_weight(wi.z.abs()), schlick_weight(wo.z.abs()));
    let f_diff = (1.0 - 0.5 * si) * (1.0 - 0.5 * so);
    let cos_d = h.dot(wi);
    let rr = 2.0 * roughness * cos_d * cos_d;
    let f_retro = rr * (so + si + so * si * (rr - 1.0));
    let lobe = if flatness > 0.0 {
        // Hanrahan–Krueger's flattened form.
        let fss90 = rr / 2.0;
        let fss = (1.0 + (fss90 - 1.0) * so) * (1.0 + (fss90 - 1.0) * si);
        let f_ss = 1.25 * (fss * (1.0 / (wi.z.abs() + wo.z.abs()) - 0.5) + 0.5);
        f_diff + f_retro + (f_ss - f_diff - f_retro) * flatness
    } else {
        f_diff + f_retro
    };
    wi.z.abs() * FRAC_1_PI * lobe
}

/// The sheen, cosine included: `sheen S(ω_i·h) lerp(1, tint, sheen_tint)
/// |cos θ_i|`.
pub(super) fn sheen(base: Rgb, sheen: f64, sheen_tint: f64, wi: DVec3, h: DVec3) -> Rgb {
    if sheen <= 0.0 {
        return Rgb::BLACK;
    }
    let c = Rgb::WHITE + (tint(base) - Rgb::WHITE) * sheen_tint;
    c * (sheen * schlick_weight(h.dot(wi).abs()) * wi.z.abs())
}

/// The Lambertian part the cache serves of a Disney diffuse lobe of
/// `weight` seen from `wo`: its cosine-weighted mean over `ω_i` (module
/// docs).
pub(super) fn diffuse_mean(base: Rgb, weight: f64, flatness: f64, wo: DVec3) -> Rgb {
    base * (weight * (1.0 - flatness) * (1.0 - 0.5 * schlick_weight(wo.z.abs())) * (41.0 / 42.0))
}

/// `(1 − c)⁵`, the Schlick weight, `c` clipped to [0, 1].
pub(super) fn schlick_weight(c: f64) -> f64 {
    (1.0 - c).clamp(0.0, 1.0).powi(5)
}

/// Mitsuba's `calc_schlick`: Schlick's Fresnel from `r0` at `cos_i`
/// (signed, positive outside), taken at the transmitted angle when light
/// leaves the denser side.
pub(super) fn schlick(r0: Rgb, cos_i: f64, eta: f64) -> Rgb {
    let eta_it = if cos_i >= 0.0 { eta } else { 1.0 / eta };
    let c = if eta_it > 1.0 {
        cos_i.abs()
    } else {
        let eta_ti = 1.0 / eta_it;
        (1.0 - (1.0 - cos_i * cos_i) * eta_ti * eta_ti).max(0.0).sqrt()
    };
    let w = schlick_weight(c);
    r0 + (Rgb::WHITE - r0) * w
}

/// Smith's masking for GGX of α seen from `v` on either side, zero where
/// `v` sees the back of `m` (Mitsuba's `smith_g1` and `smith_ggx1`).
pub(super) fn smith_g1(alpha: (f64, f64), v: DVec3, m: DVec3) -> f64 {
    if v.dot(m) * v.z <= 0.0 {
        return 0.0;
    }
    let xy = (alpha.0 * v.x).powi(2) + (alpha.1 * v.y).powi(2);
    if xy == 0.0 {
        return 1.0;
    }
    2.0 / (1.0 + (1.0 + xy / (v.z * v.z)).sqrt())
}

/// GTR1 (Burley 2012), the clearcoat's distribution of normals.
fn gtr1(alpha: f64, m: DVec3) -> f64 {
    let a2 = alpha * alpha;
    let d = (a2 - 1.0) / (PI * a2.ln() * (1.0 + (a2 - 1.0) * m.z * m.z));
    if d * m.z > 1e-20 { d } else { 0.0 }
}

/// A GTR1 normal drawn with density `D(m) cos θ_m`.
fn sample_gtr1(alpha: f64, u: [f64; 2]) -> DVec3 {
    let a2 = alpha * alpha;
    let cos2 = (1.0 - a2.powf(1.0 - u[1])) / (1.0 - a2);
    let (sin_phi, cos_phi) = (2.0 * PI * u[0]).sin_cos();
    let sin_theta = (1.0 - cos2).max(0.0).sqrt();
    DVec3::new(cos_phi * sin_theta, sin_phi * sin_theta, cos2.max(0.0).sqrt())
}

/// Whether `m` faces both directions as reflection (or, `!reflection`,
/// refraction) about it needs, `wo` on its front (Mitsuba's
/// `mac_mic_compatibility`).
pub(super) fn compatible(m: DVec3, wo: DVec3, wi: DVec3, reflection: bool) -> bool {
    let m = if wo.z >= 0.0 { m } else { -m };
    wo.dot(m) > 0.0 && if reflection { wi.dot(m) > 0.0 } else { wi.dot(m) < 0.0 }
}

/// The lobe `u` in [0, 1) picks among lobes of selection `weights` (any
/// scale; `None` when all are zero).
pub(super) fn pick_lobe<const N: usize>(weights: [f64; N], u: f64) -> Option<usize> {
    let mut sum = 0.0;
    normalised(weights).iter().position(|x| {
        sum += x;
        u < sum
    })
}

/// `weights` over their sum (zeros when they sum to zero).
pub(super) fn normalised<const N: usize>(weights: [f64; N]) -> [f64; N] {
    let total: f64 = weights.iter().sum();
    if total > 0.0 { weights.map(|x| x / total) } else { [0.0; N] }
}

impl Principled {
    fn lobe_weights(&self) -> (f64, f64) {
        let keep = 1.0 - self.metallic;
        (keep * (1.0 - self.spec_trans), keep * self.spec_trans)
    }

    /// The lobes' selection weights seen from `wo` (diffuse, clearcoat,
    /// transmission, specular), with the Fresnel reflectance at `wo`'s
    /// angle to the normal (module docs).
    fn selection(&self, wo: DVec3) -> [f64; 4] {
        let (brdf, bsdf) = self.lobe_weights();
        let f = fresnel::dielectric(wo.z, self.eta).reflectance;
        let [spec_rate, cc_rate, diff_rate] = self.rates;
        if wo.z > 0.0 {
            [
                brdf * diff_rate,
                0.25 * self.clearcoat * cc_rate,
                spec_rate * bsdf * (1.0 - f),
                spec_rate * (1.0 - bsdf * (1.0 - f)),
            ]
        } else if bsdf > 0.0 {
            [0.0, 0.0, 1.0 - f, f]
        } else {
            [0.0; 4]
        }
    }

    /// The half vector of `wo` and `wi` turned outwards, and the path's
    /// relative index (`η` from the front, `1/η` from inside).
    fn half(&self, wo: DVec3, wi: DVec3) -> (DVec3, f64, bool) {
        let reflect = wo.z * wi.z > 0.0;
        let eta_path = if wo.z > 0.0 { self.eta } else { 1.0 / self.eta };
        let h = (wo + wi * if reflect { 1.0 } else { eta_path }).normalize();
        (if h.z < 0.0 { -h } else { h }, eta_path, reflect)
    }

    /// Mitsuba's `eval`: `f(ω_o, ω_i) |cos θ_i|`.
    fn cosine_weighted(&self, wo: DVec3, wi: DVec3) -> Rgb {
        if wo.z == 0.0 || wi.z == 0.0 {
            return Rgb::BLACK;
        }
        let (brdf, bsdf) = self.lobe_weights();
        let (h, eta_path, reflect) = self.half(wo, wi);
        if !h.is_finite() {
            return Rgb::BLACK;
        }
        let front = wo.z > 0.0;
        let (oh, ih) = (wo.dot(h), wi.dot(h));
        let f = fresnel::dielectric(oh, self.eta).reflectance;
        let alpha = self.specular.alpha();
        let d = self.specular.d(h);
        let g = smith_g1(alpha, wo, h) * smith_g1(alpha, wi, h);
        let base = self.base_color;
        let mut value = Rgb::BLACK;
        if reflect && compatible(h, wo, wi, true) && f > 0.0 {
            let fp = if front {
                let eta_it = if oh >= 0.0 { self.eta } else { 1.0 / self.eta };
                let r0 = ((eta_it - 1.0) / (eta_it + 1.0)).powi(2);
                Rgb::WHITE * ((1.0 - self.metallic) * (1.0 - self.spec_tint) * f)
                    + schlick(base, oh, self.eta) * self.metallic
                    + schlick(tint(base) * r0, oh, self.eta) * ((1.0 - self.metallic) * self.spec_tint)
            } else {
                Rgb::WHITE * (bsdf * f)
            };
            value += fp * (d * g / (4.0 * wo.z.abs()));
        }
        if !reflect && bsdf > 0.0 && compatible(h, wo, wi, false) && f < 1.0 {
            let radiance = 1.0 / (eta_path * eta_path);
            let t = (radiance * (1.0 - f) * d * g * eta_path * eta_path * oh * ih
                / (wo.z * (oh + eta_path * ih).powi(2)))
            .abs();
            value += Rgb::new(base.r.sqrt(), base.g.sqrt(), base.b.sqrt()) * (bsdf * t);
        }
        if !front || !reflect {
            return value;
        }
        if self.clearcoat > 0.0 && compatible(h, wo, wi, true) {
            let fcc = schlick(Rgb::splat(0.04), oh, self.eta).r;
            let gcc = smith_g1((0.25, 0.25), wo, h) * smith_g1((0.25, 0.25), wi, h);
            value += Rgb::splat(0.25 * self.clearcoat * fcc * gtr1(self.clearcoat_alpha, h) * gcc * wi.z);
        }
        if brdf > 0.0 {
            let diffuse = disney_diffuse(self.roughness, self.flatness, wo, wi, h);
            value += base * (brdf * diffuse) + sheen(base, self.sheen, self.sheen_tint, wi, h) * (1.0 - self.metallic);
        }
        value
    }

    /// `|∂h/∂ω_i|` of the half vector for reflection or refraction.
    fn jacobian(wo: DVec3, wi: DVec3, h: DVec3, eta_path: f64, reflect: bool) -> f64 {
        let (oh, ih) = (wo.dot(h), wi.dot(h));
        if reflect {
            (1.0 / (4.0 * ih)).abs()
        } else {
            (eta_path * eta_path * ih / (oh + eta_path * ih).powi(2)).abs()
        }
    }
}

impl Model for Principled {
    fn eval(&self, wo: DVec3, wi: DVec3) -> Rgb {
        match wi.z.abs() {
            0.0 => Rgb::BLACK,
            c => self.cosine_weighted(wo, wi) * (1.0 / c),
        }
    }

    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        if wo.z == 0.0 || wi.z == 0.0 {
            return 0.0;
        }
        let [p_diffuse, p_clearcoat, p_trans, p_spec] = normalised(self.selection(wo));
        let (h, eta_path, reflect) = self.half(wo, wi);
        if !h.is_finite() {
            return 0.0;
        }
        let jacobian = Self::jacobian(wo, wi, h, eta_path, reflect);
        let viewer = if wo.z > 0.0 { wo } else { -wo };
        let visible = self.specular.pdf(viewer, h);
        let mut pdf = 0.0;
        if reflect {
            pdf += p_diffuse * warp::cosine_hemisphere_pdf(wi);
            if compatible(h, wo, wi, true) {
                pdf += p_spec * visible * jacobian;
                pdf += p_clearcoat * gtr1(self.clearcoat_alpha, h) * h.z * jacobian;
            }
        } else if compatible(h, wo, wi, false) {
            pdf += p_trans * visible * jacobian;
        }
        pdf
    }

    fn sample(&self, wo: DVec3, u_lobe: f64, u: [f64; 2]) -> Option<LobeSample> {
        if wo.z == 0.0 {
            return None;
        }
        let lobe = pick_lobe(self.selection(wo), u_lobe)?;
        // Normals of the upper side, drawn as seen from `wo` turned up.
        let viewer = if wo.z > 0.0 { wo } else { -wo };
        // A specular or clearcoat normal that reflects through the surface,
        // or refracts back, gives no direction (Mitsuba's masks, which
        // `pdf` applies alike).
        let reflected = |wi: DVec3, m: DVec3| {
            (wi.z * wo.z > 0.0 && compatible(m, wo, wi, true)).then_some(wi)
        };
        let wi = match lobe {
            0 => warp::cosine_hemisphere(u),
            1 => {
                let m = sample_gtr1(self.clearcoat_alpha, u);
                reflected(reflect(wo, m), m)?
            }
            2 => {
                // Refraction about m: ω_t = −ω_o/η + (ω_o·m/η + cos θ_t) m,
                // `cos_t` signed for the side light leaves to.
                let m = self.specular.sample(viewer, u).m;
                let om = wo.dot(m);
                let fr = fresnel::dielectric(om, self.eta);
                if fr.reflectance >= 1.0 {
                    return None;
                }
                let wi = (-wo / fr.eta + (om / fr.eta + fr.cos_t) * m).normalize();
                (wi.z * wo.z < 0.0 && compatible(m, wo, wi, false)).then_some(wi)?
            }
            _ => {
                let m = self.specular.sample(viewer, u).m;
                reflected(reflect(wo, m), m)?
            }
        };
        let pdf = self.pdf(wo, wi);
        LobeSample::spread(wi, pdf, || self.eval(wo, wi))
    }

    fn flags(&self) -> BsdfFlags {
        let (brdf, bsdf) = self.lobe_weights();
        BsdfFlags {
            diffuse: brdf > 0.0 && self.flatness < 1.0,
            glossy: true,
            delta: false,
            transmission: bsdf > 0.0,
        }
    }

    /// The diffuse term with its `ω_i` factor at its cosine-weighted mean
    /// (module docs).
    fn lambertian(&self, wo: DVec3) -> Rgb {
        let (brdf, _) = self.lobe_weights();
        if wo.z <= 0.0 {
            return Rgb::BLACK;
        }
        diffuse_mean(self.base_color, brdf, self.flatness, wo)
    }

    fn is_anisotropic(&self) -> bool {
        let (u, v) = self.specular.alpha();
        u != v
    }
}

#[cfg(test)]
mod tests;
