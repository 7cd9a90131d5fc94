//! PLY meshes (ASCII and binary, via `ply-rs-bw`): `vertex` x/y/z, and
//! nx/ny/nz and texture coordinates (u/v, texture_u/texture_v or s/t) when
//! every vertex has them; `face` `vertex_indices` (or `vertex_index`)
//! polygons fanned into triangles. Elements are read into typed records
//! ([`Vertex`], [`Face`]) rather than the crate's map per element, which
//! allocates for every property of every vertex.
//!
//! A header can claim any number of elements of any kind, so before a
//! payload is read every element's count is held to what the file's bytes
//! can hold ([`min_element_bytes`]), elements other than `vertex` and
//! `face` are skipped without being kept (and not read at all past the
//! last of those two), and the records of `vertex` and `face` are reserved
//! from the load's budget. Payloads are read in chunks of [`CHUNK`]
//! elements, the load's cancel flag asked between them.

use std::io::BufReader;
use std::path::Path;

use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{
    DefaultElement, ElementDef, Encoding, Header, Property, PropertyAccess, PropertyAccessResult,
    PropertyType, ScalarType,
};

use super::MAX_TRIANGLES;
use super::budget::Budget;
use super::error::SceneError;
use super::mesh::MeshData;

/// Elements read between two looks at the load's cancel flag.
const CHUNK: usize = 1 << 16;

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

/// An element this reader has no use for: read past, nothing kept.
struct Skip;

impl PropertyAccess for Skip {
    fn new() -> Self {
        Skip
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

/// Bytes of one scalar of `t` in a binary file.
fn scalar_bytes(t: &ScalarType) -> u64 {
    match t {
        ScalarType::Char | ScalarType::UChar => 1,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    }
}

/// Fewest bytes one `element` takes in a file of `encoding`: in binary its
/// scalars and its lists' counts (a list may be empty); in ASCII a digit
/// and a separator per property, and at least a line break.
fn min_element_bytes(element: &ElementDef, encoding: Encoding) -> u64 {
    match encoding {
        Encoding::Ascii => (2 * element.properties.len() as u64).max(1),
        _ => element
            .properties
            .values()
            .map(|p| match &p.data_type {
                PropertyType::Scalar(t) | PropertyType::List(t, _) => scalar_bytes(t),
            })
            .sum(),
    }
}

/// Reads `element`'s payload in chunks of [`CHUNK`], asking `budget`'s
/// cancel flag between them.
fn read_element<E: PropertyAccess>(
    reader: &mut Reader<impl std::io::BufRead>,
    element: &ElementDef,
    header: &Header,
    budget: &Budget,
) -> Result<Result<Vec<E>, String>, SceneError> {
    let parser = Parser::<E>::new();
    let mut out = Vec::new();
    let mut left = element.count;
    while left > 0 {
        budget.check_cancel()?;
        let chunk = ElementDef {
            count: left.min(CHUNK),
            ..element.clone()
        };
        match parser.read_payload_for_element(reader, &chunk, header) {
            Ok(part) => out.extend(part),
            Err(e) => return Ok(Err(format!("invalid PLY: {e}"))),
        }
        left -= chunk.count;
    }
    Ok(Ok(out))
}

/// Reads the PLY mesh at `path` (module docs), named by the scene's
/// `field`, refusing more than `max_triangles` triangles, and elements
/// the file cannot hold or the budget cannot take, before its payload is
/// read.
pub(crate) fn read_ply(
    path: &Path,
    field: &str,
    max_triangles: usize,
    budget: &Budget,
) -> Result<MeshData, SceneError> {
    let fail = |message: String| SceneError::file(field, path, message);
    let file = super::read::open_regular(path).map_err(|e| fail(format!("cannot open: {e}")))?;
    let file_bytes = file
        .metadata()
        .map_err(|e| fail(format!("cannot read: {e}")))?
        .len();
    let file = super::read::Capped::new(file, MAX_PLY_BYTES);
    let mut reader = Reader::new(BufReader::new(file));
    let header = Parser::<DefaultElement>::new()
        .read_header(&mut reader)
        .map_err(|e| fail(format!("invalid PLY: {e}")))?;
    let count = |element: &str| header.elements.get(element).map_or(0, |e| e.count);
    // Each face gives at least one triangle; refuse before reading payload.
    if count("face") > max_triangles || count("vertex") > 3 * MAX_TRIANGLES {
        return Err(fail(format!(
            "{} vertices and {} faces exceed the scene's triangle limit",
            count("vertex"),
            count("face")
        )));
    }
    for (name, element) in &header.elements {
        let least = min_element_bytes(element, header.encoding);
        if (element.count as u64).saturating_mul(least) > file_bytes {
            return Err(fail(format!(
                "element {name:?} claims {} entries of at least {least} bytes each, more than the file's {file_bytes} bytes hold",
                element.count
            )));
        }
    }
    if let Some(vertex) = header.elements.get("vertex")
        && let Some(axis) = ["x", "y", "z"]
            .into_iter()
            .find(|a| !vertex.properties.contains_key(*a))
    {
        return Err(fail(format!("the vertex element has no property {axis:?}")));
    }
    // The records of both elements are held at once while the mesh is made
    // from them; a face's indices are a list of its own (a triangle's or a
    // quad's fits in 32 bytes).
    let records = count("vertex") as u64 * std::mem::size_of::<Vertex>() as u64
        + count("face") as u64 * (std::mem::size_of::<Face>() as u64 + 32);
    budget.reserve(
        records,
        field,
        &format!(
            "its {} vertices and {} faces",
            count("vertex"),
            count("face")
        ),
    )?;
    // Elements are read in the header's order, each by the record type
    // that wants it; others are read past, and nothing after the last of
    // `vertex` and `face`.
    let last = header
        .elements
        .keys()
        .rposition(|name| name == "vertex" || name == "face");
    let (mut vertices, mut faces) = (Vec::new(), Vec::new());
    for (i, (name, element)) in header.elements.iter().enumerate() {
        if last.is_none_or(|last| i > last) {
            break;
        }
        match name.as_str() {
            "vertex" => {
                vertices =
                    read_element::<Vertex>(&mut reader, element, &header, budget)?.map_err(fail)?;
            }
            "face" => {
                faces =
                    read_element::<Face>(&mut reader, element, &header, budget)?.map_err(fail)?;
            }
            // Nothing to read past in a binary element of no bytes.
            _ if min_element_bytes(element, header.encoding) == 0
                && header.encoding != Encoding::Ascii => {}
            _ => {
                read_element::<Skip>(&mut reader, element, &header, budget)?.map_err(fail)?;
            }
        }
    }
    let mesh = mesh_of(&vertices, &faces, max_triangles).map_err(fail);
    budget.release(records);
    mesh
}

/// The mesh of the `vertex` and `face` records (module docs).
fn mesh_of(vertices: &[Vertex], faces: &[Face], max_triangles: usize) -> Result<MeshData, String> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::budget::LoadLimits;

    const QUAD: &str = "0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 3\n";

    fn read(header: &str, payload: &[u8], limits: &LoadLimits) -> Result<MeshData, String> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.ply");
        let mut bytes = header.as_bytes().to_vec();
        bytes.extend(payload);
        std::fs::write(&path, bytes).unwrap();
        read_ply(&path, "shapes[0]", MAX_TRIANGLES, &Budget::new(limits)).map_err(|e| e.to_string())
    }

