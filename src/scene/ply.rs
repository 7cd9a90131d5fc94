//! PLY meshes (ASCII and binary, via `ply-rs-bw`): `vertex` x/y/z, and
//! nx/ny/nz and texture coordinates (u/v, texture_u/texture_v or s/t) when
//! every vertex has them; `face` `vertex_indices` (or `vertex_index`)
//! polygons fanned into triangles. Elements are read into typed records
//! ([`Vertex`], [`Face`]) rather than the crate's map per element, which
//! allocates for every property of every vertex.

use std::io::BufReader;
use std::path::Path;

use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{DefaultElement, Property, PropertyAccess, PropertyAccessResult};

use super::MAX_TRIANGLES;
use super::mesh::MeshData;

/// Largest accepted PLY file, bytes.
const MAX_PLY_BYTES: u64 = 1 << 30;

/// The properties of a vertex this reader uses; `has` marks those seen.
#[derive(Default)]
struct Vertex {
    position: [f64; 3],
    normal: [f64; 3],
    uv: [f64; 2],
    has: u16,
}

const X: u16 = 1;
const Y: u16 = 2;
const Z: u16 = 4;
const NX: u16 = 8;
const NY: u16 = 16;
const NZ: u16 = 32;
const U: u16 = 64;
const V: u16 = 128;

impl PropertyAccess for Vertex {
    fn new() -> Self {
        Vertex::default()
    }

    fn set_property(&mut self, name: &str, property: Property) -> PropertyAccessResult {
        let Some(value) = scalar(&property) else {
            return PropertyAccessResult::Ignored;
        };
        let (slot, bit) = match name {
            "x" => (&mut self.position[0], X),
            "y" => (&mut self.position[1], Y),
            "z" => (&mut self.position[2], Z),
            "nx" => (&mut self.normal[0], NX),
            "ny" => (&mut self.normal[1], NY),
            "nz" => (&mut self.normal[2], NZ),
            "u" | "texture_u" | "s" => (&mut self.uv[0], U),
            "v" | "texture_v" | "t" => (&mut self.uv[1], V),
            _ => return PropertyAccessResult::Ignored,
        };
        *slot = value;
        self.has |= bit;
        PropertyAccessResult::Set
    }
}

/// A face's vertex indices (`None`: it has no integer index list).
#[derive(Default)]
struct Face {
    indices: Option<Vec<i64>>,
}

impl PropertyAccess for Face {
    fn new() -> Self {
        Face::default()
    }

    fn set_property(&mut self, name: &str, property: Property) -> PropertyAccessResult {
        if name != "vertex_indices" && name != "vertex_index" {
            return PropertyAccessResult::Ignored;
        }
        self.indices = index_list(&property);
        PropertyAccessResult::Set
    }
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

/// Reads the PLY mesh at `path` (module docs), refusing more than
/// `max_triangles` triangles before its payload is read.
pub(crate) fn read_ply(path: &Path, max_triangles: usize) -> Result<MeshData, String> {
    let file =
        super::read::open_capped(path, MAX_PLY_BYTES).map_err(|e| format!("cannot open: {e}"))?;
    let mut reader = Reader::new(BufReader::new(file));
    let invalid = |e: ply_rs_bw::parser::ParseError| format!("invalid PLY: {e}");
    let header = Parser::<DefaultElement>::new()
        .read_header(&mut reader)
        .map_err(invalid)?;
    let count = |element: &str| header.elements.get(element).map_or(0, |e| e.count);
    // Each face gives at least one triangle; refuse before reading payload.
    if count("face") > max_triangles || count("vertex") > 3 * MAX_TRIANGLES {
        return Err(format!(
            "{} vertices and {} faces exceed the scene's triangle limit",
            count("vertex"),
            count("face")
        ));
    }
    // Elements are read in the header's order, each by the record type
    // that wants it; others are read and dropped.
    let (mut vertices, mut faces) = (Vec::new(), Vec::new());
    for (name, element) in &header.elements {
        match name.as_str() {
            "vertex" => {
                vertices = Parser::<Vertex>::new()
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(invalid)?;
            }
            "face" => {
                faces = Parser::<Face>::new()
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(invalid)?;
            }
            _ => {
                Parser::<DefaultElement>::new()
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(invalid)?;
            }
        }
    }
    let mut mesh = MeshData::default();
    mesh.positions.reserve(vertices.len());
    let every = |bits: u16| vertices.iter().all(|v| v.has & bits == bits);
    let with_normals = every(NX | NY | NZ);
    let with_uvs = every(U | V)
        && vertices
            .iter()
            .all(|v| v.uv[0].is_finite() && v.uv[1].is_finite());
    for (i, v) in vertices.iter().enumerate() {
        if v.has & (X | Y | Z) != X | Y | Z {
            return Err(format!("vertex {i} lacks numeric x, y, z"));
        }
        mesh.positions.push(glam::DVec3::from_array(v.position));
    }
    if with_normals && !vertices.is_empty() {
        mesh.normals = Some(
            vertices
                .iter()
                .map(|v| glam::DVec3::from_array(v.normal))
                .collect(),
        );
    }
    if with_uvs && !vertices.is_empty() {
        mesh.uvs = Some(
            vertices
                .iter()
                .map(|v| glam::DVec2::from_array(v.uv))
                .collect(),
        );
    }
    mesh.indices.reserve(faces.len());
    for (f, face) in faces.iter().enumerate() {
        let idx = face
            .indices
            .as_deref()
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
    Ok(mesh)
}
