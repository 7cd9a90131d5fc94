//! What a replica does with what the others share (`service::shared_store`):
//! merges their tile parts into its tile store, adopts the scenes posted to
//! them (and forgets deleted ones), and looks a scene it does not hold up
//! in the shared store before answering 404, so any replica can serve any
//! scene as soon as its upload has been answered.

use std::sync::Arc;

use super::error::ApiError;
use super::posted_scenes::Posted;
use super::scenes::{LoadedScene, NotInserted, SceneSource, log_warnings};
use super::shared_store::SharedEvent;
use super::state::AppState;

impl AppState {
    /// The scene with this id: held here, or else posted to another replica
    /// and adopted now (`service::replicas`); 404 `not_found` otherwise.
    pub async fn scene(&self, id: &str) -> Result<Arc<LoadedScene>, ApiError> {
        if let Some(scene) = self.scenes.get(id) {
            return Ok(scene);
        }
        if self.shared.is_some() {
            match adopt(self, id, None).await {
                Ok(Some(scene)) => return Ok(scene),
                Ok(None) => {}
                // A shared copy this replica cannot load (damaged, or from a
                // release that writes another format) is as good as none:
                // the scene is not here, which says more than a 500 would.
                Err(err) => {
                    tracing::warn!(%id, %err, "the shared copy of the scene does not load; answering 404")
                }
            }
        }
        Err(ApiError::NotFound {
            what: "scene",
            id: id.to_owned(),
        })
    }

    /// Whether another replica posted a scene `id` this one has not
    /// adopted (false without a shared store).
    pub async fn shared_scene_exists(&self, id: &str) -> bool {
        match &self.shared {
            Some(shared) => shared.has_scene(id).await,
            None => false,
        }
    }
}

/// Starts following the other replicas, if a shared store is configured;
/// the task stops when it is aborted or the state is gone.
pub fn follow(state: &Arc<AppState>) -> Option<tokio::task::JoinHandle<()>> {
    let shared = state.shared.as_ref()?;
    let state = Arc::downgrade(state);
    Some(shared.follow(move |events| {
        let state = state.upgrade();
        async move {
            if let Some(state) = state {
                apply(&state, events).await;
            }
        }
    }))
}

/// Applies one batch of what other replicas shared, in order.
async fn apply(state: &Arc<AppState>, events: Vec<SharedEvent>) {
    let mut parts = Vec::new();
    for event in events {
        match event {
            SharedEvent::Part(framed) => parts.push(framed),
            SharedEvent::ScenePosted { id, digest } => {
                if let Err(err) = adopt(state, &id, Some(&digest)).await {
                    tracing::warn!(%id, %err, "scene posted to another replica not adopted");
                }
            }
            SharedEvent::SceneDeleted { id } => forget(state, &id).await,
        }
    }
    if parts.is_empty() {
        return;
    }
    let keeper = state.clone();
    // Decoding and logging parts is blocking work.
    let merged =
        tokio::task::spawn_blocking(move || parts.iter().filter(|p| keeper.tiles.merge(p)).count())
            .await
            .unwrap_or(0);
    if let Some(shared) = &state.shared {
        shared.count_merged(merged as u64);
    }
}

/// Takes scene `id` from the shared store unless this replica holds the
/// content `digest` already (`None`: whatever is shared). `Ok(None)` when
/// the shared store does not have it (or cannot be reached).
pub async fn adopt(
    state: &AppState,
    id: &str,
    digest: Option<&str>,
) -> Result<Option<Arc<LoadedScene>>, ApiError> {
    let held = state.scenes.get(id);
    if let (Some(held), Some(digest)) = (&held, digest)
        && held.transport.scene().digest.to_string() == digest
    {
        return Ok(Some(held.clone()));
    }
    let Some(shared) = &state.shared else {
        return Ok(None);
    };
    let Some(blob) = shared.scene(id).await else {
        return Ok(None);
    };
    let posted = Posted::decode(&blob).map_err(|err| ApiError::Internal {
        message: format!("shared scene `{id}` does not decode: {err}"),
    })?;
    let dir = state.config.scenes.dir.clone();
    let limits = state.scenes.load_limits(id, crate::cancel::Cancel::never());
    let (loaded, posted) =
        tokio::task::spawn_blocking(move || (posted.load(&dir, &limits), posted)).await?;
    let (mut scene, warnings) = loaded?;
    log_warnings(id, &warnings);
    if scene.name.is_empty() {
        scene.name = id.to_owned();
    }
    // A concurrent request may have adopted the same content meanwhile.
    if let Some(current) = state.scenes.get(id)
        && current.transport.scene().digest == scene.digest
    {
        return Ok(Some(current));
    }
    let loaded = LoadedScene::new(id.to_owned(), SceneSource::Uploaded, scene);
    let generation = loaded.generation;
    if let Err(NotInserted::OverBudget(over)) = state.scenes.insert(loaded, true) {
        return Err(over.into());
    }
    state.irradiance_caches.retire(id, Some(generation));
    let (keeper, kept) = (state.posted.clone(), id.to_owned());
    if let Ok(Err(err)) = tokio::task::spawn_blocking(move || keeper.save(&kept, &posted)).await {
        tracing::warn!(%id, %err, "adopted scene not kept for restarts");
    }
    shared.count_adopted();
    tracing::info!(%id, "scene adopted from another replica");
    Ok(state.scenes.get(id))
}

/// How often, and how many times, a deletion Redis did not take is sent
/// again: replicas that never hear of it would serve the scene for ever.
const DELETION_RETRY: std::time::Duration = std::time::Duration::from_secs(1);
const DELETION_ATTEMPTS: u32 = 3600;

/// Tells the other replicas, if any, that scene `id` was deleted here. If
/// Redis does not take it now (down, or stalled past its timeout), it is
/// sent again in the background until Redis does, unless the scene has been
/// posted here again meanwhile.
pub async fn announce_deletion(state: &Arc<AppState>, id: &str) {
    let Some(shared) = &state.shared else {
        return;
    };
    if shared.delete_scene(id).await {
        return;
    }
    tracing::warn!(%id, "deletion not shared with other replicas yet; retrying in the background");
    let (shared, state, id) = (shared.clone(), Arc::downgrade(state), id.to_owned());
    tokio::spawn(async move {
        for _ in 0..DELETION_ATTEMPTS {
            tokio::time::sleep(DELETION_RETRY).await;
            let Some(state) = state.upgrade() else {
                return;
            };
            if state.scenes.get(&id).is_some() {
                return;
            }
            if shared.delete_scene(&id).await {
                tracing::info!(%id, "deletion shared with other replicas");
                return;
            }
        }
        tracing::error!(%id, "deletion never shared with other replicas");
    });
}

/// Drops scene `id`, deleted on another replica.
async fn forget(state: &AppState, id: &str) {
    if state.scenes.remove(id).is_some() {
        state.irradiance_caches.retire(id, None);
        let (keeper, kept) = (state.posted.clone(), id.to_owned());
        let _ = tokio::task::spawn_blocking(move || keeper.remove(&kept)).await;
        tracing::info!(%id, "scene deleted on another replica");
    }
}
