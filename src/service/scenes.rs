//! The scene registry: scenes loaded from the scenes directory at startup or
//! posted later, each with its light-transport state built once.
//!
//! A scene's id is its file stem (`scenes/cornell-box.json` → `cornell-box`),
//! its folder's name for a scene folder (see [`find_scenes`], also for XML
//! twins) or, for a posted scene, its JSON `name` or
//! the `id` query parameter given with XML. Ids are restricted to
//! `[A-Za-z0-9_-]{1,64}` because they appear in URL paths. A broken scene file
//! is logged and skipped at startup, never fatal: one bad file must not keep the
//! other scenes from being served.

use crate::scene::bundle::main_scene_file;
use crate::scene::formats::DocumentKind;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, RwLock};

use rayon::prelude::*;
use serde::Serialize;
use utoipa::ToSchema;

use crate::cancel::Cancel;
use crate::estimators::calibration::Calibrations;
use crate::estimators::lengthscale::{FittedKernel, FittedKernels};
use crate::render::Transport;
use crate::scene::{LoadLimits, MitsubaOptions, Scene, SceneError, Warnings};
use crate::service::config::ScenesConfig;
use crate::service::error::ApiError;

/// Longest accepted scene id.
pub const MAX_ID_LEN: usize = 64;

/// Where a loaded scene came from.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum SceneSource {
    /// A `*.json` or Mitsuba `*.xml` file of the scenes directory, loaded at startup.
    File,
    /// A document posted to `POST /v1/scenes`.
    Uploaded,
}

/// Source of [`LoadedScene::generation`].
static NEXT_GENERATION: AtomicU64 = AtomicU64::new(0);

/// A scene ready to answer queries.
pub struct LoadedScene {
    /// Registry key, used in URLs.
    pub id: String,
    pub source: SceneSource,
    /// The scene with its light-selection tables and BSDFs, built once.
    pub transport: Transport,
    /// Unique per load (a scene posted again gets a new one), so caches
    /// keyed by it never mix versions of a scene.
    pub generation: u64,
    /// Lengthscales fitted for `"lengthscale": "auto"`, per estimator
    /// configuration; they live and die with this loaded scene.
    pub kernels: FittedKernels,
    /// Error-bar calibrations per estimator configuration, likewise.
    pub calibrations: Calibrations,
    /// Triangles of the scene, counted against `scenes.max_triangles`.
    pub triangles: usize,
    /// Heap bytes of the scene, counted against `scenes.max_scene_bytes`.
    pub bytes: u64,
    /// What loading approximated (lenient Mitsuba XML), the first
    /// [`crate::scene::MAX_WARNINGS`] of them, and how many there were.
    pub approximated: Vec<String>,
    pub approximations: usize,
}

/// What `GET /v1/scenes[/{id}]` tells about a scene.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct SceneSummary {
    pub id: String,
    /// The document's display name.
    pub name: String,
    pub source: SceneSource,
    /// Content digest of the document and its files (64 hex digits): the
    /// same scene has the same digest in every process.
    #[schema(value_type = String)]
    pub digest: crate::scene::SceneDigest,
    /// Entries of the document's `shapes`.
    pub shapes: usize,
    /// Triangles (spheres and disks are analytic and not counted).
    pub triangles: usize,
    /// Area emitters.
    pub emitters: usize,
    pub materials: Vec<String>,
    /// Whether an environment (constant or map) lights the scene.
    pub environment: bool,
    /// Camera image size `[width, height]` in pixels (the tile space).
    pub resolution: [u32; 2],
    /// Axis-aligned bounds of the geometry, world units.
    pub bounds_min: [f64; 3],
    pub bounds_max: [f64; 3],
    /// Kernels fitted so far for `"lengthscale": "auto"` (`estimators::lengthscale`):
    /// `kernel`, `sample_set`, `decomposition`, `lengthscale`, `noise_ratio`,
    /// `log_marginal_likelihood`, `at_bound`, `fit_samples`, `points`.
    #[schema(value_type = Vec<Object>)]
    pub fitted_kernels: Vec<FittedKernel>,
    /// What a lenient load approximated, one line each (`line N: <element>:
    /// what was done`), at most the first 100; empty for an exact load.
    pub approximated: Vec<String>,
    /// How many approximations there were in all.
    pub approximations: usize,
}

