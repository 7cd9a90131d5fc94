//! A set of irradiance-cache records with the rules they are computed
//! with and their direct-light twins (docs/math.md §10.8): the unit the
//! service's shared caches and the gatherings of point queries' records
//! hold, and, as a [`PriorSource`], a source of point queries' priors.

use std::collections::HashSet;
use std::sync::{Arc, Mutex};

use super::{CachedShading, RecordSource, TwinRule, direct_records};
use crate::cache::{Accuracy, CacheConfig, CacheError, IrradianceCache, RECORD_BYTES, TwinCaches};
use crate::render::{Cancel, Decomposition, PathDepth, RenderError, Transport};

/// The direct-light twins of a cache's records, both kinds, and their
/// shadow probes may use `1/DIRECT_SHARE` of the cache's budget, a quarter
/// each (beyond it their own FIFO eviction drops the oldest).
pub const DIRECT_SHARE: usize = 4;

/// Seed of every direct-light twin (with its place: the same record has the
/// same twin in every replica and after every restart).
const DIRECT_SEED: u64 = 0x00D1_2EC7;

/// One cache with the BMC rules its records are computed with (built once
/// per cache, so no request refactorises them).
pub struct SceneCache {
    pub cache: IrradianceCache,
    pub shading: CachedShading,
    /// Direct-light twins of the records (docs/math.md §10.8) for queries
    /// under the hemisphere decomposition (the record rule's) and for split
    /// ones (light-sampled).
    hemisphere_twins: DirectTwins,
    split_twins: DirectTwins,
    /// The configuration as people read it in `GET /v1/scenes/{id}/cache`.
    pub description: serde_json::Value,
}

impl SceneCache {
    /// An empty cache of `config` for records computed with `shading`'s
    /// rules; each kind of its direct-light twins, and their probes, take a
    /// quarter of `1/DIRECT_SHARE` of its budget (at least one record).
    pub fn new(
        config: CacheConfig,
        shading: CachedShading,
        description: serde_json::Value,
    ) -> Result<Self, CacheError> {
        let direct = CacheConfig {
            byte_budget: (config.byte_budget / (4 * DIRECT_SHARE)).max(RECORD_BYTES),
            ..config
        };
        Ok(Self {
            cache: IrradianceCache::new(config)?,
            hemisphere_twins: DirectTwins::new(direct)?,
            split_twins: DirectTwins::new(direct)?,
            shading,
            description,
        })
    }

    /// Empties the records, their twins and the rules' secondary caches;
    /// returns the records dropped.
    pub fn clear(&self) -> u64 {
        let records = self.cache.stats().records;
        self.cache.clear();
        self.hemisphere_twins.clear();
        self.split_twins.clear();
        records + self.shading.secondary.clear()
    }

    /// The direct-light twins of every record held now (docs/math.md §10.8)
    /// for queries under `decomposition`, made for the records that have
    /// none yet. Returns them and the rays traced for the new ones.
    pub fn direct_twins(
        &self,
        transport: &Transport,
        decomposition: Decomposition,
        cancel: &Cancel,
    ) -> Result<(&TwinCaches, u64), RenderError> {
        let direct = match decomposition {
            Decomposition::Hemisphere => &self.hemisphere_twins,
            Decomposition::Split => &self.split_twins,
        };
        // One request makes the missing twins; others wait for them rather
        // than trace the same rays.
        let mut mirrored = direct.mirrored.lock().unwrap_or_else(|e| e.into_inner());
        let records = self.cache.records();
        // Forget the places of records the cache has evicted since.
        let held: HashSet<[u64; 3]> = records.iter().map(place).collect();
        mirrored.retain(|p| held.contains(p));
        let new: Vec<_> = records
            .into_iter()
            .filter(|r| !mirrored.contains(&place(r)))
            .collect();
        let rays = direct_records(
            transport,
            &new,
            TwinRule::for_queries(decomposition, &self.shading.rule),
            &direct.twins,
            DIRECT_SEED,
            cancel,
        )?;
        mirrored.extend(new.iter().map(place));
        Ok((&direct.twins, rays))
    }
}

/// A record's place as bits (records are told apart by where they are).
fn place(record: &crate::cache::Record) -> [u64; 3] {
    record.position.to_array().map(f64::to_bits)
}

/// The direct-light twins of one cache's records.
struct DirectTwins {
    twins: TwinCaches,
    /// The places of the records whose twin has been made.
    mirrored: Mutex<HashSet<[u64; 3]>>,
}

impl DirectTwins {
    fn new(config: CacheConfig) -> Result<Self, CacheError> {
        Ok(Self {
            twins: TwinCaches::new(config)?,
            mirrored: Mutex::new(HashSet::new()),
        })
    }

    fn clear(&self) {
        let mut mirrored = self.mirrored.lock().unwrap_or_else(|e| e.into_inner());
        self.twins.clear();
        mirrored.clear();
    }
}

/// One cache of a scene version as a prior source: its records sum paths
/// of up to `max_depth` segments counted from the camera, so one segment
/// fewer from their own point.
pub struct PriorSource {
    max_depth: PathDepth,
    entry: Arc<SceneCache>,
    origin: &'static str,
}

impl PriorSource {
    /// `entry`'s records, whose camera paths had `max_depth` segments;
    /// `origin` names them in responses.
    pub fn new(max_depth: PathDepth, entry: Arc<SceneCache>, origin: &'static str) -> Self {
        Self {
            max_depth,
            entry,
            origin,
        }
    }
}

impl RecordSource for PriorSource {
    fn records(&self) -> (&IrradianceCache, Accuracy) {
        (&self.entry.cache, self.entry.shading.accuracy())
    }

    fn origin(&self) -> &'static str {
        self.origin
    }

    fn depth_from_point(&self) -> Option<PathDepth> {
        self.max_depth.after_first_segment()
    }

    fn direct_twins(
        &self,
        transport: &Transport,
        decomposition: Decomposition,
        cancel: &Cancel,
    ) -> Result<Option<(&TwinCaches, u64)>, RenderError> {
        self.entry
            .direct_twins(transport, decomposition, cancel)
            .map(Some)
    }
}
