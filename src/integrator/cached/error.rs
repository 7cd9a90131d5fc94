//! Cache errors as the render API's errors.

use crate::cache::CacheError;
use crate::render::RenderError;

/// The integrator is where the record store meets the pixel loop: a cache
/// error becomes the render API's typed error, keeping the field name (a
/// failed record rule names the `quadrature`).
impl From<CacheError> for RenderError {
    fn from(e: CacheError) -> Self {
        match e {
            CacheError::Invalid { field, reason } => RenderError::InvalidOption { field, reason },
            CacheError::Bmc(b) => RenderError::InvalidOption {
                field: "quadrature",
                reason: b.to_string(),
            },
            CacheError::Render(r) => r,
        }
    }
}
