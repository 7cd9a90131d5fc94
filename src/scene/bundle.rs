//! A scene uploaded with its files: the document (JSON or Mitsuba XML) and
//! the assets it references (OBJ/PLY meshes, EXR maps, PNG textures), each
//! under the relative path the document names it by.
//!
//! The assets are written into a fresh private directory as they arrive,
//! which is the scenes root of the load (so the document can reach nothing
//! else), and removed with the bundle: a loaded scene holds everything it
//! needs in memory. Asset names are checked before anything is written: relative
//! paths of plain components only (no `..`, no root or drive, no `.`
//! segments, no backslashes or NULs), each at most [`MAX_NAME_BYTES`] long
//! and [`MAX_DEPTH`] deep, no name twice, at most the bundle's `max_assets`
//! of them (the service's `limits.max_assets`).
//! The files are created by this code, never links, so nothing can point
//! outside the directory either.

use std::collections::HashSet;
use std::path::{Component, Path, PathBuf};

use super::Scene;
use super::budget::LoadLimits;
use super::error::SceneError;
use super::formats::DocumentKind;
use super::mitsuba::{MitsubaOptions, Warnings};

/// Longest asset name, bytes.
pub const MAX_NAME_BYTES: usize = 255;
/// Most directory levels in an asset name.
pub const MAX_DEPTH: usize = 8;

/// The scene file of a folder named `folder` whose root holds the scene
/// files `candidates`: the only one, else the one conventionally its scene
/// (stem `scene`, or the folder's name: `lego/scene.xml` beside
/// `lego/scene_box.xml`) when exactly one is; `None` when none or several.
pub fn main_scene_file<'a>(candidates: &'a [PathBuf], folder: Option<&str>) -> Option<&'a Path> {
    if let [one] = candidates {
        return Some(one);
    }
    let mut named = candidates.iter().filter(|path| {
        path.file_stem()
            .and_then(|s| s.to_str())
            .is_some_and(|stem| stem == "scene" || Some(stem) == folder)
    });
    match (named.next(), named.next()) {
        (Some(one), None) => Some(one),
        _ => None,
    }
}

/// A document's assets (module docs), each a file in a private directory
/// from the moment it is added: an upload is written to disk as it arrives,
/// never held whole in memory.
#[derive(Debug)]
pub struct SceneBundle {
    /// The scenes root of loads of this bundle, removed on drop.
    dir: tempfile::TempDir,
    /// Relative names in upload order.
    assets: Vec<PathBuf>,
    /// The most assets it takes.
    max_assets: usize,
    /// The names and their folders as a case-insensitive file system sees
    /// them (lower case), to refuse clashes in constant time per asset.
    folded_files: HashSet<PathBuf>,
    folded_folders: HashSet<PathBuf>,
}

impl SceneBundle {
    /// An empty bundle of at most `max_assets` assets in a fresh private
    /// directory of the system's temporary one.
    pub fn new(max_assets: usize) -> Result<SceneBundle, SceneError> {
        Self::new_in(max_assets, None)
    }

    /// [`SceneBundle::new`] in a fresh directory under `parent` when given
    /// (a folder its owner clears at startup, so that a bundle whose process
    /// ended before dropping it does not stay on disk for ever).
    pub fn new_in(max_assets: usize, parent: Option<&Path>) -> Result<SceneBundle, SceneError> {
        let mut builder = tempfile::Builder::new();
        builder.prefix("bmc-upload-");
        let dir = match parent {
            Some(parent) => builder.tempdir_in(parent),
            None => builder.tempdir(),
        }
        .map_err(|e| io_error(Path::new("<upload directory>"), e))?;
        Ok(SceneBundle {
            dir,
            assets: Vec::new(),
            max_assets,
            folded_files: HashSet::new(),
            folded_folders: HashSet::new(),
        })
    }

