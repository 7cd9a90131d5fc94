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
//! Tiles rendered through the shared cache (`reproducible: false`) depend
//! on what ran before and are not kept here; their records live in the
//! scene's shared cache.

use std::sync::Arc;

use moka::sync::Cache;

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

    /// Tiles' records by content key.
    pub fn records(&self) -> &Cache<Key, Arc<TileRecords>> {
        &self.records
    }

    /// Rendered passes by content key.
    pub fn passes(&self) -> &Cache<Key, Arc<RenderedPass>> {
        &self.passes
    }
}
