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
//! the same URLs cost nothing again. A torn or corrupt tail is cut on load.
//! Eviction: memory holds `cache.tile_bytes` by TinyLFU; the log is
//! rewritten with what memory holds whenever it passes twice that.
//!
//! Tiles rendered through the shared cache (`reproducible: false`) depend
//! on what ran before and are not kept here; their records live in the
//! scene's shared cache.

use std::path::Path;
use std::sync::Arc;

use moka::sync::Cache;

use crate::cache::log::{AppendLog, LogReport};
use crate::cache::{RECORD_BYTES, Record};
use crate::image::Image;
use crate::integrator::cached::CachedTileReport;

/// A content key (BLAKE3 of a canonical description).
pub type Key = [u8; 32];

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
}

/// Log entry kinds.
const RECORDS: u8 = 1;
const PASS: u8 = 2;

/// What `/health` reports about the store.
#[derive(Clone, Copy, Debug, serde::Serialize, utoipa::ToSchema)]
pub struct TileStoreStats {
    /// Tiles whose records are held, and rendered passes held.
    pub tiles: u64,
    pub passes: u64,
    /// Size of the on-disk log, bytes (0 without one).
    pub log_bytes: u64,
    /// Entries read from the log at startup, and bytes of a damaged tail cut.
    pub loaded_entries: u64,
    pub dropped_bytes: u64,
}