    /// Reserves asset `name` and creates its empty file, to which the caller
    /// writes the asset's bytes; `field` names it in errors (e.g. `assets[2]`).
    pub fn create(&mut self, name: &str, field: &str) -> Result<std::fs::File, SceneError> {
        if self.assets.len() >= self.max_assets {
            return Err(SceneError::invalid(
                field,
                format!("more than {} assets (limits.max_assets)", self.max_assets),
            ));
        }
        let path = check_name(name).map_err(|reason| {
            SceneError::invalid(field, format!("asset name {name:?}: {reason}"))
        })?;
        // Names are compared as a case-insensitive file system would: two
        // names that differ only in case, or a name that is also another's
        // folder, cannot both be files.
        let (folded, folders) = folded(&path);
        let clash = if self.folded_files.contains(&folded) {
            match self.assets.iter().find(|p| **p == path) {
                Some(_) => Some(format!("asset {name:?} is named twice")),
                None => Some(format!(
                    "asset {name:?} differs from another asset only in case"
                )),
            }
        } else if self.folded_folders.contains(&folded)
            || folders.iter().any(|f| self.folded_files.contains(f))
        {
            Some(format!(
                "asset {name:?} and another asset would make one name both a file and a folder"
            ))
        } else {
            None
        };
        if let Some(reason) = clash {
            return Err(SceneError::invalid(field, reason));
        }
        let file = self.dir.path().join(&path);
        if let Some(parent) = file.parent() {
            std::fs::create_dir_all(parent).map_err(|e| io_error(&path, e))?;
        }
        // `create_new`: a name cannot reuse a file written before it.
        let created = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&file)
            .map_err(|e| io_error(&path, e))?;
        self.assets.push(path);
        self.folded_files.insert(folded);
        self.folded_folders.extend(folders);
        Ok(created)
    }

    /// Adds an asset whose bytes are at hand ([`Self::create`], then written).
    pub fn add(&mut self, name: &str, bytes: &[u8], field: &str) -> Result<(), SceneError> {
        let mut file = self.create(name, field)?;
        std::io::Write::write_all(&mut file, bytes).map_err(|e| io_error(Path::new(name), e))
    }

    /// The most assets it takes.
    pub fn max_assets(&self) -> usize {
        self.max_assets
    }

    /// Makes `folder` (a folder of the assets) the bundle's root: the
    /// assets inside it are renamed relative to it, the others removed and
    /// returned.
    pub fn rebase(&mut self, folder: &Path) -> Result<Vec<PathBuf>, SceneError> {
        let root = tempfile::Builder::new()
            .prefix("bmc-upload-")
            .tempdir()
            .map_err(|e| io_error(Path::new("<upload directory>"), e))?;
        // `rename` replaces the fresh, empty directory with the folder.
        std::fs::rename(self.dir.path().join(folder), root.path())
            .map_err(|e| io_error(folder, e))?;
        let (inside, outside): (Vec<PathBuf>, Vec<PathBuf>) = std::mem::take(&mut self.assets)
            .into_iter()
            .partition(|name| name.starts_with(folder));
        let old = std::mem::replace(&mut self.dir, root);
        drop(old);
        self.folded_files.clear();
        self.folded_folders.clear();
        for name in inside {
            let name = name
                .strip_prefix(folder)
                .expect("partitioned on the prefix")
                .to_path_buf();
            let (folded, folders) = folded(&name);
            self.folded_folders.extend(folders);
            self.folded_files.insert(folded);
            self.assets.push(name);
        }
        Ok(outside)
    }

    /// The assets' relative names, in upload order.
    pub fn names(&self) -> impl Iterator<Item = &Path> {
        self.assets.iter().map(PathBuf::as_path)
    }

    /// Where asset `name` (one of [`Self::names`]) is on disk.
    pub fn path_of(&self, name: &Path) -> PathBuf {
        self.dir.path().join(name)
    }

    /// The bytes of every asset, read from disk: `(name, bytes)`.
    pub fn contents(&self) -> impl Iterator<Item = std::io::Result<(&Path, Vec<u8>)>> {
        self.names()
            .map(|name| std::fs::read(self.path_of(name)).map(|bytes| (name, bytes)))
    }

    /// Bytes the assets take on disk.
    pub fn bytes(&self) -> u64 {
        self.names()
            .filter_map(|name| std::fs::metadata(self.path_of(name)).ok())
            .map(|m| m.len())
            .sum()
    }

    /// Keeps only the assets `scene` was built from (its [`Scene::files`],
    /// as loaded by [`Self::load`]); returns the names of those dropped,
    /// which no one needs and no one should have to store.
    pub fn keep_used(&mut self, scene: &Scene) -> Vec<PathBuf> {
        let (kept, dropped): (Vec<PathBuf>, Vec<PathBuf>) = std::mem::take(&mut self.assets)
            .into_iter()
            .partition(|name| scene.files.contains(name));
        for name in &dropped {
            let _ = std::fs::remove_file(self.path_of(name));
        }
        self.assets = kept;
        dropped
    }

    pub fn len(&self) -> usize {
        self.assets.len()
    }

    pub fn is_empty(&self) -> bool {
        self.assets.is_empty()
    }

    /// Loads `document` against the bundle's directory (module docs)
    /// within `limits`.
    pub fn load(
        &self,
        document: &Document,
        options: &MitsubaOptions,
        limits: &LoadLimits,
    ) -> Result<(Scene, Warnings), SceneError> {
        load_document(document, options, self.dir.path(), limits)
    }
}

