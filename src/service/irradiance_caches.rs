//! The irradiance caches of all scenes: one [`IrradianceCache`] per (scene
//! version, estimator configuration), shared by every request that renders
//! that scene with that configuration.
//!
//! # Versions
//! Each [`LoadedScene`] carries a generation number, new for every load, and
//! the cache key includes it; so a scene posted again under the same id never
//! sees records of its previous version. The routes that replace or delete a
//! scene also drop the old version's caches at once to free their memory.
//!
//! # Memory
//! `cache.irradiance_bytes` bounds all caches together, rules included: each
//! cache's records may take [`SHARE`]⁻¹ of it (its own FIFO eviction keeps it
//! there, see `cache::irradiance_cache`), and its records' BMC rule (Cholesky
//! factor and gradient tables, `≈ 24 N²` bytes for `N` directions per record:
//! 25 MB at 1024, 400 MB at 4096) is weighed beside them. The set of caches
//! is a moka cache weighed by the sum, so creating a cache beyond the total
//! evicts the least valuable one (moka's TinyLFU) as a whole. A configuration
//! whose rule alone exceeds the total is refused (422) and its rule dropped.
//! Each cache also holds the direct-light twins of its records (docs/math.md
//! §10.8), one kind for queries under each decomposition, made when a
//! records-prior query first needs them, both kinds and their shadow probes
//! within [`DIRECT_SHARE`]⁻¹ of the cache's own budget (a quarter each),
//! weighed with it.

use std::sync::Arc;

use moka::sync::Cache;
use serde::Serialize;
use utoipa::ToSchema;

use super::scenes::LoadedScene;
use crate::cache::{CacheConfig, CacheError, CacheStats, RECORD_BYTES};
use crate::integrator::cached::{CachedShading, DIRECT_SHARE, PriorSource, RecordsKey, SceneCache};

/// Each cache may use `1/SHARE` of the total budget.
pub const SHARE: usize = 4;

/// Identity of one cache.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
struct CacheKey {
    scene: String,
    generation: u64,
    /// What the records' values depend on.
    records: RecordsKey,
}

/// One cache as `GET /v1/scenes/{id}/cache` reports it.
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct ConfigurationStats {
    /// The estimator configuration the records were computed with (JSON).
    #[schema(value_type = Object)]
    pub configuration: serde_json::Value,
    #[schema(value_type = Object)]
    pub stats: CacheStats,
    /// Bytes of the records' BMC rule (factor and tables), held beside the records.
    pub rule_bytes: usize,
    /// Records of the scene's secondary caches for this configuration
    /// (`secondary_cache`, docs/math.md §9.6), apart from `stats`.
    pub secondary_records: u64,
}

/// The byte budget of each cache when all share `total_bytes`.
pub fn per_cache_bytes(total_bytes: usize) -> usize {
    (total_bytes / SHARE).max(RECORD_BYTES)
}

/// All irradiance caches of the service.
pub struct IrradianceCaches {
    caches: Cache<CacheKey, Arc<SceneCache>>,
    per_cache_bytes: usize,
    total_bytes: usize,
}

impl IrradianceCaches {
    /// Caches sharing `total_bytes` (module docs).
    pub fn new(total_bytes: usize) -> Self {
        let per_cache_bytes = per_cache_bytes(total_bytes);
        let kib = |bytes: usize| u32::try_from(bytes.div_ceil(1024)).unwrap_or(u32::MAX);
        Self {
            caches: Cache::builder()
                .max_capacity(total_bytes.div_ceil(1024) as u64)
                .weigher(move |_, entry: &Arc<SceneCache>| {
                    let records = per_cache_bytes + per_cache_bytes / DIRECT_SHARE;
                    kib(records + entry.shading.rule.size_bytes())
                })
                .support_invalidation_closures()
                .build(),
            per_cache_bytes,
            total_bytes,
        }
    }

