//! Camera tiles as both tile routes render them: the passes of a preset
//! (or of explicit knobs) up to a requested one, averaged, with the work a
//! reproducible tile has done kept for the next request.
//!
//! # What is kept
//! A reproducible tile's output is a function of the scene's content and
//! the request, so its parts are memoised by a content key
//! ([`TileStore`], `cache.tile_bytes`): the tile's **records** (keyed by
//! scene digest, integrator configuration, depth, rectangle and seed; every
//! pass and AOV shares them) and each **pass** image (the same key plus the
//! pass and its samples per pixel). Pass `k` after pass `k − 1` therefore
//! costs one pass of camera rays, and other AOVs or exposures of a tile
//! cost only encoding. Concurrent requests for one key wait for one
//! computation (moka's single flight). Entries are weighed in bytes and the
//! least valuable are evicted (moka's TinyLFU), never needed for
//! correctness: an evicted part is computed again, bit-identically.
//!
//! Tiles rendered through the shared cache (`reproducible: false`) depend
//! on what ran before and are not kept here; their records live in the
//! scene's shared cache.

use std::sync::Arc;

use moka::sync::Cache;

use super::config::Limits;
use super::error::ApiError;
use super::integrator_doc::{ResolvedCache, cached_setup};
use super::scenes::LoadedScene;
use super::state::AppState;
use crate::cache::{RECORD_BYTES, Record};
use crate::image::Image;
use crate::integrator::Integrator;
use crate::integrator::cached::{CachedIntegrator, CachedTileReport};
use crate::render::{Cancel, TileRequest};

/// A content key (BLAKE3 of a canonical description).
type Key = [u8; 32];

/// The records a reproducible tile placed, and what placing them took.
pub struct TileRecords {
    pub records: Vec<Record>,
    pub report: CachedTileReport,
}

/// One rendered pass of a tile.
pub struct RenderedPass {
    pub image: Image,
    /// Rays the pass traced (camera and shading rays).
    pub rays: u64,
    /// Diffuse shading points served by records.
    pub cache_hits: u64,
}

/// Memoised parts of reproducible tiles (module docs).
pub struct TileStore {
    records: Cache<Key, Arc<TileRecords>>,
    passes: Cache<Key, Arc<RenderedPass>>,
}

impl TileStore {
    /// A store of about `bytes` in all, half for records and half for passes.
    pub fn new(bytes: u64) -> Self {
        let half_kib = (bytes / 2).div_ceil(1024).max(1);
        let kib = |b: usize| u32::try_from(b.div_ceil(1024)).unwrap_or(u32::MAX);
        Self {
            records: Cache::builder()
                .max_capacity(half_kib)
                .weigher(move |_, r: &Arc<TileRecords>| kib(r.records.len() * RECORD_BYTES + 64))
                .build(),
            passes: Cache::builder()
                .max_capacity(half_kib)
                .weigher(move |_, p: &Arc<RenderedPass>| {
                    // RGB and variance as f32 per pixel.
                    kib(p.image.rgb().len() * 16 + 64)
                })
                .build(),
        }
    }

    /// Records and passes held, for `GET /v1/scenes/{id}/cache`-style reports.
    pub fn counts(&self) -> (u64, u64) {
        (self.records.entry_count(), self.passes.entry_count())
    }
}

/// One progressive tile request, resolved and checked.
#[derive(Clone, Copy, Debug)]
pub struct TileJob {
    /// The rectangle, depth, seed and samples per pixel of each pass
    /// (`pass` is ignored: passes `0..=last_pass` are rendered).
    pub request: TileRequest,
    pub integrator: Integrator,
    /// The cache integrator's configuration (`Some` iff `integrator` is `Cache`).
    pub cached: Option<ResolvedCache>,
    /// The last pass averaged (0-based).
    pub last_pass: u32,
}

impl TileJob {
    /// Whether the output depends only on the scene's content and the job.
    pub fn reproducible(&self) -> bool {
        self.cached
            .is_none_or(|c| c.config.options.reproducible && c.shared)
    }

    /// Refuses a job whose estimated paths exceed the work budget: camera
    /// paths of every pass, plus at most one record per pixel.
    pub fn check_work(&self, limits: &Limits) -> Result<(), ApiError> {
        let r = &self.request;
        let area = u64::from(r.width) * u64::from(r.height);
        let camera = area
            .saturating_mul(u64::from(r.samples_per_pixel))
            .saturating_mul(u64::from(self.last_pass) + 1);
        let records = self
            .cached
            .map_or(0, |c| area.saturating_mul(c.config.paths_per_record()));
        limits.check_work(camera.saturating_add(records))
    }

