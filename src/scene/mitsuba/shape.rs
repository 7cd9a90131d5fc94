//! Mitsuba shapes → document shapes. The shape registry's Mitsuba plugins
//! map one to one, each property the plugin takes copied under its name
//! (the plugin's file reads and validates it, with Mitsuba's defaults); an
//! `instance` of a `shapegroup` adds the group's shapes with the
//! instance's `to_world` applied after their own.

use crate::color::spectrum::SpectrumUse;
use crate::scene::MAX_SHAPES;
use crate::scene::format::{EmitterDoc, EmitterKind, SensorDoc, ShapeDoc, ShapeKind, ShapeParam};

use super::parse::{Element, quote};
use super::props::{Props, boolean_value, number, vec3};
use super::texture::parameter;
use super::transform::Ops;
use super::{Ctx, XmlError, bsdf};

/// Adds the shape(s) of `<shape>` element `el`; `outer` is applied after the
/// shape's own `to_world` (an enclosing instance's transform).
pub(crate) fn add<'a>(ctx: &mut Ctx<'a>, el: &'a Element, outer: &Ops) -> Result<(), XmlError> {
    let kind = el.attr("type").unwrap_or("");
    let mut props = Props::new(el);
    let to_world = match props.get("to_world")? {
        Some(t) => Ops::read(t)?,
        None => Ops::default(),
    }
    .then(outer);
    // Mitsuba's shape plugins are the registry's of the same name.
    let registered = ShapeKind::named(kind).filter(|k| k.plugin().mitsuba);
    let kind = match (registered, kind) {
        (Some(kind), _) => kind,
        // Declares shapes for instances; adds nothing by itself.
        (None, "shapegroup") => return Ok(()),
        (None, "instance") => return instance(ctx, el, props, &to_world),
        (None, other) => {
            return ctx.unsupported(
                el,
                "type",
                &format!("shape type {} is not supported", quote(other)),
                "leaving the shape out",
            );
        }
    };
    if ctx.shapes.len() >= MAX_SHAPES {
        return Err(el.error("", format!("more than {MAX_SHAPES} shapes")));
    }
    let emitters = props.nested(ctx, "emitter")?;
    let sensors = props.nested(ctx, "sensor")?;
    let media = props.nested(ctx, "medium")?;
    ctx.media(&media)?;
    let material = match props.nested(ctx, "bsdf")?[..] {
        [] => bsdf::default_material(ctx, !emitters.is_empty()),
        [b] => bsdf::material(ctx, b)?,
        _ => return Err(el.error("bsdf", "a shape takes at most one BSDF")),
    };
    let mut doc = ShapeDoc::new(kind, material);
    doc.id = el.attr("id").map(str::to_string);
    doc.flip_normals = props.boolean("flip_normals", false)?;
    doc.emitter = match emitters[..] {
        [] => None,
        [e] => Some(area(ctx, e)?),
        _ => return Err(el.error("emitter", "a shape takes at most one emitter")),
    };
    doc.sensor = match sensors[..] {
        [] => None,
        [s] => meter(ctx, s)?,
        _ => return Err(el.error("sensor", "a shape takes at most one sensor")),
    };
    // The plugin's own parameters, copied under their names; whatever it
    // does not take is left for `finish` to report.
    for name in kind.plugin().fields {
        if let Some(child) = props.get(name)? {
            doc.params
                .insert(name.to_string(), param(ctx.deref(child)?)?);
        }
    }
    props.finish(ctx)?;
    let field = format!("shapes[{}]", ctx.shapes.len());
    ctx.origin(field.clone(), el);
    doc.to_world = to_world.into_doc(ctx, &format!("{field}.to_world"));
    ctx.shapes.push(doc);
    Ok(())
}

/// `<sensor type="irradiancemeter">` inside a shape: the shape's meter
/// (`scene::meter`). Its film (one pixel) and sampler change nothing in
/// the scene; other sensor types on a shape are not supported.
fn meter<'a>(ctx: &mut Ctx<'a>, el: &'a Element) -> Result<Option<SensorDoc>, XmlError> {
    match el.attr("type").unwrap_or("") {
        "irradiancemeter" => {
            let mut props = Props::new(el);
            props.ignore_tags(&["film", "sampler"]);
            props.finish(ctx)?;
            Ok(Some(SensorDoc::Irradiancemeter))
        }
        other => {
            ctx.unsupported(
                el,
                "type",
                &format!(
                    "sensor type {} on a shape is not supported (irradiancemeter)",
                    quote(other)
                ),
                "leaving the sensor out",
            )?;
            Ok(None)
        }
    }
}

/// A shape plugin's parameter from its Mitsuba property: numbers, booleans
/// and strings as they are, points and vectors as `[x, y, z]`.
fn param(el: &Element) -> Result<ShapeParam, XmlError> {
    Ok(match el.tag.as_str() {
        "float" | "integer" => ShapeParam::Number(number(el, "value")?),
        "boolean" => ShapeParam::Bool(boolean_value(el)?),
        "string" => ShapeParam::Text(
            el.attr("value")
                .ok_or_else(|| el.error("value", "missing attribute `value`"))?
                .to_string(),
        ),
        "point" | "vector" => ShapeParam::Numbers(vec3(el, 0.0)?.to_vec()),
        other => {
            return Err(el.error(
                "",
                format!(
                    "a shape's {} cannot be a <{other}>",
                    quote(el.attr("name").unwrap_or(""))
                ),
            ));
        }
    })
}

/// `<emitter type="area">` inside a shape.
fn area<'a>(ctx: &mut Ctx<'a>, el: &'a Element) -> Result<EmitterDoc, XmlError> {
    if el.attr("type") != Some("area") {
        return Err(el.error("type", "only `area` emitters can be attached to a shape"));
    }
    let mut props = Props::new(el);
    // A colour, or a texture over the shape (Mitsuba's textured area light).
    let radiance = match props.get("radiance")? {
        Some(child) => parameter(ctx, child, SpectrumUse::Emission)?,
        None => serde_json::Value::from(vec![1.0; 3]),
    };
    props.finish(ctx)?;
    Ok(EmitterDoc {
        kind: EmitterKind::Area,
        radiance,
    })
}

/// `<shape type="instance">`: the referenced shapegroup's shapes, each with
/// its own `to_world` followed by the instance's.
fn instance<'a>(
    ctx: &mut Ctx<'a>,
    el: &'a Element,
    mut props: Props<'a>,
    to_world: &Ops,
) -> Result<(), XmlError> {
    let groups = props.nested(ctx, "shape")?;
    let [group] = groups[..] else {
        return Err(el.error("", "an instance needs exactly one <ref> to a shapegroup"));
    };
    if group.attr("type") != Some("shapegroup") {
        return Err(el.error("", format!("{} is not a shapegroup", group.label())));
    }
    props.finish(ctx)?;
    ctx.enter(group)?;
    for child in &group.children {
        if child.tag != "shape" || child.attr("type") == Some("shapegroup") {
            return Err(child.error("", "a shapegroup may only hold shapes"));
        }
        add(ctx, child, to_world)?;
    }
    ctx.leave();
    Ok(())
}