    fn header(before: &str, after: &str) -> String {
        format!(
            "ply\nformat ascii 1.0\n{before}element vertex 4\nproperty float x\nproperty float y\n\
             property float z\nelement face 2\nproperty list uchar int vertex_indices\n{after}end_header\n"
        )
    }

    #[test]
    fn elements_the_file_cannot_hold_are_refused_before_reading() {
        let limits = LoadLimits::default();
        // 244 bytes claiming 10¹¹ elements of nothing: read one by one, they
        // grew memory without bound.
        let junk = crate::testing::ply_with_junk_element();
        let end = b"end_header\n";
        let at = junk.windows(end.len()).position(|w| w == end).unwrap() + end.len();
        let (junk, payload) = (std::str::from_utf8(&junk[..at]).unwrap(), &junk[at..]);
        // Binary elements of no bytes take nothing to read past.
        assert_eq!(read(junk, payload, &limits).unwrap().indices.len(), 1);
        let ascii_junk = header("element junk 100000000000\n", "");
        let e = read(&ascii_junk, QUAD.as_bytes(), &limits).unwrap_err();
        assert!(e.contains("\"junk\" claims 100000000000 entries"), "{e}");
        let e = read(
            &header("", "").replace("vertex 4", "vertex 4000000"),
            QUAD.as_bytes(),
            &limits,
        )
        .unwrap_err();
        assert!(e.contains("\"vertex\" claims 4000000 entries"), "{e}");
    }

    #[test]
    fn other_elements_are_read_past_and_nothing_after_the_mesh_is_read() {
        let limits = LoadLimits::default();
        let mesh = read(
            &header("element camera 1\nproperty float fov\n", ""),
            format!("45\n{QUAD}").as_bytes(),
            &limits,
        )
        .unwrap();
        assert_eq!((mesh.positions.len(), mesh.indices.len()), (4, 2));
        // A trailing element is never read: its entries need not be there.
        let trailing = header("", "element edge 3\nproperty int a\n");
        assert_eq!(
            read(&trailing, QUAD.as_bytes(), &limits)
                .unwrap()
                .indices
                .len(),
            2
        );
    }

    #[test]
    fn the_records_are_reserved_from_the_load_budget() {
        let limits = LoadLimits {
            max_bytes: 100,
            budget: "scenes.max_scene_bytes",
            ..LoadLimits::default()
        };
        let e = read(&header("", ""), QUAD.as_bytes(), &limits).unwrap_err();
        assert!(e.contains("its 4 vertices and 2 faces"), "{e}");
    }
}
