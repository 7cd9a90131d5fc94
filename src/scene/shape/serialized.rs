//! `serialized`: mesh `shape_index` of a Mitsuba `serialized` file
//! (zlib-compressed indexed triangles, single or double precision, with
//! normals and texture coordinates if stored; versions 3 and 4), in local
//! coordinates.
//!
//! Parameters: `filename` (relative to the scene file, required),
//! `shape_index` (which mesh of the file, default 0, the first),
//! `face_normals` (shade each triangle flat, default false),
//! `flip_tex_coords` (replace each `v` by `1 − v`, default false).

use super::{Input, Local, Plugin, ReadMesh, ShapeFields, file_mesh};
use crate::scene::error::SceneError;
use crate::scene::serialized::read_serialized;

/// The serialized plugin; see the module docs.
pub struct SerializedShape;

impl Plugin for SerializedShape {
    const FIELDS: &'static [&'static str] =
        &["filename", "face_normals", "flip_tex_coords", "shape_index"];
    const MESH_FILE: Option<ReadMesh> = Some(read_serialized);

    fn mesh_index(fields: &ShapeFields) -> Result<u32, SceneError> {
        let index = fields.index("shape_index", u32::MAX.into())?;
        Ok(index.unwrap_or(0) as u32)
    }

    fn build<'a>(fields: &ShapeFields<'a>, input: &Input<'a>) -> Result<Local<'a>, SceneError> {
        file_mesh(fields, input, false)
    }
}
