//! `AppState`: everything a handler may touch, built once at startup and shared
//! by `Arc` between all requests. Nothing here is global except the metrics
//! recorder (see `metrics.rs` for why).

use std::sync::Arc;

use crate::bmc::cache::QuadratureCache;

use super::config::Config;
use super::error::ApiError;
use super::irradiance_caches::IrradianceCaches;
use super::metrics::Metrics;
use super::pool::CpuPool;
use super::posted_scenes::PostedScenes;
use super::scenes::{LoadedScene, SceneRegistry};
use super::shared_store::SharedStore;
use super::tile_store::TileStore;
use crate::integrator::point_query::{PointRecords, QueryState};

/// Shared, read-mostly state of one running service.
pub struct AppState {
    /// The validated configuration; handlers read the request limits from it.
    pub config: Config,
    /// Where CPU-heavy work runs; bounded so overload turns into 503s, not memory growth.
    pub pool: CpuPool,
    /// Renders `/metrics`; domain counters are recorded through the `metrics` facade.
    pub metrics: Metrics,
    /// Loaded scenes by id; each keeps its light-transport state so requests never rebuild it.
    pub scenes: SceneRegistry,
    /// Irradiance-cache records per (scene version, estimator configuration).
    pub irradiance_caches: IrradianceCaches,
    /// The tile store's records (reproducible tiles' and those placed among
    /// query points) gathered as priors of point queries.
    pub point_records: PointRecords,
    /// BMC factorisations and weights, `cache.factorisation_bytes` big, shared by
    /// `/v1/quadratures` and every BMC point request (see `routes::quadratures`).
    pub quadratures: Arc<QuadratureCache>,
    /// Records and passes of reproducible tiles, `cache.tile_bytes` big.
    pub tiles: TileStore,
    /// Where posted scenes are kept across restarts (`cache.data_dir`).
    pub posted: PostedScenes,
    /// The Redis shared with other replicas (`cluster.redis_url`), if any.
    pub shared: Option<Arc<SharedStore>>,
    /// One permit per upload, or records import being read and checked
    /// (`limits.max_concurrent_uploads`).
    pub uploads: Arc<tokio::sync::Semaphore>,
    /// A secret drawn at startup that keys which records of an import are
    /// checked (`service::import_check`), so a forger cannot aim at the
    /// records left unchecked.
    pub import_key: [u8; 32],
}

impl AppState {
    /// An empty bundle for an upload's assets, of at most
    /// `limits.max_assets`, in `PostedScenes::incoming` when the service
    /// keeps a data directory (cleared at startup: a bundle whose process
    /// was stopped mid-upload is not left behind), else in the system's
    /// temporary directory.
    pub fn new_bundle(&self) -> Result<crate::scene::bundle::SceneBundle, ApiError> {
        let incoming = self.posted.incoming();
        Ok(crate::scene::bundle::SceneBundle::new_in(
            self.config.limits.max_assets,
            incoming.as_deref(),
        )?)
    }

    /// What a point query of `scene` reuses and adds to: the scene's fitted
    /// kernels and calibrations, the quadrature cache, the tile store's
    /// records and their gatherings, and the scene's shared caches.
    pub fn point_query_state<'a>(&'a self, scene: &'a LoadedScene) -> QueryState<'a, TileStore> {
        QueryState {
            kernels: &scene.kernels,
            calibrations: &scene.calibrations,
            quadratures: &self.quadratures,
            store: &self.tiles,
            gatherings: &self.point_records,
            shared: self.irradiance_caches.prior_sources(scene).collect(),
            max_records: self.config.limits.max_tile_area,
        }
    }

    /// A permit to read an upload or import body, or 503 (retry in a second)
    /// when `limits.max_concurrent_uploads` are being read.
    pub fn upload_permit(&self) -> Result<tokio::sync::OwnedSemaphorePermit, ApiError> {
        self.uploads
            .clone()
            .try_acquire_owned()
            .map_err(|_| ApiError::UploadsBusy {
                limit: self.config.limits.max_concurrent_uploads,
            })
    }
}
