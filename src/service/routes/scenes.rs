//! `/v1/scenes`: list, inspect, add (or replace) and remove scenes.

use std::sync::Arc;

use axum::Json;
use axum::extract::{Request, State};
use axum::http::StatusCode;
use tokio::io::AsyncWriteExt;

use crate::scene::archive::{self, ArchiveFormat, ArchiveLimits};
use crate::scene::bundle::{Document, SceneBundle};
use crate::scene::formats::DocumentKind;
use crate::service::config::Limits;
use crate::service::error::{ApiError, AtField, ErrorBody};
use crate::service::extract::{
    ApiQueryWithParameters, MediaType, SCENE_PARAMETER_PREFIX, SceneId, body_bytes,
    body_media_type, content_type_text, parse_json,
};
use crate::service::posted_scenes::Posted;
use crate::service::scene_changes::{self, Target};
use crate::service::scenes::{SceneSummary, validate_id};
use crate::service::state::AppState;

/// Every loaded scene, sorted by id.
#[utoipa::path(get, path = "/v1/scenes", tag = "scenes",
    responses((status = 200, description = "Loaded scenes", body = Vec<SceneSummary>)))]
pub async fn list_scenes(State(state): State<Arc<AppState>>) -> Json<Vec<SceneSummary>> {
    Json(state.scenes.summaries())
}

/// One scene's summary.
#[utoipa::path(get, path = "/v1/scenes/{id}", tag = "scenes",
    params(("id" = String, Path, description = "Scene id")),
    responses((status = 200, body = SceneSummary),
               (status = 404, description = "Unknown scene", body = ErrorBody)))]
pub async fn get_scene(
    State(state): State<Arc<AppState>>,
    SceneId(id): SceneId,
) -> Result<Json<SceneSummary>, ApiError> {
    Ok(Json(state.scene(&id).await?.summary()))
}

/// Query parameters of `POST /v1/scenes`, used by Mitsuba XML bodies only
/// (a JSON document carries its id as `name`; `id` with JSON is refused).
#[derive(Debug, Default, serde::Deserialize, utoipa::IntoParams)]
#[serde(deny_unknown_fields)]
pub struct PostSceneQuery {
    /// Id of a scene posted as Mitsuba XML (required for XML; it is also the
    /// scene's `name`). Refused (422 naming `id`) with a JSON body, whose id
    /// is its `name`.
    pub id: Option<String>,
    /// Approximate unsupported Mitsuba features instead of rejecting them.
    #[serde(default)]
    pub lenient: bool,
    /// The scene file of an uploaded archive, when its root holds several
    /// (or none): `scene.xml`, or `lego/scene.xml`; an XML scene named so
    /// takes the file's stem as its id unless `id` gives one. Refused with
    /// other bodies.
    pub file: Option<String>,
    /// Replace the scene of the same id if there is one (200); without it,
    /// posting under an id the service holds is refused, 409 naming `id`
    /// (or `name`), and nothing changes.
    #[serde(default)]
    pub replace: bool,
    // `param.NAME=VALUE` pairs (the XML scene's `$NAME` values, overriding
    // its `<default>`s) are taken apart by `ApiQueryWithParameters`.
}

/// Adds a scene, or with `replace=true` replaces the one with the same id
/// (409 `scene_exists` without it). The body is either a scene
/// document (`application/json`, `docs/scene-format.md`) whose `name` becomes
/// its id (an `id` query parameter with it is refused, 422), or a Mitsuba 3
/// scene (`application/xml`) whose id, and name, is the `id` query parameter.
/// As `multipart/form-data`, the document comes with the files it references:
/// a part `scene` (the document) and parts `asset` whose filenames are the
/// relative paths it names (`..`, absolute paths and the like are refused,
/// 422 naming `assets[i]`; more than `limits.max_upload_bytes` in all is a
/// 422 naming that limit).
/// As an archive (`application/zip`, `application/x-tar`, `application/gzip`
/// for a gzipped tar, or `application/octet-stream`: known by its bytes), the
/// body is a packed scene folder: the scene file at its root or at the root
/// of the one folder that holds everything (else named by `file`), beside the
/// files it references. Its id is the `id` parameter, else (XML) that
/// folder's name or the file's stem. Tars as `tar` and `git archive` write
/// them and gzips of several members are read (`scene::archive` says what
/// is). Entries are checked as assets are, and links, FIFOs, devices, a zip
/// naming an entry twice, a tar cut short and entries (skipped ones too)
/// past `limits.max_asset_bytes`, `limits.max_unpacked_bytes` or
/// `limits.max_compression_ratio` are refused, 422 naming `archive[i]` and
/// the entry's name. The archive is unpacked on the CPU pool (503 with
/// `Retry-After` when it is full).
/// Otherwise files the scene references must already be in the scenes directory.
/// `param.NAME=VALUE` query parameters set an XML scene's `$NAME` (overriding
/// its `<default>`, like `mitsuba -D`); with a JSON scene they are refused.
/// A scene that would take the loaded scenes over a `scenes.max_*` budget is
/// refused with 507 and nothing loaded changes.
#[utoipa::path(post, path = "/v1/scenes", tag = "scenes", params(PostSceneQuery),
    request_body(content = Object, description = "A scene document with a `name` (JSON), or Mitsuba 3 XML",
                 content_type = "application/json"),
    responses((status = 201, description = "Scene added", body = SceneSummary),
               (status = 200, description = "Scene replaced", body = SceneSummary),
               (status = 409, description = "A scene holds the id and `replace` is not set", body = ErrorBody),
               (status = 415, description = "Neither JSON, XML nor multipart", body = ErrorBody),
               (status = 422, description = "Invalid scene", body = ErrorBody),
               (status = 507, description = "Over a scenes budget", body = ErrorBody)))]