impl LoadedScene {
    pub fn new(id: String, source: SceneSource, scene: Scene) -> LoadedScene {
        let triangles = scene.triangle_count();
        let bytes = scene.heap_bytes();
        LoadedScene {
            id,
            source,
            transport: Transport::new(Arc::new(scene)),
            generation: NEXT_GENERATION.fetch_add(1, Ordering::Relaxed),
            kernels: FittedKernels::default(),
            calibrations: Calibrations::default(),
            triangles,
            bytes,
            approximated: Vec::new(),
            approximations: 0,
        }
    }

    /// The same scene, with what loading it approximated.
    pub fn approximating(mut self, warnings: &Warnings) -> LoadedScene {
        self.approximated = warnings.iter().map(ToString::to_string).collect();
        self.approximations = warnings.total();
        self
    }

    pub fn summary(&self) -> SceneSummary {
        let scene = self.transport.scene();
        let (min, max) = scene.bounds();
        let (width, height) = scene.camera.resolution();
        SceneSummary {
            id: self.id.clone(),
            name: scene.name.clone(),
            source: self.source.clone(),
            digest: scene.digest,
            shapes: scene.shape_count(),
            triangles: scene.triangle_count(),
            emitters: scene.emitters.len(),
            materials: scene.material_ids.clone(),
            environment: scene.environment.is_some(),
            resolution: [width, height],
            bounds_min: min.to_array(),
            bounds_max: max.to_array(),
            fitted_kernels: self.kernels.list(),
            approximated: self.approximated.clone(),
            approximations: self.approximations,
        }
    }
}

/// A scene that would take the loaded scenes over a `scenes.max_*` budget.
#[derive(Debug, Clone, PartialEq)]
pub struct OverBudget {
    /// The config key of the budget, e.g. `scenes.max_triangles`.
    pub field: &'static str,
    /// The total the scene would bring the loaded scenes to.
    pub total: u64,
    pub limit: u64,
}

impl std::fmt::Display for OverBudget {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "loading this scene would bring the loaded scenes to {} against `{}` = {}; delete scenes first",
            self.total, self.field, self.limit
        )
    }
}

impl From<OverBudget> for ApiError {
    fn from(over: OverBudget) -> Self {
        ApiError::InsufficientStorage {
            field: over.field.to_owned(),
            message: over.to_string(),
        }
    }
}

/// Why [`SceneRegistry::insert`] did not insert a scene.
#[derive(Debug, Clone, PartialEq)]
pub enum NotInserted {
    /// It would take the loaded scenes over a budget.
    OverBudget(OverBudget),
    /// A scene holds its id, and it was not to be replaced.
    Exists,
}

/// Scenes by id; readers share, writers (post/delete) are brief.
pub struct SceneRegistry {
    scenes: RwLock<HashMap<String, Arc<LoadedScene>>>,
    /// Its `max_scenes`, `max_triangles` and `max_scene_bytes` are the
    /// budgets of all loaded scenes together.
    budget: ScenesConfig,
}

impl SceneRegistry {
    pub fn new(budget: &ScenesConfig) -> Self {
        SceneRegistry {
            scenes: RwLock::default(),
            budget: budget.clone(),
        }
    }

    pub fn get(&self, id: &str) -> Option<Arc<LoadedScene>> {
        self.read().get(id).cloned()
    }

    /// What loading scene `id` may hold: the `scenes.max_scene_bytes` left
    /// beside the other loaded scenes (the one it would replace does not
    /// count), stopped by `cancel`. Concurrent loads may each see the same
    /// room; [`Self::insert`] still holds the sum to the budget.
    pub fn load_limits(&self, id: &str, cancel: Cancel) -> LoadLimits {
        let others: u64 = self
            .read()
            .values()
            .filter(|s| s.id != id)
            .map(|s| s.bytes)
            .sum();
        LoadLimits {
            max_bytes: self.budget.max_scene_bytes.saturating_sub(others),
            budget: "scenes.max_scene_bytes",
            cancel,
        }
    }

