//! Mitsuba BSDFs → the project's materials (Lambertian, or Lambertian plus a
//! normalised Phong lobe).
//!
//! Mapping (documented in `docs/scene-format.md`):
//! - `diffuse`: exact.
//! - `twosided`: its nested BSDF, with a warning: the project's BSDFs are
//!   one-sided like Mitsuba's plain ones (back faces are black, see
//!   `render::bsdf`), so back faces stay black where Mitsuba would reflect.
//! - `plastic` / `roughplastic`: diffuse `ρ_d·(1 − F₀)`, specular
//!   `ρ_s·F₀` with `F₀ = ((η − 1)/(η + 1))²`, `η = int_ior / ext_ior`
//!   (Fresnel reflectance at normal incidence).
//! - `conductor` / `roughconductor`: no diffuse part, specular `ρ_s·F₀`
//!   with the conductor's normal-incidence reflectance
//!   `F₀ = ((n − 1)² + k²) / ((n + 1)² + k²)` per channel (`F₀ = 1` for
//!   Mitsuba's default `material="none"`).
//! - Roughness: a Beckmann (or GGX) `alpha` becomes the Phong exponent
//!   `m = 2/α² − 2`, the correspondence of Walter, Marschner, Li & Torrance,
//!   "Microfacet Models for Refraction through Rough Surfaces", EGSR 2007,
//!   §5.2; clamped to `[0, MAX_PHONG_EXPONENT]`. Smooth variants (`plastic`,
//!   `conductor`) use `MAX_PHONG_EXPONENT`, the closest lobe to a mirror.

use crate::scene::format::{MaterialDoc, MaterialKind, Rgb};
use crate::scene::material::MAX_PHONG_EXPONENT;

use super::parse::{Element, quote};
use super::props::Props;
use super::texture::color;
use super::{Ctx, XmlError};

/// Mitsuba's default `alpha` for rough BSDFs.
const DEFAULT_ALPHA: f64 = 0.1;

/// The material a shape without a BSDF gets (Mitsuba: diffuse, 0.5).
const DEFAULT_MATERIAL_ID: &str = "default-diffuse@mitsuba";

/// Phong exponent equivalent to microfacet roughness `alpha` (Walter et al.
/// 2007, §5.2: `α_p = 2 α_b⁻² − 2`).
pub(crate) fn phong_exponent(alpha: f64) -> f64 {
    (2.0 / (alpha * alpha) - 2.0).clamp(0.0, MAX_PHONG_EXPONENT)
}

/// Fresnel reflectance at normal incidence of a dielectric interface with
/// relative index `eta`.
fn dielectric_f0(eta: f64) -> f64 {
    ((eta - 1.0) / (eta + 1.0)).powi(2)
}

/// Fresnel reflectance at normal incidence of a conductor `n + ik`.
fn conductor_f0(n: f64, k: f64) -> f64 {
    ((n - 1.0).powi(2) + k * k) / ((n + 1.0).powi(2) + k * k)
}

/// The material id for BSDF element `el` (inline or referenced), adding the
/// material to the document the first time.
pub(crate) fn material<'a>(ctx: &mut Ctx<'a>, el: &'a Element) -> Result<String, XmlError> {
    let el = ctx.deref(el)?;
    if let Some(id) = ctx.material_of.get(&el.key()) {
        return Ok(id.clone());
    }
    if el.tag != "bsdf" {
        return Err(el.error("", format!("expected a <bsdf>, found <{}>", el.tag)));
    }
    let mut doc = describe(ctx, el)?;
    doc.id = match el.attr("id") {
        Some(id) => id.to_string(),
        // Anonymous BSDFs are named by position, which no two share.
        None => format!(
            "{}@{}:{}",
            el.attr("type").unwrap_or("bsdf"),
            el.line,
            el.column
        ),
    };
    let field = format!("materials[{}]", ctx.materials.len());
    ctx.origin(field, el);
    ctx.material_of.insert(el.key(), doc.id.clone());
    ctx.materials.push(doc);
    Ok(ctx.materials[ctx.materials.len() - 1].id.clone())
}

