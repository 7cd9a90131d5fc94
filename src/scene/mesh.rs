//! Triangle meshes before placement in the world: the built-in rectangle and
//! cube, inline triangle lists and OBJ files (via `tobj`).
//!
//! Front faces wind counter-clockwise seen from the front; the geometric
//! normal is `(p1 − p0) × (p2 − p0)`, normalised.

use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use glam::{DVec2, DVec3};

use super::error::SceneError;

/// Largest accepted OBJ file, bytes.
pub const MAX_OBJ_BYTES: u64 = 1 << 30;

/// Vertices and triangles in local coordinates.
#[derive(Clone, Debug, Default)]
pub struct MeshData {
    pub positions: Vec<DVec3>,
    pub indices: Vec<[u32; 3]>,
    /// Optional per-vertex shading normals (same length as `positions`).
    pub normals: Option<Vec<DVec3>>,
    /// Optional per-vertex texture coordinates (same length as `positions`)
    /// as the file stores them; a shape may flip `v` when placing the mesh
    /// (`flip_tex_coords`, `docs/scene-format.md`).
    pub uvs: Option<Vec<DVec2>>,
}

impl MeshData {
    /// Bytes the mesh holds on the heap.
    pub fn heap_bytes(&self) -> u64 {
        fn bytes<T>(v: &[T]) -> u64 {
            std::mem::size_of_val(v) as u64
        }
        bytes(&self.positions)
            + bytes(&self.indices)
            + self.normals.as_deref().map_or(0, bytes)
            + self.uvs.as_deref().map_or(0, bytes)
    }

    /// Gives a mesh without shading normals smooth ones, as Mitsuba 3 does
    /// for OBJ and PLY files unless `face_normals` is set: at each vertex,
    /// the unit normals of the triangles around it weighted by their angle
    /// there (Thürmer & Wüthrich 1998, "Computing vertex normals from
    /// polygonal facets"), so a vertex's normal does not depend on how the
    /// faces around it are split into triangles. Vertices that only
    /// degenerate triangles touch, which no ray hits, get `+z`. Files whose
    /// vertices are split at seams (an OBJ's distinct `v/vt` pairs) keep
    /// those seams, as in Mitsuba.
    pub fn with_smooth_normals(mut self) -> MeshData {
        if self.normals.is_some() {
            return self;
        }
        let mut sums = vec![DVec3::ZERO; self.positions.len()];
        for t in &self.indices {
            let p = t.map(|i| self.positions[i as usize]);
            let Some(n) = (p[1] - p[0]).cross(p[2] - p[0]).try_normalize() else {
                continue;
            };
            for k in 0..3 {
                let (a, b) = (p[(k + 1) % 3] - p[k], p[(k + 2) % 3] - p[k]);
                let angle = a.angle_between(b);
                if angle.is_finite() {
                    sums[t[k] as usize] += n * angle;
                }
            }
        }
        self.normals = Some(
            sums.into_iter()
                .map(|s| s.try_normalize().unwrap_or(DVec3::Z))
                .collect(),
        );
        self
    }
}

/// `[-1, 1]²` in the xy plane, normal +z (Mitsuba's `rectangle`).
pub fn rectangle() -> MeshData {
    MeshData {
        positions: vec![
            DVec3::new(-1.0, -1.0, 0.0),
            DVec3::new(1.0, -1.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(-1.0, 1.0, 0.0),
        ],
        indices: vec![[0, 1, 2], [0, 2, 3]],
        normals: None,
        // Mitsuba's: (u, v) = ((x + 1)/2, (y + 1)/2).
        uvs: Some(vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(1.0, 0.0),
            DVec2::new(1.0, 1.0),
            DVec2::new(0.0, 1.0),
        ]),
    }
}

