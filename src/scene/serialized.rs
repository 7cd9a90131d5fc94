//! Mitsuba's `serialized` meshes: one or more indexed triangle meshes in a
//! file, each a small header followed by a zlib stream, and a table of
//! where each mesh starts at the file's end (little endian throughout):
//!
//! - `u16` 0x041C, `u16` version (3 or 4);
//! - zlib: `u32` flags (0x1 vertex normals, 0x2 texture coordinates, 0x8
//!   vertex colours, 0x2000 double precision, else single), in version 4 the
//!   mesh's name (NUL-terminated UTF-8), `u64` vertex and `u64` triangle
//!   counts, then positions (3 per vertex), normals, texture coordinates
//!   (2 per vertex) and colours (3, skipped) as present, and `u32` indices;
//! - the end: each mesh's offset (`u64` in version 4, `u32` in version 3),
//!   then the `u32` mesh count.
//!
//! Texture coordinates are taken as stored, as Mitsuba 3 does. The face
//! normals flag (0x10) is ignored, as Mitsuba 3 ignores it: the shape's
//! `face_normals` decides.
//!
//! A few compressed bytes can claim any counts, so the counts are checked
//! before anything is inflated: at most three vertices per triangle (no
//! triangle can use more) and the mesh they make reserved from the load's
//! budget. The arrays are then inflated in chunks of [`CHUNK`] values, the
//! load's cancel flag asked between them.

use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use glam::{DVec2, DVec3};

use super::budget::Budget;
use super::error::SceneError;
use super::mesh::MeshData;
use super::{MAX_TRIANGLES, read};

/// Values inflated between two looks at the load's cancel flag.
const CHUNK: usize = 1 << 20;

/// Largest accepted file, bytes.
const MAX_FILE_BYTES: u64 = 1 << 30;
/// Longest mesh name (version 4), bytes.
const MAX_NAME_BYTES: usize = 4096;
const MAGIC: u16 = 0x041C;
const HAS_NORMALS: u32 = 0x1;
const HAS_TEXCOORDS: u32 = 0x2;
const HAS_COLORS: u32 = 0x8;
const DOUBLE_PRECISION: u32 = 0x2000;

/// Why a mesh was not read: the file is broken (the message), or the load
/// refused it (budget, cancel).
enum Failure {
    File(String),
    Load(SceneError),
}

impl From<String> for Failure {
    fn from(message: String) -> Self {
        Failure::File(message)
    }
}

impl From<SceneError> for Failure {
    fn from(e: SceneError) -> Self {
        Failure::Load(e)
    }
}

/// Reads mesh `index` of the serialized file at `path`, named by the
/// scene's `field`, refusing more than `max_triangles` triangles, or a mesh
/// the budget cannot take, before any is inflated.
pub(crate) fn read_serialized(
    path: &Path,
    index: u32,
    field: &str,
    max_triangles: usize,
    budget: &Budget,
) -> Result<MeshData, SceneError> {
    read_mesh(path, index, field, max_triangles, budget).map_err(|failure| match failure {
        Failure::File(message) => SceneError::file(field, path, message),
        Failure::Load(e) => e,
    })
}

/// Bytes a mesh of `vertices` and `triangles` with the arrays `flags` says
/// it has takes while it is read: its [`MeshData`] and, beside it, the
/// largest array's bytes as stored while they are converted.
fn mesh_bytes(flags: u32, vertices: u64, triangles: u64) -> u64 {
    let width = if flags & DOUBLE_PRECISION != 0 { 8 } else { 4 };
    let normals = if flags & HAS_NORMALS != 0 { 24 } else { 0 };
    let uvs = if flags & HAS_TEXCOORDS != 0 { 16 } else { 0 };
    let stored = (3 * width * vertices).max(12 * triangles);
    (24 + normals + uvs) * vertices + 12 * triangles + stored
}

