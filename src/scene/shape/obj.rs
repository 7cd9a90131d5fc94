//! `obj`: the triangles of a Wavefront OBJ file (all objects, polygons
//! triangulated; front = counter-clockwise), in local coordinates.
//!
//! Parameters: `filename` (relative to the scene file, required),
//! `flip_tex_coords` (replace each texture coordinate `v` by `1 − v`;
//! default true, as OBJ files put `v = 0` at an image's bottom; Mitsuba
//! 3's), `face_normals` (where the file gives no vertex normals, shade
//! with each triangle's own normal instead of smooth vertex normals;
//! default false).

use std::path::Path;

use super::{Input, Local, Plugin, ReadMesh, ShapeFields, file_mesh};
use crate::scene::budget::Budget;
use crate::scene::error::SceneError;
use crate::scene::mesh::{self, MeshData};

/// The OBJ plugin; see the module docs.
pub struct ObjShape;

/// An OBJ file holds one mesh (`index` is 0) and is small enough to be
/// reserved from the budget once read.
fn read(
    path: &Path,
    _index: u32,
    field: &str,
    max_triangles: usize,
    _: &Budget,
) -> Result<MeshData, SceneError> {
    mesh::load_obj(path, field, max_triangles)
}

impl Plugin for ObjShape {
    const FIELDS: &'static [&'static str] = &["filename", "face_normals", "flip_tex_coords"];
    const MESH_FILE: Option<ReadMesh> = Some(read);

    fn build<'a>(fields: &ShapeFields<'a>, input: &Input<'a>) -> Result<Local<'a>, SceneError> {
        file_mesh(fields, input, true)
    }
}
