//! Scenes posted at runtime, kept under `cache.data_dir/scenes/<id>/` so
//! they survive a restart: the document (`scene.json` or `scene.xml`), the
//! assets it came with, and `post.json` saying how it was posted. A scene
//! posted without assets resolves its files against the scenes directory
//! again when reloaded, as it did when posted. A replacement is written
//! beside the old copy and renamed over it; `DELETE` removes the copy.
//!
//! Replicas pass posted scenes to each other as one blob
//! ([`Posted::encode`]): `BMCSCN01 | header length: u32 LE | header JSON |
//! asset bytes`, the header holding the document, how it was posted and
//! each asset's name and length, in order.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::scenes::{LoadedScene, SceneSource, log_warnings, validate_id};
use crate::scene::bundle::{Document, SceneBundle, load_document};
use crate::scene::formats::DocumentKind;
use crate::scene::{LoadLimits, MitsubaOptions, Scene, SceneError, Warnings};

/// First bytes of a posted scene's blob.
const BLOB_MAGIC: &[u8; 8] = b"BMCSCN01";

/// A posted scene as it was received.
pub struct Posted {
    pub document: Document,
    pub lenient: bool,
    /// Values of a Mitsuba XML scene's `$NAME` parameters.
    pub parameters: BTreeMap<String, String>,
    /// The assets it came with (`None`: its files are in the scenes directory).
    pub bundle: Option<SceneBundle>,
}

/// The header of a posted scene's blob (module docs).
#[derive(Serialize, Deserialize)]
struct BlobHeader {
    xml: bool,
    lenient: bool,
    #[serde(default)]
    parameters: BTreeMap<String, String>,
    document: String,
    /// The document's name as posted (older blobs have none).
    #[serde(default)]
    name: Option<String>,
    /// `(name, bytes)` of each asset; `None`: posted without assets.
    assets: Option<Vec<(String, u64)>>,
}

impl Posted {
    /// The blob replicas exchange (module docs); the assets are read from
    /// the bundle's files.
    pub fn encode(&self) -> std::io::Result<Vec<u8>> {
        let contents: Vec<(&Path, Vec<u8>)> = self
            .bundle
            .iter()
            .flat_map(SceneBundle::contents)
            .collect::<std::io::Result<_>>()?;
        let header = BlobHeader {
            xml: self.document.kind == DocumentKind::MitsubaXml,
            lenient: self.lenient,
            parameters: self.parameters.clone(),
            document: self.document.text.clone(),
            name: Some(self.document.name.clone()),
            assets: self.bundle.as_ref().map(|_| {
                contents
                    .iter()
                    .map(|(p, bytes)| (p.to_string_lossy().into_owned(), bytes.len() as u64))
                    .collect()
            }),
        };
        let header = serde_json::to_vec(&header).expect("a header serialises");
        let mut out = BLOB_MAGIC.to_vec();
        out.extend((header.len() as u32).to_le_bytes());
        out.extend(header);
        for (_, bytes) in &contents {
            out.extend_from_slice(bytes);
        }
        Ok(out)
    }

    /// A blob read back; asset names are checked again (`SceneBundle::add`).
    pub fn decode(blob: &[u8]) -> anyhow::Result<Posted> {
        let rest = blob
            .strip_prefix(BLOB_MAGIC.as_slice())
            .ok_or_else(|| anyhow::anyhow!("not a posted-scene blob"))?;
        let (length, rest) = rest
            .split_first_chunk::<4>()
            .ok_or_else(|| anyhow::anyhow!("truncated blob"))?;
        let length = u32::from_le_bytes(*length) as usize;
        anyhow::ensure!(rest.len() >= length, "truncated blob header");
        let (header, mut rest) = rest.split_at(length);
        let header: BlobHeader = serde_json::from_slice(header)?;
        let bundle = match header.assets {
            None => None,
            Some(assets) => {
                // Checked against the poster's limit when it was posted.
                let mut bundle = SceneBundle::new(assets.len())?;
                for (i, (name, len)) in assets.into_iter().enumerate() {
                    let len = usize::try_from(len)?;
                    anyhow::ensure!(rest.len() >= len, "truncated asset {name:?}");
                    let (bytes, tail) = rest.split_at(len);
                    bundle.add(&name, bytes, &format!("assets[{i}]"))?;
                    rest = tail;
                }
                Some(bundle)
            }
        };
        anyhow::ensure!(rest.is_empty(), "trailing bytes after the assets");
        Ok(Posted {
            document: kept_document(header.document, header.xml, header.name),
            lenient: header.lenient,
            parameters: header.parameters,
            bundle,
        })
    }

