//! Builds a [`Scene`] from the JSON document: validation with field paths,
//! file resolution confined to the scenes directory, and acceleration
//! structure construction.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{DAffine3, DMat3, DVec2, DVec3};

use super::bitmap::{Bitmaps, read_bitmap};
use super::budget::{Budget, LoadLimits};
use super::bvh::{Aabb, Bvh};
use super::digest::SceneDigest;
use super::emitter::{self, Emitter};
use super::environment::{Environment, EnvironmentMap};
use super::error::SceneError;
use super::files::Files;
use super::format::{EnvironmentDoc, EnvironmentKind, SceneDoc, ShapeDoc, ShapeKind};
use super::material::{Declared, Material};
use super::mesh::{self, MeshData};
use super::shape::{self, Geometry, Shape, Triangle, TriangleAccel, TriangleTag};
use super::{Camera, MAX_PATH_DEPTH, MAX_SHAPES, MAX_TRIANGLES, Scene, transform};

/// Largest accepted scene file (inline triangle lists can be big).
const MAX_SCENE_BYTES: u64 = 1 << 30;

/// Loads a JSON scene document from `path` within `limits`.
pub(super) fn load_json(
    path: &Path,
    scenes_root: &Path,
    limits: &LoadLimits,
) -> Result<Scene, SceneError> {
    let text = read_scene_file(path)?;
    let base = path.parent().unwrap_or(Path::new("."));
    let mut scene = from_json_str(
        &text,
        &path.display().to_string(),
        base,
        scenes_root,
        limits,
    )?;
    name_from_file(&mut scene, path);
    Ok(scene)
}

/// Reads a scene file as text: a regular file of at most [`MAX_SCENE_BYTES`].
pub(crate) fn read_scene_file(path: &Path) -> Result<String, SceneError> {
    super::read::read_to_string(path, MAX_SCENE_BYTES).map_err(|source| SceneError::Io {
        file: path.to_path_buf(),
        source,
    })
}

/// Names an unnamed scene after its file's stem.
pub(super) fn name_from_file(scene: &mut Scene, path: &Path) {
    if scene.name.is_empty() {
        scene.name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
    }
}

/// Parses and validates within `limits`; `file` is used in syntax error
/// messages.
pub(super) fn from_json_str(
    text: &str,
    file: &str,
    base_dir: &Path,
    scenes_root: &Path,
    limits: &LoadLimits,
) -> Result<Scene, SceneError> {
    let mut de = serde_json::Deserializer::from_str(text);
    let syntax = |field: String, e: &serde_json::Error| {
        let message = e.to_string();
        // serde_json appends the position, which we report separately.
        let message = match message.rsplit_once(" at line ") {
            Some((m, _)) => m.to_string(),
            None => message,
        };
        SceneError::Syntax {
            file: file.to_string(),
            line: e.line(),
            column: e.column(),
            field,
            message,
        }
    };
    let doc: SceneDoc = serde_path_to_error::deserialize(&mut de)
        .map_err(|e| syntax(e.path().to_string(), e.inner()))?;
    de.end().map_err(|e| syntax(".".into(), &e))?;
    let files = Files::new(base_dir, scenes_root)?;
    let budget = Budget::new(limits);
    build(doc, &files, &Bitmaps::new(&files, &budget)).map_err(|e| files.relative(e))
}

/// Errors if any of the named optional fields is present.
fn reject_fields(field: &str, kind: &str, present: &[(&str, bool)]) -> Result<(), SceneError> {
    match present.iter().find(|(_, p)| *p) {
        Some((name, _)) => Err(SceneError::invalid(
            format!("{field}.{name}"),
            format!("not a field of a {kind}"),
        )),
        None => Ok(()),
    }
}

