//! `triangles`: an inline triangle list in local coordinates; front =
//! counter-clockwise. Not a Mitsuba plugin (XML scenes give meshes in
//! files).
//!
//! Parameters: `positions` (`[[x, y, z], …]`, local coordinates,
//! required), `indices` (`[[i, j, k], …]`, 0-based into `positions`,
//! counter-clockwise seen from the front, required), `normals` (optional
//! per-vertex shading normals, local frame, one per position; without
//! them the triangles are flat), `uvs` (optional per-vertex texture
//! coordinates `[u, v]`, one per position), `flip_tex_coords` (replace
//! each `v` by `1 − v`, default false).

use std::borrow::Cow;

use glam::{DVec2, DVec3};

use super::{Input, Local, Plugin, ShapeFields};
use crate::scene::error::SceneError;
use crate::scene::mesh::MeshData;
use crate::scene::transform;

/// The inline triangle list plugin; see the module docs.
pub struct TrianglesShape;

impl Plugin for TrianglesShape {
    const FIELDS: &'static [&'static str] =
        &["positions", "indices", "normals", "uvs", "flip_tex_coords"];
    // Mitsuba has no inline triangle lists.
    const MITSUBA: bool = false;

    fn inline_triangles(fields: &ShapeFields) -> Result<usize, SceneError> {
        Ok(fields.rows("indices", 3)?.map_or(0, |i| i.len() / 3))
    }

    fn build<'a>(fields: &ShapeFields<'a>, input: &Input<'a>) -> Result<Local<'a>, SceneError> {
        let data = inline_mesh(fields, input.max_triangles)?;
        Ok(Local::Mesh {
            data: Cow::Owned(data),
            flip_tex_coords: fields.boolean("flip_tex_coords")?.unwrap_or(false),
        })
    }
}

/// The mesh the document lists, each field checked.
fn inline_mesh(f: &ShapeFields, max_triangles: usize) -> Result<MeshData, SceneError> {
    let positions = f.rows("positions", 3)?.ok_or_else(|| f.missing("positions"))?;
    let indices = f.rows("indices", 3)?.ok_or_else(|| f.missing("indices"))?;
    let triangles = indices.len() / 3;
    if triangles == 0 || triangles > max_triangles {
        return Err(SceneError::invalid(
            f.path("indices"),
            format!("{triangles} triangles; need 1..={max_triangles}"),
        ));
    }
    let positions = rows3(positions, &f.path("positions"))?;
    let mut out = Vec::with_capacity(triangles);
    for (k, tri) in indices.chunks_exact(3).enumerate() {
        let mut vertices = [0u32; 3];
        for (j, &i) in tri.iter().enumerate() {
            if !(i >= 0.0 && i.fract() == 0.0 && i < positions.len() as f64) {
                return Err(SceneError::invalid(
                    format!("{}.indices[{k}][{j}]", f.field),
                    format!("vertex {i} does not exist ({} positions)", positions.len()),
                ));
            }
            vertices[j] = i as u32;
        }
        out.push(vertices);
    }
    let normals = match per_vertex(f, "normals", 3, positions.len())? {
        None => None,
        Some(ns) => {
            let field = f.path("normals");
            let mut out = Vec::with_capacity(positions.len());
            for (i, n) in rows3(ns, &field)?.into_iter().enumerate() {
                let n = n.try_normalize().ok_or_else(|| {
                    SceneError::invalid(format!("{field}[{i}]"), "zero-length normal")
                })?;
                out.push(n);
            }
            Some(out)
        }
    };
    let uvs = match per_vertex(f, "uvs", 2, positions.len())? {
        None => None,
        Some(uvs) => {
            if let Some(i) = uvs.iter().position(|x| !x.is_finite()) {
                let field = format!("{}[{}]", f.path("uvs"), i / 2);
                return Err(SceneError::invalid(field, "not finite"));
            }
            Some(uvs.chunks_exact(2).map(|uv| DVec2::new(uv[0], uv[1])).collect())
        }
    };
    Ok(MeshData {
        positions,
        indices: out,
        normals,
        uvs,
    })
}

/// Optional list `name` of one row of `arity` numbers per vertex, refused
/// (naming it) when its length is not the `vertices`'.
fn per_vertex<'a>(
    f: &ShapeFields<'a>,
    name: &str,
    arity: usize,
    vertices: usize,
) -> Result<Option<&'a [f64]>, SceneError> {
    let rows = f.rows(name, arity)?;
    match rows {
        Some(r) if r.len() != arity * vertices => Err(SceneError::invalid(
            f.path(name),
            format!("{} {name} for {vertices} positions", r.len() / arity),
        )),
        _ => Ok(rows),
    }
}

/// Rows of three finite numbers as vectors; `field` names the list.
fn rows3(values: &[f64], field: &str) -> Result<Vec<DVec3>, SceneError> {
    values
        .chunks_exact(3)
        .enumerate()
        .map(|(i, p)| transform::check_vec3(&[p[0], p[1], p[2]], &format!("{field}[{i}]")))
        .collect()
}
