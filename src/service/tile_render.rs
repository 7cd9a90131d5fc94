//! Camera tiles as both tile routes render them: the library's progressive
//! tiles (`integrator::progressive`) within the service's limits, with the
//! work a reproducible tile has done kept for the next request.
//!
//! What a reproducible tile keeps for the next request: `tile_store`; its
//! records serve point queries from there (`integrator::point_query::PointRecords`).

use std::sync::Arc;

use super::config::Limits;
use super::error::ApiError;
use super::integrator::{CachedSetup, cached_setup, resolve_integrator};
use super::scenes::LoadedScene;
use super::state::AppState;
use super::tile_store::{Key, TileStore};
use crate::integrator::Integrator;
use crate::integrator::progressive::{
    self, PassMemo, ProgressiveTile, RenderedPass, TileJob, TileParams, TileRecords,
};
use crate::render::{Cancel, RenderError, TileRequest};
use crate::scene::Scene;

/// The job of `params` on `scene`, every field checked against its camera's
/// resolution and the limits (errors name the field), all before any work;
/// the work budget is [`check_work`].
pub fn tile_job(params: &TileParams, scene: &Scene, limits: &Limits) -> Result<TileJob, ApiError> {
    let area = u64::from(params.width) * u64::from(params.height);
    ApiError::check_limit("width*height", area, limits.max_tile_area as u64)?;
    let request = params.request(scene)?;
    ApiError::check_limit(
        "samples_per_pixel",
        u64::from(request.samples_per_pixel),
        limits.max_samples as u64,
    )?;
    Ok(TileJob {
        request,
        integrator: resolve_integrator(params.integrator_spec(scene), limits)?,
        denoise: params.denoise(scene),
    })
}

/// Refuses a job on `scene` whose estimated paths exceed the work budget:
/// camera paths of every pass, plus at most one record per pixel of the
/// record blocks it may place.
pub fn check_work(job: &TileJob, scene: &Scene, limits: &Limits) -> Result<(), ApiError> {
    limits.check_work(job.estimated_paths(scene.camera.resolution()))
}

/// The content key of the records of `block` (a record block, or a tile
/// of its own): everything they depend on, the release included (a new
/// release may compute them differently, so it never reads an older
/// release's entries from the tile log).
fn records_key(block: &TileRequest, integrator: &Integrator, scene: &LoadedScene) -> Key {
    let r = block;
    let text = format!(
        "records\0{}\0{}\0{}\0{} {} {} {} {} {}",
        env!("CARGO_PKG_VERSION"),
        scene.transport.scene().digest,
        integrator.content_key(),
        r.x,
        r.y,
        r.width,
        r.height,
        r.max_depth,
        r.seed
    );
    *blake3::hash(text.as_bytes()).as_bytes()
}

/// The tile store as a [`PassMemo`] for one job.
struct StoreMemo<'a> {
    store: &'a TileStore,
    scene: &'a LoadedScene,
    job: &'a TileJob,
}

impl StoreMemo<'_> {
    /// The content key of the pass `request` names.
    fn pass_key(&self, request: &TileRequest) -> Key {
        let mut hasher = blake3::Hasher::new();
        // Passes of a ladder take their rays per pixel from the passes
        // before (`TileJob::plan`), which older entries did not.
        // Passes shaded by the record blocks around the tile (not only
        // its own records) differ from older entries.
        hasher.update(b"adaptive pass\0record blocks\0");
        hasher.update(&records_key(request, &self.job.integrator, self.scene));
        hasher.update(&request.samples_per_pixel.to_le_bytes());
        hasher.update(&request.passes.to_le_bytes());
        hasher.update(&request.pass.to_le_bytes());
        *hasher.finalize().as_bytes()
    }
}

impl PassMemo for StoreMemo<'_> {
    fn records_or(
        &self,
        block: &TileRequest,
        place: impl FnOnce() -> Result<TileRecords, RenderError> + Send,
    ) -> Result<Arc<TileRecords>, RenderError> {
        let key = records_key(block, &self.job.integrator, self.scene);
        self.store.records_or(key, place)
    }

    fn pass_or(
        &self,
        request: &TileRequest,
        render: impl FnOnce() -> Result<RenderedPass, RenderError> + Send,
    ) -> Result<Arc<RenderedPass>, RenderError> {
        self.store.pass_or(self.pass_key(request), render)
    }
}

/// Renders `job` on the calling (pool) thread, its reproducible parts kept
/// in the tile store; stops once `cancel` is set. A reproducible tile's
/// records stay out of the shared cache: point queries meet them through
/// the tile store (`integrator::point_query::PointRecords`), the same on every replica whichever of
/// them rendered the tile.
pub fn render_progressive(
    state: &AppState,
    scene: &LoadedScene,
    job: &TileJob,
    cancel: &Cancel,
) -> Result<ProgressiveTile, ApiError> {
    let transport = &scene.transport;
    let setup = cached_setup(state, scene, &job.integrator, job.request.max_depth)?;
    let bound = job
        .integrator
        .bind(transport, setup.as_ref().map(CachedSetup::binding))?;
    let memo = StoreMemo {
        store: &state.tiles,
        scene,
        job,
    };
    Ok(progressive::render_progressive(
        transport, &bound, job, &memo, cancel,
    )?)
}
