//! Mitsuba shapes → document shapes. `rectangle`, `cube`, `sphere`, `disk`
//! and `obj` map one to one (same local geometry); `ply` meshes (ASCII and
//! binary, via `ply-rs-bw`) become inline triangle lists, with smooth
//! vertex normals where the file has none unless `face_normals` is set
//! (Mitsuba's default; `MeshData::with_smooth_normals`); an `instance` of a `shapegroup` adds the group's shapes
//! with the instance's `to_world` applied after their own.

use std::io::BufReader;
use std::path::Path;
use std::sync::Arc;

use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{DefaultElement, Property};

use crate::scene::format::{EmitterDoc, EmitterKind, ShapeDoc, ShapeKind};
use crate::scene::mesh::MeshData;
use crate::scene::{MAX_SCENE_MEMORY_BYTES, MAX_SHAPES, MAX_TRIANGLES, SceneError, TRIANGLE_BYTES};

use super::parse::{Element, quote};
use super::props::Props;
use super::texture::color;
use super::transform::Ops;
use super::{Ctx, XmlError, bsdf};

/// Largest accepted PLY file.
const MAX_PLY_BYTES: u64 = 1 << 30;

/// A document shape with only the required fields set.
pub(crate) fn shape_doc(kind: ShapeKind, material: String) -> ShapeDoc {
    ShapeDoc {
        uvs: None,
        flip_tex_coords: None,
        face_normals: None,
        kind,
        id: None,
        material,
        to_world: None,
        emitter: None,
        flip_normals: false,
        center: None,
        radius: None,
        filename: None,
        positions: None,
        indices: None,
        normals: None,
    }
}

/// Adds the shape(s) of `<shape>` element `el`; `outer` is applied after the
/// shape's own `to_world` (an enclosing instance's transform).
pub(crate) fn add<'a>(ctx: &mut Ctx<'a>, el: &'a Element, outer: &Ops) -> Result<(), XmlError> {
    let kind = el.attr("type").unwrap_or("");
    let mut props = Props::new(el);
    let to_world = match props.get("to_world")? {
        Some(t) => Ops::read(t)?,
        None => Ops::default(),
    }
    .then(outer);
    let kind = match kind {
        "rectangle" => ShapeKind::Rectangle,
        "cube" => ShapeKind::Cube,
        "sphere" => ShapeKind::Sphere,
        "disk" => ShapeKind::Disk,
        "obj" | "ply" => ShapeKind::Triangles,
        // Declares shapes for instances; adds nothing by itself.
        "shapegroup" => return Ok(()),
        "instance" => return instance(ctx, el, props, &to_world),
        other => {
            return ctx.unsupported(
                el,
                "type",
                &format!("shape type {} is not supported", quote(other)),
                "leaving the shape out",
            );
        }
    };
    if ctx.shapes.len() >= MAX_SHAPES {
        return Err(el.error("", format!("more than {MAX_SHAPES} shapes")));
    }
    let material = match props.nested(ctx, "bsdf")?[..] {
        [] => bsdf::default_material(ctx),
        [b] => bsdf::material(ctx, b)?,
        _ => return Err(el.error("bsdf", "a shape takes at most one BSDF")),
    };
    let mut doc = shape_doc(kind, material);
    doc.id = el.attr("id").map(str::to_string);
    doc.flip_normals = props.boolean("flip_normals", false)?;
    doc.emitter = match props.nested(ctx, "emitter")?[..] {
        [] => None,
        [e] => Some(area(ctx, e)?),
        _ => return Err(el.error("emitter", "a shape takes at most one emitter")),
    };
    match el.attr("type") {
        Some("sphere") => {
            doc.center = props.point("center")?;
            doc.radius = props.opt_float("radius")?;
        }
        Some("obj") => {
            // Resolved by the shared loader, exactly as a JSON `obj`.
            doc.kind = ShapeKind::Obj;
            doc.filename = Some(filename(&mut props)?.to_string());
            doc.face_normals = Some(props.boolean("face_normals", false)?);
            doc.flip_tex_coords = Some(props.boolean("flip_tex_coords", true)?);
        }
        Some("ply") => {
            let name = filename(&mut props)?;
            let face_normals = props.boolean("face_normals", false)?;
            doc.flip_tex_coords = Some(props.boolean("flip_tex_coords", false)?);
            let path = ctx.resolve(el, "filename", name)?;
            let data = mesh_file(ctx, &path, MeshFormat::Ply, |budget| {
                read_ply(&path, budget).map_err(|m| SceneError::file("filename", &path, m))
            })
            .map_err(|e| source_error(el, e))?;
            if face_normals || data.normals.is_some() {
                set_triangles(&mut doc, &data, !face_normals);
            } else {
                set_triangles(
                    &mut doc,
                    &MeshData::clone(&data).with_smooth_normals(),
                    true,
                );
            }
        }
        _ => {}
    }
    props.finish(ctx)?;
    let field = format!("shapes[{}]", ctx.shapes.len());
    ctx.origin(field.clone(), el);
    doc.to_world = to_world.into_doc(ctx, &format!("{field}.to_world"));
    ctx.shapes.push(doc);
    Ok(())
}