pub async fn post_scene(
    State(state): State<Arc<AppState>>,
    ApiQueryWithParameters(query, parameters): ApiQueryWithParameters<PostSceneQuery>,
    request: Request,
) -> Result<(StatusCode, Json<SceneSummary>), ApiError> {
    let media_type = body_media_type(&request);
    if query.file.is_some() && !matches!(media_type, MediaType::Archive(_)) {
        return Err(ApiError::invalid(
            "file",
            "`file` names the scene file of an uploaded archive",
        ));
    }
    // What messages call a document sent as the body itself.
    const BODY: &str = "body";
    let (id, document, kind, name, bundle) = match media_type {
        MediaType::Document(kind) => {
            let bytes = body_bytes(request, &()).await?;
            let id = posted_id(kind, query.id, &bytes)?;
            let text = body_text(&bytes, kind.label())?;
            (id, text, kind, BODY.to_owned(), None)
        }
        MediaType::Multipart => {
            let reading = state.upload_permit()?;
            let bundle = state.new_bundle()?;
            let upload = read_upload(request, &state.config.limits, bundle).await?;
            drop(reading);
            let id = posted_id(upload.kind, query.id, upload.document.as_bytes())?;
            let name = upload.name;
            (id, upload.document, upload.kind, name, Some(upload.bundle))
        }
        MediaType::Archive(format) => {
            let reading = state.upload_permit()?;
            let archive = body_to_file(request, state.config.limits.max_upload_bytes).await?;
            let limits = &state.config.limits;
            let archive_limits = ArchiveLimits {
                max_entry_bytes: limits.max_asset_bytes,
                max_total_bytes: limits.max_unpacked_bytes,
                max_ratio: limits.max_compression_ratio,
            };
            let bundle = state.new_bundle()?;
            let file = query.file.clone();
            // On the CPU pool, as other heavy work: inflating is bounded by
            // its slots and stops when the request is gone; ahead of the
            // queue, as the load that follows it.
            let unpacked = state
                .pool
                .run_first(move |cancel| {
                    let format = match format {
                        Some(format) => format,
                        None => sniff(&archive)?,
                    };
                    Ok::<_, ApiError>(archive::unpack(
                        archive,
                        format,
                        &archive_limits,
                        bundle,
                        file.as_deref(),
                        cancel,
                    )?)
                })
                .await??;
            drop(reading);
            if !unpacked.outside.is_empty() {
                tracing::info!(file = %unpacked.file, left_out = ?unpacked.outside,
                    "archive entries outside the scene file's folder left out");
            }
            let id = match (unpacked.kind, query.id.clone()) {
                (DocumentKind::MitsubaXml, None) => {
                    // The named scene file's stem (several scenes of one
                    // folder are several ids), else the folder's name, as
                    // the scenes directory names a scene folder.
                    let stem = std::path::Path::new(&unpacked.file)
                        .file_stem()
                        .map(|s| s.to_string_lossy().into_owned())
                        .unwrap_or_default();
                    let id = match (&query.file, &unpacked.folder) {
                        (None, Some(folder)) => folder.clone(),
                        _ => stem,
                    };
                    validate_id(&id).at("id")?;
                    id
                }
                (kind, id) => posted_id(kind, id, unpacked.document.as_bytes())?,
            };
            let name = unpacked.file;
            (
                id,
                unpacked.document,
                unpacked.kind,
                name,
                Some(unpacked.bundle),
            )
        }
        MediaType::Other => {
            return Err(ApiError::UnsupportedSceneMediaType {
                got: content_type_text(&request),
            });
        }
    };
    if kind == DocumentKind::Json
        && let Some(name) = parameters.keys().next()
    {
        return Err(ApiError::invalid(
            format!("{SCENE_PARAMETER_PREFIX}{name}"),
            "`param.NAME` sets a Mitsuba XML scene's `$NAME`; a JSON scene has no parameters",
        ));
    }
    let posted = Posted {
        document: Document {
            text: document,
            kind,
            name,
        },
        lenient: query.lenient,
        parameters,
        bundle,
    };
    let target = Target {
        id,
        field: kind.id_field(),
        replace: query.replace,
    };
    let (replaced, summary) = scene_changes::post(&state, target, posted).await?;
    let status = if replaced {
        StatusCode::OK
    } else {
        StatusCode::CREATED
    };
    Ok((status, Json(summary)))
}