    /// Byte budget of each cache.
    pub fn per_cache_bytes(&self) -> usize {
        self.per_cache_bytes
    }

    /// The cache of `scene` for the records `records`, created on first use
    /// from `template` (whose byte budget is replaced by
    /// [`Self::per_cache_bytes`]), the rules `shading` builds and the
    /// description `describe` gives. Concurrent first uses create it once;
    /// errors are not cached.
    pub fn get_or_create(
        &self,
        scene: &LoadedScene,
        records: RecordsKey,
        describe: impl FnOnce() -> serde_json::Value + Send,
        template: CacheConfig,
        shading: impl FnOnce() -> Result<CachedShading, CacheError> + Send,
    ) -> Result<Arc<SceneCache>, CacheError> {
        let key = CacheKey {
            scene: scene.id.clone(),
            generation: scene.generation,
            records,
        };
        let config = CacheConfig {
            byte_budget: self.per_cache_bytes,
            ..template
        };
        let total = self.total_bytes;
        crate::isolated::try_get_with(&self.caches, key, || -> Result<_, CacheError> {
                let shading = shading()?;
                let bytes = shading.rule.size_bytes();
                if bytes > total {
                    return Err(CacheError::invalid(
                        "samples",
                        format!(
                            "the records' rule would take {bytes} bytes, more than all of cache.irradiance_bytes ({total}); use fewer directions"
                        ),
                    ));
                }
                SceneCache::new(config, shading, describe()).map(Arc::new)
            })
            .map_err(|err: Arc<CacheError>| (*err).clone())
    }

    /// The caches of this version of `scene`.
    fn of_scene(
        &self,
        scene: &LoadedScene,
    ) -> impl Iterator<Item = (Arc<CacheKey>, Arc<SceneCache>)> {
        self.caches
            .iter()
            .filter(|(key, _)| key.scene == scene.id && key.generation == scene.generation)
    }

    /// Every cache of this version of `scene`, as sources of point
    /// queries' priors (`integrator::cached::point_priors` picks among them).
    pub fn prior_sources(&self, scene: &LoadedScene) -> impl Iterator<Item = PriorSource> {
        self.of_scene(scene)
            .map(|(key, entry)| PriorSource::new(key.records.max_depth(), entry, "cache"))
    }

    /// Stats of every cache of this version of `scene`, sorted by configuration.
    pub fn stats(&self, scene: &LoadedScene) -> Vec<ConfigurationStats> {
        let mut all: Vec<ConfigurationStats> = self
            .of_scene(scene)
            .map(|(_, entry)| ConfigurationStats {
                configuration: entry.description.clone(),
                stats: entry.cache.stats(),
                rule_bytes: entry.shading.rule.size_bytes(),
                secondary_records: entry.shading.secondary.records(),
            })
            .collect();
        all.sort_by_key(|c| c.configuration.to_string());
        all
    }

    /// Empties every cache of this version of `scene`, secondary caches
    /// included; returns the records dropped.
    pub fn clear(&self, scene: &LoadedScene) -> u64 {
        self.of_scene(scene).map(|(_, entry)| entry.clear()).sum()
    }

