//! Memoised parts of reproducible tiles.
//!
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
//! With `cache.data_dir` set (the default `data/`), the store is also an
//! append-only log on disk (`cache::log`, `tiles.log` there): every part
//! computed is appended, and a restarted service loads the log first, so
//! the same URLs cost nothing again. Damaged entries are skipped on load
//! and a torn tail is cut (`cache::log`).
//! Eviction: memory holds `cache.tile_bytes` by TinyLFU; the log is
//! rewritten with what memory holds whenever it passes twice that.
//!
//! With `cluster.redis_url` set, every part computed here is also sent to
//! the other replicas (`service::shared_store`), and theirs are merged in
//! ([`TileStore::merge`]); parts are content-keyed and computed
//! deterministically, so a merged part is the one this replica would have
//! computed, bit for bit.
//!
//! A scene's records can be exported as a log image and imported into
//! another service ([`TileStore::export`], [`TileStore::decode_import`],
//! [`TileStore::add_import`]); each records entry names the scene content
//! it belongs to, and an import's records are checked against fresh
//! estimates of the scene before they are added (`service::import_check`),
//! as an imported tile is served under the ETag of a computed one.
//!
//! Tiles rendered through the shared cache (`reproducible: false`) depend
//! on what ran before and are not kept here; their records live in the
//! scene's shared cache.

mod import;

use std::borrow::Cow;
use std::path::Path;
use std::sync::Arc;

use moka::sync::Cache;

use super::shared_store::Outbox;
use crate::cache::log::{self, AppendLog, LogEntry, LogReport};
use crate::cache::{CacheConfig, MAX_IRRADIANCE, RECORD_BYTES, RadiusLimits, Record};
use crate::image::Image;
use crate::integrator::cached::CachedTileReport;
use crate::integrator::point_query::RecordsStore;
use crate::integrator::progressive::{RenderedPass, TileRecords};
use crate::render::{PathDepth, RenderError};

#[cfg(test)]
pub(super) use import::DecodedImport;
pub use import::{ImportError, ImportReport};

pub use crate::integrator::point_query::Key;

/// Memoised parts of reproducible tiles (module docs), kept on disk too
/// when the store was opened on a log.
pub struct TileStore {
    records: Cache<Key, Arc<TileRecords>>,
    passes: Cache<Key, Arc<RenderedPass>>,
    log: Option<AppendLog>,
    /// The memory budget, bytes; the log is compacted past twice this.
    budget: u64,
    /// What opening the log found.
    loaded: LogReport,
    /// Where parts computed here go to reach other replicas (framed log
    /// entries); `None` without a shared store.
    outbox: Option<Outbox>,
    /// The largest tile, pixels (`limits.max_tile_area`): a tile places at
    /// most one record per pixel, and a pass has one value per pixel, so
    /// parts received with more are refused.
    max_tile_area: usize,
}

/// Log entry kinds. Kinds 1 (records without their scene) and 3 (records
/// without their depth) are no longer written and are skipped when read.
const PASS: u8 = 2;
const RECORDS: u8 = 4;

/// What `/health` reports about the store.
#[derive(Clone, Copy, Debug, serde::Serialize, utoipa::ToSchema)]
pub struct TileStoreStats {
    /// Tiles whose records are held, and rendered passes held.
    pub tiles: u64,
    pub passes: u64,
    /// Size of the on-disk log, bytes (0 without one).
    pub log_bytes: u64,
    /// Entries read from the log at startup, and bytes of damaged entries
    /// skipped or of a torn tail cut.
    pub loaded_entries: u64,
    pub dropped_bytes: u64,
}

