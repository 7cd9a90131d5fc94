//! Mitsuba BSDFs → the scene model's materials. The scene model takes
//! Mitsuba's plugin and parameter names (`scene::material`), so a `<bsdf>`
//! of a supported plugin becomes a material document by copying its
//! properties (colours, numbers, strings, booleans and nested BSDFs, a
//! referenced one by its id); the scene loader validates them, and its errors point back at the property's
//! element. A plugin the scene model lacks is refused, or with `lenient`
//! becomes Mitsuba's default diffuse.

use serde_json::{Map, Value};

use crate::color::RgbArray;
use crate::color::spectrum::SpectrumUse;
use crate::scene::format::MaterialDoc;
use crate::scene::material::{Material, plugin_names};

use super::parse::{Element, quote};
use super::texture::{mean, parameter};
use super::{Ctx, XmlError};

/// The material a shape without a BSDF gets (Mitsuba: diffuse, 0.5).
const DEFAULT_MATERIAL_ID: &str = "default-diffuse@mitsuba";
/// The default material of a shape that emits (see [`default_material`]).
const DEFAULT_EMITTER_MATERIAL_ID: &str = "default-emitter@mitsuba";

/// Plugins of the scene model that are this project's own, not Mitsuba's.
const NOT_MITSUBA: &[&str] = &["glossy"];

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
    let field = format!("materials[{}]", ctx.materials.len());
    let (kind, params) = describe(ctx, el, &field)?;
    let id = match el.attr("id") {
        Some(id) => id.to_string(),
        // Anonymous BSDFs are named by position, which no two share.
        None => format!(
            "{}@{}:{}",
            el.attr("type").unwrap_or("bsdf"),
            el.line,
            el.column
        ),
    };
    ctx.material_of.insert(el.key(), id.clone());
    ctx.materials.push(MaterialDoc { id, kind, params });
    Ok(ctx.materials[ctx.materials.len() - 1].id.clone())
}

/// Mitsuba's default material for shapes without a BSDF: diffuse, ρ = 0.5,
/// or black for a shape that emits (Mitsuba 3's `Shape` gives emitters a
/// diffuse BSDF of reflectance 0, so lights do not reflect).
pub(crate) fn default_material(ctx: &mut Ctx, emits: bool) -> String {
    if emits {
        builtin_diffuse(ctx, DEFAULT_EMITTER_MATERIAL_ID, [0.0; 3])
    } else {
        builtin_diffuse(ctx, DEFAULT_MATERIAL_ID, [0.5; 3])
    }
}

/// A diffuse material the translation itself needs, added once under `id`.
pub(crate) fn builtin_diffuse(ctx: &mut Ctx, id: &str, reflectance: RgbArray) -> String {
    if !ctx.materials.iter().any(|m| m.id == id) {
        ctx.materials.push(MaterialDoc {
            id: id.to_string(),
            ..diffuse(reflectance)
        });
    }
    id.to_string()
}

fn diffuse(reflectance: RgbArray) -> MaterialDoc {
    let mut params = Map::new();
    params.insert("reflectance".into(), Value::from(reflectance.to_vec()));
    MaterialDoc {
        id: String::new(),
        kind: "diffuse".into(),
        params,
    }
}

