//! `GET /health` (liveness) and `GET /ready` (readiness), for load
//! balancers, orchestrators and smoke tests.
//!
//! Liveness fails (503, `"status": "wedged"`) when a CPU job has been running
//! for more than [`WEDGED_AFTER_DEADLINES`] request deadlines: cancelled work
//! stops within one pixel, record or point, so such a job is stuck and only a
//! restart frees its worker. Readiness fails as well while every CPU job slot
//! is taken, so a balancer sends new work elsewhere until the backlog drains.

use std::sync::Arc;

use axum::Json;
use axum::extract::State;
use axum::http::StatusCode;
use serde::Serialize;
use utoipa::ToSchema;

use crate::service::pool::PoolStatus;
use crate::service::state::AppState;

/// A job running longer than this many request deadlines means a wedged pool.
pub const WEDGED_AFTER_DEADLINES: f64 = 2.0;

/// The service's state as `/health` and `/ready` report it.
#[derive(Debug, Serialize, ToSchema)]
pub struct Health {
    /// `"ok"`; `"wedged"` when a CPU job runs far past any deadline
    /// (module docs); from `/ready` also `"busy"` when every job slot is taken.
    pub status: &'static str,
    /// Crate version of the running binary.
    pub version: String,
    /// Number of scenes loaded.
    pub scenes: usize,
    /// Running and queued CPU jobs and the age of the oldest running one.
    pub cpu: PoolStatus,
    /// Reproducible tiles' records and passes held, the on-disk log's size
    /// and what loading it at startup found.
    pub tiles: crate::service::tile_store::TileStoreStats,
    /// Sharing with other replicas through Redis (absent without
    /// `cluster.redis_url`): whether Redis is reachable, the last error and
    /// what was shared. An unreachable Redis leaves the service serving
    /// from its own stores, so it does not fail liveness or readiness.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shared: Option<crate::service::shared_store::SharedStoreStatus>,
}

/// Reports whether the service is alive and which version it runs: 200, or
/// 503 when its CPU pool is wedged.
#[utoipa::path(get, path = "/health", tag = "service",
    responses((status = 200, description = "The service is up", body = Health),
               (status = 503, description = "A CPU job is stuck; restart the service", body = Health)))]
pub async fn health(State(state): State<Arc<AppState>>) -> (StatusCode, Json<Health>) {
    report(&state, false)
}

/// Whether the service should be sent new work: 200, or 503 when wedged or
/// when every CPU job slot is taken.
#[utoipa::path(get, path = "/ready", tag = "service",
    responses((status = 200, description = "Ready for requests", body = Health),
               (status = 503, description = "Wedged or saturated", body = Health)))]
pub async fn ready(State(state): State<Arc<AppState>>) -> (StatusCode, Json<Health>) {
    report(&state, true)
}

fn report(state: &AppState, readiness: bool) -> (StatusCode, Json<Health>) {
    let cpu = state.pool.status();
    let deadline = state.config.limits.request_deadline().as_secs_f64();
    let status = if cpu.oldest_job_secs > WEDGED_AFTER_DEADLINES * deadline {
        "wedged"
    } else if readiness && state.pool.in_flight() >= state.pool.capacity() {
        "busy"
    } else {
        "ok"
    };
    let code = if status == "ok" {
        StatusCode::OK
    } else {
        StatusCode::SERVICE_UNAVAILABLE
    };
    let health = Health {
        status,
        version: env!("CARGO_PKG_VERSION").into(),
        scenes: state.scenes.len(),
        cpu,
        tiles: state.tiles.stats(),
        shared: state.shared.as_ref().map(|s| s.status()),
    };
    (code, Json(health))
}
