//! Top-level Mitsuba emitters: `envmap` and `constant` become the scene's
//! environment; the light plugins of the scene model (`scene::emitter`:
//! `point`, `spot`, `directional`) its delta lights, their properties
//! copied. Area emitters live on shapes (`shape.rs`).

use glam::DVec3;
use serde_json::{Map, Value};

use crate::color::spectrum::SpectrumUse;
use crate::scene::emitter::{Emitter, light_names};
use crate::scene::format::{EnvironmentDoc, EnvironmentKind};
use crate::scene::transform;

use super::parse::{Element, quote};
use super::props::{Props, number, vec3};
use super::texture::{color, value};
use super::transform::Ops;
use super::{Ctx, XmlError};

pub(crate) fn add<'a>(ctx: &mut Ctx<'a>, el: &'a Element) -> Result<(), XmlError> {
    let kind = el.attr("type").unwrap_or("");
    let mut props = Props::new(el);
    let environment = match kind {
        "constant" => EnvironmentDoc {
            kind: EnvironmentKind::Constant,
            radiance: Some(color(
                ctx,
                &mut props,
                "radiance",
                [1.0; 3],
                SpectrumUse::Emission,
            )?),
            filename: None,
            scale: None,
            to_world: None,
        },
        "envmap" => {
            let filename = props
                .string("filename")?
                .ok_or_else(|| el.error("filename", "missing property `filename`"))?;
            let scale = props.opt_float("scale")?;
            let to_world = match props.get("to_world")? {
                Some(t) => Ops::read(t)?,
                None => Ops::default(),
            };
            props.ignore(&["filter_type", "mis_compensation"]);
            EnvironmentDoc {
                kind: EnvironmentKind::Envmap,
                radiance: None,
                filename: Some(filename.to_string()),
                scale,
                to_world: to_world.into_doc(ctx, "environment.to_world"),
            }
        }
        kind if light_names().contains(&kind) => return light(ctx, el, kind, props),
        "area" => {
            return Err(el.error(
                "type",
                "an area emitter must be nested inside the <shape> it lights",
            ));
        }
        other => {
            return ctx.unsupported(
                el,
                "type",
                &format!("emitter type {} is not supported", quote(other)),
                "leaving the emitter out",
            );
        }
    };
    props.finish(ctx)?;
    if ctx.environment.is_some() {
        return ctx.unsupported(
            el,
            "",
            "the scene model has one environment; this is a second one",
            "keeping the first",
        );
    }
    ctx.origin("environment", el);
    ctx.environment = Some(environment);
    Ok(())
}

/// `to_world` of a light: its translation (the position) and where it
/// sends +z (the axis), or `None` without one.
fn placement(t: Option<&Element>) -> Result<Option<(DVec3, DVec3)>, XmlError> {
    let Some(t) = t else {
        return Ok(None);
    };
    let Some(doc) = Ops::read(t)?.doc() else {
        return Ok(Some((DVec3::ZERO, DVec3::Z)));
    };
    let affine = transform::build(&doc, "to_world").map_err(|e| t.error("", e.to_string()))?;
    Ok(Some((
        affine.translation,
        affine.transform_vector3(DVec3::Z),
    )))
}

/// Properties that place a light: where the plugin does not take them
/// (a point light's `direction`, a directional light's `position`), they
/// are dropped without a word, as `to_world` gives every light both.
const PLACEMENT: [&str; 2] = ["position", "direction"];

/// A light plugin of the scene model becomes one of the scene's `lights`
/// by copying its properties under their (Mitsuba's) names: points and
/// vectors as `[x, y, z]`, colours as `[r, g, b]` (a number too where the
/// plugin takes a colour), other numbers as they are; `to_world` gives it
/// a `position` (its translation) and a `direction` (where it sends +z).
/// The plugin's own parser validates them; properties it does not take
/// are reported as unsupported.
fn light<'a>(
    ctx: &mut Ctx<'a>,
    el: &'a Element,
    kind: &str,
    mut props: Props<'a>,
) -> Result<(), XmlError> {
    let field = format!("lights[{}]", ctx.lights.len());
    ctx.origin(field.clone(), el);
    let placed = placement(props.get("to_world")?)?;
    let mut doc = Map::new();
    let mut copied = Vec::new();
    for child in &el.children {
        let Some(name) = child.attr("name").filter(|n| *n != "to_world") else {
            continue;
        };
        let target = ctx.deref(child)?;
        let value = match target.tag.as_str() {
            "point" | "vector" => Value::from(vec3(target, 0.0)?.to_vec()),
            "float" | "integer" if !Emitter::takes_colour(kind, name) => {
                Value::from(number(target, "value")?)
            }
            _ => Value::from(value(ctx, child, SpectrumUse::Emission)?.to_vec()),
        };
        doc.insert(name.to_string(), value);
        copied.push((name, child));
    }
    if placed.is_some() && PLACEMENT.iter().any(|n| doc.contains_key(*n)) {
        return Err(el.error(
            "to_world",
            "give `to_world`, or `position`/`direction`, not both",
        ));
    }
    if let Some((p, d)) = placed {
        doc.insert("position".into(), Value::from(p.to_array().to_vec()));
        doc.insert("direction".into(), Value::from(d.to_array().to_vec()));
    }
    for name in Emitter::unknown_parameters(kind, &doc) {
        doc.remove(&name);
        if PLACEMENT.contains(&name.as_str()) {
            props.get(&name)?;
        }
    }
    for (name, child) in copied {
        if doc.contains_key(name) {
            props.get(name)?;
            ctx.origin(format!("{field}.{name}"), child);
        }
    }
    props.finish(ctx)?;
    doc.insert("type".into(), Value::from(kind));
    ctx.lights.push(doc);
    Ok(())
}
