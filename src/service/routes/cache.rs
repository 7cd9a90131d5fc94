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
    /// Records dropped by this request (`DELETE` only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cleared_records: Option<u64>,
}

async fn report(
    state: &AppState,
    id: &str,
    cleared_records: Option<u64>,
) -> Result<SceneCacheReport, ApiError> {
    let scene = state.scene(id).await?;
    Ok(SceneCacheReport {
        scene: scene.id.clone(),
        byte_budget_per_cache: state.irradiance_caches.per_cache_bytes(),
        caches: state.irradiance_caches.stats(&scene),
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
