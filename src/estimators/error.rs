//! Why a point estimator's spec or estimate failed.

use crate::bmc::BmcError;
use crate::render::RenderError;

/// Why a spec or an estimate failed; a variant about a field names its path
/// below the spec it belongs to (`sample_set.kind`, `kernel.variance`).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EstimatorError {
    /// An option of the `EstimatorSpec` outside its domain; `field` is
    /// below the spec (`samples`, `kernel.variance`).
    #[error("estimator `{field}`: {message}")]
    Invalid { field: String, message: String },
    /// A field of a point query beside its estimator and target
    /// (`points[3].normal`, `max_depth`); `field` is below the query.
    #[error("`{field}`: {message}")]
    InvalidQuery { field: String, message: String },
    /// An error target (`estimators::error_target`) outside its
    /// domain; `field` is below the target (empty: the target as a whole).
    #[error("target `{field}`: {message}")]
    InvalidTarget { field: String, message: String },
    /// The marginal-likelihood fit of an `"auto"` lengthscale failed.
    #[error("lengthscale fit failed: {0}")]
    Fit(String),
    #[error(transparent)]
    Render(#[from] RenderError),
}

impl EstimatorError {
    pub(super) fn invalid(field: impl Into<String>, message: impl Into<String>) -> Self {
        EstimatorError::Invalid {
            field: field.into(),
            message: message.into(),
        }
    }

    /// A BMC error about the kernel (or its sample set).
    pub(super) fn kernel(err: BmcError) -> Self {
        let field = match err.field() {
            Some("samples") => "samples".to_owned(),
            Some(field) => format!("kernel.{field}"),
            None => "kernel".to_owned(),
        };
        EstimatorError::invalid(field, err.to_string())
    }
}
