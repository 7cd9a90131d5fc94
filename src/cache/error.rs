//! Errors of the irradiance cache. Every variant caused by a bad parameter
//! names it (`field`), so the service layer can report it as is.

use thiserror::Error;

use crate::bmc::BmcError;
use crate::render::RenderError;

/// Failure of a cache operation; never a panic on bad input.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum CacheError {
    /// A configuration value or argument outside its domain.
    #[error("invalid {field}: {reason}")]
    Invalid { field: &'static str, reason: String },
    /// Building the BMC rule for records failed.
    #[error(transparent)]
    Bmc(#[from] BmcError),
    /// Shading a record's rays through the cache failed.
    #[error(transparent)]
    Render(#[from] RenderError),
}

impl CacheError {
    pub(crate) fn invalid(field: &'static str, reason: impl Into<String>) -> Self {
        CacheError::Invalid {
            field,
            reason: reason.into(),
        }
    }

    /// Name of the offending field, if the error is about one.
    pub fn field(&self) -> Option<&str> {
        match self {
            CacheError::Invalid { field, .. } => Some(field),
            CacheError::Bmc(e) => e.field(),
            CacheError::Render(e) => e.field(),
        }
    }
}

/// `Ok(value)` if `value` is finite and `> 0`, else an error naming `field`.
pub(crate) fn positive(field: &'static str, value: f64) -> Result<f64, CacheError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(CacheError::invalid(
            field,
            format!("must be finite and > 0, got {value}"),
        ))
    }
}