/// The id of a posted scene, by one rule for every body: a JSON document's
/// `name` (an `id` query parameter with it is refused), an XML document's
/// `id` query parameter (required).
fn posted_id(
    kind: DocumentKind,
    query_id: Option<String>,
    bytes: &[u8],
) -> Result<String, ApiError> {
    match kind {
        DocumentKind::Json => {
            if query_id.is_some() {
                return Err(ApiError::invalid(
                    "id",
                    "the `id` query parameter is for XML scenes; a JSON scene's id is its `name`",
                ));
            }
            // Syntax errors (400) and a duplicate or non-string `name` are
            // found here; the scene parser then reads the text itself, so
            // duplicate keys anywhere are refused as on every other route.
            let PostedName { name } = parse_json(bytes)?;
            document_id(name)
        }
        DocumentKind::MitsubaXml => {
            let id = query_id.ok_or_else(|| {
                ApiError::invalid("id", "an XML scene needs an `id` query parameter")
            })?;
            validate_id(&id).at("id")?;
            Ok(id)
        }
    }
}

/// An asset the server could not write to its disk while receiving it:
/// 507 naming the part when the disk is full, else 500.
fn unwritable(field: &str, err: &std::io::Error) -> ApiError {
    let message = format!("the server could not store {field} while receiving it: {err}");
    match err.kind() {
        std::io::ErrorKind::StorageFull | std::io::ErrorKind::QuotaExceeded => {
            ApiError::InsufficientStorage {
                field: field.to_owned(),
                message,
            }
        }
        _ => ApiError::Internal { message },
    }
}

/// Writes the body to a fresh anonymous file as it arrives, at most `limit`
/// bytes (413 naming `limits.max_upload_bytes` beyond), and rewinds it.
async fn body_to_file(request: Request, limit: u64) -> Result<std::fs::File, ApiError> {
    use http_body_util::BodyExt;
    let file = tempfile::tempfile().map_err(|e| unwritable("body", &e))?;
    let mut out = tokio::fs::File::from_std(file);
    let mut body = request.into_body();
    let mut received = 0u64;
    while let Some(frame) = body.frame().await {
        let frame = frame.map_err(|e| ApiError::invalid("body", format!("cannot be read: {e}")))?;
        let Ok(chunk) = frame.into_data() else {
            continue;
        };
        received += chunk.len() as u64;
        if received > limit {
            return Err(ApiError::upload_too_large(limit));
        }
        out.write_all(&chunk)
            .await
            .map_err(|e| unwritable("body", &e))?;
    }
    out.flush().await.map_err(|e| unwritable("body", &e))?;
    let mut file = out.into_std().await;
    std::io::Seek::rewind(&mut file).map_err(|e| unwritable("body", &e))?;
    Ok(file)
}

/// The format of an archive sent as `application/octet-stream`, by its
/// first bytes (415 when they show none).
fn sniff(archive: &std::fs::File) -> Result<ArchiveFormat, ApiError> {
    use std::io::{Read, Seek};
    let mut head = Vec::with_capacity(512);
    let mut reader = archive;
    reader
        .take(512)
        .read_to_end(&mut head)
        .and_then(|_| reader.rewind())
        .map_err(|e| unwritable("body", &e))?;
    ArchiveFormat::sniff(&head).ok_or_else(|| ApiError::UnsupportedSceneMediaType {
        got: "application/octet-stream whose bytes are not a zip, tar or gzipped tar".into(),
    })
}

/// A scene uploaded with its assets.
struct Upload {
    document: String,
    kind: DocumentKind,
    /// The `scene` part's file name (`scene` if it gave none).
    name: String,
    bundle: SceneBundle,
}