/// Builds the scene `doc` describes, its files resolved by `files` and its
/// images read through `bitmaps`, whose budget every reader shares.
pub(super) fn build(doc: SceneDoc, files: &Files, bitmaps: &Bitmaps) -> Result<Scene, SceneError> {
    let budget = bitmaps.budget();
    let mut materials = Vec::new();
    let mut material_ids = Vec::new();
    let mut by_id = HashMap::new();
    // What nested references may name: the materials before each one,
    // shared (a material named many times is held once).
    let mut declared = Declared::new();
    for (i, m) in doc.materials.iter().enumerate() {
        let field = format!("materials[{i}]");
        if by_id.insert(m.id.clone(), i).is_some() {
            return Err(SceneError::invalid(
                format!("{field}.id"),
                format!("duplicate material id {:?}", m.id),
            ));
        }
        budget.check_cancel()?;
        let material = Material::from_doc(m, &field, bitmaps, &declared)?;
        declared.insert(m.id.clone(), Arc::new(material.clone()));
        materials.push(material);
        material_ids.push(m.id.clone());
    }

    if doc.shapes.len() > MAX_SHAPES {
        return Err(SceneError::invalid(
            "shapes",
            format!(
                "{} shapes exceed the limit of {MAX_SHAPES}",
                doc.shapes.len()
            ),
        ));
    }
    // Every mesh file is read once, however many shapes use it, all of
    // them in parallel, and the scene's size is known before any triangle
    // is built.
    // Each shape's mesh file is resolved once, here.
    let (mut wanted, mut keys) = (Vec::new(), Vec::with_capacity(doc.shapes.len()));
    let mut inline = 0usize;
    for (i, s) in doc.shapes.iter().enumerate() {
        let key = match (s.kind, &s.filename, &s.indices) {
            (ShapeKind::Obj | ShapeKind::Ply | ShapeKind::Serialized, Some(name), _) => {
                let field = format!("shapes[{i}].filename");
                let key = (files.resolve(name, &field)?, s.shape_index.unwrap_or(0));
                wanted.push((key.clone(), s.kind, field));
                Some(key)
            }
            (ShapeKind::Triangles, _, Some(indices)) => {
                inline += indices.len();
                None
            }
            _ => None,
        };
        keys.push(key);
    }
    let meshes = MeshFiles::read_all(wanted, MAX_TRIANGLES - inline.min(MAX_TRIANGLES), budget)?;
    // The mesh of each shape that names a file.
    let shape_meshes: Vec<Option<Arc<MeshData>>> = keys
        .iter()
        .map(|key| key.as_ref().and_then(|k| meshes.get(k)))
        .collect();
    let mut triangles = 0usize;
    for (i, s) in doc.shapes.iter().enumerate() {
        let field = format!("shapes[{i}]");
        let shape_triangles = match (s.kind, &shape_meshes[i], &s.indices) {
            (ShapeKind::Rectangle, ..) => 2,
            (ShapeKind::Cube, ..) => 12,
            (_, Some(mesh), _) => mesh.indices.len(),
            (ShapeKind::Triangles, _, Some(indices)) => indices.len(),
            _ => 0,
        };
        triangles += shape_triangles;
        check_triangles(triangles, &field)?;
        budget.reserve(
            super::triangle_bytes(shape_triangles),
            &field,
            &format!("its {shape_triangles} triangles, built,"),
        )?;
    }
    let mut builder = GeometryBuilder {
        triangles: Vec::with_capacity(triangles),
        ..GeometryBuilder::default()
    };
    let mut emitters = Vec::new();
    for (i, s) in doc.shapes.iter().enumerate() {
        budget.check_cancel()?;
        let field = format!("shapes[{i}]");
        let material = *by_id.get(&s.material).ok_or_else(|| {
            SceneError::invalid(
                format!("{field}.material"),
                format!(
                    "unknown material id {:?} (known: {})",
                    s.material,
                    material_ids.join(", ")
                ),
            )
        })?;
        let emitter = match &s.emitter {
            Some(e) => {
                emitters.push(Emitter::from_doc(
                    e,
                    i,
                    &format!("{field}.emitter"),
                    bitmaps,
                )?);
                Some(emitters.len() - 1)
            }
            None => None,
        };
        builder.add_shape(s, &field, material, emitter, shape_meshes[i].as_deref())?;
    }
    for (i, light) in doc.lights.iter().enumerate() {
        emitters.push(Emitter::from_light_doc(light, &format!("lights[{i}]"))?);
    }

    let environment = doc
        .environment
        .as_ref()
        .map(|e| load_environment(e, files, budget))
        .transpose()?;
    let camera = Camera::from_doc(&doc.camera, "camera")?;
    if let Some(d) = doc.max_depth.filter(|d| !(1..=MAX_PATH_DEPTH).contains(d)) {
        return Err(SceneError::invalid(
            "max_depth",
            format!("must be in 1..={MAX_PATH_DEPTH} (1 = emitters seen directly only), got {d}"),
        ));
    }
    let digest = files.digest(&doc)?;
    let read = files.relative_opened();
    // The meshes as read are not needed once placed.
    drop(shape_meshes);
    drop(meshes);
    budget.check_cancel()?;
    let mut scene = builder.finish();
    scene.name = doc.name.unwrap_or_default();
    Ok(Scene {
        materials,
        material_ids,
        emitters,
        environment,
        camera,
        hide_emitters: doc.hide_emitters,
        max_depth: doc.max_depth,
        digest,
        files: read,
        ..scene
    })
}