fn read_mesh(
    path: &Path,
    index: u32,
    field: &str,
    max_triangles: usize,
    budget: &Budget,
) -> Result<MeshData, Failure> {
    let file = read::open_regular(path).map_err(|e| format!("cannot open: {e}"))?;
    let size = file.metadata().map_err(|e| e.to_string())?.len();
    if size > MAX_FILE_BYTES {
        return Err(format!("larger than {MAX_FILE_BYTES} bytes").into());
    }
    let mut file = BufReader::new(file);
    fn truncated(what: &'static str) -> impl Fn(std::io::Error) -> String {
        move |e| format!("truncated {what}: {e}")
    }
    let version = header(&mut file).map_err(truncated("header"))??;
    if index > 0 {
        // The offset table at the end says where mesh `index` starts.
        file.seek(SeekFrom::End(-4))
            .map_err(truncated("mesh count"))?;
        let count = u32_of(&mut file).map_err(truncated("mesh count"))?;
        if index >= count {
            return Err(format!("shape_index {index}: the file holds {count} meshes").into());
        }
        let width: i64 = if version == 4 { 8 } else { 4 };
        let back = 4 + width * i64::from(count - index);
        file.seek(SeekFrom::End(-back))
            .map_err(truncated("offset table"))?;
        let offset = if version == 4 {
            u64_of(&mut file).map_err(truncated("offset table"))?
        } else {
            u64::from(u32_of(&mut file).map_err(truncated("offset table"))?)
        };
        if offset >= size {
            return Err(format!("mesh {index} starts past the file's end").into());
        }
        file.seek(SeekFrom::Start(offset))
            .map_err(truncated("mesh header"))?;
        let again = header(&mut file).map_err(truncated("mesh header"))??;
        if again != version {
            return Err(format!("mesh {index} has version {again}, the file {version}").into());
        }
    }
    let mut z = flate2::read::ZlibDecoder::new(file);
    let corrupt = |e: std::io::Error| format!("corrupt mesh {index}: {e}");
    let flags = u32_of(&mut z).map_err(corrupt)?;
    if version == 4 {
        let mut name = Vec::new();
        loop {
            let mut byte = [0u8];
            z.read_exact(&mut byte).map_err(corrupt)?;
            if byte[0] == 0 {
                break;
            }
            if name.len() >= MAX_NAME_BYTES {
                return Err(format!(
                    "mesh {index}: its name is longer than {MAX_NAME_BYTES} bytes"
                )
                .into());
            }
            name.push(byte[0]);
        }
    }
    let vertices = u64_of(&mut z).map_err(corrupt)?;
    let triangles = u64_of(&mut z).map_err(corrupt)?;
    if triangles > max_triangles as u64 || vertices > 3 * MAX_TRIANGLES as u64 {
        return Err(format!(
            "{vertices} vertices and {triangles} triangles exceed the scene's triangle limit"
        )
        .into());
    }
    if vertices > 3 * triangles {
        return Err(format!(
            "mesh {index} claims {vertices} vertices for {triangles} triangles; its triangles can use at most {}",
            3 * triangles
        )
        .into());
    }
    let bytes = mesh_bytes(flags, vertices, triangles);
    let what = format!("the {vertices} vertices and {triangles} triangles of mesh {index}");
    budget.reserve(bytes, field, &what)?;
    let mesh = read_arrays(&mut z, flags, vertices as usize, triangles as usize, budget).map_err(
        |failure| match failure {
            Failure::File(message) => Failure::File(format!("corrupt mesh {index}: {message}")),
            load => load,
        },
    );
    budget.release(bytes);
    let mesh = mesh?;
    if let Some((t, bad)) = mesh.indices.iter().enumerate().find_map(|(t, tri)| {
        tri.iter()
            .find(|&&i| i as usize >= mesh.positions.len())
            .map(|b| (t, *b))
    }) {
        return Err(format!(
            "mesh {index}: triangle {t} refers to vertex {bad} ({vertices} vertices)"
        )
        .into());
    }
    if mesh.indices.is_empty() {
        return Err(format!("mesh {index} has no triangles").into());
    }
    Ok(mesh)
}

/// Inflates the arrays of a mesh whose counts were checked (module docs).
fn read_arrays(
    z: &mut impl Read,
    flags: u32,
    vertices: usize,
    triangles: usize,
    budget: &Budget,
) -> Result<MeshData, Failure> {
    let width = if flags & DOUBLE_PRECISION != 0 { 8 } else { 4 };
    let real = |b: &[u8]| match b.len() {
        8 => f64::from_le_bytes(b.try_into().expect("8 bytes")),
        _ => f64::from(f32::from_le_bytes(b.try_into().expect("4 bytes"))),
    };
    let mut reals = |count: usize| {
        let mut values = Vec::with_capacity(count);
        read_values(z, count, width, budget, &mut |b| values.push(real(b)))?;
        Ok::<_, Failure>(values)
    };
    let triples = |v: Vec<f64>| -> Vec<DVec3> {
        v.chunks_exact(3)
            .map(|c| DVec3::new(c[0], c[1], c[2]))
            .collect()
    };
    let positions = triples(reals(3 * vertices)?);
    let normals = match flags & HAS_NORMALS != 0 {
        true => Some(triples(reals(3 * vertices)?)),
        false => None,
    };
    let uvs = match flags & HAS_TEXCOORDS != 0 {
        true => Some(
            reals(2 * vertices)?
                .chunks_exact(2)
                .map(|c| DVec2::new(c[0], c[1]))
                .collect(),
        ),
        false => None,
    };
    if flags & HAS_COLORS != 0 {
        read_values(z, 3 * vertices, width, budget, &mut |_| {})?;
    }
    let mut indices = Vec::with_capacity(triangles);
    read_values(z, triangles, 12, budget, &mut |b| {
        indices
            .push([0, 4, 8].map(|k| u32::from_le_bytes(b[k..k + 4].try_into().expect("4 bytes"))));
    })?;
    Ok(MeshData {
        positions,
        indices,
        normals,
        uvs,
    })
}