/// Mitsuba's default material for shapes without a BSDF (diffuse, ρ = 0.5).
pub(crate) fn default_material(ctx: &mut Ctx) -> String {
    builtin_diffuse(ctx, DEFAULT_MATERIAL_ID, [0.5; 3])
}

/// A diffuse material the translation itself needs, added once under `id`.
pub(crate) fn builtin_diffuse(ctx: &mut Ctx, id: &str, reflectance: Rgb) -> String {
    if !ctx.materials.iter().any(|m| m.id == id) {
        ctx.materials.push(MaterialDoc {
            id: id.to_string(),
            ..diffuse(reflectance)
        });
    }
    id.to_string()
}

fn diffuse(reflectance: Rgb) -> MaterialDoc {
    MaterialDoc {
        id: String::new(),
        kind: MaterialKind::Diffuse,
        reflectance: Some(reflectance),
        diffuse: None,
        specular: None,
        exponent: None,
    }
}

fn glossy(diffuse: Rgb, specular: Rgb, exponent: f64) -> MaterialDoc {
    MaterialDoc {
        id: String::new(),
        kind: MaterialKind::Glossy,
        reflectance: None,
        diffuse: Some(diffuse),
        specular: Some(specular),
        exponent: Some(exponent),
    }
}

/// The material (without id) a BSDF element describes.
fn describe<'a>(ctx: &mut Ctx<'a>, el: &'a Element) -> Result<MaterialDoc, XmlError> {
    ctx.enter(el)?;
    let kind = el.attr("type").unwrap_or("");
    let mut props = Props::new(el);
    let doc = match kind {
        "diffuse" => diffuse(color(ctx, &mut props, "reflectance", [0.5; 3])?),
        "twosided" => {
            let inner = props.nested(ctx, "bsdf")?;
            ctx.warn(
                el,
                "BSDFs are one-sided in the scene model: back faces stay black",
            );
            match inner[..] {
                [front] => describe(ctx, front)?,
                [front, _] => {
                    ctx.unsupported(
                        el,
                        "",
                        "a twosided BSDF with different front and back BSDFs",
                        "using the front BSDF on both sides",
                    )?;
                    describe(ctx, front)?
                }
                _ => {
                    return Err(el.error(
                        "",
                        format!(
                            "a twosided BSDF needs 1 or 2 nested BSDFs, found {}",
                            inner.len()
                        ),
                    ));
                }
            }
        }
        "plastic" | "roughplastic" => {
            let rho_d = color(ctx, &mut props, "diffuse_reflectance", [0.5; 3])?;
            let rho_s = color(ctx, &mut props, "specular_reflectance", [1.0; 3])?;
            let int_ior = ior(ctx, &mut props, "int_ior", 1.49)?;
            let ext_ior = ior(ctx, &mut props, "ext_ior", 1.000277)?;
            let exponent = roughness(ctx, &mut props, kind == "roughplastic")?;
            props.ignore(&["nonlinear", "sample_visible", "distribution"]);
            let f0 = dielectric_f0(int_ior / ext_ior);
            ctx.warn(
                el,
                format!(
                    "approximated as diffuse + Phong lobe (F0 = {f0:.4}, exponent {exponent:.1})"
                ),
            );
            glossy(
                rho_d.map(|d| d * (1.0 - f0)),
                rho_s.map(|s| s * f0),
                exponent,
            )
        }
        "conductor" | "roughconductor" => {
            let rho_s = color(ctx, &mut props, "specular_reflectance", [1.0; 3])?;
            let eta = props.get("eta")?;
            let k = props.get("k")?;
            let named = props.string("material")?;
            let f0 = match (eta, k, named) {
                (None, None, None | Some("none")) => [1.0; 3],
                (Some(eta), Some(k), None) => {
                    let (n, k) = (
                        super::texture::value(ctx, eta)?,
                        super::texture::value(ctx, k)?,
                    );
                    std::array::from_fn(|i| conductor_f0(n[i], k[i]))
                }
                (None, None, Some(name)) => {
                    ctx.unsupported(
                        el,
                        "material",
                        &format!(
                            "named conductor {} is not supported (give eta and k as rgb)",
                            quote(name)
                        ),
                        "treating it as a perfect reflector (F0 = 1)",
                    )?;
                    [1.0; 3]
                }
                _ => {
                    return Err(el.error(
                        "eta",
                        "give either both `eta` and `k`, or `material`, not a mix",
                    ));
                }
            };
            let exponent = roughness(ctx, &mut props, kind == "roughconductor")?;
            props.ignore(&["sample_visible", "distribution"]);
            ctx.warn(
                el,
                format!("approximated as a Phong lobe (exponent {exponent:.1})"),
            );
            glossy(
                [0.0; 3],
                std::array::from_fn(|i| rho_s[i] * f0[i]),
                exponent,
            )
        }
        other => {
            ctx.unsupported(
                el,
                "type",
                &format!("BSDF type {} is not supported", quote(other)),
                "using Mitsuba's default diffuse (reflectance 0.5)",
            )?;
            ctx.leave();
            return Ok(diffuse([0.5; 3]));
        }
    };
    props.finish(ctx)?;
    ctx.leave();
    Ok(doc)
}

