//! Scenes posted at runtime, kept under `cache.data_dir/scenes/<id>/` so
//! they survive a restart: the document (`scene.json` or `scene.xml`), the
//! assets it came with, and `post.json` saying how it was posted. A scene
//! posted without assets resolves its files against the scenes directory
//! again when reloaded, as it did when posted. A replacement is written
//! beside the old copy and renamed over it; `DELETE` removes the copy.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::scenes::{LoadedScene, SceneSource, log_warnings, validate_id};
use crate::scene::bundle::{DocumentKind, SceneBundle};
use crate::scene::{MitsubaOptions, Scene};

/// A posted scene as it was received.
pub struct Posted {
    pub document: String,
    pub kind: DocumentKind,
    pub lenient: bool,
    /// The assets it came with (`None`: its files are in the scenes directory).
    pub bundle: Option<SceneBundle>,
}

/// `post.json`.
#[derive(Serialize, Deserialize)]
struct PostRecord {
    xml: bool,
    lenient: bool,
    with_assets: bool,
}

/// Where posted scenes are kept; `None` keeps them in memory only.
pub struct PostedScenes {
    dir: Option<PathBuf>,
}

impl PostedScenes {
    /// Posted scenes under `data_dir/scenes` (empty `data_dir`: not kept).
    pub fn new(data_dir: &Path) -> Self {
        Self {
            dir: (!data_dir.as_os_str().is_empty()).then(|| data_dir.join("scenes")),
        }
    }

    /// Keeps `posted` as scene `id`, replacing an earlier copy.
    pub fn save(&self, id: &str, posted: &Posted) -> std::io::Result<()> {
        let Some(dir) = &self.dir else {
            return Ok(());
        };
        std::fs::create_dir_all(dir)?;
        let staging = tempfile::Builder::new()
            .prefix(".posting-")
            .tempdir_in(dir)?;
        let xml = posted.kind == DocumentKind::MitsubaXml;
        let name = if xml { "scene.xml" } else { "scene.json" };
        std::fs::write(staging.path().join(name), &posted.document)?;
        let record = PostRecord {
            xml,
            lenient: posted.lenient,
            with_assets: posted.bundle.is_some(),
        };
        std::fs::write(
            staging.path().join("post.json"),
            serde_json::to_vec(&record).map_err(std::io::Error::other)?,
        )?;
        for (path, bytes) in posted.bundle.iter().flat_map(SceneBundle::assets) {
            let target = staging.path().join("assets").join(path);
            if let Some(parent) = target.parent() {
                std::fs::create_dir_all(parent)?;
            }
            std::fs::write(target, bytes)?;
        }
        let kept = staging.keep();
        let final_dir = dir.join(id);
        let _ = std::fs::remove_dir_all(&final_dir);
        std::fs::rename(&kept, &final_dir)
    }

    /// Forgets scene `id`.
    pub fn remove(&self, id: &str) {
        if let Some(dir) = &self.dir {
            let _ = std::fs::remove_dir_all(dir.join(id));
        }
    }

    /// Every kept scene, loaded; `scenes_dir` resolves the files of those
    /// posted without assets. Broken copies are logged and skipped.
    pub fn load_all(&self, scenes_dir: &Path) -> Vec<LoadedScene> {
        let Some(dir) = &self.dir else {
            return Vec::new();
        };
        let Ok(entries) = std::fs::read_dir(dir) else {
            return Vec::new();
        };
        let mut loaded = Vec::new();
        for entry in entries.filter_map(Result::ok) {
            let id = entry.file_name().to_string_lossy().into_owned();
            if id.starts_with('.') || validate_id(&id).is_err() {
                continue;
            }
            match load_one(&entry.path(), scenes_dir) {
                Ok(mut scene) => {
                    if scene.name.is_empty() {
                        scene.name = id.clone();
                    }
                    loaded.push(LoadedScene::new(id, SceneSource::Uploaded, scene));
                }
                Err(err) => tracing::warn!(%id, %err, "posted scene not reloaded"),
            }
        }
        loaded.sort_by(|a, b| a.id.cmp(&b.id));
        loaded
    }
}

fn load_one(dir: &Path, scenes_dir: &Path) -> anyhow::Result<Scene> {
    let record: PostRecord = serde_json::from_slice(&std::fs::read(dir.join("post.json"))?)?;
    let name = if record.xml {
        "scene.xml"
    } else {
        "scene.json"
    };
    let document = std::fs::read_to_string(dir.join(name))?;
    let root = if record.with_assets {
        dir.join("assets")
    } else {
        scenes_dir.to_owned()
    };
    std::fs::create_dir_all(&root)?;
    let scene = if record.xml {
        let options = MitsubaOptions {
            lenient: record.lenient,
            ..MitsubaOptions::default()
        };
        let (scene, warnings) = Scene::from_mitsuba_xml_str(&document, &root, &root, &options)?;
        log_warnings(&dir.display().to_string(), &warnings);
        scene
    } else {
        Scene::from_json_str(&document, &root, &root)?
    };
    Ok(scene)
}