    /// Adds a scene, or replaces the one with its id if `replace`; returns
    /// the one it replaced. A scene whose id is taken (without `replace`),
    /// or that would take the loaded scenes over the budget (counting them
    /// without the scene it replaces), is refused and nothing changes.
    pub fn insert(
        &self,
        scene: LoadedScene,
        replace: bool,
    ) -> Result<Option<Arc<LoadedScene>>, NotInserted> {
        let mut scenes = self.scenes.write().unwrap_or_else(|p| p.into_inner());
        if !replace && scenes.contains_key(&scene.id) {
            return Err(NotInserted::Exists);
        }
        let others = scenes.values().filter(|s| s.id != scene.id);
        let (count, triangles, bytes) = others
            .fold((1u64, scene.triangles as u64, scene.bytes), |acc, s| {
                (acc.0 + 1, acc.1 + s.triangles as u64, acc.2 + s.bytes)
            });
        let checks = [
            ("scenes.max_scenes", count, self.budget.max_scenes as u64),
            (
                "scenes.max_triangles",
                triangles,
                self.budget.max_triangles as u64,
            ),
            ("scenes.max_scene_bytes", bytes, self.budget.max_scene_bytes),
        ];
        if let Some(&(field, total, limit)) = checks.iter().find(|(_, total, limit)| total > limit)
        {
            return Err(NotInserted::OverBudget(OverBudget {
                field,
                total,
                limit,
            }));
        }
        Ok(scenes.insert(scene.id.clone(), Arc::new(scene)))
    }

    /// Undoes an [`Self::insert`] or [`Self::remove`] of `id` whose change
    /// could not be persisted: `previous` (what it replaced or removed) goes
    /// back, or `id` goes away if there was none.
    pub fn restore(&self, id: &str, previous: Option<Arc<LoadedScene>>) {
        let mut scenes = self.scenes.write().unwrap_or_else(|p| p.into_inner());
        match previous {
            Some(scene) => scenes.insert(id.to_owned(), scene),
            None => scenes.remove(id),
        };
    }

    /// Removes a scene; in-flight requests holding it finish with their `Arc`.
    pub fn remove(&self, id: &str) -> Option<Arc<LoadedScene>> {
        let mut scenes = self.scenes.write().unwrap_or_else(|p| p.into_inner());
        scenes.remove(id)
    }

    pub fn len(&self) -> usize {
        self.read().len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Summaries of every scene, sorted by id.
    pub fn summaries(&self) -> Vec<SceneSummary> {
        let mut all: Vec<_> = self.read().values().map(|s| s.summary()).collect();
        all.sort_by(|a, b| a.id.cmp(&b.id));
        all
    }

    /// A poisoned lock only means a writer panicked mid-insert of a whole
    /// `Arc`, which leaves the map consistent, so keep serving.
    fn read(&self) -> std::sync::RwLockReadGuard<'_, HashMap<String, Arc<LoadedScene>>> {
        self.scenes.read().unwrap_or_else(|p| p.into_inner())
    }
}

/// Checks that `id` can be used as a scene id (see module docs).
pub fn validate_id(id: &str) -> Result<(), InvalidId> {
    let ok_chars = id
        .chars()
        .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_');
    if id.is_empty() || id.len() > MAX_ID_LEN || !ok_chars {
        Err(InvalidId(format!(
            "scene id must be 1..={MAX_ID_LEN} characters of A-Z, a-z, 0-9, '-', '_', got {id:?}"
        )))
    } else {
        Ok(())
    }
}

/// Why a string is not a scene id ([`validate_id`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct InvalidId(String);

/// A 422 about whichever request field carries the id: a handler places it
/// with [`super::error::AtField::at`] (`id` of a query, `name` of a document).
impl From<InvalidId> for ApiError {
    fn from(InvalidId(reason): InvalidId) -> Self {
        ApiError::invalid("", reason)
    }
}

/// The regular `*.json` and `*.xml` files at the root of `dir`, sorted;
/// anything else with those extensions is skipped with a warning.
fn scene_files_in(dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)?
        .filter_map(Result::ok)
        .map(|entry| entry.path())
        .filter(|path| DocumentKind::of_file_name(path).is_some())
        // A FIFO would block the reader (and startup) forever and a device
        // can read endlessly; loading refuses them too, this says why early.
        .filter(|path| match std::fs::metadata(path) {
            Ok(meta) if meta.is_file() => true,
            Ok(_) => {
                tracing::warn!(file = %path.display(), "scene skipped: not a regular file");
                false
            }
            Err(err) => {
                tracing::warn!(file = %path.display(), %err, "scene skipped: cannot stat");
                false
            }
        })
        .collect();
    files.sort();
    Ok(files)
}

