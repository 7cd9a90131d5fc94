//! Bayesian irradiance cache (bmc-math.md §9): records computed by BMC with
//! their posterior variance, a concurrent spatial index, Ward-weighted
//! interpolation with gradients, and reproducible record placement.

pub mod error;
pub mod index;
pub mod irradiance_cache;
pub mod placement;
pub mod record;
pub mod record_rule;

pub use error::CacheError;
pub use irradiance_cache::{
    Accuracy, CacheConfig, CacheStats, Interpolated, IrradianceCache, RECORD_BYTES,
};
pub use placement::{
    PlacementOptions, PlacementPoint, PlacementReport, compute_record, place_and_shade,
    place_records, shade,
};
pub use record::{PixelFootprint, RadiusLimits, Record, harmonic_mean_distance};
pub use record_rule::{RecordEstimate, RecordRule, RecordRuleSpec};
