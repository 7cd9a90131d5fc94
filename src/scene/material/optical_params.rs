//! Parameters that only materials have: indices of refraction (numbers or
//! named media), conductors' complex indices (or named metals) and
//! microfacet roughness, each read from a plugin's [`Params`] with
//! Mitsuba's defaults.

use serde_json::Value;

use super::{Distribution, Lookup, Params, Roughness, ior as media, metals};
use crate::color::{Rgb, RgbArray};
use crate::scene::error::SceneError;
use crate::scene::texture::{self, Texture};

/// Mitsuba's default `alpha` of rough BSDFs.
const DEFAULT_ALPHA: f64 = 0.1;

/// The indices of refraction a medium may have (`int_ior`, `ext_ior`).
/// Mitsuba takes any positive number, but the Fresnel and coating terms
/// overflow to NaN for relative indices far from 1 (`tests/it/
/// scene_parameters.rs` found 1e-12 and 1e6 failing), and every real
/// medium lies within [1, 4].
pub const IOR_RANGE: std::ops::RangeInclusive<f64> = 0.01..=100.0;

/// The bounds of a conductor's complex index `η + i k`, each channel: `η`
/// and `k` in `[0, MAX_METAL_INDEX]` (real metals stay below 10 in the
/// visible) and `|η + i k| ≥ MIN_METAL_MODULUS`, as the Fresnel terms
/// divide by `(η + i k)²`.
pub const MAX_METAL_INDEX: f64 = 100.0;
/// See [`MAX_METAL_INDEX`].
pub const MIN_METAL_MODULUS: f64 = 0.01;

/// An index of refraction: a number in [`IOR_RANGE`] or a named medium
/// ([`media::named_ior`]), `default` when absent.
pub(super) fn ior(params: &mut Params, name: &str, default: f64) -> Result<f64, SceneError> {
    match params.peek(name) {
        None => Ok(default),
        Some(Value::String(_)) => {
            let medium = params.string(name)?.unwrap_or_default();
            media::named_ior(&medium).ok_or_else(|| {
                params.invalid(
                    name,
                    format!(
                        "unknown medium {medium:?} (known: {})",
                        media::media_names()
                    ),
                )
            })
        }
        Some(_) => match params.number(name)? {
            Some(x) if !IOR_RANGE.contains(&x) => Err(params.invalid(
                name,
                format!(
                    "{x} is not an index of refraction in [{}, {}]",
                    IOR_RANGE.start(),
                    IOR_RANGE.end()
                ),
            )),
            x => Ok(x.unwrap_or(default)),
        },
    }
}

/// `int_ior / ext_ior` with Mitsuba's defaults `int_default` and air;
/// refuses the ratio 1, an interface that is not one.
pub(super) fn relative_ior(params: &mut Params, int_default: f64) -> Result<f64, SceneError> {
    let int_ior = ior(params, "int_ior", int_default)?;
    let ext_ior = ior(params, "ext_ior", media::AIR)?;
    if int_ior == ext_ior {
        return Err(params.invalid(
            "int_ior",
            "equals ext_ior: the interface would not refract or reflect",
        ));
    }
    Ok(int_ior / ext_ior)
}

/// A conductor's complex index `(eta, k)`: both as colours, or a named
/// metal `material` ([`metals::named_metal`]); Mitsuba's default is
/// the perfect mirror `none`.
pub(super) fn metal(params: &mut Params) -> Result<(RgbArray, RgbArray), SceneError> {
    let eta = params.color("eta")?;
    let k = params.color("k")?;
    let named = params.string("material")?;
    match (eta, k, named) {
        (Some(eta), Some(k), None) => {
            let in_range = |x: f64| (0.0..=MAX_METAL_INDEX).contains(&x);
            for (name, values) in [("eta", eta), ("k", k)] {
                if let Some(x) = values.iter().find(|x| !in_range(**x)) {
                    return Err(
                        params.invalid(name, format!("{x} is not in [0, {MAX_METAL_INDEX}]"))
                    );
                }
            }
            if (0..3).any(|c| eta[c].hypot(k[c]) < MIN_METAL_MODULUS) {
                return Err(params.invalid(
                    "eta",
                    format!("|eta + i k| must be at least {MIN_METAL_MODULUS} in every channel"),
                ));
            }
            Ok((eta, k))
        }
        (None, None, name) => {
            let name = name.unwrap_or_else(|| "none".to_string());
            metals::named_metal(&name).ok_or_else(|| {
                let known: Vec<&str> = metals::NAMED_METALS.iter().map(|m| m.0).collect();
                params.invalid(
                    "material",
                    format!("unknown metal {name:?} (known: {})", known.join(", ")),
                )
            })
        }
        _ => Err(params.invalid("eta", "give both `eta` and `k`, or `material`, not a mix")),
    }
}