/// A scene the scenes directory holds: its id, its file and the directory
/// its files may not leave.
struct Found {
    id: String,
    path: PathBuf,
    root: PathBuf,
}

/// The scenes of `dir`: each `*.json` and `*.xml` file at its root (id: the
/// file stem, except an XML file whose stem a JSON file also has: it gets
/// `<stem>-xml`, `cornell-box.xml` → `cornell-box-xml`, so both stay
/// reachable; its files may come from anywhere under `dir`), and each
/// subfolder with a scene file at its root (id: the folder's name; its
/// files stay inside the folder): the only one, or among several the one
/// named `scene` or after the folder ([`main_scene_file`]). A folder with
/// several and none of those names is skipped with a warning naming them;
/// one with none (`meshes/`) is not a scene. An id taken twice keeps the first.
fn find_scenes(dir: &Path) -> std::io::Result<Vec<Found>> {
    let files = scene_files_in(dir)?;
    let has_json_twin = |path: &Path| files.contains(&path.with_extension("json"));
    let mut found: Vec<Found> = files
        .iter()
        .filter_map(|path| {
            let stem = path.file_stem()?.to_string_lossy().into_owned();
            let is_xml = DocumentKind::of_file_name(path) == Some(DocumentKind::MitsubaXml);
            let id = if is_xml && has_json_twin(path) {
                format!("{stem}-xml")
            } else {
                stem
            };
            Some(Found {
                id,
                path: path.clone(),
                root: dir.to_path_buf(),
            })
        })
        .collect();
    let mut folders: Vec<PathBuf> = std::fs::read_dir(dir)?
        .filter_map(Result::ok)
        .filter(|entry| entry.file_type().is_ok_and(|t| t.is_dir()))
        .map(|entry| entry.path())
        .collect();
    folders.sort();
    for folder in folders {
        let Ok(inner) = scene_files_in(&folder) else {
            continue;
        };
        let id = folder
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        match (main_scene_file(&inner, Some(&id)), inner.as_slice()) {
            (_, []) => {}
            (Some(path), _) if found.iter().any(|f| f.id == id) => {
                tracing::warn!(file = %path.display(), %id, "scene skipped: its id is taken");
            }
            (Some(path), _) => found.push(Found {
                id,
                path: path.to_path_buf(),
                root: folder.clone(),
            }),
            (None, several) => tracing::warn!(
                folder = %folder.display(),
                files = ?several,
                "scene folder skipped: it holds several scene files at its root, none named \
                 `scene` or after the folder"
            ),
        }
    }
    Ok(found)
}

/// Loads every scene of `dir` ([`find_scenes`]) in parallel, Mitsuba XML
/// strictly or, with `lenient`, approximating what the scene model cannot
/// represent (each scene says what in its summary). Files that fail are
/// logged and skipped. A missing directory or one that gives no scene is not
/// an error but a warning ([`warn_no_scenes`]). Each scene is loaded within
/// `limits`.
pub fn load_dir(dir: &Path, lenient: bool, limits: &LoadLimits) -> Vec<LoadedScene> {
    let found = match find_scenes(dir) {
        Ok(found) => found,
        Err(err) => {
            warn_no_scenes(dir, &format!("cannot read the scenes directory ({err})"));
            return Vec::new();
        }
    };
    let options = MitsubaOptions {
        lenient,
        ..MitsubaOptions::default()
    };
    let loaded: Vec<LoadedScene> = found
        .par_iter()
        .filter_map(|Found { id, path, root }| {
            if let Err(reason) = validate_id(id) {
                tracing::warn!(file = %path.display(), %reason, "scene skipped");
                return None;
            }
            match Scene::load_within(path, root, &options, limits) {
                Ok((scene, warnings)) => {
                    tracing::info!(%id, file = %path.display(), "scene loaded");
                    log_warnings(id, &warnings);
                    let scene = LoadedScene::new(id.clone(), SceneSource::File, scene);
                    Some(scene.approximating(&warnings))
                }
                Err(err) => {
                    log_broken(path, &err);
                    None
                }
            }
        })
        .collect();
    if loaded.is_empty() {
        warn_no_scenes(
            dir,
            "the scenes directory holds no loadable *.json or *.xml scene",
        );
    }
    loaded
}

