//! Surface materials (BSDFs as data; evaluation and sampling live with the
//! light transport code).
//!
//! - `Diffuse`: Lambertian, `f = ρ/π`.
//! - `Glossy`: diffuse plus a normalised Phong lobe (Lafortune & Willems,
//!   "Using the modified Phong reflectance model for physically based
//!   rendering", 1994): `f = ρ_d/π + ρ_s·(n+2)/(2π)·max(0, cos α)ⁿ`, where α is
//!   the angle between the outgoing direction and the mirror direction of the
//!   incoming one. With `ρ_d + ρ_s ≤ 1` per channel the BSDF conserves energy,
//!   which the loader enforces.

use super::error::SceneError;
use super::format::{MaterialDoc, MaterialKind, Rgb};

/// Largest accepted Phong exponent; beyond it the lobe is a mirror for all
/// practical purposes and sampling it in f64 loses precision.
pub const MAX_PHONG_EXPONENT: f64 = 1e6;

#[derive(Clone, Debug, PartialEq)]
pub enum Material {
    /// Lambertian reflector; `reflectance` is the albedo in [0, 1] per channel.
    Diffuse { reflectance: [f64; 3] },
    /// Diffuse albedo plus a normalised Phong lobe with albedo `specular`
    /// (at normal incidence) and exponent `exponent ≥ 0`.
    Glossy {
        diffuse: [f64; 3],
        specular: [f64; 3],
        exponent: f64,
    },
}

fn albedo(value: Option<Rgb>, field: &str, name: &str) -> Result<[f64; 3], SceneError> {
    let value =
        value.ok_or_else(|| SceneError::invalid(field, format!("missing field `{name}`")))?;
    for (i, x) in value.iter().enumerate() {
        if !(0.0..=1.0).contains(x) {
            return Err(SceneError::invalid(
                format!("{field}.{name}[{i}]"),
                format!("{x} is not an albedo in [0, 1]"),
            ));
        }
    }
    Ok(value)
}

fn reject(present: bool, field: &str, name: &str, kind: &str) -> Result<(), SceneError> {
    if present {
        return Err(SceneError::invalid(
            format!("{field}.{name}"),
            format!("not a field of a {kind} material"),
        ));
    }
    Ok(())
}

impl Material {
    /// Validates one `materials[i]` entry; `field` is its path.
    pub(crate) fn from_doc(doc: &MaterialDoc, field: &str) -> Result<Self, SceneError> {
        match doc.kind {
            MaterialKind::Diffuse => {
                reject(doc.diffuse.is_some(), field, "diffuse", "diffuse")?;
                reject(doc.specular.is_some(), field, "specular", "diffuse")?;
                reject(doc.exponent.is_some(), field, "exponent", "diffuse")?;
                Ok(Material::Diffuse {
                    reflectance: albedo(doc.reflectance, field, "reflectance")?,
                })
            }
            MaterialKind::Glossy => {
                reject(doc.reflectance.is_some(), field, "reflectance", "glossy")?;
                let diffuse = albedo(doc.diffuse, field, "diffuse")?;
                let specular = albedo(doc.specular, field, "specular")?;
                for i in 0..3 {
                    if diffuse[i] + specular[i] > 1.0 {
                        return Err(SceneError::invalid(
                            format!("{field}.specular[{i}]"),
                            "diffuse + specular exceeds 1: the material would create energy",
                        ));
                    }
                }
                let exponent = doc
                    .exponent
                    .ok_or_else(|| SceneError::invalid(field, "missing field `exponent`"))?;
                if !(0.0..=MAX_PHONG_EXPONENT).contains(&exponent) {
                    return Err(SceneError::invalid(
                        format!("{field}.exponent"),
                        format!("{exponent} is outside [0, {MAX_PHONG_EXPONENT:e}]"),
                    ));
                }
                Ok(Material::Glossy {
                    diffuse,
                    specular,
                    exponent,
                })
            }
        }
    }
}
