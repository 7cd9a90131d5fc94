//! What adding, replacing and removing a scene does beyond the request:
//! loading it off the async runtime, keeping it on disk for the next start
//! (a change that would not survive a restart is neither acknowledged nor
//! made), sharing it with the other replicas, and freeing the records of
//! the version it replaces. The routes only read the request.

use std::sync::Arc;

use super::error::ApiError;
use super::posted_scenes::Posted;
use super::scenes::{LoadedScene, NotInserted, SceneSource, SceneSummary, log_warnings};
use super::state::AppState;
use crate::scene::LoadLimits;

/// Where a posted scene goes: its id, the request field that gave it
/// (`id`, or `name` of a JSON document) and whether it may replace a scene
/// of that id.
pub struct Target {
    pub id: String,
    pub field: &'static str,
    pub replace: bool,
}

/// Adds the scene `posted` describes under `target`'s id, replacing one
/// with the same id if `target` says so (409 otherwise, before anything is
/// loaded); returns whether it replaced one, and its summary.
pub async fn post(
    state: &Arc<AppState>,
    target: Target,
    mut posted: Posted,
) -> Result<(bool, SceneSummary), ApiError> {
    let Target { id, field, replace } = target;
    let exists = |id: &str| ApiError::SceneExists {
        field,
        id: id.to_owned(),
    };
    // Known here or to another replica: refused before any work.
    if !replace && (state.scenes.get(&id).is_some() || state.shared_scene_exists(&id).await) {
        return Err(exists(&id));
    }
    let root = state.config.scenes.dir.clone();
    let limits = state
        .scenes
        .load_limits(&id, crate::cancel::Cancel::never());
    // Ahead of the queue: a write must not wait out a load of reads.
    let (loaded, returned) = state
        .pool
        .run_first(move |cancel| {
            let limits = LoadLimits {
                cancel: cancel.clone(),
                ..limits
            };
            (posted.load(&root, &limits), posted)
        })
        .await?;
    posted = returned;
    let (mut scene, warnings) = loaded?;
    log_warnings(&id, &warnings);
    if scene.name.is_empty() {
        scene.name = id.clone();
    }
    // Only what the scene was built from is kept (and shared).
    if let Some(bundle) = posted.bundle.as_mut() {
        let unused = bundle.keep_used(&scene);
        if !unused.is_empty() {
            tracing::info!(%id, ?unused, "assets the scene does not use were not kept");
        }
    }
    let loaded = LoadedScene::new(id, SceneSource::Uploaded, scene).approximating(&warnings);
    let summary = loaded.summary();
    let generation = loaded.generation;
    let previous = state
        .scenes
        .insert(loaded, replace)
        .map_err(|refused| match refused {
            NotInserted::OverBudget(over) => over.into(),
            NotInserted::Exists => exists(&summary.id),
        })?;
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
    tracing::info!(id = %summary.id, "scene posted");
    Ok((replaced, summary))
}

/// Removes scene `id` here, from the disk and from the other replicas;
/// requests already using it finish normally.
pub async fn delete(state: &Arc<AppState>, id: &str) -> Result<(), ApiError> {
    // A scene posted to another replica is known here through the shared
    // store; deleting it here deletes it everywhere.
    state.scene(id).await?;
    let removed = state.scenes.remove(id).ok_or_else(|| ApiError::NotFound {
        what: "scene",
        id: id.to_owned(),
    })?;
    // A deletion that would be undone by a restart is not acknowledged.
    let (keeper, kept) = (state.posted.clone(), id.to_owned());
    let gone = tokio::task::spawn_blocking(move || keeper.remove(&kept)).await;
    if let Ok(Err(err)) | Err(err) = gone.map_err(std::io::Error::other) {
        state.scenes.restore(id, Some(removed));
        tracing::error!(%id, %err, "kept copy of the scene not removed; deletion refused");
        return Err(ApiError::not_persisted("the deletion", &err));
    }
    state.irradiance_caches.retire(id, None);
    super::replicas::announce_deletion(state, id).await;
    tracing::info!(%id, "scene deleted");
    Ok(())
}

/// What keeping a posted scene came to.
enum Kept {
    /// Kept, with the blob to share with other replicas (if any).
    Saved(Option<Vec<u8>>),
    /// Not kept: the kept scenes would take this many bytes with it.
    OverBudget(u64),
}