/// A scene document as text, with what it is.
#[derive(Clone, Debug)]
pub struct Document {
    pub text: String,
    pub kind: DocumentKind,
    /// What messages call it: the scene file's name as the client gave it
    /// (`lego/scene.xml`), never a path on the server.
    pub name: String,
}

/// Parses `document` with the files it references resolved against `root`,
/// within `limits`.
pub fn load_document(
    document: &Document,
    options: &MitsubaOptions,
    root: &Path,
    limits: &LoadLimits,
) -> Result<(Scene, Warnings), SceneError> {
    document
        .kind
        .load_text(&document.text, &document.name, root, root, options, limits)
}

/// `path` in lower case and its folders, as a case-insensitive file system
/// compares names.
fn folded(path: &Path) -> (PathBuf, Vec<PathBuf>) {
    let folded = PathBuf::from(path.to_string_lossy().to_lowercase());
    let folders = folded
        .ancestors()
        .skip(1)
        .filter(|a| !a.as_os_str().is_empty())
        .map(Path::to_path_buf)
        .collect();
    (folded, folders)
}

fn io_error(path: &Path, source: std::io::Error) -> SceneError {
    SceneError::Io {
        file: path.to_owned(),
        source,
    }
}

/// The asset name as a relative path of plain components, or why not.
fn check_name(name: &str) -> Result<PathBuf, &'static str> {
    if name.is_empty() {
        return Err("is empty");
    }
    if name.len() > MAX_NAME_BYTES {
        return Err("is too long");
    }
    if name.contains('\\') || name.contains('\0') {
        return Err("contains a backslash or NUL");
    }
    let path = Path::new(name);
    let mut depth = 0;
    for component in path.components() {
        match component {
            Component::Normal(_) => depth += 1,
            Component::ParentDir => return Err("climbs out with `..`"),
            Component::RootDir | Component::Prefix(_) => return Err("is absolute"),
            Component::CurDir => return Err("has a `.` segment"),
        }
    }
    // `Path::components` drops inner `.` segments and repeated slashes;
    // refuse them too, so the name is exactly the path.
    if name.split('/').any(|s| s.is_empty() || s == ".") {
        return Err("has an empty or `.` segment");
    }
    if depth > MAX_DEPTH {
        return Err("is nested too deeply");
    }
    Ok(path.to_owned())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_that_would_collide_on_disk_are_refused() {
        for (first, second, says) in [
            ("tri.obj", "tri.obj", "twice"),
            ("tri.obj", "TRI.obj", "only in case"),
            ("a", "a/tri.obj", "file and a folder"),
            ("meshes/a.obj", "Meshes", "file and a folder"),
        ] {
            let mut bundle = SceneBundle::new(16).unwrap();
            bundle.add(first, &[1], "assets[0]").unwrap();
            let err = bundle.add(second, &[2], "assets[1]").unwrap_err();
            assert_eq!(err.field(), Some("assets[1]"), "{first} {second}");
            assert!(err.to_string().contains(says), "{err}");
        }
        let mut bundle = SceneBundle::new(16).unwrap();
        bundle.add("a/b.obj", &[1], "assets[0]").unwrap();
        bundle.add("a/c.obj", &[1], "assets[1]").unwrap();
        bundle.add("ab", &[1], "assets[2]").unwrap();
        // The bundle's size limit names the asset and the setting.
        let mut small = SceneBundle::new(2).unwrap();
        small.add("a.obj", &[1], "assets[0]").unwrap();
        small.add("b.obj", &[1], "assets[1]").unwrap();
        let err = small.add("c.obj", &[1], "assets[2]").unwrap_err();
        assert_eq!(err.field(), Some("assets[2]"));
        assert!(err.to_string().contains("limits.max_assets"), "{err}");
    }

    #[test]
    fn names_that_could_escape_are_refused() {
        for bad in [
            "",
            "../x.obj",
            "a/../../x.obj",
            "/etc/passwd",
            "a\\b.obj",
            "./a.obj",
            "a/./b.obj",
            "a//b.obj",
            "a/",
            "x\0.obj",
            &"d/".repeat(9).to_string(),
        ] {
            assert!(check_name(bad).is_err(), "{bad:?}");
        }
        for good in ["blob.obj", "meshes/blob.obj", "a/b/c/d.exr", "x..y.png"] {
            assert_eq!(check_name(good).unwrap(), Path::new(good));
        }
        let mut bundle = SceneBundle::new(16).unwrap();
        bundle.add("a.obj", &[], "assets[0]").unwrap();
        let err = bundle.add("a.obj", &[], "assets[1]").unwrap_err();
        assert_eq!(err.field(), Some("assets[1]"));
    }

    #[test]
    fn a_document_loads_with_its_mesh_and_reaches_nothing_else() {
        let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        let doc = |file: &str| Document {
            text: format!(
                r#"{{"name": "up", "shapes": [{{"type": "obj", "filename": "{file}", "material": "m"}}],
                    "materials": [{{"id": "m", "type": "diffuse", "reflectance": [0.5, 0.5, 0.5]}}],
                    "camera": {{"type": "perspective", "fov": 40, "width": 8, "height": 8,
                                "origin": [0, 0, 3], "target": [0, 0, 0], "up": [0, 1, 0]}}}}"#
            ),
            kind: DocumentKind::Json,
            name: "up.json".into(),
        };
        let limits = LoadLimits::default();
        let mut bundle = SceneBundle::new(16).unwrap();
        bundle
            .add("meshes/tri.obj", obj.as_bytes(), "assets[0]")
            .unwrap();
        let options = MitsubaOptions::default();
        let (scene, _) = bundle
            .load(&doc("meshes/tri.obj"), &options, &limits)
            .unwrap();
        assert_eq!(scene.triangle_count(), 1);
        // The document cannot name a file outside the bundle.
        let Err(err) = bundle.load(&doc("../../etc/hosts"), &options, &limits) else {
            panic!("a name outside the bundle loaded");
        };
        assert!(matches!(err, SceneError::PathEscape { .. }), "{err}");
        // The same content gives the same digest as the same files on disk.
        let (again, _) = bundle
            .load(&doc("meshes/tri.obj"), &options, &limits)
            .unwrap();
        assert_eq!(again.digest, scene.digest);
        // An asset the document does not name is not kept.
        bundle.add("notes/unused.txt", b"x", "assets[1]").unwrap();
        let (scene, _) = bundle
            .load(&doc("meshes/tri.obj"), &options, &limits)
            .unwrap();
        assert_eq!(scene.files, [PathBuf::from("meshes/tri.obj")]);
        assert_eq!(
            bundle.keep_used(&scene),
            [PathBuf::from("notes/unused.txt")]
        );
        assert_eq!(bundle.len(), 1);
    }
}
