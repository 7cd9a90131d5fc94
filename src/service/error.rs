//! The one error type every handler returns, and its JSON form.
//!
//! Every error response has the body
//! `{"error": {"code": "<machine-readable>", "message": "<human-readable>", "field": "<path>" | null}}`
//! where `field` names the offending request field (e.g. `points[3].normal`) when
//! there is one. Codes and statuses:
//!
//! | status | code | when |
//! |---|---|---|
//! | 400 | `malformed_json` | the body is not JSON (syntax error, truncated) |
//! | 401 | `unauthorized` | a mutating route without the configured bearer token |
//! | 404 | `not_found` | unknown route or unknown resource id |
//! | 405 | `method_not_allowed` | the route exists but not for this method |
//! | 413 | `payload_too_large` | body over `limits.max_body_bytes` |
//! | 414 | `uri_too_long` | a request target over 8 KiB |
//! | 415 | `unsupported_media_type` | a `content-type` other than JSON |
//! | 422 | `invalid_field` | JSON of the wrong shape or a value out of range |
//! | 422 | `limit_exceeded` | more points/samples/pixels/estimated paths than the limits allow |
//! | 431 | `headers_too_large` | request headers over 32 KiB |
//! | 500 | `internal` | a bug (a panic in a handler or a CPU job) |
//! | 503 | `overloaded` | the CPU queue is full; carries `Retry-After` |
//! | 503 | `cancelled` | the request's work was cancelled (its client is normally gone) |
//! | 504 | `deadline_exceeded` | the request ran past `limits.request_deadline_secs` |
//! | 507 | `insufficient_storage` | a posted scene would exceed a `scenes.max_*` budget |

use axum::Json;
use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use utoipa::ToSchema;

/// A request that could not be answered, with the status it maps to.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ApiError {
    #[error("malformed JSON: {message}")]
    MalformedJson { message: String },
    #[error("{message}")]
    InvalidField { field: String, message: String },
    #[error("`{field}` is {value}, above the limit of {limit}")]
    LimitExceeded {
        field: String,
        value: u64,
        limit: u64,
    },
    #[error("{what} `{id}` not found")]
    NotFound { what: &'static str, id: String },
    #[error("no route for {path}")]
    NoRoute { path: String },
    #[error("method {method} is not allowed here")]
    MethodNotAllowed { method: String },
    #[error("request body larger than the configured limits.max_body_bytes")]
    PayloadTooLarge,
    #[error("content-type must be application/json, got {got}")]
    UnsupportedMediaType { got: String },
    #[error(
        "the CPU queue is full ({capacity} job slots) or its expected wait is over limits.max_queue_wait_secs; retry in {retry_after_secs} s"
    )]
    Overloaded {
        capacity: usize,
        retry_after_secs: u64,
    },
    #[error("request exceeded its deadline of {secs} s")]
    DeadlineExceeded { secs: u64 },
    #[error("internal error: {message}")]
    Internal { message: String },
    #[error("the request's work was cancelled")]
    Cancelled,
    #[error(
        "this route changes the service's state and needs `Authorization: Bearer <token>` with the configured server.auth_token"
    )]
    Unauthorized,
    #[error("the request target is {len} bytes, above the limit of {limit}")]
    UriTooLong { len: usize, limit: usize },
    #[error("the request headers are {len} bytes, above the limit of {limit}")]
    HeadersTooLarge { len: usize, limit: usize },
    /// A posted scene would take loaded scenes over a service-wide budget;
    /// `field` names the config key (`scenes.max_triangles`).
    #[error("{message}")]
    InsufficientStorage { field: String, message: String },
    /// `POST /v1/scenes` with a body that is neither JSON, XML nor multipart (415).
    #[error(
        "content-type must be application/json (a scene document), application/xml (Mitsuba 3) or multipart/form-data (a scene with its assets), got {got}"
    )]
    UnsupportedSceneMediaType { got: String },
}

/// The JSON error body (documented in the OpenAPI schema).
#[derive(Debug, Serialize, serde::Deserialize, ToSchema)]
pub struct ErrorBody {
    pub error: ErrorDetail,
}

/// What went wrong, for machines (`code`, `field`) and for people (`message`).
#[derive(Debug, Serialize, serde::Deserialize, ToSchema)]
pub struct ErrorDetail {
    /// Stable machine-readable error code (see the table in `service::error`).
    pub code: String,
    /// Human-readable explanation.
    pub message: String,
    /// Path of the offending request field, e.g. `points[2].normal`, when there is one.
    pub field: Option<String>,
}

