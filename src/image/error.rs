//! Errors of image construction, encoding, decoding and comparison. Each
//! names the offending field or file.

use thiserror::Error;

#[derive(Debug, Error)]
pub enum ImageError {
    /// Sizes or buffers that do not describe an image (zero or huge sides,
    /// wrong buffer lengths, tiles outside the image, images of different sizes).
    #[error("invalid image `{field}`: {reason}")]
    Invalid { field: &'static str, reason: String },
    /// An EXR file or buffer that cannot be read or written.
    #[error("EXR {what}: {reason}")]
    Exr { what: String, reason: String },
    /// PNG encoding failed, or the PNG file could not be written.
    #[error("PNG {what}: {reason}")]
    Png { what: String, reason: String },
}

impl ImageError {
    pub(crate) fn invalid(field: &'static str, reason: impl Into<String>) -> Self {
        Self::Invalid {
            field,
            reason: reason.into(),
        }
    }
}