    /// Drops the caches of every version of scene `id` older than
    /// `keep_generation` (all of them for `None`, when the scene is deleted).
    pub fn retire(&self, id: &str, keep_generation: Option<u64>) {
        let id = id.to_owned();
        // Only fails if invalidation closures were not enabled, which `new` does.
        let _ = self.caches.invalidate_entries_if(move |key, _| {
            key.scene == id && keep_generation.is_none_or(|g| key.generation < g)
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bmc::cache::QuadratureCache;
    use crate::cache::RecordRuleSpec;
    use crate::integrator::cached::{CacheShadingOptions, default_rule_spec};
    use crate::scene::Scene;
    use crate::service::scenes::SceneSource;
    use crate::sphere::SampleSetKind;

    fn rules() -> Result<CachedShading, CacheError> {
        let mut spec: RecordRuleSpec = default_rule_spec();
        spec.samples.kind = SampleSetKind::Fibonacci;
        spec.samples.count = 8;
        let quadratures = Arc::new(QuadratureCache::new(1 << 20));
        CachedShading::new(spec, 2, quadratures, CacheShadingOptions::default())
    }

    /// The records key and description of the default configuration with
    /// `samples` directions per record.
    fn records(samples: usize) -> (RecordsKey, serde_json::Value) {
        let config = crate::integrator::cached::CachedSpec {
            samples: Some(samples),
            ..Default::default()
        }
        .resolve()
        .unwrap();
        let depth = crate::render::PathDepth::default();
        (config.records_key(depth), config.describe(depth))
    }

    fn scene(id: &str) -> LoadedScene {
        let text = r#"{
            "materials": [{"id": "w", "type": "diffuse", "reflectance": [0.5, 0.5, 0.5]}],
            "shapes": [{"type": "rectangle", "material": "w"}],
            "camera": {"fov": 40, "origin": [0, 0, 3], "target": [0, 0, 0], "up": [0, 1, 0],
                       "width": 4, "height": 4}
        }"#;
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let scene = Scene::from_json_str(text, root, root).expect("loads");
        LoadedScene::new(id.into(), SceneSource::Uploaded, scene)
    }

    #[test]
    fn caches_are_per_version_and_configuration() {
        let caches = IrradianceCaches::new(1 << 20);
        let (a, a_again) = (scene("a"), scene("a"));
        assert_ne!(a.generation, a_again.generation);
        let (key, description) = records(64);
        let describe = || description.clone();
        let first = caches
            .get_or_create(&a, key, describe, CacheConfig::default(), rules)
            .expect("valid");
        let same = caches
            .get_or_create(&a, key, describe, CacheConfig::default(), rules)
            .expect("valid");
        assert!(Arc::ptr_eq(&first, &same));
        assert_eq!(first.cache.config().byte_budget, caches.per_cache_bytes());
        let (key16, description16) = records(16);
        let other = caches
            .get_or_create(&a, key16, || description16, CacheConfig::default(), rules)
            .expect("valid");
        assert!(!Arc::ptr_eq(&first, &other));
        let reloaded = caches
            .get_or_create(&a_again, key, describe, CacheConfig::default(), rules)
            .expect("valid");
        assert!(!Arc::ptr_eq(&first, &reloaded));
        caches.caches.run_pending_tasks();
        assert_eq!(caches.stats(&a).len(), 2);
        assert_eq!(caches.stats(&a_again).len(), 1);
        let counts: Vec<u64> = caches
            .stats(&a)
            .iter()
            .map(|c| {
                c.configuration["rule"]["samples"]["count"]
                    .as_u64()
                    .unwrap()
            })
            .collect();
        assert_eq!(counts.len(), 2);
        assert!(counts.contains(&16) && counts.contains(&64), "{counts:?}");

        caches.retire("a", Some(a_again.generation));
        caches.caches.run_pending_tasks();
        assert!(caches.stats(&a).is_empty());
        assert_eq!(caches.stats(&a_again).len(), 1);
        caches.retire("a", None);
        caches.caches.run_pending_tasks();
        assert!(caches.stats(&a_again).is_empty());
    }

    #[test]
    fn bad_settings_are_not_cached() {
        let caches = IrradianceCaches::new(1 << 20);
        let a = scene("a");
        let bad = CacheConfig {
            min_radius: -1.0,
            ..CacheConfig::default()
        };
        let (key, description) = records(64);
        let describe = || description.clone();
        assert!(caches.get_or_create(&a, key, describe, bad, rules).is_err());
        assert!(
            caches
                .get_or_create(&a, key, describe, CacheConfig::default(), rules)
                .is_ok()
        );
    }
}