impl TileStore {
    /// A store of about `bytes` in memory, half for records and half for
    /// passes, kept in this process only, of tiles of at most
    /// `max_tile_area` pixels.
    pub fn new(bytes: u64, max_tile_area: usize) -> Self {
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
            log: None,
            budget: bytes,
            loaded: LogReport::default(),
            outbox: None,
            max_tile_area,
        }
    }

    /// The same store, sending every part it computes to `outbox` as a
    /// framed log entry (`cache::log::encode_entry`).
    pub fn sharing_through(mut self, outbox: Outbox) -> Self {
        self.outbox = Some(outbox);
        self
    }

    /// [`Self::new`] backed by the log at `path`: every intact entry is
    /// loaded now (damaged entries skipped, a torn tail cut, `cache::log`), and every part
    /// computed later is appended.
    pub fn open(bytes: u64, max_tile_area: usize, path: &Path) -> std::io::Result<Self> {
        let mut store = Self::new(bytes, max_tile_area);
        let (log, entries, report) = AppendLog::open(path)?;
        for entry in &entries {
            store.insert_entry(entry);
        }
        store.log = Some(log);
        store.loaded = report;
        Ok(store)
    }

    /// The tile records under `key`, placed by `place` if absent (once for
    /// concurrent callers) and then logged.
    pub fn records_or<E: Clone + Send + Sync + 'static>(
        &self,
        key: Key,
        place: impl FnOnce() -> Result<TileRecords, E> + Send,
    ) -> Result<Arc<TileRecords>, E> {
        crate::isolated::try_get_with(&self.records, key, || {
            let records = place()?;
            self.persist(RECORDS, &key, || Cow::Owned(encode_records(&records)), true);
            Ok(Arc::new(records))
        })
        .map_err(|e: Arc<E>| (*e).clone())
    }

    /// The pass under `key`, rendered by `render` if absent (once for
    /// concurrent callers) and then logged.
    pub fn pass_or<E: Clone + Send + Sync + 'static>(
        &self,
        key: Key,
        render: impl FnOnce() -> Result<RenderedPass, E> + Send,
    ) -> Result<Arc<RenderedPass>, E> {
        crate::isolated::try_get_with(&self.passes, key, || {
            let pass = render()?;
            self.persist(PASS, &key, || Cow::Owned(encode_pass(&pass)), true);
            Ok(Arc::new(pass))
        })
        .map_err(|e: Arc<E>| (*e).clone())
    }

    pub fn stats(&self) -> TileStoreStats {
        // Counts are exact only after moka's pending maintenance.
        self.records.run_pending_tasks();
        self.passes.run_pending_tasks();
        TileStoreStats {
            tiles: self.records.entry_count(),
            passes: self.passes.entry_count(),
            log_bytes: self.log.as_ref().map_or(0, AppendLog::bytes),
            loaded_entries: self.loaded.entries,
            dropped_bytes: self.loaded.dropped_bytes,
        }
    }

    /// Adds a part another replica computed (a framed log entry from the
    /// shared store), unless it is held already; it is logged here too, so
    /// it survives a restart of this replica. Returns whether it was new;
    /// a damaged frame or an unknown kind is ignored.
    pub fn merge(&self, framed: &[u8]) -> bool {
        let Some(entry) = log::decode_entry(framed) else {
            return false;
        };
        let held = match entry.kind {
            RECORDS => self.records.contains_key(&entry.key),
            PASS => self.passes.contains_key(&entry.key),
            _ => true,
        };
        if held || !self.insert_entry(&entry) {
            return false;
        }
        self.persist(
            entry.kind,
            &entry.key,
            || Cow::Borrowed(&entry.payload),
            false,
        );
        true
    }

    /// The keys of the tiles of the scene content `scene` whose records are
    /// held here, for an export ([`Self::export_entry`] each, after
    /// [`log::MAGIC`]: a log image).
    pub fn export_keys(&self, scene: &[u8; 32]) -> Vec<Key> {
        self.tiles_of(scene)
            .into_iter()
            .map(|(key, _)| key)
            .collect()
    }

    /// The records of every tile of the scene content `scene` held here,
    /// in the order of their keys.
    pub fn tiles_of(&self, scene: &[u8; 32]) -> Vec<(Key, Arc<TileRecords>)> {
        self.records.run_pending_tasks();
        let mut tiles: Vec<_> = self
            .records
            .iter()
            .filter(|(_, t)| &t.scene == scene)
            .map(|(key, tile)| (*key, tile))
            .collect();
        tiles.sort_unstable_by_key(|(key, _)| *key);
        tiles
    }

    /// The records entry of the tile `key`, framed as in the log; `None`
    /// when it is no longer held (or over the format's size limit).
    pub fn export_entry(&self, key: &Key) -> Option<Vec<u8>> {
        let tile = self.records.get(key)?;
        log::encode_entry(RECORDS, key, &encode_records(&tile)).ok()
    }

    /// The whole export of `scene` at once ([`Self::export_keys`]).
    #[cfg(test)]
    fn export(&self, scene: &[u8; 32]) -> Vec<u8> {
        let mut image = log::MAGIC.to_vec();
        for key in self.export_keys(scene) {
            image.extend(self.export_entry(&key).unwrap_or_default());
        }
        image
    }

    /// The records of an entry's payload (`encode_records`), each checked
    /// as strictly as computed records hold ([`Record::validate_received`]
    /// with the radius limits of the service's caches), at most one per
    /// pixel of the largest tile and no two at one place.
    fn decode_records(&self, bytes: &[u8]) -> Result<TileRecords, Refusal> {
        let (scene, bytes) = bytes.split_first_chunk::<32>().ok_or(Refusal::Malformed)?;
        let (depth, bytes) = bytes.split_first_chunk::<4>().ok_or(Refusal::Malformed)?;
        let max_depth =
            PathDepth::new(u32::from_le_bytes(*depth)).map_err(|_| Refusal::Malformed)?;
        if !bytes.len().is_multiple_of(Record::ENCODED_BYTES) {
            return Err(Refusal::Malformed);
        }
        let count = bytes.len() / Record::ENCODED_BYTES;
        if count > self.max_tile_area {
            return Err(Refusal::Record {
                record: self.max_tile_area,
                reason: format!(
                    "{count} records, more than one per pixel of the largest tile ({} pixels, limits.max_tile_area)",
                    self.max_tile_area
                ),
            });
        }
        let limits = received_radius_limits();
        let mut records = Vec::with_capacity(count);
        for (i, chunk) in bytes.chunks_exact(Record::ENCODED_BYTES).enumerate() {
            let refused = |reason: String| Refusal::Record { record: i, reason };
            let record = Record::from_le_bytes(chunk).ok_or_else(|| {
                refused("not a valid record (non-finite value, zero normal or radius)".into())
            })?;
            record
                .validate_received(limits)
                .map_err(|e| refused(e.to_string()))?;
            records.push(record);
        }
        // Two records at one place (same position and normal) are never
        // placed, and would make every lookup there scan them all.
        let mut places: Vec<([u64; 6], usize)> = records
            .iter()
            .enumerate()
            .map(|(i, r)| {
                let [a, b, c] = r.position.to_array().map(f64::to_bits);
                let [d, e, f] = r.normal.to_array().map(f64::to_bits);
                ([a, b, c, d, e, f], i)
            })
            .collect();
        places.sort_unstable();
        if let Some(pair) = places.windows(2).find(|w| w[0].0 == w[1].0) {
            return Err(Refusal::Record {
                record: pair[0].1.max(pair[1].1),
                reason: format!(
                    "repeats record {} (same position and normal)",
                    pair[0].1.min(pair[1].1)
                ),
            });
        }
        Ok(TileRecords {
            scene: *scene,
            max_depth,
            records,
            report: CachedTileReport::default(),
        })
    }

    /// Decodes and inserts one entry; false when it does not decode.
    fn insert_entry(&self, entry: &LogEntry) -> bool {
        match entry.kind {
            RECORDS => self
                .decode_records(&entry.payload)
                .map(|records| self.records.insert(entry.key, Arc::new(records)))
                .is_ok(),
            PASS => decode_pass(&entry.payload, self.max_tile_area)
                .map(|pass| self.passes.insert(entry.key, Arc::new(pass)))
                .is_some(),
            _ => false,
        }
    }

    /// Appends an entry to the log, if any, and with `share` sends it to
    /// the other replicas, if any. Past twice the budget, the log is
    /// rewritten with what memory still holds (the eviction policy of the
    /// disk: what the in-memory TinyLFU keeps). A failing disk or a full
    /// outbox costs persistence or sharing, never the request.
    fn persist<'a>(
        &self,
        kind: u8,
        key: &Key,
        payload: impl FnOnce() -> Cow<'a, [u8]>,
        share: bool,
    ) {
        let outbox = self.outbox.as_ref().filter(|_| share);
        if outbox.is_none() && self.log.is_none() {
            // Memory only: nothing to encode for.
            return;
        }
        let payload = payload();
        if let Some(outbox) = outbox {
            match log::encode_entry(kind, key, &payload) {
                Ok(framed) => outbox.send(framed),
                Err(err) => tracing::warn!(%err, "tile part too large to share"),
            }
        }
        let Some(log) = &self.log else {
            return;
        };
        if let Err(err) = log.append(kind, key, &payload) {
            tracing::warn!(%err, "cannot append to the tile log; this part will not survive a restart");
            return;
        }
        if log.bytes() > self.budget.saturating_mul(2) {
            self.records.run_pending_tasks();
            self.passes.run_pending_tasks();
            let records: Vec<(Arc<Key>, Vec<u8>)> = self
                .records
                .iter()
                .map(|(k, v)| (k, encode_records(&v)))
                .collect();
            let passes: Vec<(Arc<Key>, Vec<u8>)> = self
                .passes
                .iter()
                .map(|(k, v)| (k, encode_pass(&v)))
                .collect();
            let entries = records
                .iter()
                .map(|(k, p)| (RECORDS, &**k, p.as_slice()))
                .chain(passes.iter().map(|(k, p)| (PASS, &**k, p.as_slice())));
            match log.rewrite(entries) {
                Ok(()) => tracing::info!(bytes = log.bytes(), "tile log compacted"),
                Err(err) => tracing::warn!(%err, "cannot compact the tile log"),
            }
        }
    }
}

