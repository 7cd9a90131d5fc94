//! Direct-light twins beside their shadow probes (docs/math.md §10.8).

use super::error::CacheError;
use super::irradiance_cache::{CacheConfig, IrradianceCache};

/// The direct-light twins of a cache's records and, for light-sampled
/// twins, at each twin's place, normal and radius, the shadow probe there
/// (`render::shadow_probe`, no variance, its rotation gradient): both
/// caches take the same records in the same order, so a lookup weighs a
/// twin and its probe alike and both evict alike.
pub struct TwinCaches {
    pub twins: IrradianceCache,
    pub probes: IrradianceCache,
}

impl TwinCaches {
    /// Both empty, each with `config`.
    pub fn new(config: CacheConfig) -> Result<Self, CacheError> {
        Ok(Self {
            twins: IrradianceCache::new(config)?,
            probes: IrradianceCache::new(config)?,
        })
    }

    pub fn clear(&self) {
        self.twins.clear();
        self.probes.clear();
    }
}