/// A microfacet roughness: `distribution` (`beckmann`, the default, or
/// `ggx`), and `alpha` or both `alpha_u` and `alpha_v` (default 0.1),
/// each in `(0, 4]`. `sample_visible` is accepted and always on.
pub(super) fn roughness(params: &mut Params) -> Result<Roughness, SceneError> {
    let name = params
        .string("distribution")?
        .map(|d| d.to_ascii_lowercase());
    let distribution = match name.as_deref() {
        None | Some("beckmann") => Distribution::Beckmann,
        Some("ggx") => Distribution::Ggx,
        Some(other) => {
            return Err(params.invalid(
                "distribution",
                format!("unknown distribution {other:?} (known: beckmann, ggx)"),
            ));
        }
    };
    params.boolean("sample_visible", true)?;
    let (alpha_u, alpha_v) = match (
        alpha(params, "alpha")?,
        alpha(params, "alpha_u")?,
        alpha(params, "alpha_v")?,
    ) {
        (Some(a), None, None) => (a.clone(), a),
        (None, None, None) => (
            Texture::Constant([DEFAULT_ALPHA; 3]),
            Texture::Constant([DEFAULT_ALPHA; 3]),
        ),
        (None, Some(u), Some(v)) => (u, v),
        _ => {
            return Err(params.invalid(
                "alpha",
                "give either `alpha` or both `alpha_u` and `alpha_v`",
            ));
        }
    };
    // A constant is the number given (all three channels alike), a
    // texture stands as its mean where no surface point is at hand.
    let value = |t: &Texture| t.constant().map_or_else(|| t.mean_scalar(), |c| c[0]);
    let textured = alpha_u.constant().is_none() || alpha_v.constant().is_none();
    Ok(Roughness {
        distribution,
        alpha_u: value(&alpha_u),
        alpha_v: value(&alpha_v),
        textures: textured.then(|| Box::new([alpha_u, alpha_v])),
    })
}

/// Roughness parameter `name`: a number in (0, 4], or a texture whose
/// values are at most 4 (a roughness map; Mitsuba's rough conductors and
/// dielectrics take one; where it is below `MIN_ALPHA` the surface is
/// shaded at that roughness, never as a mirror).
fn alpha(params: &mut Params, name: &str) -> Result<Option<Texture>, SceneError> {
    if params.peek(name).is_some_and(Value::is_object) {
        let doc = params.take(name).expect("present");
        let texture = Texture::parse(params, name, doc)?;
        let max = texture.max();
        if !(max > 0.0 && max <= 4.0) {
            return Err(params.invalid(
                name,
                format!("the texture reaches {max}, not a roughness in (0, 4]"),
            ));
        }
        return Ok(Some(texture));
    }
    match params.number(name)? {
        Some(a) if a > 0.0 && a <= 4.0 => Ok(Some(Texture::Constant([a; 3]))),
        Some(a) => Err(params.invalid(name, format!("{a} is not a roughness in (0, 4]"))),
        None => Ok(None),
    }
}

/// What every dielectric plugin takes (`dielectric`, `thindielectric`,
/// `roughdielectric`; Mitsuba 3's names and defaults): the relative index
/// `int_ior / ext_ior` (interior default BK7, exterior air) and factors on
/// the reflected and transmitted light.
#[derive(Clone, Debug, PartialEq)]
pub struct Interface {
    /// Interior over exterior index of refraction, in [`IOR_RANGE`] ratios, ≠ 1.
    pub eta: f64,
    /// Factors on the reflected and transmitted light, in [0, 1], default 1.
    pub specular_reflectance: Texture,
    pub specular_transmittance: Texture,
}

impl Interface {
    /// Read in Mitsuba's order: the indices, then the two factors.
    pub(super) fn parse(params: &mut Params) -> Result<Self, SceneError> {
        Ok(Self {
            eta: relative_ior(params, media::BK7)?,
            specular_reflectance: texture::albedo(params, "specular_reflectance", [1.0; 3])?,
            specular_transmittance: texture::albedo(params, "specular_transmittance", [1.0; 3])?,
        })
    }

    pub(super) fn textures(&self) -> Vec<&Texture> {
        vec![&self.specular_reflectance, &self.specular_transmittance]
    }

    /// `(eta, reflectance factor, transmittance factor)` where `lookup` says.
    pub(super) fn at(&self, lookup: Lookup) -> (f64, Rgb, Rgb) {
        (
            self.eta,
            lookup.rgb(&self.specular_reflectance),
            lookup.rgb(&self.specular_transmittance),
        )
    }
}