/// Inflates `count` values of `width` bytes each and hands each to
/// `value`, [`CHUNK`] values at a time, asking the load's cancel flag
/// between chunks.
fn read_values(
    z: &mut impl Read,
    count: usize,
    width: usize,
    budget: &Budget,
    value: &mut dyn FnMut(&[u8]),
) -> Result<(), Failure> {
    let mut bytes = Vec::new();
    let mut left = count;
    while left > 0 {
        budget.check_cancel()?;
        let n = left.min(CHUNK);
        bytes.resize(n * width, 0);
        z.read_exact(&mut bytes).map_err(|e| e.to_string())?;
        bytes.chunks_exact(width).for_each(&mut *value);
        left -= n;
    }
    Ok(())
}

/// The file format identifier and version at the reader's position: the
/// version, or why it is not a serialized mesh.
fn header(r: &mut impl Read) -> std::io::Result<Result<u16, String>> {
    let mut b = [0u8; 4];
    r.read_exact(&mut b)?;
    let (magic, version) = (
        u16::from_le_bytes([b[0], b[1]]),
        u16::from_le_bytes([b[2], b[3]]),
    );
    Ok(if magic != MAGIC {
        Err("not a Mitsuba serialized mesh (no 0x041C identifier)".to_string())
    } else if version != 3 && version != 4 {
        Err(format!("serialized version {version} (3 and 4 are read)"))
    } else {
        Ok(version)
    })
}

fn u32_of(r: &mut impl Read) -> std::io::Result<u32> {
    let mut b = [0u8; 4];
    r.read_exact(&mut b)?;
    Ok(u32::from_le_bytes(b))
}

fn u64_of(r: &mut impl Read) -> std::io::Result<u64> {
    let mut b = [0u8; 8];
    r.read_exact(&mut b)?;
    Ok(u64::from_le_bytes(b))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::budget::LoadLimits;

    /// The checked-in file made by `docs/validation/mitsuba_serialized.py`,
    /// which Mitsuba 3 reads back to the numbers asserted here.
    fn data(name: &str) -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/mitsuba")
            .join(name)
    }

    fn read(path: &Path, index: u32, max_triangles: usize) -> Result<MeshData, String> {
        let budget = Budget::new(&LoadLimits::default());
        read_serialized(path, index, "shapes[0]", max_triangles, &budget).map_err(|e| e.to_string())
    }

    #[test]
    fn both_meshes_of_a_file_read_as_mitsuba_reads_them() {
        let path = data("two_meshes.serialized");
        // Mesh 0: a single-precision quad with normals and texture coordinates.
        let quad = read(&path, 0, MAX_TRIANGLES).unwrap();
        assert_eq!((quad.positions.len(), quad.indices.len()), (4, 2));
        assert_eq!(quad.positions[2], DVec3::new(1.0, 1.0, 0.0));
        assert_eq!(quad.normals.as_ref().unwrap()[0], DVec3::Z);
        assert_eq!(quad.uvs.as_ref().unwrap()[1], DVec2::new(1.0, 0.0));
        assert_eq!(quad.indices[1], [0, 2, 3]);
        // Mesh 1: a double-precision triangle without either.
        let tri = read(&path, 1, MAX_TRIANGLES).unwrap();
        assert_eq!((tri.positions.len(), tri.indices.len()), (3, 1));
        assert_eq!(tri.positions[1], DVec3::new(2.5, 0.0, 1.0 / 3.0));
        assert!(tri.normals.is_none() && tri.uvs.is_none());
        // Past the last mesh, past the budget: refused, saying why.
        let e = read(&path, 2, MAX_TRIANGLES).unwrap_err();
        assert!(e.contains("holds 2 meshes"), "{e}");
        let e = read(&path, 0, 1).unwrap_err();
        assert!(e.contains("triangle limit"), "{e}");
        let e = read(&data("quad.ply"), 0, MAX_TRIANGLES).unwrap_err();
        assert!(e.contains("0x041C"), "{e}");
    }

    #[test]
    fn counts_a_few_bytes_claim_are_refused_before_inflating() {
        let dir = tempfile::tempdir().unwrap();
        // 30 million vertices and one triangle in 30 kB: 360 MB of zeros.
        let path = dir.path().join("bomb.serialized");
        std::fs::write(&path, crate::testing::serialized_mesh(30_000_000, 1)).unwrap();
        assert!(std::fs::metadata(&path).unwrap().len() < 2_000_000);
        let e = read(&path, 0, MAX_TRIANGLES).unwrap_err();
        assert!(e.contains("30000000 vertices for 1 triangles"), "{e}");
        // As many vertices as its triangles use, but more than the load may hold.
        let path = dir.path().join("large.serialized");
        std::fs::write(&path, crate::testing::serialized_mesh(3_000_000, 1_000_000)).unwrap();
        let limits = LoadLimits {
            max_bytes: 100 << 20,
            ..LoadLimits::default()
        };
        let budget = Budget::new(&limits);
        let e = read_serialized(&path, 0, "shapes[2]", MAX_TRIANGLES, &budget).unwrap_err();
        assert!(matches!(e, SceneError::OverBudget { .. }), "{e}");
        assert_eq!(e.field(), Some("shapes[2]"));
        budget
            .reserve(100 << 20, "", "the whole budget, given back")
            .unwrap();
    }
}
