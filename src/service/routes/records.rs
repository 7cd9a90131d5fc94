//! `GET /v1/scenes/{id}/records` (export the records of a scene's
//! reproducible tiles) and `POST /v1/scenes/{id}/records` (import them):
//! backups, inspection, and seeding a new replica or release machine.
//!
//! The format is the tile log's (`cache::log`): the magic `BMCLOG01`, then
//! one checksummed entry per tile, whose payload starts with the content
//! digest of the scene it belongs to (`service::tile_store`). Records are
//! tied to the scene's content and to the release that computed them (their
//! keys include both), so an import into another release is accepted but
//! never read.

use std::sync::Arc;

use axum::Json;
use axum::body::Bytes;
use axum::extract::{Request, State};
use axum::http::header;
use axum::response::IntoResponse;

use crate::service::error::{ApiError, ErrorBody};
use crate::service::extract::{SceneId, body_up_to};
use crate::service::state::AppState;
use crate::service::tile_store::ImportReport;

/// Media type of an export.
const RECORDS_MEDIA_TYPE: &str = "application/vnd.bmc-records";

/// The records of every reproducible tile of the scene held by this
/// replica, as a log image (module docs); an empty export is the magic alone.
#[utoipa::path(get, path = "/v1/scenes/{id}/records", tag = "scenes",
    params(("id" = String, Path, description = "Scene id")),
    responses((status = 200, description = "The records (`BMCLOG01` log image)", content_type = "application/vnd.bmc-records"),
               (status = 404, description = "Unknown scene", body = ErrorBody)))]
pub async fn export_records(
    State(state): State<Arc<AppState>>,
    SceneId(id): SceneId,
) -> Result<impl IntoResponse, ApiError> {
    let scene = state.scene(&id).await?;
    let digest = *scene.transport.scene().digest.as_bytes();
    let keeper = state.clone();
    let image = tokio::task::spawn_blocking(move || keeper.tiles.export(&digest)).await?;
    let name = format!("attachment; filename=\"{id}.records\"");
    Ok((
        [
            (header::CONTENT_TYPE, RECORDS_MEDIA_TYPE.to_owned()),
            (header::CONTENT_DISPOSITION, name),
        ],
        Bytes::from(image),
    ))
}

/// Adds the records of an export of the same scene content (all or
/// nothing: a damaged entry, or one of another scene content, refuses the
/// whole body with 422 naming `entries[i]`); tiles already held are kept.
/// The body may be up to `limits.max_upload_bytes`.
#[utoipa::path(post, path = "/v1/scenes/{id}/records", tag = "scenes",
    params(("id" = String, Path, description = "Scene id")),
    request_body(content = Vec<u8>, description = "An export of this scene's records", content_type = "application/vnd.bmc-records"),
    responses((status = 200, body = ImportReport),
               (status = 404, description = "Unknown scene", body = ErrorBody),
               (status = 422, description = "Not an export of this scene", body = ErrorBody)))]
pub async fn import_records(
    State(state): State<Arc<AppState>>,
    SceneId(id): SceneId,
    request: Request,
) -> Result<Json<ImportReport>, ApiError> {
    let scene = state.scene(&id).await?;
    let body = body_up_to(request, state.config.limits.max_upload_bytes).await?;
    let digest = *scene.transport.scene().digest.as_bytes();
    let keeper = state.clone();
    let report = tokio::task::spawn_blocking(move || keeper.tiles.import(&digest, &body)).await??;
    tracing::info!(%id, imported = report.imported, records = report.records, "records imported");
    Ok(Json(report))
}
