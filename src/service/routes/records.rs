//! `GET /v1/scenes/{id}/records` (export the records of a scene's
//! reproducible tiles) and `POST /v1/scenes/{id}/records` (import them):
//! backups, inspection, and seeding a new replica or release machine.
//!
//! The format is the tile log's (`cache::log`): the magic `BMCLOG01`, then
//! one checksummed entry per tile, whose payload starts with the content
//! digest of the scene it belongs to (`service::tile_store`). Records are
//! tied to the scene's content and to the release that computed them (their
//! keys include both), so the tiles of an import into another release are
//! never read (point queries gather records by scene content, and do meet
//! them). An import's records are checked against fresh estimates of the
//! scene before anything is added (`service::import_check`, docs/math.md
//! §9.8): what is added serves tiles under the ETags of computed ones.

use std::sync::Arc;

use std::time::Duration;

use axum::Json;
use axum::body::{Body, Bytes};
use http_body_util::channel::Channel;

use crate::cache::log;
use axum::extract::{Request, State};
use axum::http::header;
use axum::response::IntoResponse;

use crate::service::error::{ApiError, ErrorBody};
use crate::service::extract::{SceneId, body_up_to};
use crate::service::import_check;
use crate::service::state::AppState;
use crate::service::tile_store::{ImportError, ImportReport};

/// Tile entries an export has encoded ahead of what the client has read.
const EXPORT_ENTRIES_IN_FLIGHT: usize = 2;

/// Media type of an export.
const RECORDS_MEDIA_TYPE: &str = "application/vnd.bmc-records";

/// The records of every reproducible tile of the scene held by this
/// replica, as a log image (module docs); an empty export is the magic alone.
///
/// Streamed one tile's entry at a time through a channel of
/// [`EXPORT_ENTRIES_IN_FLIGHT`] entries, so a client that reads slowly holds
/// that much memory, not the whole export; one that reads nothing for
/// `server.header_read_timeout_secs` has the response cut off.
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
    let keys = tokio::task::spawn_blocking(move || keeper.tiles.export_keys(&digest)).await?;
    let stall = Duration::from_secs(state.config.server.header_read_timeout_secs);
    let (mut sender, body) = Channel::<Bytes, std::io::Error>::new(EXPORT_ENTRIES_IN_FLIGHT);
    let keeper = state.clone();
    tokio::spawn(async move {
        let mut next = Some(Bytes::from_static(log::MAGIC));
        let mut keys = keys.into_iter();
        while let Some(chunk) = next.take() {
            match tokio::time::timeout(stall, sender.send_data(chunk)).await {
                Ok(Ok(())) => {}
                // The client is gone.
                Ok(Err(_)) => return,
                Err(_) => {
                    sender.abort(std::io::Error::new(
                        std::io::ErrorKind::TimedOut,
                        "the client stopped reading the export",
                    ));
                    return;
                }
            }
            // Encoding one tile's entry is cheap (a copy of its records).
            next = keys
                .by_ref()
                .find_map(|key| keeper.tiles.export_entry(&key))
                .map(Bytes::from);
        }
    });
    let name = format!("attachment; filename=\"{id}.records\"");
    Ok((
        [
            (header::CONTENT_TYPE, RECORDS_MEDIA_TYPE.to_owned()),
            (header::CONTENT_DISPOSITION, name),
        ],
        Body::new(body),
    ))
}

/// Adds the records of an export of the same scene content (all or
/// nothing: a damaged entry, or one of another scene content, refuses the
/// whole body with 422 naming `entries[i]`, a record that computed ones
/// could not be (non-finite, negative, huge, outside the scene, repeated)
/// with 422 naming `entries[i].records[j]`, and records of which too many
/// disagree with fresh estimates of the scene (docs/math.md §9.8) with 422
/// naming the first that does); tiles already held are kept. The body may
/// be up to `limits.max_upload_bytes`; the check runs on the CPU pool (503
/// when it is full).
#[utoipa::path(post, path = "/v1/scenes/{id}/records", tag = "scenes",
    params(("id" = String, Path, description = "Scene id")),
    request_body(content = Vec<u8>, description = "An export of this scene's records", content_type = "application/vnd.bmc-records"),
    responses((status = 200, body = ImportReport),
               (status = 404, description = "Unknown scene", body = ErrorBody),
               (status = 422, description = "Not an export of this scene, or records that disagree with it", body = ErrorBody),
               (status = 503, description = "CPU queue full; see Retry-After", body = ErrorBody)))]
pub async fn import_records(
    State(state): State<Arc<AppState>>,
    SceneId(id): SceneId,
    request: Request,
) -> Result<Json<ImportReport>, ApiError> {
    let scene = state.scene(&id).await?;
    // Held until the import is added: the body and its decoded records stay
    // in memory through the check.
    let _reading = state.upload_permit()?;
    let body = body_up_to(request, state.config.limits.max_upload_bytes).await?;
    let digest = *scene.transport.scene().digest.as_bytes();
    let bounds = scene.transport.scene().bounds();
    let keeper = state.clone();
    let (decoded, picked) = tokio::task::spawn_blocking(move || {
        let decoded = keeper.tiles.decode_import(&digest, bounds, &body)?;
        let tiles = decoded
            .new_tiles()
            .map(|(i, tile)| (i, tile.records.as_slice(), tile.max_depth));
        let picked = import_check::pick(tiles, &body, &keeper.import_key).map_err(|u| {
            ImportError::InvalidRecord {
                entry: u.entry,
                record: u.record,
                reason: u.reason,
            }
        })?;
        Ok::<_, ImportError>((decoded, picked))
    })
    .await??;
    let verdict = state
        .pool
        .run(move |cancel| import_check::check(&scene.transport, &picked, cancel))
        .await??;
    let import = decoded.accept(&verdict).inspect_err(|_| {
        let (checked, disagreeing) = (verdict.checked(), verdict.disagreeing());
        tracing::warn!(%id, checked, disagreeing, "records import refused");
    })?;
    let keeper = state.clone();
    let report = tokio::task::spawn_blocking(move || keeper.tiles.add_import(import)).await?;
    tracing::info!(%id, imported = report.imported, records = report.records, checked = report.checked, "records imported");
    Ok(Json(report))
}
