//! `GET /v1/scenes/{id}/cache` (irradiance-cache statistics of a scene) and
//! `DELETE /v1/scenes/{id}/cache` (drop its records).

use std::sync::Arc;

use axum::Json;
use axum::extract::State;
use serde::Serialize;
use utoipa::ToSchema;

use crate::service::error::{ApiError, ErrorBody};
use crate::service::extract::SceneId;
use crate::service::irradiance_caches::ConfigurationStats;
use crate::service::state::AppState;

/// The irradiance caches of the current version of a scene.
#[derive(Debug, Serialize, ToSchema)]
pub struct SceneCacheReport {
    pub scene: String,
    /// Byte budget of each (scene version, configuration) cache.
    pub byte_budget_per_cache: usize,
    /// One entry per estimator configuration that has records, sorted.
    pub caches: Vec<ConfigurationStats>,
    /// The content-keyed records of the scene's reproducible tiles and of
    /// the point queries that placed records among their points, held in
    /// the tile store (they serve those tiles again and the records prior
    /// of point queries). `DELETE` leaves them: they are a function of the
    /// scene's content and the request alone, so they would come back bit
    /// for bit.
    pub content_keyed: ContentKeyedRecords,
    /// Records dropped by this request (`DELETE` only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cleared_records: Option<u64>,
}

/// What the tile store holds for a scene's content.
#[derive(Debug, Default, Serialize, ToSchema)]
pub struct ContentKeyedRecords {
    /// Tiles and point sets whose records are held.
    pub sets: u64,
    /// Records over all of them.
    pub records: u64,
}

async fn report(
    state: &AppState,
    id: &str,
    cleared_records: Option<u64>,
) -> Result<SceneCacheReport, ApiError> {
    let scene = state.scene(id).await?;
    // A scan of the store's records entries, as cheap as the caches' stats.
    let held = state
        .tiles
        .tiles_of(scene.transport.scene().digest.as_bytes());
    let content_keyed = ContentKeyedRecords {
        sets: held.len() as u64,
        records: held.iter().map(|(_, t)| t.records.len() as u64).sum(),
    };
    Ok(SceneCacheReport {
        scene: scene.id.clone(),
        byte_budget_per_cache: state.irradiance_caches.per_cache_bytes(),
        caches: state.irradiance_caches.stats(&scene),
        content_keyed,
        cleared_records,
    })
}

/// Statistics (records, bytes, lookups, hits, misses, evictions) of every
/// irradiance cache of the scene.
#[utoipa::path(get, path = "/v1/scenes/{id}/cache", tag = "scenes",
    params(("id" = String, Path, description = "Scene id")),
    responses((status = 200, body = SceneCacheReport),
               (status = 404, description = "Unknown scene", body = ErrorBody)))]
pub async fn get_cache(
    State(state): State<Arc<AppState>>,
    SceneId(id): SceneId,
) -> Result<Json<SceneCacheReport>, ApiError> {
    Ok(Json(report(&state, &id, None).await?))
}

/// Drops every record of the scene's irradiance caches, secondary caches
/// included; later requests compute records afresh. Answers the stats after clearing.
#[utoipa::path(delete, path = "/v1/scenes/{id}/cache", tag = "scenes",
    params(("id" = String, Path, description = "Scene id")),
    responses((status = 200, body = SceneCacheReport),
               (status = 404, description = "Unknown scene", body = ErrorBody)))]
pub async fn delete_cache(
    State(state): State<Arc<AppState>>,
    SceneId(id): SceneId,
) -> Result<Json<SceneCacheReport>, ApiError> {
    let scene = state.scene(&id).await?;
    let cleared = state.irradiance_caches.clear(&scene);
    Ok(Json(report(&state, &id, Some(cleared)).await?))
}
