//! `ApiJson<T>`: a JSON body extractor whose rejections are [`ApiError`]s naming the field.
//!
//! axum's own `Json` answers wrong types with a plain-text 422 that does not say
//! which field was wrong; here the body is deserialised through
//! `serde_path_to_error`, so `{"points": [{"normal": "up"}]}` is rejected with
//! `field: "points[0].normal"`. Syntax errors are 400 `malformed_json`; shape
//! errors (wrong type, missing or unknown field) are 422 `invalid_field`; a body
//! over `limits.max_body_bytes` (enforced by axum's `DefaultBodyLimit` layer) is 413.
//! A request without `content-type` is read as JSON; any other content type than
//! JSON is 415.

use axum::body::Bytes;
use axum::extract::{FromRequest, FromRequestParts, Path, Request};
use axum::http::header;
use axum::http::request::Parts;
use serde::de::{DeserializeOwned, IgnoredAny};

use super::error::ApiError;
use crate::scene::archive::ArchiveFormat;
use crate::scene::formats::DocumentKind;

/// A JSON request body of type `T`; see the module docs for how failures map to errors.
#[derive(Debug, Clone)]
pub struct ApiJson<T>(pub T);

/// The `{id}` segment of a scene route. Unlike axum's `Path`, whose
/// rejections are plain text, a segment that is not valid percent-encoded
/// UTF-8 gets the JSON error body (422 naming `id`).
pub struct SceneId(pub String);

impl<S: Send + Sync> FromRequestParts<S> for SceneId {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, ApiError> {
        let Path(id) = Path::<String>::from_request_parts(parts, state).await?;
        Ok(SceneId(id))
    }
}

impl<T, S> FromRequest<S> for ApiJson<T>
where
    T: DeserializeOwned,
    S: Send + Sync,
{
    type Rejection = ApiError;

    async fn from_request(req: Request, state: &S) -> Result<Self, ApiError> {
        match body_media_type(&req) {
            MediaType::Document(DocumentKind::Json) => {
                parse_json(&body_bytes(req, state).await?).map(ApiJson)
            }
            MediaType::Document(DocumentKind::MitsubaXml)
            | MediaType::Multipart
            | MediaType::Archive(_)
            | MediaType::Other => Err(ApiError::UnsupportedMediaType {
                got: content_type_text(&req),
            }),
        }
    }
}

/// The query string of a GET request as a `T` (serde_urlencoded: flat
/// fields, numbers from their text). A bad value or an unknown parameter is
/// a 422 naming the parameter.
#[derive(Debug, Clone)]
pub struct ApiQuery<T>(pub T);

impl<T, S> FromRequestParts<S> for ApiQuery<T>
where
    T: DeserializeOwned,
    S: Send + Sync,
{
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, _: &S) -> Result<Self, ApiError> {
        query_as(parts.uri.query().unwrap_or("")).map(ApiQuery)
    }
}

/// `query` as a `T`, errors naming the parameter (see [`ApiQuery`]).
fn query_as<T: DeserializeOwned>(query: &str) -> Result<T, ApiError> {
    let pairs = url::form_urlencoded::parse(query.as_bytes());
    let deserializer = serde_urlencoded::Deserializer::new(pairs);
    serde_path_to_error::deserialize(deserializer).map_err(|err| {
        let message = err.inner().to_string();
        // Unknown parameters are reported at the top: name them.
        let field = match message.strip_prefix("unknown field `") {
            Some(rest) => rest.split('`').next().unwrap_or("").to_owned(),
            None => err.path().to_string(),
        };
        let field = if field == "." { String::new() } else { field };
        // A number's parser says what is wrong with some text ("invalid
        // digit found in string"); say which text, and what was wanted.
        let given = url::form_urlencoded::parse(query.as_bytes())
            .find(|(name, _)| *name == field)
            .map(|(_, value)| value.into_owned());
        let message = match given {
            Some(value) if is_number_error(&message) => {
                let wanted = match message.as_str() {
                    "invalid float literal" => "a number",
                    _ => "a whole number in its range",
                };
                format!("{value:?} is not a {field}: expected {wanted} ({message})")
            }
            _ => message,
        };
        ApiError::invalid(field, message)
    })
}

/// Whether `message` is what Rust's integer or float parsers say of text
/// that is not a number of the type.
fn is_number_error(message: &str) -> bool {
    [
        "invalid digit found in string",
        "number too large to fit in target type",
        "number too small to fit in target type",
        "cannot parse integer from empty string",
        "invalid float literal",
    ]
    .contains(&message)
}

/// Prefix of a query parameter that sets a Mitsuba scene's `$NAME`.
pub const SCENE_PARAMETER_PREFIX: &str = "param.";

/// The query string as a `T` plus its `param.NAME=VALUE` pairs: the values
/// of a Mitsuba 3 scene's `$NAME` parameters (like `mitsuba -D`), which
/// `T` does not see. A `NAME` that is empty, not made of ASCII letters,
/// digits and `_`, or given twice is a 422 naming `param.NAME`.
#[derive(Debug, Clone)]
pub struct ApiQueryWithParameters<T>(pub T, pub std::collections::BTreeMap<String, String>);

