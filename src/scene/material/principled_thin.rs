//! `principledthin`: Mitsuba 3's principled BSDF for thin, two-sided
//! surfaces (leaves, paper, curtains, window panes): the same from either
//! side, with light passing through it specularly or diffusely
//! (docs/math.md §18.6). Every direction is first turned to the viewer's
//! side; with `st = spec_trans`, `dt = diff_trans / 2`, `h` the half vector
//! of `ω_o` and `ω_i` mirrored to the viewer's side, `F` the dielectric
//! Fresnel reflectance at `ω_o·h` for `η`, Mitsuba's value (cosine
//! included) is the sum of
//!
//! - specular reflection `st · lerp(F, Schlick(tint R₀(η), ω_o·h),
//!   spec_tint) D G / (4 |cos θ_o|)`, GGX of the roughness;
//! - specular transmission, mirrored through the sheet: `st · base (1 − F)
//!   D' G' / (4 |cos θ_o|)`, GGX of the roughness scaled by `0.65 η −
//!   0.35`;
//! - diffuse reflection `(1 − st)(1 − dt) base` times the Disney diffuse
//!   lobe (`principled`'s, with flatness), and the sheen with the same
//!   weights;
//! - diffuse transmission `(1 − st) dt base |cos θ_i| / π`.
//!
//! Sampling picks the lobes with weights `st/2`, `st/2`, `(1 − st)(1 −
//! dt)`, `(1 − st) dt` (each times its sampling rate), as Mitsuba does; the
//! density it reports is exact. The cache serves the diffuse reflection's
//! cosine-weighted mean on either side.
//!
//! Parameters (Mitsuba's names and defaults): `base_color` (0.5);
//! `roughness` (0.5), `spec_trans`, `spec_tint`, `sheen`, `sheen_tint`,
//! `flatness`, `anisotropic` (0), `diff_trans` (0, in [0, 2]): numbers or
//! textures; `eta` (1.5, a number or texture); the sampling rates
//! `specular_reflectance_sampling_rate`,
//! `specular_transmittance_sampling_rate`,
//! `diffuse_reflectance_sampling_rate`,
//! `diffuse_transmittance_sampling_rate` (1, ≥ 0).

use glam::DVec3;

use super::principled::{
    compatible, diffuse_mean, disney_diffuse, ggx, normalised, pick_lobe, rates, schlick, sheen,
    smith_g1, tint, weights,
};
use super::{Bsdf, BsdfFlags, LobeSample, Lookup, Model, Params, Parameters, Plugin, reflect};
use crate::color::Rgb;
use crate::optics::fresnel;
use crate::optics::microfacet::Microfacet;
use crate::optics::warp;
use crate::scene::error::SceneError;
use crate::scene::texture::{self, Texture};

/// The scalar parameters in [0, 1], in the order of `weights`.
const WEIGHTS: [(&str, f64); 7] = [
    ("roughness", 0.5),
    ("spec_trans", 0.0),
    ("spec_tint", 0.0),
    ("sheen", 0.0),
    ("sheen_tint", 0.0),
    ("flatness", 0.0),
    ("anisotropic", 0.0),
];

/// The sampling rates' names, in the order of the lobes: specular
/// reflection and transmission, diffuse reflection and transmission.
const RATES: [&str; 4] = [
    "specular_reflectance_sampling_rate",
    "specular_transmittance_sampling_rate",
    "diffuse_reflectance_sampling_rate",
    "diffuse_transmittance_sampling_rate",
];

/// The parameters of a `principledthin` material; see the module docs.
#[derive(Clone, Debug, PartialEq)]
pub struct PrincipledThinMaterial {
    pub base_color: Texture,
    /// The textures of [`WEIGHTS`], in its order (scalar lookups).
    pub weights: Vec<Texture>,
    /// `diff_trans`, in [0, 2].
    pub diff_trans: Texture,
    /// The sheet's index of refraction.
    pub eta: Texture,
    pub rates: [f64; 4],
}

impl Plugin for PrincipledThinMaterial {
    type Model = PrincipledThin;
}

