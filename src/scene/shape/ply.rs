//! `ply`: the triangles of a PLY file (ASCII or binary; `vertex` x/y/z,
//! nx/ny/nz and texture coordinates if every vertex has them; `face`
//! polygons fanned into triangles; front = counter-clockwise), in local
//! coordinates.
//!
//! Parameters: `filename` (relative to the scene file, required),
//! `flip_tex_coords` (replace each `v` by `1 − v`, default false),
//! `face_normals` (shade each triangle flat, default false).

use std::path::Path;

use super::{Input, Local, Plugin, ReadMesh, ShapeFields, file_mesh};
use crate::scene::budget::Budget;
use crate::scene::error::SceneError;
use crate::scene::mesh::MeshData;

/// The PLY plugin; see the module docs.
pub struct PlyShape;

/// A PLY file holds one mesh (`index` is 0).
fn read(
    path: &Path,
    _index: u32,
    field: &str,
    max_triangles: usize,
    budget: &Budget,
) -> Result<MeshData, SceneError> {
    crate::scene::ply::read_ply(path, field, max_triangles, budget)
}

impl Plugin for PlyShape {
    const FIELDS: &'static [&'static str] = &["filename", "face_normals", "flip_tex_coords"];
    const MESH_FILE: Option<ReadMesh> = Some(read);

    fn build<'a>(fields: &ShapeFields<'a>, input: &Input<'a>) -> Result<Local<'a>, SceneError> {
        file_mesh(fields, input, false)
    }
}