impl<T, S> FromRequestParts<S> for ApiQueryWithParameters<T>
where
    T: DeserializeOwned,
    S: Send + Sync,
{
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, _: &S) -> Result<Self, ApiError> {
        let query = parts.uri.query().unwrap_or("");
        let mut parameters = std::collections::BTreeMap::new();
        let mut rest = url::form_urlencoded::Serializer::new(String::new());
        for (key, value) in url::form_urlencoded::parse(query.as_bytes()) {
            let Some(name) = key.strip_prefix(SCENE_PARAMETER_PREFIX) else {
                rest.append_pair(&key, &value);
                continue;
            };
            let valid =
                !name.is_empty() && name.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_');
            if !valid {
                return Err(ApiError::invalid(
                    key.as_ref(),
                    "a scene parameter's name is ASCII letters, digits and `_`",
                ));
            }
            if parameters
                .insert(name.to_owned(), value.into_owned())
                .is_some()
            {
                return Err(ApiError::invalid(key.as_ref(), "given twice"));
            }
        }
        Ok(ApiQueryWithParameters(
            query_as(&rest.finish())?,
            parameters,
        ))
    }
}

/// What a request body's `content-type` declares; a missing header counts as JSON.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MediaType {
    /// A scene document ([`DocumentKind::of_media_type`]; JSON when there
    /// is no header at all).
    Document(DocumentKind),
    /// `multipart/form-data` (a scene with its assets).
    Multipart,
    /// A packed scene folder: `application/zip`, `application/x-tar`,
    /// `application/gzip` (a gzipped tar) and their aliases, or
    /// `application/octet-stream` (`None`: known by its first bytes).
    Archive(Option<ArchiveFormat>),
    /// Anything else.
    Other,
}

/// Classifies the request's `content-type` (parameters such as `charset` ignored).
pub fn body_media_type(req: &Request) -> MediaType {
    if req.headers().get(header::CONTENT_TYPE).is_none() {
        return MediaType::Document(DocumentKind::Json);
    }
    let text = content_type_text(req).to_ascii_lowercase();
    let essence = text.split(';').next().unwrap_or("").trim();
    if let Some(kind) = DocumentKind::of_media_type(essence) {
        MediaType::Document(kind)
    } else if essence == "multipart/form-data" {
        MediaType::Multipart
    } else if let Some(format) = archive_format(essence) {
        MediaType::Archive(format)
    } else {
        MediaType::Other
    }
}

/// The archive format a media type essence declares (`Some(None)`: an
/// archive of a format its bytes show).
fn archive_format(essence: &str) -> Option<Option<ArchiveFormat>> {
    match essence {
        "application/zip" | "application/x-zip-compressed" => Some(Some(ArchiveFormat::Zip)),
        "application/x-tar" => Some(Some(ArchiveFormat::Tar)),
        "application/gzip"
        | "application/x-gzip"
        | "application/x-gtar"
        | "application/x-compressed-tar" => Some(Some(ArchiveFormat::TarGz)),
        "application/octet-stream" => Some(None),
        _ => None,
    }
}

/// The raw `content-type` header, for error messages.
pub fn content_type_text(req: &Request) -> String {
    req.headers()
        .get(header::CONTENT_TYPE)
        .map(|value| value.to_str().unwrap_or("<not UTF-8>").to_owned())
        .unwrap_or_default()
}

/// Reads the whole body; a body over the configured limit is a 413.
pub async fn body_bytes<S: Send + Sync>(req: Request, state: &S) -> Result<Bytes, ApiError> {
    Ok(Bytes::from_request(req, state).await?)
}

/// Reads the whole body of a route with a byte limit of its own (uploads
/// and imports, `limits.max_upload_bytes`), rather than the
/// `limits.max_body_bytes` of JSON bodies; over the limit is a 422 naming
/// `limits.max_upload_bytes`.
pub async fn body_up_to(req: Request, limit: u64) -> Result<Bytes, ApiError> {
    use http_body_util::{BodyExt, LengthLimitError, Limited};
    let limited = Limited::new(
        req.into_body(),
        usize::try_from(limit).unwrap_or(usize::MAX),
    );
    match limited.collect().await {
        Ok(collected) => Ok(collected.to_bytes()),
        Err(err) if err.is::<LengthLimitError>() => Err(ApiError::upload_too_large(limit)),
        Err(err) => Err(ApiError::invalid(
            "body",
            format!("cannot read the body: {err}"),
        )),
    }
}

