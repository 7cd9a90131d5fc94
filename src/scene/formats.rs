//! Scene formats by file extension: the one place that maps a scene file to
//! its reader. Adding a format: its module beside `mitsuba` and a line here.

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
    let extension = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    match extension.as_deref() {
        Some("xml") => mitsuba::load(path, scenes_root, options, limits),
        _ => loader::load_json(path, scenes_root, limits).map(|scene| (scene, Warnings::default())),
    }
}
