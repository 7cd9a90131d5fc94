//! Typed scene-loading errors. Every variant names where the problem is: the
//! JSON field path (`shapes[3].to_world.matrix[1][2]`), and for syntax errors
//! also the file, line and column, or the referenced file that is broken.

use std::path::PathBuf;

/// Why a scene could not be loaded. Loading never panics on user input.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file itself could not be read.
    #[error("{file}: cannot read scene file: {source}")]
    Io {
        file: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// Malformed JSON, a wrong type, a missing or unknown field. `line` and
    /// `column` are 1-based positions in `file` as reported by serde_json.
    #[error("{file}:{line}:{column}: {field}: {message}")]
    Syntax {
        file: String,
        line: usize,
        column: usize,
        field: String,
        message: String,
    },
    /// A well-formed value that is not acceptable (NaN, singular transform,
    /// unknown material id, a limit exceeded, ...).
    #[error("{field}: {message}")]
    Invalid { field: String, message: String },
    /// A referenced file resolves outside the scenes directory (`root`,
    /// which the message leaves out: it is the server's business).
    #[error("{field}: {path:?} is outside the folder the scene's files must stay in")]
    PathEscape {
        field: String,
        path: String,
        root: PathBuf,
    },
    /// A referenced file (OBJ, EXR) is missing or broken.
    #[error("{field}: {file}: {message}")]
    File {
        field: String,
        file: PathBuf,
        message: String,
    },
    /// What `field` asks for would take the load over its byte budget
    /// (`scene::LoadLimits`), named by `budget`; nothing was allocated for it.
    #[error("{field}: {message}")]
    OverBudget {
        field: String,
        budget: &'static str,
        message: String,
    },
    /// The load's cancel flag was set (`scene::LoadLimits::cancel`).
    #[error("the scene load was cancelled")]
    Cancelled,
}

impl SceneError {
    /// The JSON field path the error is about, if it concerns one.
    pub fn field(&self) -> Option<&str> {
        match self {
            SceneError::Io { .. } | SceneError::Cancelled => None,
            SceneError::Syntax { field, .. }
            | SceneError::Invalid { field, .. }
            | SceneError::PathEscape { field, .. }
            | SceneError::File { field, .. }
            | SceneError::OverBudget { field, .. } => Some(field),
        }
    }

    pub(crate) fn invalid(field: impl Into<String>, message: impl Into<String>) -> Self {
        SceneError::Invalid {
            field: field.into(),
            message: message.into(),
        }
    }

    pub(crate) fn file(
        field: impl Into<String>,
        file: impl Into<PathBuf>,
        message: impl Into<String>,
    ) -> Self {
        SceneError::File {
            field: field.into(),
            file: file.into(),
            message: message.into(),
        }
    }
}
