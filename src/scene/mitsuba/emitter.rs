//! Top-level Mitsuba emitters: `envmap` and `constant` become the scene's
//! environment; `point` (the scene model has no point lights) becomes a
//! small black sphere emitting uniformly with the same radiant intensity.
//! Area emitters live on shapes (`shape.rs`).

use crate::scene::format::{EmitterDoc, EmitterKind, EnvironmentDoc, EnvironmentKind, ShapeKind};
use crate::scene::transform;

use super::parse::{Element, quote};
use super::props::Props;
use super::shape::shape_doc;
use super::texture::color;
use super::transform::Ops;
use super::{Ctx, XmlError};

/// Material of the spheres standing in for point lights (they reflect
/// nothing, like a point).
const POINT_MATERIAL_ID: &str = "point-light@mitsuba";

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
        "point" => return point(ctx, el, props),
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

/// A point light of intensity `I` (W/sr) at `p` → a sphere of radius `r`
/// at `p` with radiance `L = I / (π r²)`, which has the same intensity
/// `L · π r²` (projected area) in every direction.
fn point<'a>(ctx: &mut Ctx<'a>, el: &'a Element, mut props: Props<'a>) -> Result<(), XmlError> {
    let intensity = color(ctx, &mut props, "intensity", [1.0; 3])?;
    let position = match (props.point("position")?, props.get("to_world")?) {
        (Some(p), None) => p,
        (None, Some(t)) => match Ops::read(t)?.doc() {
            Some(doc) => transform::build(&doc, "to_world")
                .map_err(|e| t.error("", e.to_string()))?
                .translation
                .to_array(),
            None => [0.0; 3],
        },
        (None, None) => [0.0; 3],
        (Some(_), Some(_)) => {
            return Err(el.error("position", "give `position` or `to_world`, not both"));
        }
    };
    props.finish(ctx)?;
    let r = ctx.point_light_radius;
    if !(r > 0.0 && r.is_finite()) {
        return Err(el.error("", format!("point light radius {r} must be positive")));
    }
    ctx.warn(
        el,
        format!("point light approximated by an emitting sphere of radius {r}"),
    );
    let material = super::bsdf::builtin_diffuse(ctx, POINT_MATERIAL_ID, [0.0; 3]);
    let mut doc = shape_doc(ShapeKind::Sphere, material);
    doc.center = Some(position);
    doc.radius = Some(r);
    let area = std::f64::consts::PI * r * r;
    doc.emitter = Some(EmitterDoc {
        kind: EmitterKind::Area,
        radiance: intensity.map(|i| i / area),
    });
    ctx.origin(format!("shapes[{}]", ctx.shapes.len()), el);
    ctx.shapes.push(doc);
    Ok(())
}