impl ApiError {
    /// A 422 for a value that is well-formed JSON but not acceptable.
    pub fn invalid(field: impl Into<String>, message: impl Into<String>) -> Self {
        ApiError::InvalidField {
            field: field.into(),
            message: message.into(),
        }
    }

    /// Checks a count against its configured limit (422 `limit_exceeded` above it).
    pub fn check_limit(field: &str, value: u64, limit: u64) -> Result<(), ApiError> {
        if value > limit {
            Err(ApiError::LimitExceeded {
                field: field.into(),
                value,
                limit,
            })
        } else {
            Ok(())
        }
    }

    /// Checks a count that must be in `1..=limit`: 422 `invalid_field` for
    /// zero, `limit_exceeded` above the limit.
    pub fn check_count(field: &str, value: u64, limit: u64) -> Result<(), ApiError> {
        if value == 0 {
            return Err(ApiError::invalid(field, "must be at least 1"));
        }
        ApiError::check_limit(field, value, limit)
    }

    /// A 500 for a panic caught in a handler or a CPU job; the payload's text is kept.
    pub fn from_panic(panic: &(dyn std::any::Any + Send)) -> Self {
        let text = panic
            .downcast_ref::<&str>()
            .copied()
            .or_else(|| panic.downcast_ref::<String>().map(String::as_str))
            .unwrap_or("non-string panic payload");
        ApiError::Internal {
            message: format!("panic: {text}"),
        }
    }

    pub fn status(&self) -> StatusCode {
        match self {
            ApiError::MalformedJson { .. } => StatusCode::BAD_REQUEST,
            ApiError::InvalidField { .. } | ApiError::LimitExceeded { .. } => {
                StatusCode::UNPROCESSABLE_ENTITY
            }
            ApiError::NotFound { .. } | ApiError::NoRoute { .. } => StatusCode::NOT_FOUND,
            ApiError::MethodNotAllowed { .. } => StatusCode::METHOD_NOT_ALLOWED,
            ApiError::PayloadTooLarge => StatusCode::PAYLOAD_TOO_LARGE,
            ApiError::UnsupportedMediaType { .. } => StatusCode::UNSUPPORTED_MEDIA_TYPE,
            ApiError::Overloaded { .. } | ApiError::Cancelled => StatusCode::SERVICE_UNAVAILABLE,
            ApiError::Unauthorized => StatusCode::UNAUTHORIZED,
            ApiError::UriTooLong { .. } => StatusCode::URI_TOO_LONG,
            ApiError::HeadersTooLarge { .. } => StatusCode::REQUEST_HEADER_FIELDS_TOO_LARGE,
            ApiError::DeadlineExceeded { .. } => StatusCode::GATEWAY_TIMEOUT,
            ApiError::Internal { .. } => StatusCode::INTERNAL_SERVER_ERROR,
            ApiError::InsufficientStorage { .. } => StatusCode::INSUFFICIENT_STORAGE,
            ApiError::UnsupportedSceneMediaType { .. } => StatusCode::UNSUPPORTED_MEDIA_TYPE,
        }
    }

    pub fn code(&self) -> &'static str {
        match self {
            ApiError::MalformedJson { .. } => "malformed_json",
            ApiError::InvalidField { .. } => "invalid_field",
            ApiError::LimitExceeded { .. } => "limit_exceeded",
            ApiError::NotFound { .. } | ApiError::NoRoute { .. } => "not_found",
            ApiError::MethodNotAllowed { .. } => "method_not_allowed",
            ApiError::PayloadTooLarge => "payload_too_large",
            ApiError::UnsupportedMediaType { .. } => "unsupported_media_type",
            ApiError::Overloaded { .. } => "overloaded",
            ApiError::DeadlineExceeded { .. } => "deadline_exceeded",
            ApiError::Internal { .. } => "internal",
            ApiError::Cancelled => "cancelled",
            ApiError::Unauthorized => "unauthorized",
            ApiError::UriTooLong { .. } => "uri_too_long",
            ApiError::HeadersTooLarge { .. } => "headers_too_large",
            ApiError::InsufficientStorage { .. } => "insufficient_storage",
            ApiError::UnsupportedSceneMediaType { .. } => "unsupported_media_type",
        }
    }

    /// The request field at fault, if any.
    pub fn field(&self) -> Option<&str> {
        match self {
            // An empty path means the body as a whole.
            ApiError::InvalidField { field, .. } | ApiError::LimitExceeded { field, .. }
                if !field.is_empty() =>
            {
                Some(field)
            }
            ApiError::InsufficientStorage { field, .. } => Some(field),
            _ => None,
        }
    }

    pub fn body(&self) -> ErrorBody {
        ErrorBody {
            error: ErrorDetail {
                code: self.code().into(),
                message: self.to_string(),
                field: self.field().map(str::to_owned),
            },
        }
    }
}