impl PrincipledThinMaterial {
    /// The parameters of a material document, each validated once.
    pub(crate) fn parse(params: &mut Params) -> Result<Self, SceneError> {
        let base_color = texture::albedo(params, "base_color", [0.5; 3])?;
        let weights = weights(params, &WEIGHTS)?;
        let diff_trans = texture::values(params, "diff_trans")?.unwrap_or(Texture::Constant([0.0; 3]));
        if diff_trans.max() > 2.0 {
            return Err(params.invalid("diff_trans", "reaches above 2, the most light a sheet can pass"));
        }
        let eta = texture::values(params, "eta")?.unwrap_or(Texture::Constant([1.5; 3]));
        let rates = rates(params, RATES)?;
        Ok(Self {
            base_color,
            weights,
            diff_trans,
            eta,
            rates,
        })
    }
}

impl Parameters for PrincipledThinMaterial {
    fn textures(&self) -> Vec<&Texture> {
        let mut all = vec![&self.base_color, &self.diff_trans, &self.eta];
        all.extend(&self.weights);
        all
    }

    /// Already the same from both sides.
    fn may_be_a_side(&self) -> bool {
        false
    }

    fn build(&self, lookup: Lookup, _: Option<&Bsdf>) -> Bsdf {
        let w: Vec<f64> = self.weights.iter().map(|t| lookup.scalar(t)).collect();
        let [roughness, spec_trans, spec_tint, sheen, sheen_tint, flatness, anisotropic] =
            <[f64; 7]>::try_from(w).expect("seven weights");
        let eta = lookup.scalar(&self.eta).max(1e-3);
        Bsdf::PrincipledThin(PrincipledThin {
            base_color: lookup.rgb(&self.base_color),
            roughness,
            spec_trans,
            spec_tint,
            sheen,
            sheen_tint,
            flatness,
            diff_trans: lookup.scalar(&self.diff_trans).clamp(0.0, 2.0) / 2.0,
            eta,
            reflection: ggx(roughness, anisotropic),
            transmission: ggx((0.65 * eta - 0.35) * roughness, anisotropic),
            rates: self.rates,
        })
    }
}

/// The thin principled model with its parameters valued; see the module docs.
#[derive(Clone, Debug, PartialEq)]
pub struct PrincipledThin {
    pub base_color: Rgb,
    pub roughness: f64,
    pub spec_trans: f64,
    pub spec_tint: f64,
    pub sheen: f64,
    pub sheen_tint: f64,
    pub flatness: f64,
    /// `diff_trans / 2`, in [0, 1].
    pub diff_trans: f64,
    pub eta: f64,
    /// The specular reflection's GGX distribution.
    pub reflection: Microfacet,
    /// The specular transmission's, of the scaled roughness.
    pub transmission: Microfacet,
    pub rates: [f64; 4],
}

impl PrincipledThin {
    /// The lobes' selection weights (module docs): specular reflection and
    /// transmission, diffuse reflection and transmission.
    fn selection(&self) -> [f64; 4] {
        let (st, dt) = (self.spec_trans, self.diff_trans);
        [
            st * self.rates[0] / 2.0,
            st * self.rates[1] / 2.0,
            self.rates[2] * (1.0 - st) * (1.0 - dt),
            self.rates[3] * (1.0 - st) * dt,
        ]
    }

    /// `wo` and `wi` turned to the viewer's side (the sheet is the same
    /// from both), and the half vector of `wo` and `wi` mirrored to it.
    fn upright(wo: DVec3, wi: DVec3) -> (DVec3, DVec3, DVec3) {
        let s = wo.z.signum();
        let (wo, wi) = (wo * s, wi * s);
        let h = (wo + DVec3::new(wi.x, wi.y, wi.z.abs())).normalize();
        (wo, wi, h)
    }

