//! A scene's content address: what caches, tile ETags and replicas use to
//! tell versions of a scene apart, the same wherever and whenever the same
//! scene is loaded.
//!
//! The digest is BLAKE3 over the canonical document (the parsed
//! [`SceneDoc`](super::format::SceneDoc) serialised as JSON, so formatting,
//! key order and a Mitsuba file's XML spelling do not matter, only what the
//! loader builds from) followed by every file the document references, each
//! as its path relative to the scenes directory, its length and its bytes,
//! in the order the loader opened them.

use std::fmt;
use std::io::Read;
use std::path::Path;

use serde::Serialize;

use super::error::SceneError;

/// Length-prefixed sections keep `("ab", "c")` and `("a", "bc")` apart.
const DOMAIN: &[u8] = b"bmc-irradiance scene v1\0";

/// 256-bit content digest of a scene (module docs); shown as 64 hex digits.
#[derive(Clone, Copy, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SceneDigest([u8; 32]);

impl SceneDigest {
    /// Digest of `canonical` (the document) and the `files` it references,
    /// named relative to `root`. Reads each file again, at most `limit` bytes.
    pub(super) fn of(
        canonical: &[u8],
        files: &[std::path::PathBuf],
        root: &Path,
    ) -> Result<Self, SceneError> {
        let mut hasher = blake3::Hasher::new();
        hasher.update(DOMAIN);
        hasher.update(&(canonical.len() as u64).to_le_bytes());
        hasher.update(canonical);
        for path in files {
            let name = path.strip_prefix(root).unwrap_or(path).to_string_lossy();
            hasher.update(&(name.len() as u64).to_le_bytes());
            hasher.update(name.as_bytes());
            let io = |source| SceneError::Io {
                file: path.clone(),
                source,
            };
            let mut file = super::read::open_regular(path).map_err(io)?;
            let len = file.metadata().map_err(io)?.len();
            hasher.update(&len.to_le_bytes());
            // Exactly `len` bytes: a file that changed size since the loader
            // read it gives an error rather than a digest of something else.
            let copied = std::io::copy(&mut (&mut file).take(len), &mut hasher).map_err(io)?;
            if copied != len {
                return Err(io(std::io::Error::new(
                    std::io::ErrorKind::UnexpectedEof,
                    "file changed while the scene was loading",
                )));
            }
        }
        Ok(Self(*hasher.finalize().as_bytes()))
    }

    pub fn as_bytes(&self) -> &[u8; 32] {
        &self.0
    }

    /// The first 16 hex digits: enough to tell versions apart in logs.
    pub fn short(&self) -> String {
        self.to_string()[..16].to_owned()
    }
}

impl fmt::Display for SceneDigest {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.0.iter().try_for_each(|b| write!(f, "{b:02x}"))
    }
}

impl fmt::Debug for SceneDigest {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "SceneDigest({self})")
    }
}

impl Serialize for SceneDigest {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}