/// Refuses a scene whose first shapes, up to `field`, already hold more
/// than [`MAX_TRIANGLES`] triangles (their bytes are the load budget's).
fn check_triangles(triangles: usize, field: &str) -> Result<(), SceneError> {
    if triangles > MAX_TRIANGLES {
        return Err(SceneError::invalid(
            "shapes",
            format!(
                "the shapes up to {field} hold {triangles} triangles, above the limit of {MAX_TRIANGLES} (MAX_TRIANGLES)"
            ),
        ));
    }
    Ok(())
}

/// A mesh file's canonical path and the mesh's index in it (0 but for
/// `serialized`).
type MeshKey = (PathBuf, u32);

/// Mesh files of one scene load, parsed once each and shared by every shape
/// that names them (keyed by canonical path, so `a.obj` and `./a.obj` are
/// one file).
pub(super) struct MeshFiles {
    meshes: HashMap<MeshKey, Arc<MeshData>>,
}

impl MeshFiles {
    /// Reads the mesh files `wanted` ((canonical path, mesh index), format,
    /// the field that names it) in parallel, each once, each refused past
    /// `max_triangles`. The first error in `wanted`'s order is returned,
    /// whatever finished first.
    ///
    /// Each mesh is reserved from `budget` as it is read (its readers
    /// reserve what a file's header claims before reading it), so the
    /// meshes held at once stay within the load's budget.
    pub(super) fn read_all(
        wanted: Vec<(MeshKey, ShapeKind, String)>,
        max_triangles: usize,
        budget: &Budget,
    ) -> Result<MeshFiles, SceneError> {
        use rayon::prelude::*;
        let mut seen = std::collections::HashSet::new();
        let unique: Vec<_> = wanted
            .into_iter()
            .filter(|(key, ..)| seen.insert(key.clone()))
            .collect();
        let read: Vec<Result<(MeshKey, Arc<MeshData>), SceneError>> = unique
            .into_par_iter()
            .map(|((path, index), kind, field)| {
                budget.check_cancel()?;
                let mesh = match kind {
                    ShapeKind::Ply => super::ply::read_ply(&path, &field, max_triangles, budget)?,
                    ShapeKind::Serialized => super::serialized::read_serialized(
                        &path,
                        index,
                        &field,
                        max_triangles,
                        budget,
                    )?,
                    _ => mesh::load_obj(&path, &field, max_triangles)?,
                };
                budget.reserve(mesh.heap_bytes(), &field, "its mesh")?;
                Ok(((path, index), Arc::new(mesh)))
            })
            .collect();
        Ok(MeshFiles {
            meshes: read.into_iter().collect::<Result<_, _>>()?,
        })
    }

    /// How many distinct files were read.
    #[cfg(test)]
    pub(super) fn len(&self) -> usize {
        self.meshes.len()
    }

    /// A mesh read by [`MeshFiles::read_all`].
    fn get(&self, key: &MeshKey) -> Option<Arc<MeshData>> {
        self.meshes.get(key).cloned()
    }
}

/// Accumulates shapes and world-space triangles, then builds the BVHs.
#[derive(Default)]
struct GeometryBuilder {
    shapes: Vec<Shape>,
    triangles: Vec<Triangle>,
    vertex_normals: Vec<[DVec3; 3]>,
    vertex_uvs: Vec<[DVec2; 3]>,
}

/// How a shape places a local mesh.
struct Placement {
    to_world: DAffine3,
    flip_normals: bool,
    /// Replace each texture coordinate `v` by `1 − v`.
    flip_tex_coords: bool,
}