/// The repository's bundled scenes, as seen when this crate was built.
const BUNDLED_SCENES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes");

/// Warns that `dir` gave no scene, naming it as configured and as an absolute
/// path and saying how to point at the bundled scenes. `scenes.dir` is relative
/// to the working directory, so a service started outside the repository
/// serves nothing, and a line at INFO was easy to miss.
fn warn_no_scenes(dir: &Path, why: &str) {
    let absolute = std::path::absolute(dir).unwrap_or_else(|_| dir.to_path_buf());
    // Suggest the bundled directory only where it still exists (not after
    // `cargo install` from a registry, whose build directory is gone).
    let example = if Path::new(BUNDLED_SCENES).is_dir() {
        BUNDLED_SCENES
    } else {
        "/path/to/scenes"
    };
    tracing::warn!(
        dir = %dir.display(),
        absolute = %absolute.display(),
        "no scenes loaded: {why}; scenes.dir is relative to the working directory: start the \
         service from the repository root, or set `[scenes] dir` in a `--config` file or \
         BMC_SCENES__DIR={example}"
    );
}

/// Warnings logged one by one per scene; the rest are only counted, so a
/// document with thousands of unsupported elements costs one log line per
/// [`LOGGED_WARNINGS`], not per element.
pub const LOGGED_WARNINGS: usize = 5;

/// Logs the approximations made while loading scene `id`: their count and
/// the first [`LOGGED_WARNINGS`].
pub fn log_warnings(id: &str, warnings: &Warnings) {
    if warnings.total() == 0 {
        return;
    }
    for warning in warnings.iter().take(LOGGED_WARNINGS) {
        tracing::warn!(%id, %warning, "scene approximated");
    }
    if warnings.total() > LOGGED_WARNINGS {
        tracing::warn!(
            %id,
            total = warnings.total(),
            logged = LOGGED_WARNINGS,
            "scene approximated in more places than logged"
        );
    }
}

