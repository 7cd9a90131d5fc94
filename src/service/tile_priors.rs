//! Reproducible tiles' records as priors of point queries (docs/math.md
//! §10.10).
//!
//! A reproducible tile's records (`tile_store`) are a function of the
//! scene's content and the tile's request, and a replica holds the same
//! ones whether it computed them, merged them from another replica, loaded
//! them from its log after a restart or imported them. For point queries,
//! the records held for one scene content and one camera depth are gathered
//! into one cache, inserted in the order of their tiles' content keys, so a
//! query meets the same prior, bit for bit, wherever the same tiles are
//! held. A gathering is built once per set of tiles held and kept
//! ([`TilePriors`]); its direct-light twins (§10.8) are made by the first
//! query that needs them, all with one rule ([`TWIN_DIRECTIONS`]).

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

use moka::sync::Cache;

use super::irradiance_caches::{PriorSource, SceneCache};
use super::scenes::LoadedScene;
use super::tile_store::{Key, TileStore};
use crate::bmc::cache::QuadratureCache;
use crate::cache::{CacheConfig, CacheError};
use crate::integrator::cached::{CachedShading, CachedSpec};

/// Directions of the rule that makes the gathered records' direct-light
/// twins: as many as the final preset's records have, with which the twins
/// were measured (docs/BENCHMARKS.md, direct-light records).
const TWIN_DIRECTIONS: usize = 1024;

/// Gatherings of reproducible tiles' records (module docs).
pub struct TilePriors {
    /// By the content key of the scene, depth and tiles gathered.
    gathered: Cache<Key, Arc<SceneCache>>,
    /// The byte budget of one gathering (its oldest tiles' records, in key
    /// order, are dropped beyond it).
    gathering_bytes: usize,
    /// The twins' rule, built on first use.
    twin_rules: Mutex<Option<CachedShading>>,
}

impl TilePriors {
    /// Gatherings of `gathering_bytes` each, `total_bytes` together.
    pub fn new(gathering_bytes: usize, total_bytes: u64) -> Self {
        Self {
            gathered: Cache::builder()
                .weigher(|_, gathering: &Arc<SceneCache>| {
                    u32::try_from(gathering.cache.stats().bytes).unwrap_or(u32::MAX)
                })
                .max_capacity(total_bytes)
                .build(),
            gathering_bytes,
            twin_rules: Mutex::new(None),
        }
    }

    /// The gatherings of the tiles `tiles` holds for `scene`'s content, one
    /// per camera depth.
    pub fn sources(
        &self,
        scene: &LoadedScene,
        tiles: &TileStore,
        quadratures: &Arc<QuadratureCache>,
    ) -> Result<Vec<PriorSource>, CacheError> {
        let digest = scene.transport.scene().digest.as_bytes();
        let mut by_depth: BTreeMap<u32, Vec<_>> = BTreeMap::new();
        for (key, tile) in tiles.tiles_of(digest) {
            if !tile.records.is_empty() {
                by_depth
                    .entry(tile.max_depth.get())
                    .or_default()
                    .push((key, tile));
            }
        }
        let mut sources = Vec::with_capacity(by_depth.len());
        for (depth, tiles) in by_depth {
            let max_depth = tiles[0].1.max_depth;
            let mut hasher = blake3::Hasher::new();
            hasher.update(b"gathered tile records\0");
            hasher.update(digest);
            hasher.update(&depth.to_le_bytes());
            for (key, _) in &tiles {
                hasher.update(key);
            }
            let key = *hasher.finalize().as_bytes();
            let gathering = crate::isolated::try_get_with(&self.gathered, key, || {
                let config = CacheConfig {
                    byte_budget: self.gathering_bytes,
                    ..CacheConfig::default()
                };
                let description = serde_json::json!({
                    "gathered_tiles": tiles.len(),
                    "max_depth": depth,
                });
                let gathering =
                    SceneCache::new(config, self.twin_rules(quadratures)?, description)?;
                for (_, tile) in &tiles {
                    for record in &tile.records {
                        gathering.cache.insert(*record)?;
                    }
                }
                Ok::<_, CacheError>(Arc::new(gathering))
            })
            .map_err(|e: Arc<CacheError>| (*e).clone())?;
            sources.push(PriorSource::new(max_depth, gathering, "tiles"));
        }
        Ok(sources)
    }

    /// The rules every gathering's twins are made with.
    fn twin_rules(&self, quadratures: &Arc<QuadratureCache>) -> Result<CachedShading, CacheError> {
        let mut rules = self.twin_rules.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(rules) = rules.as_ref() {
            return Ok(rules.clone());
        }
        let spec = CachedSpec {
            samples: Some(TWIN_DIRECTIONS),
            ..CachedSpec::default()
        };
        let built = spec.resolve()?.shading(quadratures.clone())?;
        *rules = Some(built.clone());
        Ok(built)
    }
}