impl GeometryBuilder {
    fn add_shape(
        &mut self,
        s: &ShapeDoc,
        field: &str,
        material: usize,
        emitter: Option<usize>,
        mesh_file: Option<&MeshData>,
    ) -> Result<(), SceneError> {
        let to_world = match &s.to_world {
            Some(t) => transform::build(t, &format!("{field}.to_world"))?,
            None => DAffine3::IDENTITY,
        };
        let kind = format!("{:?}", s.kind).to_lowercase();
        let sphere_fields = [
            ("center", s.center.is_some()),
            ("radius", s.radius.is_some()),
        ];
        let inline_fields = [
            ("positions", s.positions.is_some()),
            ("indices", s.indices.is_some()),
            ("normals", s.normals.is_some()),
            ("uvs", s.uvs.is_some()),
        ];
        let file_field = [
            ("filename", s.filename.is_some()),
            ("face_normals", s.face_normals.is_some()),
        ];
        let mesh_field = [("flip_tex_coords", s.flip_tex_coords.is_some())];
        let serialized_field = [("shape_index", s.shape_index.is_some())];
        let (reject_sphere, reject_inline, reject_file) = match s.kind {
            ShapeKind::Sphere => (false, true, true),
            ShapeKind::Triangles => (true, false, true),
            ShapeKind::Obj | ShapeKind::Ply | ShapeKind::Serialized => (true, true, false),
            _ => (true, true, true),
        };
        let reject_mesh = reject_inline && reject_file;
        for (reject, fields) in [
            (reject_sphere, &sphere_fields[..]),
            (reject_inline, &inline_fields[..]),
            (reject_file, &file_field[..]),
            (reject_mesh, &mesh_field[..]),
            (s.kind != ShapeKind::Serialized, &serialized_field[..]),
        ] {
            if reject {
                reject_fields(field, &kind, fields)?;
            }
        }
        let remaining = MAX_TRIANGLES - self.triangles.len();
        let placement = Placement {
            to_world,
            flip_normals: s.flip_normals,
            flip_tex_coords: s.flip_tex_coords.unwrap_or(s.kind == ShapeKind::Obj),
        };
        let (geometry, area) = match s.kind {
            ShapeKind::Rectangle => self.add_mesh(&mesh::rectangle(), &placement, field)?,
            ShapeKind::Cube => self.add_mesh(&mesh::cube(), &placement, field)?,
            ShapeKind::Obj | ShapeKind::Ply | ShapeKind::Serialized => {
                // Read while sizing the scene (see `build`); none where the
                // shape names no file.
                let data = mesh_file
                    .ok_or_else(|| SceneError::invalid(field, "missing field `filename`"))?;
                // `face_normals` discards the file's normals, as in Mitsuba;
                // without it a mesh that has none gets smooth ones.
                match (s.face_normals == Some(true), data.normals.is_some()) {
                    (true, true) => {
                        let flat = MeshData {
                            normals: None,
                            ..data.clone()
                        };
                        self.add_mesh(&flat, &placement, field)?
                    }
                    (false, false) => {
                        let smooth = data.clone().with_smooth_normals();
                        self.add_mesh(&smooth, &placement, field)?
                    }
                    _ => self.add_mesh(data, &placement, field)?,
                }
            }
            ShapeKind::Triangles => {
                let data = inline_mesh(s, field, remaining)?;
                self.add_mesh(&data, &placement, field)?
            }
            ShapeKind::Sphere => sphere(s, &to_world, field)?,
            ShapeKind::Disk => {
                let normal = (transform::normal_matrix(&to_world) * DVec3::Z).normalize();
                let geometry = Geometry::Disk {
                    to_world,
                    to_local: to_world.inverse(),
                    normal,
                };
                (geometry, shape::disk_area(&to_world))
            }
        };
        if !(area > 0.0 && area.is_finite()) {
            return Err(SceneError::invalid(
                field,
                format!("surface area is {area}"),
            ));
        }
        self.shapes.push(Shape {
            geometry,
            material,
            emitter,
            flip: s.flip_normals,
            area,
        });
        Ok(())
    }