/// `scene digest: 32 bytes | camera depth: u32 LE | records`
/// (`Record::to_le_bytes` each).
fn encode_records(tile: &TileRecords) -> Vec<u8> {
    let mut out = tile.scene.to_vec();
    out.extend(tile.max_depth.get().to_le_bytes());
    out.extend(tile.records.iter().flat_map(Record::to_le_bytes));
    out
}

/// Why a records payload was refused.
enum Refusal {
    /// Not a records payload at all.
    Malformed,
    /// Record `record` (or the count, as `record` = the limit) is not one
    /// computed records could be.
    Record { record: usize, reason: String },
}

/// The radius limits of the records the service computes: its irradiance
/// caches are all made from [`CacheConfig::default`] (`service::integrator_doc`).
fn received_radius_limits() -> RadiusLimits {
    CacheConfig::default()
        .validate()
        .expect("the default cache configuration is valid")
}

/// `width, height: u32 | rays, cache_hits: u64 | layers: u8 (0 none, 1
/// the image's variance, 2 and the shared parts, 3 and the rays per pixel)
/// | rgb f32s | variance f32s | shared f32s | rays per pixel as f32s
/// (integers below 2²⁴, exact)`, little-endian.
fn encode_pass(pass: &RenderedPass) -> Vec<u8> {
    let image = &pass.image;
    let mut out = Vec::with_capacity(25 + image.rgb().len() * 24);
    out.extend(image.width().to_le_bytes());
    out.extend(image.height().to_le_bytes());
    out.extend(pass.rays.to_le_bytes());
    out.extend(pass.cache_hits.to_le_bytes());
    let counts: Vec<f32> = pass.counts.iter().map(|&n| n as f32).collect();
    // Rays per pixel come after the shared parts, zeros if there are none.
    let zeros = vec![0.0; pass.counts.len()];
    let shared = if pass.shared.is_empty() {
        &zeros
    } else {
        &pass.shared
    };
    let layers: Vec<&[f32]> = match image.variance() {
        None => vec![],
        Some(v) if shared.is_empty() => vec![v],
        Some(v) if counts.is_empty() => vec![v, shared],
        Some(v) => vec![v, shared, &counts],
    };
    out.push(layers.len() as u8);
    out.extend(image.rgb().iter().flatten().flat_map(|c| c.to_le_bytes()));
    out.extend(
        layers
            .iter()
            .copied()
            .flatten()
            .flat_map(|v| v.to_le_bytes()),
    );
    out
}

