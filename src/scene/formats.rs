//! Scene formats by file extension: the one place that maps a scene file to
//! its reader. Adding a format: its module beside `mitsuba` and a line here.

use std::path::Path;

use super::error::SceneError;
use super::{Scene, loader, mitsuba};

/// Loads the scene file at `path` by its extension (`.xml`: Mitsuba 3 XML
/// with default options; anything else: the JSON document).
pub(super) fn load(path: &Path, scenes_root: &Path) -> Result<Scene, SceneError> {
    let extension = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    match extension.as_deref() {
        Some("xml") => {
            let options = mitsuba::MitsubaOptions::default();
            mitsuba::load(path, scenes_root, &options).map(|(scene, _)| scene)
        }
        _ => loader::load_json(path, scenes_root),
    }
}