    /// Places a local mesh in the world as this shape's triangles.
    ///
    /// Front sides follow the authored normal through the normal transform:
    /// a mirroring `to_world` (negative determinant) would reverse the
    /// winding, so it is swapped back. Triangles whose vertex normals all
    /// disagree with the winding are re-wound to face the vertex normals.
    fn add_mesh(
        &mut self,
        data: &MeshData,
        placement: &Placement,
        field: &str,
    ) -> Result<(Geometry, f64), SceneError> {
        let (to_world, flip) = (&placement.to_world, placement.flip_normals);
        let shape_index = self.shapes.len() as u32;
        let uvs: Option<Vec<DVec2>> = data.uvs.as_ref().map(|uvs| {
            uvs.iter()
                .map(|uv| match placement.flip_tex_coords {
                    true => DVec2::new(uv.x, 1.0 - uv.y),
                    false => *uv,
                })
                .collect()
        });
        let positions: Vec<DVec3> = data
            .positions
            .iter()
            .map(|p| to_world.transform_point3(*p))
            .collect();
        let normal_matrix = transform::normal_matrix(to_world);
        let normals: Option<Vec<DVec3>> = data.normals.as_ref().map(|ns| {
            ns.iter()
                .map(|n| (normal_matrix * *n).try_normalize().unwrap_or(DVec3::ZERO))
                .collect()
        });
        let mirrored = to_world.matrix3.determinant() < 0.0;
        let first = self.triangles.len();
        let mut cdf = Vec::with_capacity(data.indices.len());
        let mut total = 0.0;
        for (k, idx) in data.indices.iter().enumerate() {
            let mut idx = idx.map(|i| i as usize);
            if mirrored {
                idx.swap(1, 2);
            }
            let mut p = idx.map(|i| positions[i]);
            let mut ns = normals.as_ref().map(|ns| idx.map(|i| ns[i]));
            let mut ts = uvs.as_ref().map(|ts| idx.map(|i| ts[i]));
            let rewind = |p: &mut [DVec3; 3], ts: &mut Option<[DVec2; 3]>| {
                p.swap(1, 2);
                if let Some(t) = ts {
                    t.swap(1, 2);
                }
            };
            if let Some(n) = ns
                && (p[1] - p[0]).cross(p[2] - p[0]).dot(n[0] + n[1] + n[2]) < 0.0
            {
                rewind(&mut p, &mut ts);
                ns = Some([n[0], n[2], n[1]]);
            }
            if flip {
                rewind(&mut p, &mut ts);
                ns = ns.map(|n| [-n[0], -n[2], -n[1]]);
            }
            if !p.iter().all(|v| v.is_finite()) {
                return Err(SceneError::invalid(
                    field,
                    format!("triangle {k} is not finite after to_world"),
                ));
            }
            let normals_index = match ns {
                Some(n) => {
                    self.vertex_normals.push(n);
                    (self.vertex_normals.len() - 1) as u32
                }
                None => u32::MAX,
            };
            let uvs_index = match ts {
                Some(t) => {
                    self.vertex_uvs.push(t);
                    (self.vertex_uvs.len() - 1) as u32
                }
                None => u32::MAX,
            };
            let tri = Triangle {
                p,
                shape: shape_index,
                primitive: k as u32,
                normals: normals_index,
                uvs: uvs_index,
            };
            total += tri.area();
            cdf.push(total);
            self.triangles.push(tri);
        }
        if total > 0.0 {
            cdf.iter_mut().for_each(|c| *c /= total);
        }
        let count = self.triangles.len() - first;
        Ok((Geometry::Mesh { first, count, cdf }, total))
    }

    fn finish(self) -> Scene {
        let bounds: Vec<Aabb> = self.triangles.iter().map(Triangle::bounds).collect();
        let (triangle_bvh, order) = Bvh::build(&bounds);
        let in_order = || order.iter().map(|&i| &self.triangles[i as usize]);
        let accel = in_order().map(TriangleAccel::new).collect();
        let accel_tags = in_order().map(TriangleTag::new).collect();
        let analytic: Vec<u32> = (0..self.shapes.len() as u32)
            .filter(|&i| !matches!(self.shapes[i as usize].geometry, Geometry::Mesh { .. }))
            .collect();
        let analytic_bounds: Vec<Aabb> = analytic
            .iter()
            .map(|&i| self.shapes[i as usize].analytic_bounds())
            .collect();
        let (analytic_bvh, analytic_order) = Bvh::build(&analytic_bounds);
        let analytic_shapes = analytic_order
            .iter()
            .map(|&i| analytic[i as usize])
            .collect();
        let all = bounds
            .iter()
            .chain(&analytic_bounds)
            .fold(Aabb::EMPTY, |a, b| a.union(*b));
        Scene {
            name: String::new(),
            digest: SceneDigest::default(),
            files: Vec::new(),
            materials: Vec::new(),
            material_ids: Vec::new(),
            emitters: Vec::new(),
            environment: None,
            camera: Camera::new(DAffine3::IDENTITY, 45.0, Default::default(), 1, 1),
            hide_emitters: false,
            max_depth: None,
            shapes: self.shapes,
            triangles: self.triangles,
            vertex_normals: self.vertex_normals,
            vertex_uvs: self.vertex_uvs,
            accel,
            accel_tags,
            triangle_bvh,
            analytic_bvh,
            analytic_shapes,
            bounds: all,
        }
    }
}

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