/// Deserialises `bytes` as a `T`, naming the offending field on failure.
pub fn parse_json<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, ApiError> {
    let mut deserializer = serde_json::Deserializer::from_slice(bytes);
    let value = serde_path_to_error::deserialize(&mut deserializer).map_err(|err| {
        // Every request body is an object; other well-formed JSON (an array, a
        // number) would otherwise be reported against a made-up path like `[0]`.
        let first = bytes.iter().find(|b| !b.is_ascii_whitespace());
        let well_formed = serde_json::from_slice::<IgnoredAny>(bytes).is_ok();
        if first != Some(&b'{') && well_formed {
            return ApiError::invalid("", "the request body must be a JSON object");
        }
        let path = err.path().to_string();
        let inner = err.into_inner();
        // serde_json reports an array or object where a string enum is
        // expected as a syntax error ("expected value"), though the JSON is
        // fine: it is a value of the wrong shape at `path`.
        if well_formed
            && !path.is_empty()
            && inner.classify() == serde_json::error::Category::Syntax
        {
            return ApiError::invalid(
                path,
                format!("a value of the wrong type or shape ({inner})"),
            );
        }
        classify(inner, path)
    })?;
    deserializer
        .end()
        .map_err(|err| classify(err, String::new()))?;
    Ok(value)
}

fn classify(err: serde_json::Error, path: String) -> ApiError {
    use serde_json::error::Category;
    match err.classify() {
        // Well-formed JSON whose number does not fit the field's type (1e300
        // for an f32, 1e400 anywhere): a bad value of a known field, not bad syntax.
        Category::Syntax
            if !path.is_empty() && err.to_string().starts_with("number out of range") =>
        {
            ApiError::invalid(path, err.to_string())
        }
        Category::Syntax | Category::Eof | Category::Io => ApiError::MalformedJson {
            message: err.to_string(),
        },
        Category::Data => {
            let message = err.to_string();
            // serde reports a missing field at the struct that lacks it; name the field itself.
            let missing = message
                .strip_prefix("missing field `")
                .and_then(|rest| rest.split('`').next());
            let path = if path == "." { String::new() } else { path };
            let field = match (missing, path.is_empty()) {
                (Some(name), true) => name.to_owned(),
                (Some(name), false) => format!("{path}.{name}"),
                (None, _) => path,
            };
            ApiError::invalid(field, message)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use axum::http::StatusCode;
    use serde::Deserialize;

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)] // fields are only read through Debug in these tests
    struct Point {
        position: [f64; 3],
        normal: [f64; 3],
    }

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Query {
        points: Vec<Point>,
        seed: u64,
    }

    fn field_of(body: &str) -> (StatusCode, Option<String>) {
        let err = parse_json::<Query>(body.as_bytes()).unwrap_err();
        (err.status(), err.field().map(str::to_owned))
    }

    #[test]
    fn well_formed_body_parses() {
        let q: Query =
            parse_json(br#"{"points": [{"position": [0,0,0], "normal": [0,0,1]}], "seed": 3}"#)
                .unwrap();
        assert_eq!(q.points.len(), 1);
        assert_eq!(q.seed, 3);
    }

    #[test]
    fn syntax_errors_are_400_without_field() {
        for body in [
            r#"{"points": ["#,
            "not json",
            r#"{"points": [], "seed": 1} trailing"#,
            "",
        ] {
            let err = parse_json::<Query>(body.as_bytes()).unwrap_err();
            assert_eq!(err.status(), StatusCode::BAD_REQUEST, "{body}");
            assert_eq!(err.code(), "malformed_json");
            assert_eq!(err.field(), None);
        }
    }

    #[test]
    fn wrong_type_names_the_nested_field() {
        let body = r#"{"points": [{"position": [0,0,0], "normal": [0,0,1]},
                                  {"position": [0,0,0], "normal": "up"}], "seed": 1}"#;
        assert_eq!(
            field_of(body),
            (
                StatusCode::UNPROCESSABLE_ENTITY,
                Some("points[1].normal".into())
            )
        );
        assert_eq!(
            field_of(r#"{"points": [], "seed": -1}"#),
            (StatusCode::UNPROCESSABLE_ENTITY, Some("seed".into()))
        );
        // Syntactically fine but beyond f64: the field is at fault, not the syntax.
        assert_eq!(
            field_of(r#"{"points": [{"position": [0,1e400,0], "normal": [0,0,1]}], "seed": 1}"#),
            (
                StatusCode::UNPROCESSABLE_ENTITY,
                Some("points[0].position[1]".into())
            )
        );
    }

    #[test]
    fn missing_field_is_named_with_its_parent_path() {
        assert_eq!(
            field_of(r#"{"points": []}"#),
            (StatusCode::UNPROCESSABLE_ENTITY, Some("seed".into()))
        );
        assert_eq!(
            field_of(r#"{"points": [{"position": [0,0,0]}], "seed": 1}"#),
            (
                StatusCode::UNPROCESSABLE_ENTITY,
                Some("points[0].normal".into())
            )
        );
    }

    #[test]
    fn json_that_is_not_an_object_is_422_without_field() {
        for body in ["[1, 2, 3]", "42", " \"points\"", "null"] {
            assert_eq!(
                field_of(body),
                (StatusCode::UNPROCESSABLE_ENTITY, None),
                "{body}"
            );
        }
    }

    #[test]
    fn unknown_field_is_422() {
        let (status, field) = field_of(r#"{"points": [], "seed": 1, "sede": 2}"#);
        assert_eq!(status, StatusCode::UNPROCESSABLE_ENTITY);
        assert_eq!(field.as_deref(), Some("sede"));
    }
}
