//! `POST /v1/scenes/{id}/irradiance`: irradiance `E(x, n)` in W/m² (RGB) at points.
//!
//! The request is the library's [`PointQuerySpec`] and the response its
//! [`PointAnswer`] (`integrator::point_query`, where the estimators, their
//! defaults and the records prior are documented). This route checks the
//! service's limits, runs the query on the CPU pool with the scene's kept
//! state and the service's records, and records the metrics.

use std::sync::Arc;

use axum::Json;
use axum::extract::State;

use crate::integrator::point_query::{PointAnswer, PointQuerySpec};
use crate::service::error::{ApiError, ErrorBody};
use crate::service::extract::{ApiJson, SceneId};
use crate::service::metrics::{self, RAYS_TRACED};
use crate::service::state::AppState;

/// Irradiance at each point of the request.
#[utoipa::path(post, path = "/v1/scenes/{id}/irradiance", tag = "scenes",
    params(("id" = String, Path, description = "Scene id")),
    request_body = PointQuerySpec,
    responses((status = 200, body = PointAnswer),
               (status = 404, description = "Unknown scene", body = ErrorBody),
               (status = 422, description = "Invalid request", body = ErrorBody),
               (status = 503, description = "CPU queue full; see Retry-After", body = ErrorBody)))]
pub async fn irradiance(
    State(state): State<Arc<AppState>>,
    SceneId(id): SceneId,
    ApiJson(request): ApiJson<PointQuerySpec>,
) -> Result<Json<PointAnswer>, ApiError> {
    let scene = state.scene(&id).await?;
    let limits = &state.config.limits;
    let max_samples = limits.max_samples as u64;
    ApiError::check_count(
        "points",
        request.points.len() as u64,
        limits.max_points as u64,
    )?;
    let estimator = &request.estimator;
    ApiError::check_limit(
        "estimator.samples",
        u64::from(estimator.samples()),
        max_samples,
    )?;
    if let Some(light_samples) = estimator.light_samples {
        ApiError::check_count(
            "estimator.light_samples",
            u64::from(light_samples),
            max_samples,
        )?;
    }
    if let Some(cap) = request.target.and_then(|t| t.max_samples) {
        ApiError::check_limit("target.max_samples", u64::from(cap), max_samples)?;
    }
    let query = request.resolve(scene.transport.scene(), limits.target_max_samples())?;
    limits.check_work(query.estimated_paths())?;

    let worker = state.clone();
    let answer = state
        .pool
        .run(move |cancel| {
            let kept = worker.point_query_state(&scene);
            query.estimate(&scene.transport, kept, &|| {}, cancel)
        })
        .await??;
    if let Some(cached) = answer.quadrature_cached {
        metrics::record_quadrature_lookup(&state.quadratures, Some(cached));
    }
    ::metrics::counter!(RAYS_TRACED).increment(answer.rays);
    Ok(Json(answer))
}
