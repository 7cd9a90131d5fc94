//! The irradiance-cache integrator: camera rays and radiance queries shaded
//! through the Bayesian irradiance cache of [`crate::cache`] (docs/math.md §9,
//! §13), with records computed on demand.
//!
//! One concept per file:
//! - `config`: the integrator's options and rules, defaults written once and
//!   validated once;
//! - `glossy`: BMC with the Phong density, tabulated over `θ_r`;
//! - `shade`: outgoing radiance at a surface point (NEE direct light, cached
//!   diffuse indirect, BMC glossy) and records gathering through the cache;
//! - `placement`: records at points, the reproducible placement and shading
//!   passes, variance-driven placement and the occlusion check;
//! - `tiles`: camera tiles shaded through a shared or private cache;
//! - `radiance`: outgoing radiance at surface points, by path tracing or
//!   through a cache;
//! - `stats`: counters.

pub mod config;
pub mod glossy;
pub mod placement;
pub mod radiance;
pub mod shade;
pub mod stats;
pub mod tiles;

pub use config::{
    AMBIENT_MIN_DEPTH, CacheShadingOptions, CachedShading, MAX_AMBIENT_BOUNCES, MAX_BMC_EXPONENT,
    MAX_LIGHT_SAMPLES, default_rule_spec, indirect_paths,
};
pub use glossy::{GlossyRule, GlossyWeights, MAX_GLOSSY_BINS};
pub use placement::{
    PlacementOptions, PlacementPoint, PlacementReport, compute_record, place_and_shade,
    place_records, shade,
};
pub use radiance::{
    RadianceEstimate, RadianceOptions, RadianceQuery, RadianceShading, radiance_at_points,
    surface_at,
};
pub use shade::{Bounce, CachedIntegrator, Gather, OnMiss, RecordGather, ShadePoint};
pub use stats::ShadingStats;
pub use tiles::CachedTileReport;
