//! Resolving the file names a scene document gives (meshes, maps,
//! textures): relative to the scene file, never outside the scenes
//! directory, and each recorded for the scene's content digest.

use std::path::{Component, Path, PathBuf};

use super::digest::SceneDigest;
use super::error::SceneError;
use super::format::SceneDoc;

/// Resolves referenced file names: relative to the scene file, never outside
/// the scenes directory (checked lexically and again after following links).
pub(crate) struct Files {
    base: PathBuf,
    root: PathBuf,
    /// Every file resolved so far, in order, each once: what the scene's
    /// digest covers besides its document.
    opened: std::sync::Mutex<Vec<PathBuf>>,
}

impl Files {
    pub(super) fn new(base_dir: &Path, scenes_root: &Path) -> Result<Self, SceneError> {
        let canon = |p: &Path| {
            p.canonicalize().map_err(|e| {
                SceneError::file("scenes_root", p, format!("cannot resolve directory: {e}"))
            })
        };
        // The parent of a bare file name is empty: the current directory.
        let here = |p: &Path| match p.as_os_str().is_empty() {
            true => Path::new(".").to_path_buf(),
            false => p.to_path_buf(),
        };
        Ok(Self {
            base: canon(&here(base_dir))?,
            root: canon(scenes_root)?,
            opened: std::sync::Mutex::new(Vec::new()),
        })
    }

    /// The content digest of a scene built from `doc` and the files
    /// resolved so far.
    pub(super) fn digest(&self, doc: &SceneDoc) -> Result<SceneDigest, SceneError> {
        let canonical = serde_json::to_vec(doc)
            .map_err(|e| SceneError::invalid("", format!("cannot serialise the document: {e}")))?;
        let opened = self.opened.lock().unwrap_or_else(|p| p.into_inner());
        SceneDigest::of(&canonical, &opened, &self.root)
    }

    /// The files resolved so far, relative to the scenes root.
    pub(super) fn relative_opened(&self) -> Vec<PathBuf> {
        let opened = self.opened.lock().unwrap_or_else(|p| p.into_inner());
        opened
            .iter()
            .filter_map(|p| p.strip_prefix(&self.root).ok().map(Path::to_path_buf))
            .collect()
    }

    /// `e` naming files as the scene names them, relative to the scenes
    /// root: its messages reach clients, who know the scene's own names and
    /// not the server's directories (an upload's private folder, the scenes
    /// directory).
    pub(super) fn relative(&self, e: SceneError) -> SceneError {
        match e {
            SceneError::File {
                field,
                file,
                message,
            } => SceneError::File {
                field,
                file: file
                    .strip_prefix(&self.root)
                    .map(Path::to_path_buf)
                    .unwrap_or(file),
                message,
            },
            other => other,
        }
    }

    pub(super) fn resolve(&self, name: &str, field: &str) -> Result<PathBuf, SceneError> {
        let escape = || SceneError::PathEscape {
            field: field.to_string(),
            path: name.to_string(),
            root: self.root.clone(),
        };
        let mut path = PathBuf::new();
        for c in self.base.join(name).components() {
            match c {
                Component::ParentDir => {
                    if !path.pop() {
                        return Err(escape());
                    }
                }
                Component::CurDir => {}
                other => path.push(other),
            }
        }
        if !path.starts_with(&self.root) {
            return Err(escape());
        }
        let real = path
            .canonicalize()
            .map_err(|e| SceneError::file(field, &path, format!("cannot open: {e}")))?;
        if !real.starts_with(&self.root) {
            return Err(escape());
        }
        let mut opened = self.opened.lock().unwrap_or_else(|p| p.into_inner());
        if !opened.contains(&real) {
            opened.push(real.clone());
        }
        Ok(real)
    }
}