fn sphere(s: &ShapeDoc, to_world: &DAffine3, field: &str) -> Result<(Geometry, f64), SceneError> {
    let center = transform::check_vec3(&s.center.unwrap_or([0.0; 3]), &format!("{field}.center"))?;
    let radius = s.radius.unwrap_or(1.0);
    if !(radius > 0.0 && radius.is_finite()) {
        return Err(SceneError::invalid(
            format!("{field}.radius"),
            format!("{radius} is not a positive radius"),
        ));
    }
    let scale = similarity_scale(&to_world.matrix3).ok_or_else(|| {
        SceneError::invalid(
            format!("{field}.to_world"),
            "a sphere's transform must be a similarity (rotation, uniform scale, translation); use a mesh for ellipsoids",
        )
    })?;
    let radius = radius * scale;
    let geometry = Geometry::Sphere {
        center: to_world.transform_point3(center),
        radius,
        to_local: (to_world.matrix3 / scale).transpose(),
    };
    Ok((geometry, 4.0 * std::f64::consts::PI * radius * radius))
}

/// The uniform scale `s` if `m = s·R` with `R` orthogonal (to 1e-6).
fn similarity_scale(m: &DMat3) -> Option<f64> {
    let cols = [m.x_axis, m.y_axis, m.z_axis];
    let s = cols[0].length();
    let tol = 1e-6 * s * s;
    let ok = cols
        .iter()
        .all(|c| (c.length_squared() - s * s).abs() <= tol)
        && cols[0].dot(cols[1]).abs() <= tol
        && cols[1].dot(cols[2]).abs() <= tol
        && cols[0].dot(cols[2]).abs() <= tol;
    ok.then_some(s)
}

fn load_environment(
    e: &EnvironmentDoc,
    files: &Files,
    budget: &Budget,
) -> Result<Environment, SceneError> {
    let field = "environment";
    match e.kind {
        EnvironmentKind::Constant => {
            reject_fields(
                field,
                "constant environment",
                &[
                    ("filename", e.filename.is_some()),
                    ("scale", e.scale.is_some()),
                    ("to_world", e.to_world.is_some()),
                ],
            )?;
            let radiance = e
                .radiance
                .ok_or_else(|| SceneError::invalid(field, "missing field `radiance`"))?;
            Ok(Environment::Constant {
                radiance: emitter::check_radiance(radiance, "environment.radiance")?,
            })
        }
        EnvironmentKind::Envmap => {
            reject_fields(field, "envmap", &[("radiance", e.radiance.is_some())])?;
            let name = e
                .filename
                .as_deref()
                .ok_or_else(|| SceneError::invalid(field, "missing field `filename`"))?;
            let scale = e.scale.unwrap_or(1.0);
            if !(0.0..=emitter::MAX_RADIANCE).contains(&scale) {
                return Err(SceneError::invalid(
                    "environment.scale",
                    format!("{scale} is not in [0, {:e}]", emitter::MAX_RADIANCE),
                ));
            }
            let rotation = match &e.to_world {
                Some(t) => {
                    let t = transform::build(t, "environment.to_world")?;
                    let is_rotation = similarity_scale(&t.matrix3)
                        .is_some_and(|s| (s - 1.0).abs() < 1e-6)
                        && t.matrix3.determinant() > 0.0
                        && t.translation == DVec3::ZERO;
                    if !is_rotation {
                        return Err(SceneError::invalid(
                            "environment.to_world",
                            "must be a rotation (no translation, scale, shear or mirroring)",
                        ));
                    }
                    t.matrix3
                }
                None => DMat3::IDENTITY,
            };
            let path = files.resolve(name, "environment.filename")?;
            let (width, height, texels) =
                read_bitmap(&path, false, "environment.filename", budget)?.into_parts();
            Ok(Environment::Map(EnvironmentMap::new(
                width, height, texels, scale, rotation,
            )))
        }
    }
}