    /// Mitsuba's `eval`: `f(ω_o, ω_i) |cos θ_i|`.
    fn cosine_weighted(&self, wo: DVec3, wi: DVec3) -> Rgb {
        if wo.z == 0.0 || wi.z == 0.0 {
            return Rgb::BLACK;
        }
        let (wo, wi, h) = Self::upright(wo, wi);
        let (st, dt, base) = (self.spec_trans, self.diff_trans, self.base_color);
        let reflected = wi.z > 0.0;
        let mut value = Rgb::BLACK;
        if st > 0.0 && h.is_finite() {
            let f = fresnel::dielectric(wo.dot(h), self.eta).reflectance;
            if reflected && compatible(h, wo, wi, true) {
                let r0 = ((self.eta - 1.0) / (self.eta + 1.0)).powi(2);
                let schlick = schlick(tint(base) * r0, wo.dot(h), self.eta);
                let f_thin = Rgb::WHITE * f + (schlick - Rgb::WHITE * f) * self.spec_tint;
                value += f_thin * (st * self.lobe(&self.reflection, wo, wi, h));
            }
            if !reflected && compatible(h, wo, wi, false) {
                value += base * (st * (1.0 - f) * self.lobe(&self.transmission, wo, wi, h));
            }
        }
        if reflected && st < 1.0 && dt < 1.0 {
            let diffuse = disney_diffuse(self.roughness, self.flatness, wo, wi, h);
            let w = (1.0 - st) * (1.0 - dt);
            value += (base * diffuse + sheen(base, self.sheen, self.sheen_tint, wi, h)) * w;
        }
        if !reflected && st < 1.0 && dt > 0.0 {
            value += base * ((1.0 - st) * dt * wi.z.abs() * std::f64::consts::FRAC_1_PI);
        }
        value
    }

    /// `D G / (4 cos θ_o)` of a specular lobe of `distribution`.
    fn lobe(&self, distribution: &Microfacet, wo: DVec3, wi: DVec3, h: DVec3) -> f64 {
        let alpha = distribution.alpha();
        distribution.d(h) * smith_g1(alpha, wo, h) * smith_g1(alpha, wi, h) / (4.0 * wo.z)
    }
}

impl Model for PrincipledThin {
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
        let [p_reflect, p_trans, p_diffuse, p_diffuse_trans] = normalised(self.selection());
        let (wo, wi, h) = Self::upright(wo, wi);
        let reflected = wi.z > 0.0;
        let mut pdf = 0.0;
        if self.spec_trans > 0.0 && h.is_finite() {
            let jacobian = (1.0 / (4.0 * DVec3::new(wi.x, wi.y, wi.z.abs()).dot(h))).abs();
            if reflected && compatible(h, wo, wi, true) {
                pdf += p_reflect * self.reflection.pdf(wo, h) * jacobian;
            }
            if !reflected && compatible(h, wo, wi, false) {
                pdf += p_trans * self.transmission.pdf(wo, h) * jacobian;
            }
        }
        let mirrored = DVec3::new(wi.x, wi.y, wi.z.abs());
        pdf += if reflected { p_diffuse } else { p_diffuse_trans } * warp::cosine_hemisphere_pdf(mirrored);
        pdf
    }

    fn sample(&self, wo: DVec3, u_lobe: f64, u: [f64; 2]) -> Option<LobeSample> {
        if wo.z == 0.0 {
            return None;
        }
        let lobe = pick_lobe(self.selection(), u_lobe)?;
        let s = wo.z.signum();
        let up = wo * s;
        // A specular normal whose reflection leaves the viewer's side, or
        // whose mirrored transmission faces it, gives no direction
        // (Mitsuba's masks, which `pdf` applies alike).
        let wi = match lobe {
            0 => {
                let m = self.reflection.sample(up, u).m;
                let wi = reflect(up, m);
                (wi.z > 0.0 && compatible(m, up, wi, true)).then_some(wi)?
            }
            1 => {
                let m = self.transmission.sample(up, u).m;
                let r = reflect(up, m);
                let wi = DVec3::new(r.x, r.y, -r.z);
                (wi.z < 0.0 && compatible(m, up, wi, false)).then_some(wi)?
            }
            2 => warp::cosine_hemisphere(u),
            _ => -warp::cosine_hemisphere(u),
        } * s;
        LobeSample::spread(wi, self.pdf(wo, wi), || self.eval(wo, wi))
    }

    fn flags(&self) -> BsdfFlags {
        BsdfFlags {
            diffuse: self.spec_trans < 1.0 && self.diff_trans < 1.0 && self.flatness < 1.0,
            glossy: true,
            delta: false,
            transmission: self.spec_trans > 0.0 || self.diff_trans > 0.0,
        }
    }

    /// Either side scatters.
    fn scatters_towards(&self, _: DVec3) -> bool {
        true
    }

    /// The diffuse reflection's cosine-weighted mean, on either side.
    fn lambertian(&self, wo: DVec3) -> Rgb {
        let w = (1.0 - self.spec_trans) * (1.0 - self.diff_trans);
        diffuse_mean(self.base_color, w, self.flatness, wo)
    }

    fn is_anisotropic(&self) -> bool {
        let (u, v) = self.reflection.alpha();
        u != v
    }
}