/// Scene documents are request bodies: every field error is the client's (422);
/// only an unreadable file on the server side is ours (500).
impl From<crate::scene::SceneError> for ApiError {
    fn from(err: crate::scene::SceneError) -> Self {
        match err.field() {
            Some(field) => ApiError::invalid(field, err.to_string()),
            None => ApiError::Internal {
                message: err.to_string(),
            },
        }
    }
}

/// Estimator errors name the option below `estimator` (422); a failed
/// lengthscale fit is ours (500).
impl From<crate::render::estimators::EstimatorError> for ApiError {
    fn from(err: crate::render::estimators::EstimatorError) -> Self {
        use crate::render::estimators::EstimatorError;
        match err {
            EstimatorError::Invalid { field, message } => {
                ApiError::invalid(format!("estimator.{field}"), message)
            }
            EstimatorError::Fit(message) => ApiError::Internal {
                message: format!("lengthscale fit failed: {message}"),
            },
            EstimatorError::Render(err) => err.into(),
        }
    }
}

/// Render errors name the request field they are about (422); a cancelled
/// job has no client left to tell.
impl From<crate::render::RenderError> for ApiError {
    fn from(err: crate::render::RenderError) -> Self {
        use crate::render::RenderError;
        match &err {
            RenderError::InvalidPoint { field, .. } | RenderError::InvalidOption { field, .. } => {
                ApiError::invalid(*field, err.to_string())
            }
            RenderError::PointsRow { .. } => ApiError::Internal {
                message: err.to_string(),
            },
            RenderError::Cancelled => ApiError::Cancelled,
        }
    }
}

/// Requests are checked before their images are built or encoded, so an
/// image error is ours (500).
impl From<crate::image::ImageError> for ApiError {
    fn from(err: crate::image::ImageError) -> Self {
        ApiError::Internal {
            message: format!("image: {err}"),
        }
    }
}

/// An import names the entry it refuses (422): `body` when the body is not
/// an export at all, `entries[i]` otherwise.
impl From<crate::service::tile_store::ImportError> for ApiError {
    fn from(err: crate::service::tile_store::ImportError) -> Self {
        use crate::service::tile_store::ImportError;
        let field = match &err {
            ImportError::NotALog => "body".to_owned(),
            ImportError::Damaged { entry }
            | ImportError::NotRecords { entry, .. }
            | ImportError::Malformed { entry }
            | ImportError::OtherScene { entry, .. } => format!("entries[{entry}]"),
        };
        ApiError::invalid(field, err.to_string())
    }
}

/// A blocking task that panicked or was cancelled is ours (500).
impl From<tokio::task::JoinError> for ApiError {
    fn from(err: tokio::task::JoinError) -> Self {
        match err.try_into_panic() {
            Ok(panic) => ApiError::from_panic(panic.as_ref()),
            Err(err) => ApiError::Internal {
                message: format!("blocking task: {err}"),
            },
        }
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        if let ApiError::Internal { message } = &self {
            tracing::error!(%message, "internal error");
        }
        let mut response = (self.status(), Json(self.body())).into_response();
        if let ApiError::Unauthorized = self {
            response
                .headers_mut()
                .insert(header::WWW_AUTHENTICATE, HeaderValue::from_static("Bearer"));
        }
        if let ApiError::Overloaded {
            retry_after_secs, ..
        } = self
        {
            response
                .headers_mut()
                .insert(header::RETRY_AFTER, HeaderValue::from(retry_after_secs));
        }
        response
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overloaded_sets_retry_after_and_json_body() {
        let response = ApiError::Overloaded {
            capacity: 4,
            retry_after_secs: 2,
        }
        .into_response();
        assert_eq!(response.status(), StatusCode::SERVICE_UNAVAILABLE);
        assert_eq!(response.headers()[header::RETRY_AFTER], "2");
        assert_eq!(response.headers()[header::CONTENT_TYPE], "application/json");
    }

    #[test]
    fn limit_check_names_the_field() {
        assert!(ApiError::check_limit("points", 10, 10).is_ok());
        let err = ApiError::check_limit("points", 11, 10).unwrap_err();
        assert_eq!(err.status(), StatusCode::UNPROCESSABLE_ENTITY);
        assert_eq!(err.field(), Some("points"));
        assert_eq!(err.body().error.code, "limit_exceeded");
    }
}