    /// Loads the scene as it was when posted, within `limits`: against its
    /// assets, or against `scenes_dir` when it came without.
    pub fn load(
        &self,
        scenes_dir: &Path,
        limits: &LoadLimits,
    ) -> Result<(Scene, Warnings), SceneError> {
        match &self.bundle {
            Some(bundle) => bundle.load(&self.document, &self.options(), limits),
            None => load_document(&self.document, &self.options(), scenes_dir, limits),
        }
    }

    fn options(&self) -> MitsubaOptions {
        MitsubaOptions {
            lenient: self.lenient,
            parameters: self.parameters.clone(),
        }
    }
}

/// `post.json`.
#[derive(Serialize, Deserialize)]
struct PostRecord {
    xml: bool,
    lenient: bool,
    #[serde(default)]
    parameters: BTreeMap<String, String>,
    with_assets: bool,
    /// The document's name as posted (older records have none).
    #[serde(default)]
    name: Option<String>,
}

/// A kept document: its text, its format and the name it was posted under
/// (what the file it is kept in is called, for copies kept before names
/// were).
fn kept_document(text: String, xml: bool, name: Option<String>) -> Document {
    let kind = match xml {
        true => DocumentKind::MitsubaXml,
        false => DocumentKind::Json,
    };
    let file = kind.file_name();
    Document {
        text,
        kind,
        name: name.unwrap_or_else(|| file.to_owned()),
    }
}

/// Where posted scenes are kept; `None` keeps them in memory only.
#[derive(Clone)]
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

    /// Where uploads are written while they arrive and load
    /// (`data_dir/uploads`), created on demand; `None` when nothing is kept.
    pub fn incoming(&self) -> Option<PathBuf> {
        let dir = self.dir.as_ref()?.with_file_name("uploads");
        std::fs::create_dir_all(&dir).ok()?;
        Some(dir)
    }

    /// Removes what uploads left in [`Self::incoming`]: called once at
    /// startup, when no upload can be under way, so that one a stopped
    /// process never finished does not stay on disk.
    pub fn clear_incoming(&self) {
        if let Some(dir) = self.dir.as_ref().map(|d| d.with_file_name("uploads"))
            && let Err(err) = std::fs::remove_dir_all(&dir)
            && err.kind() != std::io::ErrorKind::NotFound
        {
            tracing::warn!(dir = %dir.display(), %err, "uploads of an earlier run not removed");
        }
    }

    /// Bytes the kept scenes would take on disk with `posted` kept as `id`
    /// (replacing an earlier copy of `id`).
    pub fn bytes_with(&self, id: &str, posted: &Posted) -> std::io::Result<u64> {
        let Some(dir) = &self.dir else {
            return Ok(0);
        };
        let new = posted.document.text.len() as u64
            + posted.bundle.as_ref().map_or(0, SceneBundle::bytes);
        let mut others = 0;
        if let Ok(entries) = std::fs::read_dir(dir) {
            for entry in entries.filter_map(Result::ok) {
                let name = entry.file_name();
                if name.to_string_lossy() != id {
                    others += tree_bytes(&entry.path());
                }
            }
        }
        Ok(new + others)
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
        let xml = posted.document.kind == DocumentKind::MitsubaXml;
        let name = posted.document.kind.file_name();
        std::fs::write(staging.path().join(name), &posted.document.text)?;
        let record = PostRecord {
            xml,
            lenient: posted.lenient,
            parameters: posted.parameters.clone(),
            with_assets: posted.bundle.is_some(),
            name: Some(posted.document.name.clone()),
        };
        std::fs::write(
            staging.path().join("post.json"),
            serde_json::to_vec(&record).map_err(std::io::Error::other)?,
        )?;
        if let Some(bundle) = &posted.bundle {
            for name in bundle.names() {
                let target = staging.path().join("assets").join(name);
                if let Some(parent) = target.parent() {
                    std::fs::create_dir_all(parent)?;
                }
                std::fs::copy(bundle.path_of(name), target)?;
            }
        }
        // Swapped in by renames, so a crash leaves the old copy or the new
        // one, never neither: the old one moves aside first.
        let final_dir = dir.join(id);
        let aside = tempfile::Builder::new()
            .prefix(".replaced-")
            .tempdir_in(dir)?;
        let old = aside.path().join(id);
        let had_old = match std::fs::rename(&final_dir, &old) {
            Ok(()) => true,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => false,
            Err(e) => return Err(e),
        };
        if let Err(e) = std::fs::rename(staging.path(), &final_dir) {
            if had_old {
                let _ = std::fs::rename(&old, &final_dir);
            }
            return Err(e);
        }
        // `staging` is gone (renamed); `aside` takes the old copy with it.
        let _ = staging.keep();
        Ok(())
    }

    /// Forgets scene `id`.
    pub fn remove(&self, id: &str) -> std::io::Result<()> {
        let Some(dir) = &self.dir else {
            return Ok(());
        };
        // Moved aside in one rename, so the copy is either whole or gone for
        // the next start (names starting with `.` are never loaded); only
        // then is it removed, at leisure.
        let aside = tempfile::Builder::new()
            .prefix(".deleted-")
            .tempdir_in(dir)?;
        match std::fs::rename(dir.join(id), aside.path().join(id)) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(e),
            _ => Ok(()),
        }
    }

    /// Every kept scene, loaded, each within `limits`; `scenes_dir`
    /// resolves the files of those posted without assets. Broken copies
    /// are logged and skipped.
    pub fn load_all(&self, scenes_dir: &Path, limits: &LoadLimits) -> Vec<LoadedScene> {
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
            match load_one(&entry.path(), scenes_dir, limits) {
                Ok((mut scene, warnings)) => {
                    if scene.name.is_empty() {
                        scene.name = id.clone();
                    }
                    loaded.push(
                        LoadedScene::new(id, SceneSource::Uploaded, scene).approximating(&warnings),
                    );
                }
                Err(err) => tracing::warn!(%id, %err, "posted scene not reloaded"),
            }
        }
        loaded.sort_by(|a, b| a.id.cmp(&b.id));
        loaded
    }
}