/// `[-1, 1]³` with outward normals, two triangles per face, laid out as
/// Mitsuba 3's `cube` so that its texture coordinates agree: each face's
/// four corners take `(0, 1), (1, 1), (1, 0), (0, 0)` in the order below.
pub fn cube() -> MeshData {
    // Corner c is (±1, ±1, ±1) with bit k of c giving the sign of axis k;
    // faces −y, +y, +x, +z, −x, −z.
    const FACES: [[u32; 4]; 6] = [
        [1, 5, 4, 0],
        [3, 2, 6, 7],
        [1, 3, 7, 5],
        [5, 7, 6, 4],
        [4, 6, 2, 0],
        [3, 1, 0, 2],
    ];
    const UVS: [[f64; 2]; 4] = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];
    let corner = |c: u32| {
        let sign = |bit: u32| if c & bit != 0 { 1.0 } else { -1.0 };
        DVec3::new(sign(1), sign(2), sign(4))
    };
    let mut mesh = MeshData {
        uvs: Some(Vec::new()),
        ..MeshData::default()
    };
    for face in FACES {
        let v = mesh.positions.len() as u32;
        for (c, uv) in face.into_iter().zip(UVS) {
            mesh.positions.push(corner(c));
            mesh.uvs.as_mut().expect("set above").push(DVec2::from(uv));
        }
        mesh.indices.push([v, v + 1, v + 2]);
        mesh.indices.push([v + 3, v, v + 2]);
    }
    mesh
}

/// Counts the lines a `BufRead` consumer has read, so OBJ parse errors can
/// name the line (tobj reports only the kind of error).
struct LineCounter<R> {
    inner: R,
    lines: usize,
}

impl<R: BufRead> Read for LineCounter<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.lines += buf[..n].iter().filter(|&&b| b == b'\n').count();
        Ok(n)
    }
}

impl<R: BufRead> BufRead for LineCounter<R> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        self.inner.fill_buf()
    }
    fn consume(&mut self, amt: usize) {
        if let Ok(buf) = self.inner.fill_buf() {
            let end = amt.min(buf.len());
            self.lines += buf[..end].iter().filter(|&&b| b == b'\n').count();
        }
        self.inner.consume(amt);
    }
}

/// Loads all objects of an OBJ file as one triangulated mesh. Material
/// libraries (`mtllib`) are ignored and never opened: materials come from
/// the scene file, and opening them could read outside the scenes directory.
/// Normals and texture coordinates are kept only if every vertex has them.
pub fn load_obj(path: &Path, field: &str, max_triangles: usize) -> Result<MeshData, SceneError> {
    let err = |message: String| SceneError::file(field, path, message);
    let file = super::read::open_capped(path, MAX_OBJ_BYTES)
        .map_err(|e| err(format!("cannot open: {e}")))?;
    let mut reader = LineCounter {
        inner: BufReader::new(file),
        lines: 0,
    };
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, _) = tobj::load_obj_buf(&mut reader, &options, |_| Ok(Default::default()))
        .map_err(|e| {
            if reader.inner.get_ref().exceeded() {
                return err(format!("larger than the {MAX_OBJ_BYTES}-byte limit"));
            }
            SceneError::file(
                field,
                format!("{}:{}", path.display(), reader.lines.max(1)),
                format!("invalid OBJ: {e}"),
            )
        })?;
    let mut mesh = MeshData::default();
    let mut normals = Vec::new();
    let mut all_normals = true;
    let mut uvs = Vec::new();
    let mut all_uvs = true;
    for model in &models {
        let m = &model.mesh;
        let base = mesh.positions.len();
        let count = m.positions.len() / 3;
        mesh.positions.extend(
            m.positions
                .chunks_exact(3)
                .map(|c| DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64)),
        );
        if m.normals.len() == m.positions.len() {
            normals.extend(
                m.normals
                    .chunks_exact(3)
                    .map(|c| DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64)),
            );
        } else {
            all_normals = false;
        }
        if m.texcoords.len() == 2 * count {
            uvs.extend(
                m.texcoords
                    .chunks_exact(2)
                    .map(|c| DVec2::new(c[0] as f64, c[1] as f64)),
            );
        } else {
            all_uvs = false;
        }
        for tri in m.indices.chunks_exact(3) {
            if tri.iter().any(|&i| i as usize >= count) {
                return Err(err(format!("face {tri:?} refers to a missing vertex")));
            }
            mesh.indices.push([
                (base + tri[0] as usize) as u32,
                (base + tri[1] as usize) as u32,
                (base + tri[2] as usize) as u32,
            ]);
        }
        if mesh.indices.len() > max_triangles {
            return Err(err(format!(
                "more than {max_triangles} triangles (the scene's remaining budget)"
            )));
        }
    }
    if mesh.indices.is_empty() {
        return Err(err("no triangles".into()));
    }
    if let Some(i) = mesh.positions.iter().position(|p| !p.is_finite()) {
        return Err(err(format!("vertex {} is not finite", i + 1)));
    }
    if all_normals && !normals.is_empty() {
        mesh.normals = Some(normals);
    }
    if all_uvs && !uvs.is_empty() {
        if let Some(i) = uvs.iter().position(|uv| !uv.is_finite()) {
            return Err(err(format!("texture coordinate {} is not finite", i + 1)));
        }
        mesh.uvs = Some(uvs);
    }
    Ok(mesh)
}

