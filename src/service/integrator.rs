//! The integrator a tile or radiance request names (`"estimator"`, the
//! library's [`IntegratorSpec`]), resolved and checked against the service
//! limits, and the scene's shared cache the cache integrator binds to.

use std::sync::Arc;

use super::config::Limits;
use super::error::{ApiError, AtField};
use super::scenes::LoadedScene;
use super::state::AppState;
use crate::cache::{CacheConfig, IrradianceCache};
use crate::integrator::cached::CachedShading;
use crate::integrator::cached::SceneCache;
use crate::integrator::{Integrator, IntegratorSpec};
use crate::render::PathDepth;

/// `spec` resolved (errors name `estimator.<knob>`), with its sample counts
/// and each record's paths checked against the limits. Cheap, so it runs
/// before the request takes a CPU slot.
pub fn resolve_integrator(spec: IntegratorSpec, limits: &Limits) -> Result<Integrator, ApiError> {
    if let Some(knobs) = spec.cached() {
        for (field, count) in [
            ("estimator.samples", knobs.samples),
            ("estimator.glossy_samples", knobs.glossy_samples),
        ] {
            if let Some(count) = count {
                ApiError::check_limit(field, count as u64, limits.max_samples as u64)?;
            }
        }
    }
    // Validated before the budget, so an out-of-range knob is named as such.
    let integrator = spec.resolve().at("estimator")?;
    if let Some(config) = integrator.cached() {
        limits.check_record_work(config.paths_per_record())?;
    }
    Ok(integrator)
}

/// The cache a request reads and extends, and its rules with the request's options.
pub struct CachedSetup {
    entry: Arc<SceneCache>,
    pub shading: CachedShading,
    /// `Some` when the request disabled the shared cache: its private cache.
    private: Option<IrradianceCache>,
}

impl CachedSetup {
    /// The cache the request reads and extends.
    pub fn cache(&self) -> &IrradianceCache {
        self.private.as_ref().unwrap_or(&self.entry.cache)
    }

    /// What [`Integrator::bind`] takes.
    pub fn binding(&self) -> (&IrradianceCache, &CachedShading) {
        (self.cache(), &self.shading)
    }
}

/// The cache and rules `integrator` binds to on `scene` (none for path
/// tracing), with paths of up to `max_depth` segments counted from the
/// camera (tiles) or viewer (radiance queries), so both share records. Call
/// it on the CPU pool: a new configuration factorises its record rule.
pub fn cached_setup(
    state: &AppState,
    scene: &LoadedScene,
    integrator: &Integrator,
    max_depth: PathDepth,
) -> Result<Option<CachedSetup>, ApiError> {
    let Some(config) = integrator.cached() else {
        return Ok(None);
    };
    let quadratures = state.quadratures.clone();
    let entry = state
        .irradiance_caches
        .get_or_create(
            scene,
            config.records_key(max_depth),
            || config.describe(max_depth),
            CacheConfig::default(),
            || config.shading(quadratures),
        )
        .at("estimator")?;
    let shading = config.apply_to(&entry.shading);
    let private = if config.shared {
        None
    } else {
        Some(IrradianceCache::new(*entry.cache.config()).at("estimator")?)
    };
    Ok(Some(CachedSetup {
        entry,
        shading,
        private,
    }))
}
