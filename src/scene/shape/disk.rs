//! `disk`: the analytic unit disk in the local xy plane, front normal +z.
//! No parameters of its own; any affine `to_world` (the disk becomes an
//! ellipse, still planar, its area scaled by a constant).

use glam::DVec3;

use super::{Geometry, Input, Local, Plugin, disk_area};
use crate::scene::error::SceneError;
use crate::scene::format::ShapeDoc;
use crate::scene::transform;

/// The disk plugin; see the module docs.
pub struct DiskShape;

impl Plugin for DiskShape {
    fn build<'a>(_: &'a ShapeDoc, input: &Input<'a>) -> Result<Local<'a>, SceneError> {
        let to_world = *input.to_world;
        let normal = (transform::normal_matrix(&to_world) * DVec3::Z).normalize();
        let geometry = Geometry::Disk {
            to_world,
            to_local: to_world.inverse(),
            normal,
        };
        Ok(Local::Analytic(geometry, disk_area(&to_world)))
    }
}
