//! Top-level Mitsuba emitters: `envmap` and `constant` become the scene's
//! environment; `point`, `spot` and `directional` its delta lights. Area
//! emitters live on shapes (`shape.rs`).

use glam::DVec3;
use serde_json::{Map, Value};

use crate::scene::format::{EnvironmentDoc, EnvironmentKind};
use crate::scene::transform;

use super::parse::{Element, quote};
use super::props::Props;
use super::texture::{color, value};
use super::transform::Ops;
use super::{Ctx, XmlError};

pub(crate) fn add<'a>(ctx: &mut Ctx<'a>, el: &'a Element) -> Result<(), XmlError> {
    let kind = el.attr("type").unwrap_or("");
    let mut props = Props::new(el);
    let environment = match kind {
        "constant" => EnvironmentDoc {
            kind: EnvironmentKind::Constant,
            radiance: Some(color(ctx, &mut props, "radiance", [1.0; 3])?),
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
        "point" | "spot" | "directional" => return light(ctx, el, kind, props),
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

/// `point`, `spot` and `directional` become the scene's `lights`, with
/// Mitsuba's parameter names; `to_world` gives a point or spot light its
/// position and a spot or directional light its axis.
fn light<'a>(
    ctx: &mut Ctx<'a>,
    el: &'a Element,
    kind: &str,
    mut props: Props<'a>,
) -> Result<(), XmlError> {
    let mut doc = Map::new();
    doc.insert("type".into(), Value::from(kind));
    let field = format!("lights[{}]", ctx.lights.len());
    ctx.origin(field.clone(), el);
    let (position, direction) = (props.point("position")?, props.point("direction")?);
    let placed = placement(props.get("to_world")?)?;
    if placed.is_some() && (position.is_some() || direction.is_some()) {
        return Err(el.error(
            "to_world",
            "give `to_world`, or `position`/`direction`, not both",
        ));
    }
    let (position, direction) = match placed {
        Some((p, d)) => (Some(p.to_array()), Some(d.to_array())),
        None => (position, direction),
    };
    if let (Some(p), false) = (position, kind == "directional") {
        doc.insert("position".into(), Value::from(p.to_vec()));
    }
    if let (Some(d), false) = (direction, kind == "point") {
        doc.insert("direction".into(), Value::from(d.to_vec()));
    }
    let emitted = if kind == "directional" {
        "irradiance"
    } else {
        "intensity"
    };
    if let Some(c) = props.get(emitted)? {
        doc.insert(emitted.into(), Value::from(value(ctx, c)?.to_vec()));
        ctx.origin(format!("{field}.{emitted}"), c);
    }
    if kind == "spot" {
        for name in ["cutoff_angle", "beam_width"] {
            if let Some(x) = props.opt_float(name)? {
                doc.insert(name.into(), Value::from(x));
            }
        }
    }
    props.finish(ctx)?;
    ctx.lights.push(doc);
    Ok(())
}
