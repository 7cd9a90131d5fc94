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

use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use glam::{DVec2, DVec3};

use super::mesh::MeshData;
use super::{MAX_TRIANGLES, read};

/// Largest accepted file, bytes.
const MAX_FILE_BYTES: u64 = 1 << 30;
/// Longest mesh name (version 4), bytes.
const MAX_NAME_BYTES: usize = 4096;
const MAGIC: u16 = 0x041C;
const HAS_NORMALS: u32 = 0x1;
const HAS_TEXCOORDS: u32 = 0x2;
const HAS_COLORS: u32 = 0x8;
const DOUBLE_PRECISION: u32 = 0x2000;

/// Reads mesh `index` of the serialized file at `path`, refusing more than
/// `max_triangles` triangles before any is read.
pub(crate) fn read_serialized(
    path: &Path,
    index: u32,
    max_triangles: usize,
) -> Result<MeshData, String> {
    let file = read::open_regular(path).map_err(|e| format!("cannot open: {e}"))?;
    let size = file.metadata().map_err(|e| e.to_string())?.len();
    if size > MAX_FILE_BYTES {
        return Err(format!("larger than {MAX_FILE_BYTES} bytes"));
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
            return Err(format!(
                "shape_index {index}: the file holds {count} meshes"
            ));
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
            return Err(format!("mesh {index} starts past the file's end"));
        }
        file.seek(SeekFrom::Start(offset))
            .map_err(truncated("mesh header"))?;
        let again = header(&mut file).map_err(truncated("mesh header"))??;
        if again != version {
            return Err(format!(
                "mesh {index} has version {again}, the file {version}"
            ));
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
                ));
            }
            name.push(byte[0]);
        }
    }
    let vertices = u64_of(&mut z).map_err(corrupt)?;
    let triangles = u64_of(&mut z).map_err(corrupt)?;
    if triangles > max_triangles as u64 || vertices > 3 * MAX_TRIANGLES as u64 {
        return Err(format!(
            "{vertices} vertices and {triangles} triangles exceed the scene's triangle limit"
        ));
    }
    let (vertices, triangles) = (vertices as usize, triangles as usize);
    let double = flags & DOUBLE_PRECISION != 0;
    let mut reals = |count: usize| -> Result<Vec<f64>, String> {
        let width = if double { 8 } else { 4 };
        let mut bytes = vec![0u8; count * width];
        z.read_exact(&mut bytes).map_err(corrupt)?;
        Ok(if double {
            bytes
                .chunks_exact(8)
                .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
                .collect()
        } else {
            bytes
                .chunks_exact(4)
                .map(|b| f64::from(f32::from_le_bytes(b.try_into().expect("4 bytes"))))
                .collect()
        })
    };
    let triples = |v: Vec<f64>| -> Vec<DVec3> {
        v.chunks_exact(3)
            .map(|c| DVec3::new(c[0], c[1], c[2]))
            .collect()
    };
    let positions = triples(reals(3 * vertices)?);
    let normals = (flags & HAS_NORMALS != 0)
        .then(|| reals(3 * vertices).map(triples))
        .transpose()?;
    let uvs = (flags & HAS_TEXCOORDS != 0)
        .then(|| {
            reals(2 * vertices).map(|v| {
                v.chunks_exact(2)
                    .map(|c| DVec2::new(c[0], c[1]))
                    .collect::<Vec<_>>()
            })
        })
        .transpose()?;
    if flags & HAS_COLORS != 0 {
        reals(3 * vertices)?;
    }
    let mut bytes = vec![0u8; 12 * triangles];
    z.read_exact(&mut bytes).map_err(corrupt)?;
    let mut indices = Vec::with_capacity(triangles);
    for (t, b) in bytes.chunks_exact(12).enumerate() {
        let tri = [0, 4, 8].map(|k| u32::from_le_bytes(b[k..k + 4].try_into().expect("4 bytes")));
        if let Some(bad) = tri.iter().find(|&&i| i as usize >= vertices) {
            return Err(format!(
                "mesh {index}: triangle {t} refers to vertex {bad} ({vertices} vertices)"
            ));
        }
        indices.push(tri);
    }
    if indices.is_empty() {
        return Err(format!("mesh {index} has no triangles"));
    }
    Ok(MeshData {
        positions,
        indices,
        normals,
        uvs,
    })
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

    /// The checked-in file made by `docs/validation/mitsuba_serialized.py`,
    /// which Mitsuba 3 reads back to the numbers asserted here.
    fn data(name: &str) -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/mitsuba")
            .join(name)
    }

    #[test]
    fn both_meshes_of_a_file_read_as_mitsuba_reads_them() {
        let path = data("two_meshes.serialized");
        // Mesh 0: a single-precision quad with normals and texture coordinates.
        let quad = read_serialized(&path, 0, MAX_TRIANGLES).unwrap();
        assert_eq!((quad.positions.len(), quad.indices.len()), (4, 2));
        assert_eq!(quad.positions[2], DVec3::new(1.0, 1.0, 0.0));
        assert_eq!(quad.normals.as_ref().unwrap()[0], DVec3::Z);
        assert_eq!(quad.uvs.as_ref().unwrap()[1], DVec2::new(1.0, 0.0));
        assert_eq!(quad.indices[1], [0, 2, 3]);
        // Mesh 1: a double-precision triangle without either.
        let tri = read_serialized(&path, 1, MAX_TRIANGLES).unwrap();
        assert_eq!((tri.positions.len(), tri.indices.len()), (3, 1));
        assert_eq!(tri.positions[1], DVec3::new(2.5, 0.0, 1.0 / 3.0));
        assert!(tri.normals.is_none() && tri.uvs.is_none());
        // Past the last mesh, past the budget: refused, saying why.
        let e = read_serialized(&path, 2, MAX_TRIANGLES).unwrap_err();
        assert!(e.contains("holds 2 meshes"), "{e}");
        let e = read_serialized(&path, 0, 1).unwrap_err();
        assert!(e.contains("triangle limit"), "{e}");
        let e = read_serialized(&data("quad.ply"), 0, MAX_TRIANGLES).unwrap_err();
        assert!(e.contains("0x041C"), "{e}");
    }
}
