//! `/v1/scenes`: list, inspect, add (or replace) and remove scenes.

use std::sync::Arc;

use axum::Json;
use axum::extract::rejection::QueryRejection;
use axum::extract::{Query, Request, State};
use axum::http::StatusCode;
use tokio::io::AsyncWriteExt;

use crate::scene::bundle::{DocumentKind, SceneBundle};
use crate::scene::{MitsubaOptions, Scene, Warnings};
use crate::service::error::{ApiError, AtField, ErrorBody};
use crate::service::extract::{
    MediaType, SceneId, body_bytes, body_media_type, content_type_text, parse_json,
};
use crate::service::posted_scenes::Posted;
use crate::service::scenes::{LoadedScene, SceneSource, SceneSummary, log_warnings, validate_id};
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
}

/// Adds a scene and replaces one with the same id. The body is either a scene
/// document (`application/json`, `docs/scene-format.md`) whose `name` becomes
/// its id (an `id` query parameter with it is refused, 422), or a Mitsuba 3
/// scene (`application/xml`) whose id, and name, is the `id` query parameter.
/// As `multipart/form-data`, the document comes with the files it references:
/// a part `scene` (the document) and parts `asset` whose filenames are the
/// relative paths it names (`..`, absolute paths and the like are refused,
/// 422 naming `assets[i]`; more than `limits.max_upload_bytes` in all is a
/// 422 naming that limit).
/// Otherwise files the scene references must already be in the scenes directory.
/// A scene that would take the loaded scenes over a `scenes.max_*` budget is
/// refused with 507 and nothing loaded changes.
#[utoipa::path(post, path = "/v1/scenes", tag = "scenes", params(PostSceneQuery),
    request_body(content = Object, description = "A scene document with a `name` (JSON), or Mitsuba 3 XML",
                 content_type = "application/json"),
    responses((status = 201, description = "Scene added", body = SceneSummary),
               (status = 200, description = "Scene replaced", body = SceneSummary),
               (status = 415, description = "Neither JSON, XML nor multipart", body = ErrorBody),
               (status = 422, description = "Invalid scene", body = ErrorBody),
               (status = 507, description = "Over a scenes budget", body = ErrorBody)))]
