//! `/v1/scenes`: list, inspect, add (or replace) and remove scenes.

use std::sync::Arc;

use axum::Json;
use axum::extract::{Path, State};
use axum::http::StatusCode;

use crate::scene::Scene;
use crate::service::error::{ApiError, ErrorBody};
use crate::service::extract::ApiJson;
use crate::service::scenes::{LoadedScene, SceneSource, SceneSummary, validate_id};
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
    Path(id): Path<String>,
) -> Result<Json<SceneSummary>, ApiError> {
    Ok(Json(scene_or_404(&state, &id)?.summary()))
}

/// Adds a scene from a scene document (`docs/scene-format.md`) whose `name`
/// becomes its id; a scene with that id is replaced. Files the document
/// references must already be in the scenes directory.
#[utoipa::path(post, path = "/v1/scenes", tag = "scenes",
    request_body(content = Object, description = "A scene document with a `name`"),
    responses((status = 201, description = "Scene added", body = SceneSummary),
               (status = 200, description = "Scene replaced", body = SceneSummary),
               (status = 422, description = "Invalid scene document", body = ErrorBody)))]
pub async fn post_scene(
    State(state): State<Arc<AppState>>,
    ApiJson(document): ApiJson<serde_json::Value>,
) -> Result<(StatusCode, Json<SceneSummary>), ApiError> {
    let id = match document.get("name") {
        Some(serde_json::Value::String(name)) => name.clone(),
        Some(_) => return Err(ApiError::invalid("name", "must be a string")),
        None => {
            return Err(ApiError::invalid(
                "name",
                "a posted scene needs a `name`, its id",
            ));
        }
    };
    validate_id(&id).map_err(|reason| ApiError::invalid("name", reason))?;
    let root = state.config.scenes.dir.clone();
    let text = document.to_string();
    let scene = state
        .pool
        .run(move || Scene::from_json_str(&text, &root, &root))
        .await??;
    let loaded = LoadedScene::new(id, SceneSource::Uploaded, scene);
    let summary = loaded.summary();
    let status = if state.scenes.insert(loaded) {
        StatusCode::OK
    } else {
        StatusCode::CREATED
    };
    tracing::info!(id = %summary.id, "scene posted");
    Ok((status, Json(summary)))
}

/// Removes a scene; requests already using it finish normally.
#[utoipa::path(delete, path = "/v1/scenes/{id}", tag = "scenes",
    params(("id" = String, Path, description = "Scene id")),
    responses((status = 204, description = "Scene removed"),
               (status = 404, description = "Unknown scene", body = ErrorBody)))]
pub async fn delete_scene(
    State(state): State<Arc<AppState>>,
    Path(id): Path<String>,
) -> Result<StatusCode, ApiError> {
    state.scenes.remove(&id).ok_or_else(|| ApiError::NotFound {
        what: "scene",
        id: id.clone(),
    })?;
    tracing::info!(%id, "scene deleted");
    Ok(StatusCode::NO_CONTENT)
}

/// The scene `id`, or 404.
pub fn scene_or_404(state: &AppState, id: &str) -> Result<Arc<LoadedScene>, ApiError> {
    state.scenes.get(id).ok_or_else(|| ApiError::NotFound {
        what: "scene",
        id: id.to_owned(),
    })
}
