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

use glam::DVec2;

use super::{Input, Local, Plugin};
use crate::scene::error::SceneError;
use crate::scene::format::ShapeDoc;
use crate::scene::mesh::MeshData;
use crate::scene::transform;

/// The inline triangle list plugin; see the module docs.
pub struct TrianglesShape;

impl Plugin for TrianglesShape {
    const FIELDS: &'static [&'static str] =
        &["positions", "indices", "normals", "uvs", "flip_tex_coords"];
    // Mitsuba has no inline triangle lists.
    const MITSUBA: bool = false;

    fn inline_triangles(doc: &ShapeDoc) -> usize {
        doc.indices.as_ref().map_or(0, Vec::len)
    }

    fn build<'a>(s: &'a ShapeDoc, input: &Input<'a>) -> Result<Local<'a>, SceneError> {
        let data = inline_mesh(s, input.field, input.max_triangles)?;
        Ok(Local::Mesh {
            data: Cow::Owned(data),
            flip_tex_coords: s.flip_tex_coords.unwrap_or(false),
        })
    }
}

/// The mesh the document lists, each field checked.
fn inline_mesh(s: &ShapeDoc, field: &str, max_triangles: usize) -> Result<MeshData, SceneError> {
    let missing = |name: &str| SceneError::invalid(field, format!("missing field `{name}`"));
    let positions = s.positions.as_ref().ok_or_else(|| missing("positions"))?;
    let indices = s.indices.as_ref().ok_or_else(|| missing("indices"))?;
    if indices.is_empty() || indices.len() > max_triangles {
        return Err(SceneError::invalid(
            format!("{field}.indices"),
            format!("{} triangles; need 1..={max_triangles}", indices.len()),
        ));
    }
    let positions = positions
        .iter()
        .enumerate()
        .map(|(i, p)| transform::check_vec3(p, &format!("{field}.positions[{i}]")))
        .collect::<Result<Vec<_>, _>>()?;
    let mut out = Vec::with_capacity(indices.len());
    for (k, tri) in indices.iter().enumerate() {
        for (j, &i) in tri.iter().enumerate() {
            if i as usize >= positions.len() {
                return Err(SceneError::invalid(
                    format!("{field}.indices[{k}][{j}]"),
                    format!("vertex {i} does not exist ({} positions)", positions.len()),
                ));
            }
        }
        out.push(tri.map(|i| i as u32));
    }
    let normals = match &s.normals {
        None => None,
        Some(ns) => {
            if ns.len() != positions.len() {
                return Err(SceneError::invalid(
                    format!("{field}.normals"),
                    format!("{} normals for {} positions", ns.len(), positions.len()),
                ));
            }
            let mut out = Vec::with_capacity(ns.len());
            for (i, n) in ns.iter().enumerate() {
                let f = format!("{field}.normals[{i}]");
                let n = transform::check_vec3(n, &f)?
                    .try_normalize()
                    .ok_or_else(|| SceneError::invalid(f, "zero-length normal"))?;
                out.push(n);
            }
            Some(out)
        }
    };
    let uvs = match &s.uvs {
        None => None,
        Some(uvs) => {
            let f = format!("{field}.uvs");
            if uvs.len() != positions.len() {
                return Err(SceneError::invalid(
                    f,
                    format!("{} uvs for {} positions", uvs.len(), positions.len()),
                ));
            }
            if let Some(i) = uvs.iter().position(|uv| !uv.iter().all(|x| x.is_finite())) {
                return Err(SceneError::invalid(format!("{f}[{i}]"), "not finite"));
            }
            Some(uvs.iter().map(|&uv| DVec2::from(uv)).collect())
        }
    };
    Ok(MeshData {
        positions,
        indices: out,
        normals,
        uvs,
    })
}