pub async fn post_scene(
    State(state): State<Arc<AppState>>,
    query: Result<Query<PostSceneQuery>, QueryRejection>,
    request: Request,
) -> Result<(StatusCode, Json<SceneSummary>), ApiError> {
    let Query(query) = query?;
    let root = state.config.scenes.dir.clone();
    let (id, scene, posted, warnings) = match body_media_type(&request) {
        MediaType::Json => {
            if query.id.is_some() {
                return Err(ApiError::invalid(
                    "id",
                    "the `id` query parameter is for XML scenes; a JSON scene's id is its `name`",
                ));
            }
            let bytes = body_bytes(request, &()).await?;
            // Syntax errors (400) and a duplicate or non-string `name` are
            // found here; the scene parser then reads the text itself, so
            // duplicate keys anywhere are refused as on every other route.
            let PostedName { name } = parse_json(&bytes)?;
            let id = document_id(name)?;
            let text = body_text(&bytes, "JSON")?;
            let posted = Posted {
                document: text.clone(),
                kind: DocumentKind::Json,
                lenient: false,
                bundle: None,
            };
            let scene = state
                .pool
                .run(move |_| Scene::from_json_str(&text, &root, &root))
                .await??;
            (id, scene, posted, Warnings::default())
        }
        MediaType::Xml => {
            let id = query.id.ok_or_else(|| {
                ApiError::invalid("id", "an XML scene needs an `id` query parameter")
            })?;
            validate_id(&id).at("id")?;
            let bytes = body_bytes(request, &()).await?;
            let text = body_text(&bytes, "XML")?;
            let options = MitsubaOptions {
                lenient: query.lenient,
                ..MitsubaOptions::default()
            };
            let posted = Posted {
                document: text.clone(),
                kind: DocumentKind::MitsubaXml,
                lenient: query.lenient,
                bundle: None,
            };
            let (mut scene, warnings) = state
                .pool
                .run(move |_| Scene::from_mitsuba_xml_str(&text, &root, &root, &options))
                .await??;
            log_warnings(&id, &warnings);
            if scene.name.is_empty() {
                scene.name = id.clone();
            }
            (id, scene, posted, warnings)
        }
        MediaType::Multipart => {
            let limit = state.config.limits.max_upload_bytes;
            let reading = state.upload_permit()?;
            let upload = read_upload(request, limit).await?;
            drop(reading);
            let options = MitsubaOptions {
                lenient: query.lenient,
                ..MitsubaOptions::default()
            };
            let id = match upload.kind {
                DocumentKind::Json => {
                    if query.id.is_some() {
                        return Err(ApiError::invalid(
                            "id",
                            "the `id` query parameter is for XML scenes; a JSON scene's id is its `name`",
                        ));
                    }
                    let PostedName { name } = parse_json(upload.document.as_bytes())?;
                    document_id(name)?
                }
                DocumentKind::MitsubaXml => {
                    let id = query.id.ok_or_else(|| {
                        ApiError::invalid("id", "an XML scene needs an `id` query parameter")
                    })?;
                    validate_id(&id).at("id")?;
                    id
                }
            };
            let (loaded, upload) = state
                .pool
                .run(move |_| {
                    let loaded = upload.bundle.load(&upload.document, upload.kind, &options);
                    (loaded, upload)
                })
                .await?;
            let (mut scene, warnings) = loaded?;
            log_warnings(&id, &warnings);
            if scene.name.is_empty() {
                scene.name = id.clone();
            }
            // Only what the scene was built from is kept (and shared).
            let mut upload = upload;
            let unused = upload.bundle.keep_used(&scene);
            if !unused.is_empty() {
                tracing::info!(%id, ?unused, "assets the scene does not use were not kept");
            }
            let posted = Posted {
                document: upload.document,
                kind: upload.kind,
                lenient: query.lenient,
                bundle: Some(upload.bundle),
            };
            (id, scene, posted, warnings)
        }
        MediaType::Other => {
            return Err(ApiError::UnsupportedSceneMediaType {
                got: content_type_text(&request),
            });
        }
    };
    let loaded = LoadedScene::new(id, SceneSource::Uploaded, scene).approximating(&warnings);
    let summary = loaded.summary();
    let generation = loaded.generation;
    let previous = state.scenes.insert(loaded)?;
    let replaced = previous.is_some();
    // Kept for the next start (with `cache.data_dir`): a change that would
    // not survive a restart is not acknowledged, and not made.
    let (keeper, id) = (state.posted.clone(), summary.id.clone());
    let (budget, share) = (
        state.config.cache.posted_scene_bytes,
        state.shared.is_some(),
    );
    let kept = tokio::task::spawn_blocking(move || -> std::io::Result<Kept> {
        let total = keeper.bytes_with(&id, &posted)?;
        if total > budget {
            return Ok(Kept::OverBudget(total));
        }
        keeper.save(&id, &posted)?;
        // A blob that cannot be made only costs the sharing.
        Ok(Kept::Saved(share.then(|| posted.encode().ok()).flatten()))
    })
    .await
    .map_err(std::io::Error::other)
    .and_then(|kept| kept);
    let blob = match kept {
        Ok(Kept::Saved(blob)) => blob,
        Ok(Kept::OverBudget(total)) => {
            state.scenes.restore(&summary.id, previous);
            return Err(ApiError::InsufficientStorage {
                field: "cache.posted_scene_bytes".into(),
                message: format!(
                    "the posted scenes kept on disk would take {total} bytes with this one, more than cache.posted_scene_bytes ({budget})"
                ),
            });
        }
        Err(err) => {
            state.scenes.restore(&summary.id, previous);
            tracing::error!(id = %summary.id, %err, "posted scene not kept; refused");
            return Err(ApiError::not_persisted("the scene", &err));
        }
    };
    // Shared with the other replicas, if any; unreachable Redis leaves the
    // scene on this replica only (and says so in /health).
    if let (Some(shared), Some(blob)) = (&state.shared, blob)
        && !shared
            .put_scene(&summary.id, &summary.digest.to_string(), blob)
            .await
    {
        tracing::warn!(id = %summary.id, "posted scene not shared with other replicas");
    }
    // The previous version's records are useless now; free them.
    state
        .irradiance_caches
        .retire(&summary.id, Some(generation));
    let status = if replaced {
        StatusCode::OK
    } else {
        StatusCode::CREATED
    };
    tracing::info!(id = %summary.id, "scene posted");
    Ok((status, Json(summary)))
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

/// What keeping a posted scene came to.
enum Kept {
    /// Kept, with the blob to share with other replicas (if any).
    Saved(Option<Vec<u8>>),
    /// Not kept: the kept scenes would take this many bytes with it.
    OverBudget(u64),
}

/// A scene uploaded with its assets.
struct Upload {
    document: String,
    kind: DocumentKind,
    bundle: SceneBundle,
}

/// Reads a `multipart/form-data` upload of at most `limit` bytes: one part
/// named `scene` (the document; `.xml` file name or an XML content type
/// means Mitsuba XML, JSON otherwise) and any number named `asset`, each
/// with a `filename` that is the relative path the document uses.
async fn read_upload(request: Request, limit: u64) -> Result<Upload, ApiError> {
    let content_type = content_type_text(&request);
    let boundary = multer::parse_boundary(&content_type)?;
    let constraints =
        multer::Constraints::new().size_limit(multer::SizeLimit::new().whole_stream(limit));
    let mut parts = multer::Multipart::with_constraints(
        request.into_body().into_data_stream(),
        boundary,
        constraints,
    );
    let (mut document, mut bundle) = (None, SceneBundle::new()?);
    while let Some(part) = parts.next_field().await? {
        match part.name() {
            Some("scene") => {
                let xml = part.file_name().is_some_and(|f| f.ends_with(".xml"))
                    || part
                        .content_type()
                        .is_some_and(|m| m.essence_str().ends_with("xml"));
                let text = part.text().await?;
                let kind = if xml {
                    DocumentKind::MitsubaXml
                } else {
                    DocumentKind::Json
                };
                if document.replace((text, kind)).is_some() {
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
                let mut part = part;
                while let Some(chunk) = part.chunk().await? {
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
    let (document, kind) =
        document.ok_or_else(|| ApiError::invalid("scene", "the upload has no `scene` part"))?;
    Ok(Upload {
        document,
        kind,
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
    // A scene posted to another replica is known here through the shared
    // store; deleting it here deletes it everywhere.
    state.scene(&id).await?;
    let removed = state.scenes.remove(&id).ok_or_else(|| ApiError::NotFound {
        what: "scene",
        id: id.clone(),
    })?;
    // A deletion that would be undone by a restart is not acknowledged.
    let (keeper, kept) = (state.posted.clone(), id.clone());
    let gone = tokio::task::spawn_blocking(move || keeper.remove(&kept)).await;
    if let Ok(Err(err)) | Err(err) = gone.map_err(std::io::Error::other) {
        state.scenes.restore(&id, Some(removed));
        tracing::error!(%id, %err, "kept copy of the scene not removed; deletion refused");
        return Err(ApiError::not_persisted("the deletion", &err));
    }
    state.irradiance_caches.retire(&id, None);
    crate::service::replicas::announce_deletion(&state, &id).await;
    tracing::info!(%id, "scene deleted");
    Ok(StatusCode::NO_CONTENT)
}
