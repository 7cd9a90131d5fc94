//! `GET /health`: liveness, for load balancers and smoke tests.

use std::sync::Arc;

use axum::Json;
use axum::extract::State;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::service::state::AppState;

/// The service is up and answering.
#[derive(Debug, Serialize, Deserialize, ToSchema)]
pub struct Health {
    /// Always `"ok"` when the service answers at all.
    pub status: String,
    /// Crate version of the running binary.
    pub version: String,
    /// Number of scenes loaded.
    pub scenes: usize,
}

/// Reports that the service is alive and which version it runs.
#[utoipa::path(get, path = "/health", tag = "service",
    responses((status = 200, description = "The service is up", body = Health)))]
pub async fn health(State(state): State<Arc<AppState>>) -> Json<Health> {
    Json(Health {
        status: "ok".into(),
        version: env!("CARGO_PKG_VERSION").into(),
        scenes: state.scenes.len(),
    })
}
