//! `cube`: the cube [-1, 1]³ in local coordinates, outward normals, as 12
//! triangles. No parameters of its own.

use std::borrow::Cow;

use super::{Input, Local, Plugin, ShapeFields};
use crate::scene::error::SceneError;
use crate::scene::mesh;

/// The cube plugin; see the module docs.
pub struct CubeShape;

impl Plugin for CubeShape {
    const FIXED_TRIANGLES: usize = 12;

    fn build<'a>(_: &ShapeFields<'a>, _: &Input<'a>) -> Result<Local<'a>, SceneError> {
        Ok(Local::Mesh {
            data: Cow::Owned(mesh::cube()),
            flip_tex_coords: false,
        })
    }
}
