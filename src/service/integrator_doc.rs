//! The irradiance-cache integrator as tile and radiance requests name it
//! (`"estimator": {"method": "cache", …}`): the request document, its
//! translation into the library's [`CachedSpec`] checked against the service
//! limits, and the scene's shared cache for the resolved configuration.

use std::sync::Arc;

use serde::Deserialize;
use utoipa::ToSchema;

use super::config::Limits;
use super::error::{ApiError, AtField};
use super::irradiance_caches::SceneCache;
use super::scenes::LoadedScene;
use super::state::AppState;
use crate::cache::{CacheConfig, IrradianceCache};
use crate::integrator::Integrator;
use crate::integrator::cached::{CachedConfig, CachedShading, CachedSpec};
use crate::render::PathDepth;

/// The integrator of a tile or radiance request; every field but `method`
/// applies to `cache` only, and every one is optional (defaults in
/// `integrator::cached::config`).
#[derive(Debug, Default, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct IntegratorDoc {
    /// `cache` (default; `bmc` is an alias): the Bayesian irradiance cache —
    /// light sampling for direct light, `(k_d/π)·E` interpolated from BMC
    /// records for diffuse indirect light, BMC with the Phong density for
    /// glossy reflection. `path`: path tracing with NEE and MIS, the
    /// unbiased reference.
    #[serde(default)]
    #[schema(value_type = String, example = "cache")]
    pub method: Integrator,
    /// Directions per record (spherical Fibonacci), 1..=`limits.max_samples`; default 64.
    pub samples: Option<u32>,
    /// Directions of each glossy BMC estimate (one per camera ray on a
    /// glossy surface), 1..=`limits.max_samples`; default `samples`.
    pub glossy_samples: Option<u32>,
    /// SE kernel lengthscale of the records' GP prior (chordal units); default 0.5.
    pub lengthscale: Option<f64>,
    /// Noise variance σ_n² relative to σ² = 1; default 1e-8.
    pub noise: Option<f64>,
    /// Paths traced per record direction and averaged (with
    /// `secondary_cache`, light samples at each direction's first hit); default 1.
    pub paths_per_direction: Option<u32>,
    /// Levels of records whose rays gather through the cache (Radiance-style
    /// ambient bounces: direct light plus cached indirect irradiance at each
    /// ray's hit), 0..=8; 0 = records trace full paths. Default 0.
    pub ambient_bounces: Option<u32>,
    /// Records' rays (of tiles and radiance queries) stop at their first
    /// hit, shaded there by light samples and the scene's secondary cache of
    /// indirect irradiance (built once per scene and configuration, by the
    /// first request that needs it) instead of tracing paths on; used when
    /// `max_depth` leaves at least 16 segments after the shading point;
    /// excludes `ambient_bounces`. Default false (true in the `final` preset).
    pub secondary_cache: Option<bool>,
    /// Ward's accuracy a ∈ (0, 1]; smaller places more records. Default 0.5.
    pub accuracy: Option<f64>,
    /// Also place a record where the interpolated relative standard error
    /// exceeds this (variance-driven placement); default off.
    pub relative_error_target: Option<f64>,
    /// Shadow ray between a point and each record it uses (no light leaks
    /// through thin walls); default false.
    pub occlusion_check: Option<bool>,
    /// Light samples per shading point for direct light; default 16.
    pub light_samples: Option<u32>,
    /// Bit-identical output whatever the thread count and whatever ran
    /// before: records are placed in a private cache for this tile, then
    /// published to the shared one. Default false.
    pub reproducible: Option<bool>,
    /// Use the scene's shared cache (default true); `false` computes every
    /// record for this request alone and keeps none.
    pub cache: Option<bool>,
}

/// A `cache` integrator resolved for one request: cheap, so it runs before
/// the request takes a CPU slot.
#[derive(Clone, Copy, Debug)]
pub struct ResolvedCache {
    pub config: CachedConfig,
    /// Whether the request reads and extends the scene's shared cache.
    pub shared: bool,
}

impl IntegratorDoc {
    /// The library spec, resolved, with the sample count and each record's
    /// paths checked against the limits.
    pub fn resolve(&self, limits: &Limits) -> Result<ResolvedCache, ApiError> {
        self.resolve_over(CachedSpec::default(), limits)
    }

    /// [`Self::resolve`] with `base` (a preset's knobs) under the fields
    /// this document sets.
    pub fn resolve_over(
        &self,
        base: CachedSpec,
        limits: &Limits,
    ) -> Result<ResolvedCache, ApiError> {
        for (field, count) in [
            ("estimator.samples", self.samples),
            ("estimator.glossy_samples", self.glossy_samples),
        ] {
            if let Some(count) = count {
                ApiError::check_limit(field, u64::from(count), limits.max_samples as u64)?;
            }
        }
        let spec = CachedSpec {
            samples: self.samples.map(|n| n as usize).or(base.samples),
            glossy_samples: self
                .glossy_samples
                .map(|n| n as usize)
                .or(base.glossy_samples),
            lengthscale: self.lengthscale.or(base.lengthscale),
            noise: self.noise.or(base.noise),
            accuracy: self.accuracy.or(base.accuracy),
            relative_error_target: self.relative_error_target.or(base.relative_error_target),
            occlusion_check: self.occlusion_check.or(base.occlusion_check),
            light_samples: self.light_samples.or(base.light_samples),
            paths_per_direction: self.paths_per_direction.or(base.paths_per_direction),
            ambient_bounces: self.ambient_bounces.or(base.ambient_bounces),
            secondary_cache: self.secondary_cache.or(base.secondary_cache),
            reproducible: self.reproducible.or(base.reproducible),
            ..base
        };
        // Validated before the budget, so an out-of-range knob is named as such.
        let config = spec.resolve().at("estimator")?;
        limits.check_record_work(config.paths_per_record())?;
        Ok(ResolvedCache {
            config,
            shared: self.cache.unwrap_or(true),
        })
    }
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
}

/// The cache and rules of `resolved` on `scene` with paths of up to
/// `max_depth` segments counted from the camera (tiles) or viewer (radiance
/// queries), so both share records. Call it on the CPU pool: a new
/// configuration factorises its record rule.
pub fn cached_setup(
    state: &AppState,
    scene: &LoadedScene,
    resolved: ResolvedCache,
    max_depth: PathDepth,
) -> Result<CachedSetup, ApiError> {
    let config = resolved.config;
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
    let shading = entry.shading.with_options(&config);
    let private = if resolved.shared {
        None
    } else {
        Some(IrradianceCache::new(*entry.cache.config()).at("estimator")?)
    };
    Ok(CachedSetup {
        entry,
        shading,
        private,
    })
}
