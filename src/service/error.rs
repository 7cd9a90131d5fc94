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
//! | 409 | `scene_exists` | a scene posted under an id the service holds, without `replace=true` |
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
//!
//! Errors of lower layers become `ApiError`s through one `From` each, below,
//! so handlers convert them with `?`. Library errors name the field below
//! the spec they check (`normal` of a point, `accuracy` of the cache
//! integrator); a handler that knows where that spec sits in the request
//! says so with [`AtField::at`] (`points[3]`, `estimator`), which prefixes the
//! path ([`ApiError::within`]).

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
    /// A body longer than the byte limit `field` (a config key) allows; its
    /// full length is unknown, as reading stops at the limit.
    #[error("the request body is larger than {limit} bytes, the limit `{field}` sets")]
    BodyTooLarge { field: &'static str, limit: u64 },
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
    /// Every upload slot is taken (503, retry in a second).
    #[error("{limit} uploads are being read (limits.max_concurrent_uploads); retry in a moment")]
    UploadsBusy { limit: usize },
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
    /// A browser page of another origin asked to change state (403).
    #[error(
        "requests from the web origin {origin} may not change this service's state; add it to server.allowed_origins to allow it"
    )]
    CrossOrigin { origin: String },
    #[error("the request target is {len} bytes, above the limit of {limit}")]
    UriTooLong { len: usize, limit: usize },
    #[error("the request headers are {len} bytes, above the limit of {limit}")]
    HeadersTooLarge { len: usize, limit: usize },
    /// A posted scene would take loaded scenes over a service-wide budget;
    /// `field` names the config key (`scenes.max_triangles`).
    #[error("{message}")]
    InsufficientStorage { field: String, message: String },
    /// `POST /v1/scenes` with a body that is neither JSON, XML, multipart
    /// nor an archive (415).
    #[error(
        "content-type must be application/json (a scene document), application/xml (Mitsuba 3), multipart/form-data (a scene with its assets) or application/zip, application/x-tar, application/gzip (a packed scene folder), got {got}"
    )]
    UnsupportedSceneMediaType { got: String },
    /// `POST /v1/scenes` under an id the service already holds, without
    /// `replace=true` (409); `field` is where the request gave the id
    /// (`id`, or `name` for a JSON document).
    #[error(
        "a scene with id `{id}` is already loaded; delete it first, choose another id, or post with replace=true to replace it"
    )]
    SceneExists { field: &'static str, id: String },
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

    /// A change the service could not write to `cache.data_dir`, so it was
    /// not made: 507 naming `cache.data_dir` when the disk or quota is
    /// full, else 500.
    pub fn not_persisted(what: &str, err: &std::io::Error) -> Self {
        use std::io::ErrorKind;
        let message =
            format!("{what} could not be written to cache.data_dir, so nothing changed: {err}");
        match err.kind() {
            ErrorKind::StorageFull | ErrorKind::QuotaExceeded => ApiError::InsufficientStorage {
                field: "cache.data_dir".into(),
                message,
            },
            _ => ApiError::Internal { message },
        }
    }

    /// An upload or import body over `limits.max_upload_bytes` (422 naming it).
    pub fn upload_too_large(limit: u64) -> Self {
        ApiError::BodyTooLarge {
            field: "limits.max_upload_bytes",
            limit,
        }
    }

    /// This error as one about the part of the request at `path`: a field
    /// it names (relative to that part) gets `path` and a dot in front, and
    /// an error naming no field names `path` itself. Errors about no field
    /// (not found, overloaded, cancelled, internal, …) are returned as they are.
    pub fn within(self, path: &str) -> Self {
        let join = |field: String| match (path.is_empty(), field.is_empty()) {
            (true, _) => field,
            (false, true) => path.to_owned(),
            (false, false) => format!("{path}.{field}"),
        };
        match self {
            ApiError::InvalidField { field, message } => ApiError::InvalidField {
                field: join(field),
                message,
            },
            ApiError::LimitExceeded {
                field,
                value,
                limit,
            } => ApiError::LimitExceeded {
                field: join(field),
                value,
                limit,
            },
            other => other,
        }
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
            ApiError::InvalidField { .. }
            | ApiError::LimitExceeded { .. }
            | ApiError::BodyTooLarge { .. } => StatusCode::UNPROCESSABLE_ENTITY,
            ApiError::NotFound { .. } | ApiError::NoRoute { .. } => StatusCode::NOT_FOUND,
            ApiError::MethodNotAllowed { .. } => StatusCode::METHOD_NOT_ALLOWED,
            ApiError::PayloadTooLarge => StatusCode::PAYLOAD_TOO_LARGE,
            ApiError::UnsupportedMediaType { .. } => StatusCode::UNSUPPORTED_MEDIA_TYPE,
            ApiError::Overloaded { .. } | ApiError::UploadsBusy { .. } | ApiError::Cancelled => {
                StatusCode::SERVICE_UNAVAILABLE
            }
            ApiError::Unauthorized => StatusCode::UNAUTHORIZED,
            ApiError::CrossOrigin { .. } => StatusCode::FORBIDDEN,
            ApiError::UriTooLong { .. } => StatusCode::URI_TOO_LONG,
            ApiError::HeadersTooLarge { .. } => StatusCode::REQUEST_HEADER_FIELDS_TOO_LARGE,
            ApiError::DeadlineExceeded { .. } => StatusCode::GATEWAY_TIMEOUT,
            ApiError::Internal { .. } => StatusCode::INTERNAL_SERVER_ERROR,
            ApiError::InsufficientStorage { .. } => StatusCode::INSUFFICIENT_STORAGE,
            ApiError::UnsupportedSceneMediaType { .. } => StatusCode::UNSUPPORTED_MEDIA_TYPE,
            ApiError::SceneExists { .. } => StatusCode::CONFLICT,
        }
    }

    pub fn code(&self) -> &'static str {
        match self {
            ApiError::MalformedJson { .. } => "malformed_json",
            ApiError::InvalidField { .. } => "invalid_field",
            ApiError::LimitExceeded { .. } | ApiError::BodyTooLarge { .. } => "limit_exceeded",
            ApiError::NotFound { .. } | ApiError::NoRoute { .. } => "not_found",
            ApiError::MethodNotAllowed { .. } => "method_not_allowed",
            ApiError::PayloadTooLarge => "payload_too_large",
            ApiError::UnsupportedMediaType { .. } => "unsupported_media_type",
            ApiError::Overloaded { .. } | ApiError::UploadsBusy { .. } => "overloaded",
            ApiError::DeadlineExceeded { .. } => "deadline_exceeded",
            ApiError::Internal { .. } => "internal",
            ApiError::Cancelled => "cancelled",
            ApiError::Unauthorized => "unauthorized",
            ApiError::CrossOrigin { .. } => "cross_origin",
            ApiError::UriTooLong { .. } => "uri_too_long",
            ApiError::HeadersTooLarge { .. } => "headers_too_large",
            ApiError::InsufficientStorage { .. } => "insufficient_storage",
            ApiError::UnsupportedSceneMediaType { .. } => "unsupported_media_type",
            ApiError::SceneExists { .. } => "scene_exists",
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
            ApiError::SceneExists { field, .. } => Some(field),
            ApiError::BodyTooLarge { field, .. } => Some(field),
            ApiError::CrossOrigin { .. } => Some("Origin"),
            ApiError::UploadsBusy { .. } => Some("limits.max_concurrent_uploads"),
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

/// Scene documents are request bodies: every field error is the client's
/// (422), but for a scene over the service's remaining
/// `scenes.max_scene_bytes` (507 naming that budget: deleting scenes makes
/// room); only an unreadable file on the server side is ours (500).
impl From<crate::scene::SceneError> for ApiError {
    fn from(err: crate::scene::SceneError) -> Self {
        use crate::scene::SceneError;
        match &err {
            SceneError::OverBudget { budget, .. } if budget.starts_with("scenes.") => {
                return ApiError::InsufficientStorage {
                    field: (*budget).to_owned(),
                    message: err.to_string(),
                };
            }
            SceneError::Cancelled => return ApiError::Cancelled,
            _ => {}
        }
        match err.field() {
            Some(field) => ApiError::invalid(field, err.to_string()),
            None => ApiError::Internal {
                message: err.to_string(),
            },
        }
    }
}

/// A step of a handler whose error, converted into an [`ApiError`], is about
/// one part of the request.
pub trait AtField<T> {
    /// The error placed at `path` in the request ([`ApiError::within`]):
    /// `QueryPoint::new(..).at("points[3]")?` reports a bad normal at
    /// `points[3].normal`.
    fn at(self, path: &str) -> Result<T, ApiError>;
}

impl<T, E: Into<ApiError>> AtField<T> for Result<T, E> {
    fn at(self, path: &str) -> Result<T, ApiError> {
        self.map_err(|err| err.into().within(path))
    }
}

/// Estimator errors name the option below `estimator` and target errors the
/// field below `target`, where requests carry them (422); a failed
/// lengthscale fit is ours (500).
impl From<crate::estimators::EstimatorError> for ApiError {
    fn from(err: crate::estimators::EstimatorError) -> Self {
        use crate::estimators::EstimatorError;
        match err {
            EstimatorError::Invalid { field, message } => {
                ApiError::invalid(field, message).within("estimator")
            }
            EstimatorError::InvalidTarget { field, message } => {
                ApiError::invalid(field, message).within("target")
            }
            EstimatorError::InvalidQuery { field, message } => ApiError::invalid(field, message),
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
            RenderError::PointsRow { .. }
            | RenderError::NotFinite { .. }
            | RenderError::Image { .. } => ApiError::Internal {
                message: err.to_string(),
            },
            RenderError::Cancelled => ApiError::Cancelled,
        }
    }
}

/// BMC errors reach a handler only from `POST /v1/quadratures` (the cache and
/// the point estimators wrap them in errors of their own), so they name the
/// field of a quadrature request: a parameter by the part of the spec it
/// belongs to (`kernel.lengthscale`, `density.exponent`,
/// `sample_set.count`), the kernel when its matrix stays indefinite,
/// `kernel_mean` when that method cannot integrate the pair (422).
impl From<crate::bmc::BmcError> for ApiError {
    fn from(err: crate::bmc::BmcError) -> Self {
        use crate::bmc::BmcError;
        let field = match (&err, err.field()) {
            (_, Some("samples")) => "sample_set.count".to_owned(),
            (_, Some(field @ ("lengthscale" | "variance" | "noise"))) => format!("kernel.{field}"),
            (_, Some(field @ ("exponent" | "mirror_elevation"))) => format!("density.{field}"),
            (_, Some(field)) => field.to_owned(),
            (BmcError::Unsupported { .. }, None) => "kernel_mean".to_owned(),
            (_, None) => "kernel".to_owned(),
        };
        ApiError::invalid(field, err.to_string())
    }
}

/// Cache and cache-integrator errors name the option below the integrator's
/// spec (`accuracy`, `samples`), to be placed with [`AtField::at`] (422).
impl From<crate::cache::CacheError> for ApiError {
    fn from(err: crate::cache::CacheError) -> Self {
        match err {
            crate::cache::CacheError::Render(err) => err.into(),
            err => ApiError::invalid(err.field().unwrap_or_default(), err.to_string()),
        }
    }
}

/// Axum's path extractor fails only on segments that are not valid
/// percent-encoded UTF-8; every route with path parameters starts with the
/// scene id, which names the path (422).
impl From<axum::extract::rejection::PathRejection> for ApiError {
    fn from(rejection: axum::extract::rejection::PathRejection) -> Self {
        ApiError::invalid("id", rejection.body_text())
    }
}

/// A query string that does not parse as the route's parameters (422).
impl From<axum::extract::rejection::QueryRejection> for ApiError {
    fn from(rejection: axum::extract::rejection::QueryRejection) -> Self {
        ApiError::invalid("query", rejection.body_text())
    }
}

/// A body that could not be read: over `limits.max_body_bytes` (413), or
/// cut off (400).
impl From<axum::extract::rejection::BytesRejection> for ApiError {
    fn from(rejection: axum::extract::rejection::BytesRejection) -> Self {
        if rejection.status() == StatusCode::PAYLOAD_TOO_LARGE {
            ApiError::PayloadTooLarge
        } else {
            ApiError::MalformedJson {
                message: rejection.body_text(),
            }
        }
    }
}

/// A `multipart/form-data` upload (`POST /v1/scenes`): a content type
/// without a boundary names `content-type`, an upload over its byte limit
/// names that limit, anything else is a malformed `body` (422).
impl From<multer::Error> for ApiError {
    fn from(err: multer::Error) -> Self {
        match err {
            multer::Error::StreamSizeExceeded { limit } => ApiError::upload_too_large(limit),
            multer::Error::NoMultipart
            | multer::Error::NoBoundary
            | multer::Error::DecodeContentType(_) => {
                ApiError::invalid("content-type", format!("no multipart boundary: {err}"))
            }
            other => ApiError::invalid("body", format!("malformed multipart upload: {other}")),
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
        let retry_after = match self {
            ApiError::Overloaded {
                retry_after_secs, ..
            } => Some(retry_after_secs),
            ApiError::UploadsBusy { .. } => Some(1),
            _ => None,
        };
        if let Some(secs) = retry_after {
            response
                .headers_mut()
                .insert(header::RETRY_AFTER, HeaderValue::from(secs));
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
    fn at_places_a_library_error_in_the_request() {
        use crate::render::{QueryPoint, RenderError};
        let bad_normal = QueryPoint::new(glam::DVec3::ZERO, glam::DVec3::ZERO);
        let err = bad_normal.at("points[3]").unwrap_err();
        assert_eq!(err.field(), Some("points[3].normal"));
        assert!(err.to_string().starts_with("invalid query point: normal"));
        // An error naming no field names the part; errors about no field pass.
        let err = ApiError::invalid("", "bad").within("estimator");
        assert_eq!(err.field(), Some("estimator"));
        assert_eq!(ApiError::Cancelled.within("estimator"), ApiError::Cancelled);
        let cancelled: Result<(), RenderError> = Err(RenderError::Cancelled);
        assert_eq!(cancelled.at("estimator"), Err(ApiError::Cancelled));
        let limit = ApiError::check_limit("samples", 9, 8).unwrap_err();
        assert_eq!(limit.within("estimator").field(), Some("estimator.samples"));
    }

    #[test]
    fn bmc_errors_name_the_field_of_a_quadrature_request() {
        use crate::bmc::{BmcError, KernelKind};
        let kernel = crate::bmc::Kernel::new(KernelKind::SquaredExponential, -1.0, 1.0, 1e-8);
        let field = |err: BmcError| ApiError::from(err).field().map(str::to_owned);
        assert_eq!(
            field(kernel.unwrap_err()).as_deref(),
            Some("kernel.lengthscale")
        );
        let unsupported = BmcError::Unsupported {
            method: "spherical_gaussian",
            what: "this kernel".into(),
        };
        assert_eq!(field(unsupported).as_deref(), Some("kernel_mean"));
        let indefinite = BmcError::NotPositiveDefinite { jitter: 1.0 };
        assert_eq!(field(indefinite).as_deref(), Some("kernel"));
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
