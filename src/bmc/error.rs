//! Errors of the BMC quadrature core.
//!
//! Every variant that stems from a bad user parameter names the parameter
//! (`field`), so a service layer can report it without parsing messages.

use thiserror::Error;

/// Failure of a BMC computation; never a panic on bad input.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum BmcError {
    /// A parameter is out of range, NaN or otherwise unusable.
    #[error("invalid {field}: {message}")]
    InvalidParameter {
        /// Name of the offending parameter as the user spells it (e.g. `lengthscale`).
        field: &'static str,
        /// Human-readable reason.
        message: String,
    },
    /// `Q = K + (σ_n² + jitter) I` stayed numerically indefinite up to the jitter cap.
    #[error("kernel matrix is not positive definite even with jitter {jitter:e}")]
    NotPositiveDefinite {
        /// Largest jitter tried (absolute, added to the diagonal).
        jitter: f64,
    },
    /// The requested kernel-mean method cannot handle this kernel/density pair.
    #[error("kernel-mean method {method} does not support {what}")]
    Unsupported {
        /// The method asked for (e.g. `spherical_gaussian`).
        method: &'static str,
        /// What it cannot do.
        what: String,
    },
    /// Two inputs that must agree in size (or origin) do not.
    #[error("{field} mismatch: expected {expected}, got {actual}")]
    Mismatch {
        /// Which input disagrees.
        field: &'static str,
        /// What the other input implies.
        expected: String,
        /// What was given.
        actual: String,
    },
}

impl BmcError {
    /// Name of the offending user-facing field, if the error is about one.
    pub fn field(&self) -> Option<&str> {
        match self {
            BmcError::InvalidParameter { field, .. } | BmcError::Mismatch { field, .. } => {
                Some(field)
            }
            BmcError::NotPositiveDefinite { .. } | BmcError::Unsupported { .. } => None,
        }
    }

    pub(crate) fn invalid(field: &'static str, message: impl Into<String>) -> BmcError {
        BmcError::InvalidParameter {
            field,
            message: message.into(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn field_is_reported_for_parameter_errors_only() {
        let e = BmcError::invalid("lengthscale", "must be positive");
        assert_eq!(e.field(), Some("lengthscale"));
        assert_eq!(e.to_string(), "invalid lengthscale: must be positive");
        assert_eq!(BmcError::NotPositiveDefinite { jitter: 1.0 }.field(), None);
    }
}
