//! `rectangle`: the square [-1, 1]² in the local xy plane, front normal
//! +z, as two triangles. No parameters of its own.

use std::borrow::Cow;

use super::{Input, Local, Plugin, ShapeFields};
use crate::scene::error::SceneError;
use crate::scene::mesh;

/// The rectangle plugin; see the module docs.
pub struct RectangleShape;

impl Plugin for RectangleShape {
    const FIXED_TRIANGLES: usize = 2;

    fn build<'a>(_: &ShapeFields<'a>, _: &Input<'a>) -> Result<Local<'a>, SceneError> {
        Ok(Local::Mesh {
            data: Cow::Owned(mesh::rectangle()),
            flip_tex_coords: false,
        })
    }
}