/// An index of refraction given as a number (named media are unsupported).
fn ior<'a>(
    ctx: &mut Ctx<'a>,
    props: &mut Props<'a>,
    name: &str,
    default: f64,
) -> Result<f64, XmlError> {
    let Some(el) = props.get(name)? else {
        return Ok(default);
    };
    if el.tag == "string" {
        ctx.unsupported(
            el,
            "value",
            "named media are not supported (give the index as a <float>)",
            &format!("using {default}"),
        )?;
        return Ok(default);
    }
    let v = super::props::number(el, "value")?;
    if v > 0.0 {
        Ok(v)
    } else {
        Err(el.error(
            "value",
            format!("{v} is not a positive index of refraction"),
        ))
    }
}

/// The Phong exponent for a rough (`alpha`) or smooth BSDF.
fn roughness<'a>(ctx: &mut Ctx<'a>, props: &mut Props<'a>, rough: bool) -> Result<f64, XmlError> {
    if !rough {
        return Ok(MAX_PHONG_EXPONENT);
    }
    let el = props.el;
    let alpha = match (
        props.opt_float("alpha")?,
        props.opt_float("alpha_u")?,
        props.opt_float("alpha_v")?,
    ) {
        (Some(a), None, None) => a,
        (None, None, None) => DEFAULT_ALPHA,
        (None, Some(u), Some(v)) => {
            if u != v {
                ctx.unsupported(
                    el,
                    "alpha_u",
                    "anisotropic roughness is not supported",
                    "using the geometric mean of alpha_u and alpha_v",
                )?;
            }
            (u * v).sqrt()
        }
        _ => {
            return Err(el.error(
                "alpha",
                "give either `alpha` or both `alpha_u` and `alpha_v`",
            ));
        }
    };
    if alpha <= 0.0 {
        return Err(el.error("alpha", format!("{alpha} is not a positive roughness")));
    }
    Ok(phong_exponent(alpha))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn phong_exponent_follows_walter_et_al() {
        assert_eq!(phong_exponent(1.0), 0.0);
        assert!((phong_exponent(0.1) - 198.0).abs() < 1e-9);
        assert_eq!(phong_exponent(1e-9), MAX_PHONG_EXPONENT);
        assert_eq!(phong_exponent(3.0), 0.0);
    }

    #[test]
    fn fresnel_at_normal_incidence() {
        assert!((dielectric_f0(1.5) - 0.04).abs() < 1e-12);
        assert_eq!(conductor_f0(1.0, 0.0), 0.0);
        assert!(conductor_f0(0.2, 3.0) > 0.9);
    }
}
