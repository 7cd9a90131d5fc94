//! Scene formats ([`DocumentKind`]): each one's extension, media type, kept
//! file name, id field and reader, in one place. Adding a format: its
//! reader beside `mitsuba` and a variant here.

use std::path::Path;

use super::budget::LoadLimits;
use super::error::SceneError;
use super::mitsuba::{MitsubaOptions, Warnings};
use super::{Scene, loader, mitsuba};

/// Loads the scene file at `path` by its extension (`.xml`: Mitsuba 3 XML
/// read with `options`; anything else: the JSON document) within `limits`.
pub(super) fn load(
    path: &Path,
    scenes_root: &Path,
    options: &MitsubaOptions,
    limits: &LoadLimits,
) -> Result<(Scene, Warnings), SceneError> {
    DocumentKind::of_file_name(path)
        .unwrap_or(DocumentKind::Json)
        .load_file(path, scenes_root, options, limits)
}

/// The document's format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DocumentKind {
    Json,
    MitsubaXml,
}

impl DocumentKind {
    /// Every scene format: adding one is a variant here and its arm in each
    /// method below (its reader a module beside `mitsuba`).
    pub const ALL: [DocumentKind; 2] = [DocumentKind::Json, DocumentKind::MitsubaXml];

    /// The extension of its files, without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            DocumentKind::Json => "json",
            DocumentKind::MitsubaXml => "xml",
        }
    }

    /// What messages call the format.
    pub fn label(self) -> &'static str {
        match self {
            DocumentKind::Json => "JSON",
            DocumentKind::MitsubaXml => "XML",
        }
    }

    /// The file a kept copy of a document of this format is written to.
    pub fn file_name(self) -> &'static str {
        match self {
            DocumentKind::Json => "scene.json",
            DocumentKind::MitsubaXml => "scene.xml",
        }
    }

    /// The format a media type's essence (lower case, no parameters)
    /// declares: `application/json` or any `+json` type; `application/xml`,
    /// `text/xml` or any `+xml` type.
    pub fn of_media_type(essence: &str) -> Option<DocumentKind> {
        match essence {
            "application/json" => Some(DocumentKind::Json),
            "application/xml" | "text/xml" => Some(DocumentKind::MitsubaXml),
            e if e.ends_with("+json") => Some(DocumentKind::Json),
            e if e.ends_with("+xml") => Some(DocumentKind::MitsubaXml),
            _ => None,
        }
    }

    /// The kind of scene file `path` is by its extension (`.json`, `.xml`,
    /// any case), or `None`: not a scene file.
    pub fn of_file_name(path: &Path) -> Option<DocumentKind> {
        let extension = path.extension()?.to_str()?;
        Self::ALL
            .into_iter()
            .find(|k| k.extension().eq_ignore_ascii_case(extension))
    }

    /// The field of a posted document that gives the scene its id: a JSON
    /// document's `name`, an XML document's `id` query parameter.
    pub fn id_field(self) -> &'static str {
        match self {
            DocumentKind::Json => "name",
            DocumentKind::MitsubaXml => "id",
        }
    }

    /// Parses `text` (what messages call `name`), its relative file names
    /// resolved against `base_dir` and kept inside `scenes_root`.
    pub fn load_text(
        self,
        text: &str,
        name: &str,
        base_dir: &Path,
        scenes_root: &Path,
        options: &MitsubaOptions,
        limits: &LoadLimits,
    ) -> Result<(Scene, Warnings), SceneError> {
        match self {
            DocumentKind::Json => loader::from_json_str(text, name, base_dir, scenes_root, limits)
                .map(|s| (s, Warnings::default())),
            DocumentKind::MitsubaXml => {
                mitsuba::from_str(text, name, base_dir, scenes_root, options, limits)
            }
        }
    }

    /// Reads and parses the scene file at `path`.
    fn load_file(
        self,
        path: &Path,
        scenes_root: &Path,
        options: &MitsubaOptions,
        limits: &LoadLimits,
    ) -> Result<(Scene, Warnings), SceneError> {
        match self {
            DocumentKind::Json => loader::load_json(path, scenes_root, limits)
                .map(|scene| (scene, Warnings::default())),
            DocumentKind::MitsubaXml => mitsuba::load(path, scenes_root, options, limits),
        }
    }
}