/// Bytes of the regular files under `path` (links not followed).
fn tree_bytes(path: &Path) -> u64 {
    match std::fs::symlink_metadata(path) {
        Ok(meta) if meta.is_dir() => std::fs::read_dir(path)
            .map(|entries| {
                entries
                    .filter_map(Result::ok)
                    .map(|e| tree_bytes(&e.path()))
                    .sum()
            })
            .unwrap_or(0),
        Ok(meta) if meta.is_file() => meta.len(),
        _ => 0,
    }
}

fn load_one(
    dir: &Path,
    scenes_dir: &Path,
    limits: &LoadLimits,
) -> anyhow::Result<(Scene, Warnings)> {
    // Read as scene files are: regular files only (a FIFO would block the
    // start for ever), with a byte cap.
    let record: PostRecord =
        serde_json::from_str(&crate::scene::read_scene_file(&dir.join("post.json"))?)?;
    let name = if record.xml {
        "scene.xml"
    } else {
        "scene.json"
    };
    let document = kept_document(
        crate::scene::read_scene_file(&dir.join(name))?,
        record.xml,
        record.name,
    );
    let root = if record.with_assets {
        dir.join("assets")
    } else {
        scenes_dir.to_owned()
    };
    std::fs::create_dir_all(&root)?;
    let options = MitsubaOptions {
        lenient: record.lenient,
        parameters: record.parameters,
    };
    let (scene, warnings) = load_document(&document, &options, &root, limits)?;
    log_warnings(&dir.display().to_string(), &warnings);
    Ok((scene, warnings))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_posted_scene_travels_as_one_blob() {
        let mut bundle = SceneBundle::new(16).unwrap();
        bundle
            .add("meshes/a.obj", b"v 0 0 0\n", "assets[0]")
            .unwrap();
        bundle.add("sky.exr", &[1, 2, 3], "assets[1]").unwrap();
        let posted = Posted {
            document: Document {
                text: "<scene/>".into(),
                kind: DocumentKind::MitsubaXml,
                name: "lego/scene.xml".into(),
            },
            lenient: true,
            parameters: [("spp".to_owned(), "8".to_owned())].into(),
            bundle: Some(bundle),
        };
        let blob = posted.encode().unwrap();
        let back = Posted::decode(&blob).unwrap();
        assert_eq!(back.document.text, "<scene/>");
        assert_eq!(back.document.kind, DocumentKind::MitsubaXml);
        assert_eq!(back.document.name, "lego/scene.xml");
        assert!(back.lenient);
        assert_eq!(back.parameters, posted.parameters);
        let assets: Vec<_> = back
            .bundle
            .as_ref()
            .unwrap()
            .contents()
            .map(Result::unwrap)
            .collect();
        assert_eq!(
            assets,
            [
                (Path::new("meshes/a.obj"), b"v 0 0 0\n".to_vec()),
                (Path::new("sky.exr"), vec![1, 2, 3])
            ]
        );
        assert!(Posted::decode(&blob[..blob.len() - 1]).is_err());
        assert!(Posted::decode(b"BMCSCN01").is_err());
        // Names are checked again on the way in.
        let escaping = blob.windows(12).position(|w| w == b"meshes/a.obj").unwrap();
        let mut evil = blob.clone();
        evil[escaping..escaping + 6].copy_from_slice(b"../../");
        assert!(Posted::decode(&evil).is_err());
    }
}