impl TileStore {
    /// A store of about `bytes` in memory, half for records and half for
    /// passes, kept in this process only.
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
            log: None,
            budget: bytes,
            loaded: LogReport::default(),
        }
    }

    /// [`Self::new`] backed by the log at `path`: every intact entry is
    /// loaded now (a damaged tail is cut, `cache::log`), and every part
    /// computed later is appended.
    pub fn open(bytes: u64, path: &Path) -> std::io::Result<Self> {
        let mut store = Self::new(bytes);
        let (log, entries, report) = AppendLog::open(path)?;
        for entry in entries {
            match entry.kind {
                RECORDS => {
                    if let Some(records) = decode_records(&entry.payload) {
                        store.records.insert(entry.key, Arc::new(records));
                    }
                }
                PASS => {
                    if let Some(pass) = decode_pass(&entry.payload) {
                        store.passes.insert(entry.key, Arc::new(pass));
                    }
                }
                _ => {}
            }
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
        place: impl FnOnce() -> Result<TileRecords, E>,
    ) -> Result<Arc<TileRecords>, E> {
        self.records
            .try_get_with(key, || {
                let records = place()?;
                self.persist(RECORDS, &key, || encode_records(&records));
                Ok(Arc::new(records))
            })
            .map_err(|e: Arc<E>| (*e).clone())
    }

    /// The pass under `key`, rendered by `render` if absent (once for
    /// concurrent callers) and then logged.
    pub fn pass_or<E: Clone + Send + Sync + 'static>(
        &self,
        key: Key,
        render: impl FnOnce() -> Result<RenderedPass, E>,
    ) -> Result<Arc<RenderedPass>, E> {
        self.passes
            .try_get_with(key, || {
                let pass = render()?;
                self.persist(PASS, &key, || encode_pass(&pass));
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

    /// Appends an entry to the log, if any; past twice the budget, the log
    /// is rewritten with what memory still holds (the eviction policy of
    /// the disk: what the in-memory TinyLFU keeps). A failing disk costs
    /// persistence, never the request.
    fn persist(&self, kind: u8, key: &Key, payload: impl FnOnce() -> Vec<u8>) {
        let Some(log) = &self.log else {
            return;
        };
        if let Err(err) = log.append(kind, key, &payload()) {
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

fn encode_records(tile: &TileRecords) -> Vec<u8> {
    tile.records.iter().flat_map(Record::to_le_bytes).collect()
}

fn decode_records(bytes: &[u8]) -> Option<TileRecords> {
    if !bytes.len().is_multiple_of(Record::ENCODED_BYTES) {
        return None;
    }
    let records = bytes
        .chunks_exact(Record::ENCODED_BYTES)
        .map(Record::from_le_bytes)
        .collect::<Option<Vec<_>>>()?;
    Some(TileRecords {
        records,
        report: CachedTileReport::default(),
    })
}

/// `width, height: u32 | rays, cache_hits: u64 | has variance: u8 | rgb
/// f32s | variance f32s`, little-endian.
fn encode_pass(pass: &RenderedPass) -> Vec<u8> {
    let image = &pass.image;
    let mut out = Vec::with_capacity(25 + image.rgb().len() * 16);
    out.extend(image.width().to_le_bytes());
    out.extend(image.height().to_le_bytes());
    out.extend(pass.rays.to_le_bytes());
    out.extend(pass.cache_hits.to_le_bytes());
    out.push(u8::from(image.variance().is_some()));
    out.extend(image.rgb().iter().flatten().flat_map(|c| c.to_le_bytes()));
    out.extend(
        image
            .variance()
            .into_iter()
            .flatten()
            .flat_map(|v| v.to_le_bytes()),
    );
    out
}

fn decode_pass(bytes: &[u8]) -> Option<RenderedPass> {
    let u32_at = |i: usize| Some(u32::from_le_bytes(bytes.get(i..i + 4)?.try_into().ok()?));
    let u64_at = |i: usize| Some(u64::from_le_bytes(bytes.get(i..i + 8)?.try_into().ok()?));
    let (width, height) = (u32_at(0)?, u32_at(4)?);
    let (rays, cache_hits) = (u64_at(8)?, u64_at(16)?);
    let has_variance = *bytes.get(24)? == 1;
    let pixels = (width as usize).checked_mul(height as usize)?;
    let floats: Vec<f32> = bytes
        .get(25..)?
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
        .collect();
    if floats.len() != pixels * (3 + usize::from(has_variance))
        || !bytes[25..].len().is_multiple_of(4)
    {
        return None;
    }
    let rgb = floats[..3 * pixels]
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    let variance = has_variance.then(|| floats[3 * pixels..].to_vec());
    let image = Image::from_parts(width, height, rgb, variance).ok()?;
    Some(RenderedPass {
        image,
        rays,
        cache_hits,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pass(seed: f32) -> RenderedPass {
        let rgb = (0..6).map(|i| [i as f32 * seed, 1.0, 2.0]).collect();
        RenderedPass {
            image: Image::from_parts(3, 2, rgb, Some(vec![0.5; 6])).unwrap(),
            rays: 99,
            cache_hits: 7,
        }
    }

    #[test]
    fn parts_survive_a_restart_through_the_log() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("tiles.log");
        let record = Record::from_le_bytes(&[0u8; Record::ENCODED_BYTES]);
        assert!(record.is_none(), "a zero normal is not a record");
        let store = TileStore::open(1 << 20, &path).unwrap();
        let p = store.pass_or::<()>([1; 32], || Ok(pass(1.5))).unwrap();
        // Cached: the closure is not called again.
        let again = store
            .pass_or::<()>([1; 32], || panic!("recomputed"))
            .unwrap();
        assert_eq!(again.image, p.image);
        drop(store);
        let reopened = TileStore::open(1 << 20, &path).unwrap();
        assert_eq!(reopened.stats().loaded_entries, 1);
        let back = reopened
            .pass_or::<()>([1; 32], || panic!("not loaded"))
            .unwrap();
        assert_eq!(
            (back.image.clone(), back.rays, back.cache_hits),
            (p.image.clone(), 99, 7)
        );
        assert!(decode_pass(&encode_pass(&p)[..30]).is_none());
    }

    #[test]
    fn the_log_is_compacted_to_what_memory_holds() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("tiles.log");
        // A budget of a few passes: the log is rewritten many times.
        let store = TileStore::open(4096, &path).unwrap();
        for i in 0..200u8 {
            store
                .pass_or::<()>([i; 32], || Ok(pass(f32::from(i))))
                .unwrap();
        }
        assert!(
            store.stats().log_bytes <= 2 * 4096 + 512,
            "{:?}",
            store.stats()
        );
        drop(store);
        let reopened = TileStore::open(4096, &path).unwrap();
        assert!(reopened.stats().loaded_entries > 0);
    }
}
