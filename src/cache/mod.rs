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
//! - `records_prior`: the records (or their direct-light twins) as a prior
//!   on a point query's indirect (or direct) irradiance.
//! - `twin_caches`: direct-light twins beside their shadow probes.
//! - `log`: the append-only, checksummed log that keeps records (and
//!   whatever else is keyed by content) across restarts.
//!
//! This is the record store alone: it knows no scene and traces no ray. The
//! integrator that computes records and shades through them is
//! `integrator::cached`, a layer above. No HTTP here; the service keeps one
//! [`IrradianceCache`] per (scene version, integrator configuration).

mod error;
mod index;
mod irradiance_cache;
pub(crate) mod log;
mod record;
mod record_rule;
mod records_prior;
mod twin_caches;

pub use error::CacheError;
pub use irradiance_cache::{
    Accuracy, CacheConfig, CacheStats, Interpolated, IrradianceCache, RECORD_BYTES, RecordSlot,
};
pub use record::{MAX_IRRADIANCE, PixelFootprint, RadiusLimits, Record, harmonic_mean_distance};
pub use record_rule::{RecordEstimate, RecordRule, RecordRuleSpec};
pub use records_prior::RecordsPrior;
pub use twin_caches::TwinCaches;