fn filename<'a>(props: &mut Props<'a>) -> Result<&'a str, XmlError> {
    props
        .string("filename")?
        .ok_or_else(|| props.el.error("filename", "missing property `filename`"))
}

fn source_error(el: &Element, e: SceneError) -> XmlError {
    XmlError {
        source: Some(Box::new(e)),
        ..el.error("filename", "")
    }
}

/// Triangles still allowed in the scene (inline meshes counted so far):
/// within [`MAX_TRIANGLES`] and [`MAX_SCENE_MEMORY_BYTES`], so that a file
/// read here is refused before its triangles are copied into the document.
fn triangle_budget(ctx: &Ctx) -> usize {
    let used: usize = ctx
        .shapes
        .iter()
        .filter_map(|s| s.indices.as_ref().map(Vec::len))
        .sum();
    let by_memory = usize::try_from(MAX_SCENE_MEMORY_BYTES / TRIANGLE_BYTES).unwrap_or(usize::MAX);
    MAX_TRIANGLES.min(by_memory).saturating_sub(used)
}

/// How a mesh file is read (one file could be named as several).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum MeshFormat {
    Ply,
}

/// The mesh in the canonical `path`, read with `read` (given the triangle
/// budget) the first time the document names it and shared afterwards;
/// every use still counts its triangles against the scene's budget.
pub(crate) fn mesh_file(
    ctx: &mut Ctx,
    path: &Path,
    format: MeshFormat,
    read: impl FnOnce(usize) -> Result<MeshData, SceneError>,
) -> Result<Arc<MeshData>, SceneError> {
    let budget = triangle_budget(ctx);
    let key = (path.to_path_buf(), format);
    let data = match ctx.mesh_files.get(&key) {
        Some(data) => data.clone(),
        None => {
            let data = Arc::new(read(budget)?);
            ctx.mesh_files.insert(key, data.clone());
            data
        }
    };
    if data.indices.len() > budget {
        return Err(SceneError::file(
            "filename",
            path,
            format!(
                "{} more triangles exceed the scene's remaining budget of {budget}",
                data.indices.len()
            ),
        ));
    }
    Ok(data)
}

fn set_triangles(doc: &mut ShapeDoc, data: &MeshData, keep_normals: bool) {
    doc.positions = Some(data.positions.iter().map(|p| p.to_array()).collect());
    doc.indices = Some(data.indices.iter().map(|t| t.map(u64::from)).collect());
    doc.normals = data
        .normals
        .as_ref()
        .filter(|_| keep_normals)
        .map(|ns| ns.iter().map(|n| n.to_array()).collect());
    doc.uvs = data
        .uvs
        .as_ref()
        .map(|uvs| uvs.iter().map(|uv| uv.to_array()).collect());
}

/// `<emitter type="area">` inside a shape.
fn area<'a>(ctx: &mut Ctx<'a>, el: &'a Element) -> Result<EmitterDoc, XmlError> {
    if el.attr("type") != Some("area") {
        return Err(el.error("type", "only `area` emitters can be attached to a shape"));
    }
    let mut props = Props::new(el);
    let radiance = color(ctx, &mut props, "radiance", [1.0; 3])?;
    props.finish(ctx)?;
    Ok(EmitterDoc {
        kind: EmitterKind::Area,
        radiance,
    })
}

/// `<shape type="instance">`: the referenced shapegroup's shapes, each with
/// its own `to_world` followed by the instance's.
fn instance<'a>(
    ctx: &mut Ctx<'a>,
    el: &'a Element,
    mut props: Props<'a>,
    to_world: &Ops,
) -> Result<(), XmlError> {
    let groups = props.nested(ctx, "shape")?;
    let [group] = groups[..] else {
        return Err(el.error("", "an instance needs exactly one <ref> to a shapegroup"));
    };
    if group.attr("type") != Some("shapegroup") {
        return Err(el.error("", format!("{} is not a shapegroup", group.label())));
    }
    props.finish(ctx)?;
    ctx.enter(group)?;
    for child in &group.children {
        if child.tag != "shape" || child.attr("type") == Some("shapegroup") {
            return Err(child.error("", "a shapegroup may only hold shapes"));
        }
        add(ctx, child, to_world)?;
    }
    ctx.leave();
    Ok(())
}