/// The pass of an entry's payload (`encode_pass`): at most `max_area`
/// pixels, every value finite, non-negative and at most [`MAX_IRRADIANCE`]
/// (variances its square), rays per pixel whole and positive, as rendered
/// passes are.
fn decode_pass(bytes: &[u8], max_area: usize) -> Option<RenderedPass> {
    let u32_at = |i: usize| Some(u32::from_le_bytes(bytes.get(i..i + 4)?.try_into().ok()?));
    let u64_at = |i: usize| Some(u64::from_le_bytes(bytes.get(i..i + 8)?.try_into().ok()?));
    let (width, height) = (u32_at(0)?, u32_at(4)?);
    let (rays, cache_hits) = (u64_at(8)?, u64_at(16)?);
    let layers = usize::from(*bytes.get(24)?);
    if layers > 3 {
        return None;
    }
    let pixels = (width as usize).checked_mul(height as usize)?;
    if pixels > max_area {
        return None;
    }
    let floats: Vec<f32> = bytes
        .get(25..)?
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
        .collect();
    if floats.len() != pixels * (3 + layers) || !bytes[25..].len().is_multiple_of(4) {
        return None;
    }
    let (max_value, max_variance) = (
        MAX_IRRADIANCE as f32,
        (MAX_IRRADIANCE * MAX_IRRADIANCE) as f32,
    );
    let (values, variances) = floats.split_at(3 * pixels);
    if !values.iter().all(|v| (0.0..=max_value).contains(v))
        || !variances.iter().all(|v| (0.0..=max_variance).contains(v))
    {
        return None;
    }
    let rgb = floats[..3 * pixels]
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    let layer = |k: usize| (layers > k).then(|| &floats[(3 + k) * pixels..(4 + k) * pixels]);
    let counts = match layer(2) {
        None => vec![],
        Some(c)
            if c.iter()
                .all(|&n| n >= 1.0 && n.fract() == 0.0 && n < 16_777_216.0) =>
        {
            c.iter().map(|&n| n as u32).collect()
        }
        Some(_) => return None,
    };
    let image = Image::from_parts(width, height, rgb, layer(0).map(<[f32]>::to_vec)).ok()?;
    Some(RenderedPass {
        image,
        shared: layer(1).map(<[f32]>::to_vec).unwrap_or_default(),
        counts,
        rays,
        cache_hits,
    })
}

/// Point queries' records prior reads the tile store's entries and keeps
/// the records placed among their points in it, like a tile's
/// (`integrator::point_query`).
impl RecordsStore for TileStore {
    fn records_or(
        &self,
        key: Key,
        place: impl FnOnce() -> Result<TileRecords, RenderError> + Send,
    ) -> Result<Arc<TileRecords>, RenderError> {
        TileStore::records_or(self, key, place)
    }

    fn records_of(&self, scene: &[u8; 32]) -> Vec<(Key, Arc<TileRecords>)> {
        self.tiles_of(scene)
    }
}

#[cfg(test)]
mod tests;