fn log_broken(path: &Path, err: &SceneError) {
    tracing::error!(file = %path.display(), error = %err, "scene skipped: cannot load");
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::testing::TINY_SCENE as TINY;

    #[test]
    fn ids_are_url_safe() {
        for good in ["cornell-box", "a", "scene_2"] {
            assert!(validate_id(good).is_ok(), "{good}");
        }
        let long = "x".repeat(MAX_ID_LEN + 1);
        for bad in ["", "a/b", "..", "sp ace", long.as_str()] {
            assert!(validate_id(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn broken_files_are_skipped_and_good_ones_loaded() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("good.json"), TINY).unwrap();
        std::fs::write(dir.path().join("broken.json"), "{ not json").unwrap();
        std::fs::write(dir.path().join("bad id!.json"), TINY).unwrap();
        std::fs::write(dir.path().join("notes.txt"), "ignored").unwrap();
        let loaded = load_dir(dir.path(), false, &LoadLimits::default());
        let ids: Vec<_> = loaded.iter().map(|s| s.id.as_str()).collect();
        assert_eq!(ids, ["good"]);

        let registry = SceneRegistry::new(&crate::service::Config::default_config().scenes);
        for scene in loaded {
            assert!(registry.insert(scene, true).unwrap().is_none());
        }
        assert_eq!(registry.len(), 1);
        let summary = &registry.summaries()[0];
        assert_eq!(summary.resolution, [8, 8]);
        assert_eq!(summary.materials, ["white"]);
        assert!(summary.environment);
        assert!(registry.remove("good").is_some());
        assert!(registry.is_empty());
    }

    #[test]
    fn budgets_refuse_scenes_net_of_the_one_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let tiny = |id: &str| {
            let scene = Scene::from_json_str(TINY, dir.path(), dir.path()).unwrap();
            LoadedScene::new(id.into(), SceneSource::Uploaded, scene)
        };
        let mut budget = crate::service::Config::default_config().scenes;
        // Two triangles per tiny scene: room for two scenes' triangles.
        budget.max_triangles = 4;
        budget.max_scenes = 2;
        let registry = SceneRegistry::new(&budget);
        assert!(registry.insert(tiny("a"), false).unwrap().is_none());
        assert!(registry.insert(tiny("b"), false).unwrap().is_none());
        // An id taken is refused unless the scene is to replace it, which
        // counts without the scene replaced.
        assert_eq!(
            registry.insert(tiny("a"), false).err(),
            Some(NotInserted::Exists)
        );
        assert!(registry.insert(tiny("a"), true).unwrap().is_some());
        let Err(NotInserted::OverBudget(over)) = registry.insert(tiny("c"), false) else {
            panic!("over the budget, yet inserted")
        };
        assert_eq!(over.field, "scenes.max_scenes");
        assert_eq!((over.total, over.limit), (3, 2));
        budget.max_scenes = 10;
        let registry = SceneRegistry::new(&budget);
        registry.insert(tiny("a"), false).unwrap();
        registry.insert(tiny("b"), false).unwrap();
        let Err(NotInserted::OverBudget(over)) = registry.insert(tiny("c"), false) else {
            panic!("over the budget, yet inserted")
        };
        assert_eq!(over.field, "scenes.max_triangles");
        assert_eq!((over.total, over.limit), (6, 4));
        // Bytes: room for exactly the scenes already loaded.
        let bytes = tiny("x").bytes;
        budget.max_triangles = 100;
        budget.max_scene_bytes = 2 * bytes;
        let registry = SceneRegistry::new(&budget);
        registry.insert(tiny("a"), false).unwrap();
        registry.insert(tiny("b"), false).unwrap();
        let Err(NotInserted::OverBudget(over)) = registry.insert(tiny("c"), false) else {
            panic!("over the budget, yet inserted")
        };
        assert_eq!(over.field, "scenes.max_scene_bytes");
        // Nothing was lost.
        assert_eq!(registry.len(), 2);
        let error = ApiError::from(over);
        assert_eq!(error.status(), axum::http::StatusCode::INSUFFICIENT_STORAGE);
        assert_eq!(error.field(), Some("scenes.max_scene_bytes"));
    }

    #[test]
    fn scene_folders_are_scenes_named_after_them() {
        let xml = |extra: &str| {
            format!(
                r#"<scene version="3.0.0"><sensor type="perspective"><film type="hdrfilm">
                <integer name="width" value="8"/><integer name="height" value="8"/></film></sensor>
                <shape type="obj"><string name="filename" value="meshes/quad.obj"/></shape>{extra}</scene>"#
            )
        };
        let dir = tempfile::tempdir().unwrap();
        let write = |path: &str, text: &str| {
            let path = dir.path().join(path);
            std::fs::create_dir_all(path.parent().unwrap()).unwrap();
            std::fs::write(path, text).unwrap();
        };
        let quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";
        write("good.json", TINY);
        // A folder scene: named after the folder, its mesh beside it.
        write("lego/scene.xml", &xml(""));
        write("lego/meshes/quad.obj", quad);
        // Not scenes: assets only, two scene files, an id already taken.
        write("meshes/quad.obj", quad);
        write("two/a.json", TINY);
        write("two/b.json", TINY);
        write("good/scene.json", TINY);
        // Approximated only when the directory's policy is lenient.
        write("approx/scene.xml", &xml("<foo/>"));
        write("approx/meshes/quad.obj", quad);
        let ids = |lenient| {
            let mut loaded = load_dir(dir.path(), lenient, &LoadLimits::default());
            loaded.sort_by(|a, b| a.id.cmp(&b.id));
            loaded
        };
        let strict = ids(false);
        let strict_ids: Vec<_> = strict.iter().map(|s| s.id.as_str()).collect();
        assert_eq!(strict_ids, ["good", "lego"]);
        assert_eq!(strict[1].transport.scene().triangle_count(), 2);
        let lenient = ids(true);
        let lenient_ids: Vec<_> = lenient.iter().map(|s| s.id.as_str()).collect();
        assert_eq!(lenient_ids, ["approx", "good", "lego"]);
        assert_eq!(lenient[0].approximations, 1);
        assert!(
            lenient[0].approximated[0].contains("<foo>"),
            "{:?}",
            lenient[0].approximated
        );
    }

    #[test]
    fn missing_directory_loads_nothing() {
        let dir = tempfile::tempdir().unwrap();
        assert!(load_dir(&dir.path().join("absent"), false, &LoadLimits::default()).is_empty());
    }
}
