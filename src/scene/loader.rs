//! Builds a [`Scene`] from the JSON document: validation with field paths,
//! file resolution confined to the scenes directory, and acceleration
//! structure construction.

mod geometry;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{DMat3, DVec3};

use super::bitmap::{Bitmaps, read_bitmap};
use super::budget::{Budget, LoadLimits};
use super::emitter::{self, Emitter};
use super::environment::{Environment, EnvironmentMap};
use super::error::SceneError;
use super::files::Files;
use super::format::{EnvironmentDoc, EnvironmentKind, SceneDoc, SensorDoc};
use super::material::{Declared, Material};
use super::mesh::MeshData;
use super::meter::IrradianceMeter;
use super::shape::{ReadMesh, ShapeFields};
use super::transform::{self, similarity_scale};
use super::{Camera, MAX_PATH_DEPTH, MAX_SHAPES, MAX_TRIANGLES, Scene};
use geometry::GeometryBuilder;

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
    // Each shape's inline triangles, counted once.
    let mut inline = Vec::with_capacity(doc.shapes.len());
    for (i, s) in doc.shapes.iter().enumerate() {
        let field = format!("shapes[{i}]");
        let fields = ShapeFields {
            doc: s,
            field: &field,
        };
        let plugin = s.kind.plugin();
        plugin.check_fields(&fields)?;
        let key = match (plugin.mesh_file, fields.text("filename")?) {
            (Some(read), Some(name)) => {
                let field = fields.path("filename");
                let key = (files.resolve(name, &field)?, (plugin.mesh_index)(&fields)?);
                wanted.push((key.clone(), read, field));
                Some(key)
            }
            _ => None,
        };
        inline.push((plugin.inline_triangles)(&fields)?);
        keys.push(key);
    }
    let listed = inline.iter().sum::<usize>().min(MAX_TRIANGLES);
    let meshes = MeshFiles::read_all(wanted, MAX_TRIANGLES - listed, budget)?;
    // The mesh of each shape that names a file.
    let shape_meshes: Vec<Option<Arc<MeshData>>> = keys
        .iter()
        .map(|key| key.as_ref().and_then(|k| meshes.get(k)))
        .collect();
    let mut triangles = 0usize;
    for (i, s) in doc.shapes.iter().enumerate() {
        let field = format!("shapes[{i}]");
        // A plugin's triangles are fixed, listed inline or in its file.
        let shape_triangles = s.kind.plugin().fixed_triangles
            + inline[i]
            + shape_meshes[i]
                .as_ref()
                .map_or(0, |mesh| mesh.indices.len());
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
    let mut meters = Vec::new();
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
        if let Some(SensorDoc::Irradiancemeter) = s.sensor {
            meters.push(IrradianceMeter {
                id: s.id.clone().unwrap_or_else(|| field.clone()),
                shape: i,
            });
        }
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
        caustic_surfaces: materials.iter().any(Material::makes_caustics),
        materials,
        material_ids,
        emitters,
        meters,
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
    /// Reads the mesh files `wanted` ((canonical path, mesh index), the
    /// shape plugin's reader, the field that names it) in parallel, each once, each refused past
    /// `max_triangles`. The first error in `wanted`'s order is returned,
    /// whatever finished first.
    ///
    /// Each mesh is reserved from `budget` as it is read (its readers
    /// reserve what a file's header claims before reading it), so the
    /// meshes held at once stay within the load's budget.
    pub(super) fn read_all(
        wanted: Vec<(MeshKey, ReadMesh, String)>,
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
            .map(|((path, index), read, field)| {
                budget.check_cancel()?;
                let mesh = read(&path, index, &field, max_triangles, budget)?;
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