#[cfg(test)]
mod tests {
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64;
    use serde_json::json;

    use super::*;
    use crate::optics::chi_square;
    use crate::scene::material::{Material, flip};

    fn thin(doc: serde_json::Value) -> PrincipledThin {
        let mut params = Params::new("test", doc.as_object().unwrap().clone());
        let material = Material::PrincipledThin(PrincipledThinMaterial::parse(&mut params).unwrap());
        params.finish().unwrap();
        match Bsdf::from(&material) {
            Bsdf::PrincipledThin(p) => p,
            other => panic!("{other:?}"),
        }
    }

    fn examples() -> Vec<PrincipledThin> {
        vec![
            thin(json!({})),
            thin(json!({"base_color": [0.3, 0.7, 0.2], "roughness": 0.6, "spec_trans": 0.6,
                "diff_trans": 0.8, "spec_tint": 0.5, "sheen": 0.7, "sheen_tint": 0.4,
                "flatness": 0.3, "anisotropic": 0.5, "eta": 1.33})),
        ]
    }

    #[test]
    fn samples_follow_the_density_and_carry_evals_value_from_either_side() {
        let mut rng = Pcg64::seed_from_u64(41);
        for p in examples() {
            for wo in [
                DVec3::new(0.3, 0.1, 0.9).normalize(),
                DVec3::new(-0.7, 0.2, -0.4).normalize(),
            ] {
                let test = chi_square::of_directions(
                    || p.sample(wo, rng.random(), [rng.random(), rng.random()]).map(|s| s.wi),
                    |wi| p.pdf(wo, wi),
                    200_000,
                    (20, 24),
                );
                assert!(test.passes(), "{p:?} from {wo}: {test}");
                for _ in 0..500 {
                    let Some(s) = p.sample(wo, rng.random(), [rng.random(), rng.random()]) else {
                        continue;
                    };
                    let (f, pdf) = (p.eval(wo, s.wi), p.pdf(wo, s.wi));
                    assert!((pdf - s.pdf).abs() <= 1e-9 * pdf);
                    assert!((f - s.value).max_component().abs() <= 1e-9 * f.max_component().max(1.0));
                }
            }
        }
    }

    #[test]
    fn the_sheet_is_the_same_from_both_sides_and_keeps_about_the_light_it_gets() {
        let p = &examples()[1];
        let (a, b) = (
            DVec3::new(0.3, 0.1, 0.9).normalize(),
            DVec3::new(-0.5, 0.4, -0.6).normalize(),
        );
        assert_eq!(p.eval(a, b), p.eval(flip(a), flip(b)));
        assert_eq!(p.pdf(a, b), p.pdf(flip(a), flip(b)));
        assert!(p.eval(a, b).max_component() > 0.0, "light passes through");
        // Furnace: a white sheet that passes all its diffuse light, and one
        // half specular, keep at most what they get (up to the Disney
        // diffuse's few percent, as `principled`'s).
        let mut rng = Pcg64::seed_from_u64(43);
        for doc in [
            json!({"base_color": 1.0, "diff_trans": 2.0, "roughness": 0.3}),
            json!({"base_color": 1.0, "spec_trans": 0.5, "diff_trans": 1.0, "roughness": 0.3}),
        ] {
            let p = thin(doc.clone());
            for wo in [DVec3::Z, DVec3::new(0.5, 0.2, -0.6).normalize()] {
                let n = 100_000;
                let mut sum = 0.0;
                for _ in 0..n {
                    if let Some(s) = p.sample(wo, rng.random(), [rng.random(), rng.random()]) {
                        sum += s.value.g * s.wi.z.abs() / s.pdf;
                    }
                }
                let albedo = sum / n as f64;
                assert!(albedo > 0.7 && albedo < 1.06, "{doc} from {wo}: {albedo}");
            }
        }
    }
}
