//! Errors of the light-transport API: bad query points, bad options and
//! unreadable point files. Each names the offending field or line.

use thiserror::Error;

#[derive(Debug, Clone, Error, PartialEq)]
pub enum RenderError {
    /// A query point or normal that cannot be used (NaN, infinite, zero length).
    #[error("invalid query point: {field} {reason}")]
    InvalidPoint { field: &'static str, reason: String },
    /// An option outside its domain, e.g. zero samples.
    #[error("invalid option `{field}`: {reason}")]
    InvalidOption { field: &'static str, reason: String },
    /// A row of a points CSV file that is not `x,y,z,nx,ny,nz` (1-based line).
    #[error("points file line {line}: {reason}")]
    PointsRow { line: usize, reason: String },
    /// The caller cancelled the work ([`super::Cancel`]) before it finished.
    #[error("cancelled before it finished")]
    Cancelled,
    /// The scene produced a value that is not finite (`what`): a model
    /// evaluated outside the range its parameters were validated for, the
    /// library's fault, never the request's.
    #[error("the scene produced {what} that is not finite")]
    NotFinite { what: String },
    /// An image could not be built or filtered from what was rendered
    /// (passes of different sizes, guides that do not fit): the library's
    /// fault, never the request's.
    #[error("image: {reason}")]
    Image { reason: String },
}

impl From<crate::image::ImageError> for RenderError {
    fn from(err: crate::image::ImageError) -> Self {
        RenderError::Image {
            reason: err.to_string(),
        }
    }
}

impl RenderError {
    /// Name of the offending field (`None` for a points-file row).
    pub fn field(&self) -> Option<&'static str> {
        match self {
            RenderError::InvalidPoint { field, .. } | RenderError::InvalidOption { field, .. } => {
                Some(field)
            }
            RenderError::PointsRow { .. }
            | RenderError::Cancelled
            | RenderError::NotFinite { .. }
            | RenderError::Image { .. } => None,
        }
    }
}