/// The plugin name and parameters of BSDF element `el`, whose document
/// path is `field` (recorded as the origin of it and of each property).
fn describe<'a>(
    ctx: &mut Ctx<'a>,
    el: &'a Element,
    field: &str,
) -> Result<(String, Map<String, Value>), XmlError> {
    ctx.check_cancel(el)?;
    ctx.origin(field, el);
    let kind = el.attr("type").unwrap_or("");
    if !plugin_names().contains(&kind) || NOT_MITSUBA.contains(&kind) {
        ctx.unsupported(
            el,
            "type",
            &format!("BSDF type {} is not supported", quote(kind)),
            "using Mitsuba's default diffuse (reflectance 0.5)",
        )?;
        let doc = diffuse([0.5; 3]);
        return Ok((doc.kind, doc.params));
    }
    ctx.enter(el)?;
    let mut params = Map::new();
    // Mitsuba's diffuse defaults its reflectance; the JSON format requires it.
    if kind == "diffuse" {
        params.insert("reflectance".into(), Value::from(vec![0.5; 3]));
    }
    let mut nested = Vec::new();
    let mut elements = Vec::new();
    for child in &el.children {
        let target = ctx.deref(child)?;
        if target.tag == "bsdf" {
            let path = format!("{field}.bsdf[{}]", nested.len());
            if child.tag == "ref" {
                // A referenced BSDF becomes a material of its own, named
                // by its id wherever it is used: shared, not copied, so a
                // chain of references that doubles is not a document that
                // doubles.
                let id = material(ctx, target)?;
                ctx.origin(path, child);
                nested.push(Value::from(id));
            } else {
                let (kind, mut inner) = describe(ctx, target, &path)?;
                inner.insert("type".into(), Value::from(kind));
                nested.push(Value::Object(inner));
            }
            continue;
        }
        let Some(name) = child.attr("name") else {
            ctx.unsupported(
                child,
                "",
                &format!("{} does not support a nested <{}>", el.label(), child.tag),
                "ignoring it",
            )?;
            continue;
        };
        let value = match target.tag.as_str() {
            "rgb" | "spectrum" | "texture" => parameter(ctx, child, spectrum_use(name))?,
            "float" | "integer" => Value::from(super::props::number(target, "value")?),
            "string" => Value::from(target.attr("value").unwrap_or_default()),
            "boolean" => match target.attr("value").map(str::trim) {
                Some("true") => Value::Bool(true),
                Some("false") => Value::Bool(false),
                other => {
                    return Err(target.error(
                        "value",
                        format!("{} is not true or false", quote(other.unwrap_or_default())),
                    ));
                }
            },
            other => {
                return Err(target.error("", format!("<{other}> is not a BSDF property")));
            }
        };
        ctx.origin(format!("{field}.{name}"), child);
        params.insert(name.to_string(), value);
        elements.push((name, child));
    }
    if !nested.is_empty() {
        params.insert("bsdf".into(), Value::Array(nested));
    }
    for name in Material::constant_parameters_given_textures(kind, &params) {
        if let Some((_, child)) = elements.iter().find(|(n, _)| *n == name) {
            ctx.unsupported(
                child,
                "name",
                &format!(
                    "{} takes {} as a constant, not a texture",
                    el.label(),
                    quote(&name)
                ),
                "using the texture's mean",
            )?;
            let texture = ctx.deref(child)?;
            let mean = mean(ctx, texture)?;
            // A colour where the plugin takes one; else (a scalar such as
            // an index of refraction) the channels' mean, as a grey mean is.
            let rgb = Value::from(mean.to_vec());
            let coloured = mean[0] != mean[1] || mean[1] != mean[2];
            let value = match coloured && Material::accepts(kind, &params, &name, rgb.clone()) {
                true => rgb,
                false => Value::from((mean[0] + mean[1] + mean[2]) / 3.0),
            };
            params.insert(name, value);
        }
    }
    for name in Material::unknown_parameters(kind, &params) {
        if let Some((_, child)) = elements.iter().find(|(n, _)| *n == name) {
            ctx.unsupported(
                child,
                "name",
                &format!("{} has no supported property {}", el.label(), quote(&name)),
                "ignoring it",
            )?;
        }
        params.remove(&name);
    }
    ctx.leave();
    Ok((kind.to_string(), params))
}

/// What a BSDF's colour property describes, as Mitsuba's BSDFs read it: a
/// conductor's complex index of refraction (`eta`, `k`) has no upper
/// bound, every other colour is a reflectance or transmittance.
fn spectrum_use(name: &str) -> SpectrumUse {
    match name {
        "eta" | "k" => SpectrumUse::Unbounded,
        _ => SpectrumUse::Reflectance,
    }
}