/// Writes `mesh` as an OBJ file (positions, optional normals, 1-based faces),
/// with `digits` decimals. Used to regenerate the bundled assets.
pub fn write_obj(path: &Path, mesh: &MeshData, digits: usize) -> std::io::Result<()> {
    use std::io::Write;
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    for p in &mesh.positions {
        writeln!(out, "v {:.digits$} {:.digits$} {:.digits$}", p.x, p.y, p.z)?;
    }
    if let Some(normals) = &mesh.normals {
        for n in normals {
            writeln!(out, "vn {:.4} {:.4} {:.4}", n.x, n.y, n.z)?;
        }
    }
    for t in &mesh.indices {
        let [a, b, c] = t.map(|i| i + 1);
        if mesh.normals.is_some() {
            writeln!(out, "f {a}//{a} {b}//{b} {c}//{c}")?;
        } else {
            writeln!(out, "f {a} {b} {c}")?;
        }
    }
    out.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn smooth_normals_weigh_faces_by_their_angle() {
        // A cube of 8 shared corners, its faces split into triangles along
        // different diagonals: each corner's normal is the diagonal however
        // many triangles of each face touch it.
        let positions = (0..8)
            .map(|i| DVec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64))
            .map(|p| 2.0 * p - DVec3::ONE)
            .collect();
        let quads = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        let indices = quads
            .iter()
            .enumerate()
            .flat_map(|(f, &[a, b, c, d])| {
                if f % 2 == 0 {
                    [[a, b, c], [a, c, d]]
                } else {
                    [[a, b, d], [b, c, d]]
                }
            })
            .collect();
        let mesh = MeshData {
            positions,
            indices,
            ..MeshData::default()
        }
        .with_smooth_normals();
        for (p, n) in mesh.positions.iter().zip(mesh.normals.as_ref().unwrap()) {
            assert!(n.distance(p.normalize()) < 1e-12, "{p} {n}");
        }
        // A flat mesh keeps its face normal; given normals are kept.
        let flat = rectangle().with_smooth_normals();
        assert!(flat.normals.unwrap().iter().all(|n| *n == DVec3::Z));
        let given = MeshData {
            normals: Some(vec![DVec3::X; 4]),
            ..rectangle()
        };
        assert_eq!(given.with_smooth_normals().normals, Some(vec![DVec3::X; 4]));
    }

    fn face_normals(mesh: &MeshData) -> Vec<(DVec3, DVec3)> {
        mesh.indices
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
                ((b - a).cross(c - a).normalize(), (a + b + c) / 3.0)
            })
            .collect()
    }

    #[test]
    fn rectangle_faces_plus_z_and_cube_faces_outwards() {
        assert!(
            face_normals(&rectangle())
                .iter()
                .all(|(n, _)| *n == DVec3::Z)
        );
        let cube = cube();
        assert_eq!(cube.indices.len(), 12);
        for (n, centre) in face_normals(&cube) {
            // The outward normal points the way the face centre lies.
            assert!(n.dot(centre) > 0.6, "{n} at {centre}");
        }
    }

    #[test]
    fn obj_round_trip_and_errors_name_the_line() {
        let dir = std::env::temp_dir().join(format!("bmc-mesh-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("cube.obj");
        write_obj(&path, &cube(), 6).unwrap();
        let back = load_obj(&path, "shapes[0].filename", 1000).unwrap();
        assert_eq!(back.indices.len(), 12);
        assert_eq!(face_normals(&back).len(), 12);
        assert!(load_obj(&path, "f", 5).is_err());

        let bad = dir.join("bad.obj");
        std::fs::write(&bad, "v 0 0 0\nv 1 0 0\nv 0 x 0\nf 1 2 3\n").unwrap();
        let err = load_obj(&bad, "shapes[0].filename", 1000).unwrap_err();
        assert_eq!(err.field(), Some("shapes[0].filename"));
        assert!(err.to_string().contains("bad.obj:3"), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