fn scalar(p: &Property) -> Option<f64> {
    Some(match *p {
        Property::Char(v) => v.into(),
        Property::UChar(v) => v.into(),
        Property::Short(v) => v.into(),
        Property::UShort(v) => v.into(),
        Property::Int(v) => v.into(),
        Property::UInt(v) => v.into(),
        Property::Float(v) => v.into(),
        Property::Double(v) => v,
        _ => return None,
    })
}

fn index_list(p: &Property) -> Option<Vec<i64>> {
    Some(match p {
        Property::ListChar(v) => v.iter().map(|&i| i.into()).collect(),
        Property::ListUChar(v) => v.iter().map(|&i| i.into()).collect(),
        Property::ListShort(v) => v.iter().map(|&i| i.into()).collect(),
        Property::ListUShort(v) => v.iter().map(|&i| i.into()).collect(),
        Property::ListInt(v) => v.iter().map(|&i| i.into()).collect(),
        Property::ListUInt(v) => v.iter().map(|&i| i.into()).collect(),
        _ => return None,
    })
}

/// Reads a PLY mesh (ASCII or binary): `vertex` x/y/z (and nx/ny/nz, and
/// texture coordinates u/v, texture_u/texture_v or s/t, each if every
/// vertex has them), `face` `vertex_indices` (or `vertex_index`) polygons
/// fanned into triangles.
fn read_ply(path: &Path, max_triangles: usize) -> Result<MeshData, String> {
    let file = crate::scene::read::open_capped(path, MAX_PLY_BYTES)
        .map_err(|e| format!("cannot open: {e}"))?;
    let parser = Parser::<DefaultElement>::new();
    let mut reader = Reader::new(BufReader::new(file));
    let invalid = |e: ply_rs_bw::parser::ParseError| format!("invalid PLY: {e}");
    let header = parser.read_header(&mut reader).map_err(invalid)?;
    let count = |element: &str| header.elements.get(element).map_or(0, |e| e.count);
    // Each face gives at least one triangle; refuse before reading payload.
    if count("face") > max_triangles || count("vertex") > 3 * MAX_TRIANGLES {
        return Err(format!(
            "{} vertices and {} faces exceed the scene's triangle limit",
            count("vertex"),
            count("face")
        ));
    }
    let payload = parser.read_payload(&mut reader, &header).map_err(invalid)?;
    let vertices = payload.get("vertex").map(Vec::as_slice).unwrap_or(&[]);
    let faces = payload.get("face").map(Vec::as_slice).unwrap_or(&[]);
    let mut mesh = MeshData::default();
    let mut normals = Vec::with_capacity(vertices.len());
    let mut uvs = Vec::with_capacity(vertices.len());
    for (i, v) in vertices.iter().enumerate() {
        let get = |k: &str| v.get(k).and_then(scalar);
        let (Some(x), Some(y), Some(z)) = (get("x"), get("y"), get("z")) else {
            return Err(format!("vertex {i} lacks numeric x, y, z"));
        };
        mesh.positions.push(glam::DVec3::new(x, y, z));
        if let (Some(nx), Some(ny), Some(nz)) = (get("nx"), get("ny"), get("nz")) {
            normals.push(glam::DVec3::new(nx, ny, nz));
        }
        let uv = [("u", "v"), ("texture_u", "texture_v"), ("s", "t")]
            .into_iter()
            .find_map(|(a, b)| Some((get(a)?, get(b)?)));
        if let Some((s, t)) = uv.filter(|(s, t)| s.is_finite() && t.is_finite()) {
            uvs.push(glam::DVec2::new(s, t));
        }
    }
    for (f, face) in faces.iter().enumerate() {
        let idx = face
            .get("vertex_indices")
            .or_else(|| face.get("vertex_index"))
            .and_then(index_list)
            .ok_or_else(|| format!("face {f} lacks an integer vertex_indices list"))?;
        if let Some(&bad) = idx
            .iter()
            .find(|&&i| i < 0 || i as usize >= mesh.positions.len())
        {
            return Err(format!(
                "face {f} refers to vertex {bad} ({} vertices)",
                mesh.positions.len()
            ));
        }
        for k in 1..idx.len().saturating_sub(1) {
            if mesh.indices.len() >= max_triangles {
                return Err(format!("more than {max_triangles} triangles"));
            }
            mesh.indices
                .push([idx[0], idx[k], idx[k + 1]].map(|i| i as u32));
        }
    }
    if mesh.indices.is_empty() {
        return Err("no triangles".to_string());
    }
    if normals.len() == mesh.positions.len() {
        mesh.normals = Some(normals);
    }
    if uvs.len() == mesh.positions.len() {
        mesh.uvs = Some(uvs);
    }
    Ok(mesh)
}
