//! `sphere`: an analytic sphere, outward normal.
//!
//! Parameters: `center` (local coordinates, default the origin), `radius`
//! (local units, default 1). Its `to_world` must be a similarity
//! (rotation, uniform scale, translation): the sphere is intersected
//! exactly, so an ellipsoid needs a mesh.

use super::{Geometry, Input, Local, Plugin};
use crate::scene::error::SceneError;
use crate::scene::format::ShapeDoc;
use crate::scene::transform;

/// The sphere plugin; see the module docs.
pub struct SphereShape;

impl Plugin for SphereShape {
    const FIELDS: &'static [&'static str] = &["center", "radius"];

    fn build<'a>(s: &'a ShapeDoc, input: &Input<'a>) -> Result<Local<'a>, SceneError> {
        let (to_world, field) = (input.to_world, input.field);
        let center =
            transform::check_vec3(&s.center.unwrap_or([0.0; 3]), &format!("{field}.center"))?;
        let radius = s.radius.unwrap_or(1.0);
        if !(radius > 0.0 && radius.is_finite()) {
            return Err(SceneError::invalid(
                format!("{field}.radius"),
                format!("{radius} is not a positive radius"),
            ));
        }
        let scale = transform::similarity_scale(&to_world.matrix3).ok_or_else(|| {
            SceneError::invalid(
                format!("{field}.to_world"),
                "a sphere's transform must be a similarity (rotation, uniform scale, translation); use a mesh for ellipsoids",
            )
        })?;
        let radius = radius * scale;
        let geometry = Geometry::Sphere {
            center: to_world.transform_point3(center),
            radius,
            to_local: (to_world.matrix3 / scale).transpose(),
        };
        Ok(Local::Analytic(
            geometry,
            4.0 * std::f64::consts::PI * radius * radius,
        ))
    }
}