    /// The content key of the tile's records: everything they depend on.
    fn records_key(&self, scene: &LoadedScene) -> Key {
        let r = &self.request;
        let text = format!(
            "records\0{}\0{:?}\0{:?}\0{} {} {} {} {} {}",
            scene.transport.scene().digest,
            self.integrator,
            self.cached.map(|c| c.config),
            r.x,
            r.y,
            r.width,
            r.height,
            r.max_depth,
            r.seed
        );
        *blake3::hash(text.as_bytes()).as_bytes()
    }

    /// The content key of pass `pass`.
    fn pass_key(&self, records: &Key, pass: u32) -> Key {
        let mut hasher = blake3::Hasher::new();
        hasher.update(b"pass\0");
        hasher.update(records);
        hasher.update(&self.request.samples_per_pixel.to_le_bytes());
        hasher.update(&pass.to_le_bytes());
        *hasher.finalize().as_bytes()
    }
}

/// A progressive tile and the work this request did for it.
pub struct ProgressiveTile {
    /// The mean of passes `0..=last_pass`.
    pub image: Image,
    /// The tile's own records (reproducible cache tiles only).
    pub records: Option<Arc<TileRecords>>,
    /// Rays traced by this request (memoised parts cost none).
    pub rays: u64,
    /// Records this request placed.
    pub records_created: u64,
    /// Diffuse shading points served by records, over the passes.
    pub cache_hits: u64,
    /// Passes this request rendered (the rest were memoised).
    pub passes_rendered: u32,
}

/// Renders `job` on the calling (pool) thread; stops once `cancel` is set.
pub fn render_progressive(
    state: &AppState,
    scene: &LoadedScene,
    job: &TileJob,
    cancel: &Cancel,
) -> Result<ProgressiveTile, ApiError> {
    let transport = &scene.transport;
    let store = &state.tiles;
    let setup = job
        .cached
        .map(|c| cached_setup(state, scene, c, job.request.max_depth))
        .transpose()?;
    let integrator = setup.as_ref().map(|s| CachedIntegrator {
        transport,
        cache: s.cache(),
        shading: &s.shading,
    });
    let mut out = ProgressiveTile {
        image: Image::black(1, 1)?,
        records: None,
        rays: 0,
        records_created: 0,
        cache_hits: 0,
        passes_rendered: 0,
    };
    let reproducible = job.reproducible();
    let records_key = job.records_key(scene);
    // The tile's records, once for every pass.
    if let (Some(integrator), true) = (&integrator, reproducible) {
        let mut placed = false;
        let records = store
            .records
            .try_get_with(records_key, || {
                placed = true;
                let (records, report) = integrator.tile_records(&job.request, cancel)?;
                Ok::<_, ApiError>(Arc::new(TileRecords { records, report }))
            })
            .map_err(|e| (*e).clone())?;
        if placed {
            out.rays += records.report.placement.rays;
            out.records_created = records.report.placement.records_created;
        }
        out.records = Some(records);
    }
    let records = out.records.clone();
    let created = std::cell::Cell::new(0);
    let mut passes = Vec::with_capacity(job.last_pass as usize + 1);
    for pass in 0..=job.last_pass {
        let request = TileRequest {
            pass,
            ..job.request
        };
        let rendered = std::cell::Cell::new(false);
        let render = || -> Result<Arc<RenderedPass>, ApiError> {
            rendered.set(true);
            let (tile, cache_hits) = match (&integrator, &records) {
                (None, _) => (transport.render_tile(&request, cancel)?, 0),
                (Some(i), Some(records)) => {
                    let (tile, stats) =
                        i.render_tile_from_records(&request, &records.records, cancel)?;
                    (tile, stats.cache_hits)
                }
                (Some(i), None) => {
                    let (tile, report) = i.render_tile(&request, cancel)?;
                    created.set(created.get() + report.placement.records_created);
                    (tile, report.shading.cache_hits)
                }
            };
            Ok(Arc::new(RenderedPass {
                image: tile.image,
                rays: tile.rays,
                cache_hits,
            }))
        };
        let pass_image = if reproducible {
            let key = job.pass_key(&records_key, pass);
            store
                .passes
                .try_get_with(key, render)
                .map_err(|e| (*e).clone())?
        } else {
            render()?
        };
        if rendered.get() {
            out.rays += pass_image.rays;
            out.passes_rendered += 1;
        }
        out.cache_hits += pass_image.cache_hits;
        passes.push(pass_image);
    }
    out.records_created += created.get();
    let images: Vec<Image> = passes.iter().map(|p| p.image.clone()).collect();
    out.image = Image::mean_of(&images)?;
    if let (Some(integrator), Some(records), true) =
        (&integrator, &out.records, out.records_created > 0)
    {
        // Let the shared cache (and its statistics) know of new records.
        integrator.publish(&records.records)?;
    }
    Ok(out)
}
