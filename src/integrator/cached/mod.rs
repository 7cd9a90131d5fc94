//! The irradiance-cache integrator: camera rays and radiance queries shaded
//! through the Bayesian irradiance cache of [`crate::cache`] (docs/math.md §9,
//! §13), with records computed on demand.
//!
//! One concept per file:
//! - `spec`: the integrator's knobs as requests and the command line name
//!   them, resolved and checked once;
//! - `config`: the checked options and the rules built from them;
//! - `glossy`: BMC with the Phong density, tabulated over `θ_r`;
//! - `shade`: outgoing radiance at a surface point (direct light, cached
//!   diffuse indirect, BMC glossy) and records computed at points, gathering
//!   through the cache: the whole shading/record recursion, so no other file
//!   takes part in it;
//! - `shade_point`: how a point is shaded (what a miss does, the ray that
//!   reaches it, an ambient bounce);
//! - `direct_light`: direct light by stratified light samples;
//! - `record_estimate`: records from gathered rays (estimates, radii), where
//!   they may be placed, and cache lookups with the occlusion check;
//! - `error`: cache errors as render errors;
//! - `placement`: the reproducible placement and shading passes over many
//!   points, and variance-driven placement;
//! - `secondary`: the scene-wide cache that records' rays read at their
//!   first hits instead of tracing paths on, and how it is built;
//! - `secondary_caches`: those caches held by a rule set, each built once;
//! - `tiles`: camera tiles shaded through a shared or private cache;
//! - `dense`: tiles where records do not pay, and the probe that finds them;
//! - `point_priors`: which caches' records serve point queries as priors;
//! - `record_view`: records as the camera sees them (positions, radii,
//!   an overlay image);
//! - `stats`: counters.

mod config;
mod dense;
mod direct_light;
mod direct_records;
mod error;
mod glossy;
mod placement;
mod point_priors;
mod point_records;
mod record_estimate;
mod record_view;
mod scene_cache;
mod secondary;
mod secondary_caches;
mod shade;
mod shade_point;
mod spec;
mod stats;
mod tiles;

pub use config::{
    AMBIENT_MIN_DEPTH, CacheShadingOptions, CachedShading, MAX_AMBIENT_BOUNCES, MAX_BMC_EXPONENT,
    MAX_LIGHT_SAMPLES, PlacementOptions, default_rule_spec, indirect_paths,
};
pub use direct_records::{TwinRule, direct_records};
pub use glossy::{GlossyRule, GlossyWeights, MAX_GLOSSY_BINS};
pub use placement::{PlacementCache, PlacementReport, place_and_shade, place_records, shade};
pub use point_priors::{DirectPrior, PointPriors, RecordSource, point_priors};
pub use point_records::point_records;
pub use record_estimate::{PlacementPoint, lookup};
pub use record_view::{RecordView, record_overlay, record_views};
pub use scene_cache::{DIRECT_SHARE, PriorSource, SceneCache};
pub use secondary::secondary_cache_of;
pub use secondary_caches::{SecondaryCache, SecondaryCaches};
pub use shade::{CachedIntegrator, Gather, RecordGather, compute_record};
pub use shade_point::{Bounce, OnMiss, ShadePoint};
pub use spec::{CachedConfig, CachedSpec, DEFAULT_GLOSSY_BINS, DEFAULT_RECORD_SAMPLES, RecordsKey};
pub use stats::ShadingStats;
pub use tiles::{CachedTileReport, RECORD_BLOCK, RecordBlock, block_margin, record_blocks};