/// Reads a `multipart/form-data` upload of at most `limits.max_upload_bytes`
/// bytes, each asset at most `limits.max_asset_bytes`: one part
/// named `scene` (the document, of the format its file name's extension
/// says, else its content type, else JSON) and any number named `asset`, each
/// with a `filename` that is the relative path the document uses, written
/// to `bundle`.
async fn read_upload(
    request: Request,
    limits: &Limits,
    mut bundle: SceneBundle,
) -> Result<Upload, ApiError> {
    let (limit, max_asset_bytes) = (limits.max_upload_bytes, limits.max_asset_bytes);
    let content_type = content_type_text(&request);
    let boundary = multer::parse_boundary(&content_type)?;
    let constraints =
        multer::Constraints::new().size_limit(multer::SizeLimit::new().whole_stream(limit));
    let mut parts = multer::Multipart::with_constraints(
        request.into_body().into_data_stream(),
        boundary,
        constraints,
    );
    let mut document = None;
    while let Some(part) = parts.next_field().await? {
        match part.name() {
            Some("scene") => {
                let kind = part
                    .file_name()
                    .and_then(|f| DocumentKind::of_file_name(std::path::Path::new(f)))
                    .or_else(|| {
                        let essence = part.content_type()?.essence_str().to_ascii_lowercase();
                        DocumentKind::of_media_type(&essence)
                    })
                    .unwrap_or(DocumentKind::Json);
                let name = part.file_name().unwrap_or("scene").to_owned();
                let text = part.text().await?;
                if document.replace((text, kind, name)).is_some() {
                    return Err(ApiError::invalid("scene", "more than one `scene` part"));
                }
            }
            Some("asset") => {
                let field = format!("assets[{}]", bundle.len());
                let name = part.file_name().map(str::to_owned).ok_or_else(|| {
                    ApiError::invalid(&field, "an asset part needs a filename (its relative path)")
                })?;
                // Written to the bundle's file chunk by chunk as it arrives.
                let file = bundle.create(&name, &field)?;
                let mut file = tokio::fs::File::from_std(file);
                let (mut part, mut written) = (part, 0u64);
                while let Some(chunk) = part.chunk().await? {
                    written += chunk.len() as u64;
                    if written > max_asset_bytes {
                        return Err(ApiError::invalid(
                            &field,
                            format!(
                                "asset {name:?} is larger than {max_asset_bytes} bytes (limits.max_asset_bytes)"
                            ),
                        ));
                    }
                    file.write_all(&chunk)
                        .await
                        .map_err(|e| unwritable(&field, &e))?;
                }
                file.flush().await.map_err(|e| unwritable(&field, &e))?;
            }
            other => {
                return Err(ApiError::invalid(
                    "body",
                    format!("unknown part {other:?}: parts are `scene` and `asset`"),
                ));
            }
        }
    }
    let (document, kind, name) =
        document.ok_or_else(|| ApiError::invalid("scene", "the upload has no `scene` part"))?;
    Ok(Upload {
        document,
        kind,
        name,
        bundle,
    })
}

/// The `name` of a posted JSON scene document; the other fields are left
/// to the scene parser.
#[derive(serde::Deserialize)]
struct PostedName {
    name: Option<serde_json::Value>,
}

/// A posted document's bytes as text; `format` (`JSON`, `XML`) names it in
/// the 422 for bytes that are not UTF-8.
fn body_text(bytes: &[u8], format: &str) -> Result<String, ApiError> {
    match String::from_utf8(bytes.to_vec()) {
        Ok(text) => Ok(text),
        Err(_) => Err(ApiError::invalid(
            "body",
            format!("the {format} is not UTF-8"),
        )),
    }
}

/// The id of a posted JSON scene document: its `name`.
fn document_id(name: Option<serde_json::Value>) -> Result<String, ApiError> {
    let id = match name {
        Some(serde_json::Value::String(name)) => name,
        Some(_) => return Err(ApiError::invalid("name", "must be a string")),
        None => {
            return Err(ApiError::invalid(
                "name",
                "a posted scene needs a `name`, its id",
            ));
        }
    };
    validate_id(&id).at("name")?;
    Ok(id)
}

/// Removes a scene; requests already using it finish normally.
#[utoipa::path(delete, path = "/v1/scenes/{id}", tag = "scenes",
    params(("id" = String, Path, description = "Scene id")),
    responses((status = 204, description = "Scene removed"),
               (status = 404, description = "Unknown scene", body = ErrorBody)))]
pub async fn delete_scene(
    State(state): State<Arc<AppState>>,
    SceneId(id): SceneId,
) -> Result<StatusCode, ApiError> {
    scene_changes::delete(&state, &id).await?;
    Ok(StatusCode::NO_CONTENT)
}
