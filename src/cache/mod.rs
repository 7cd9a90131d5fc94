//! Bayesian irradiance cache (docs/math.md §9; Ward et al. 1988 with BMC
//! records as in Brouillat et al. 2009): records computed once by BMC, with
//! their posterior variance, serve many shading points and many requests.
//!
//! One concept per file:
//! - `record_rule`: the shared BMC rule — irradiance, posterior variance and
//!   rotation/translation gradients (derivatives of the GP posterior mean).
//! - `record`: a record, its validity radius (harmonic mean distance, clamps)
//!   and Ward's weight, in-front test and gradient extrapolation.
//! - `index`: the concurrent multi-level hash grid over records.
//! - `irradiance_cache`: the shared cache — lookup, insertion with the
//!   neighbour clamp, byte budget with FIFO eviction, stats.
//! - `placement`: records at points, the reproducible placement + shading
//!   passes, variance-driven placement and the occlusion check.
//! - `shading`: outgoing radiance at a surface point through the cache
//!   (NEE direct light, cached diffuse indirect, BMC Phong glossy).
//! - `tiles`: camera tiles shaded through a shared or private cache.
//! - `radiance`: outgoing radiance at surface points (the point-query form
//!   of the tile shading), by path tracing or through a cache.
//!
//! No HTTP here; the service keeps one [`IrradianceCache`] per (scene
//! version, estimator configuration).

pub mod error;
pub mod index;
pub mod irradiance_cache;
pub mod placement;
pub mod radiance;
pub mod record;
pub mod record_rule;
pub mod shading;
pub mod tiles;

pub use error::CacheError;
pub use irradiance_cache::{
    Accuracy, CacheConfig, CacheStats, Interpolated, IrradianceCache, RECORD_BYTES,
};
pub use placement::{
    PlacementOptions, PlacementPoint, PlacementReport, compute_record, place_and_shade,
    place_records, shade,
};
pub use radiance::{
    RadianceEstimate, RadianceQuery, RadianceShading, radiance_at_points, surface_at,
};
pub use record::{PixelFootprint, RadiusLimits, Record, harmonic_mean_distance};
pub use record_rule::{RecordEstimate, RecordRule, RecordRuleSpec};
pub use shading::{
    CacheShadingOptions, CachedShading, Gather, GlossyRule, OnMiss, ShadingStats, default_rule_spec,
};
pub use tiles::CachedTileReport;
