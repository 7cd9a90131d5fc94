//! Bayesian irradiance cache (bmc-math.md §9): records computed by BMC with
//! their posterior variance, a concurrent spatial index, Ward-weighted
//! interpolation with gradients, and reproducible record placement.

pub mod error;
pub mod record_rule;

pub use error::CacheError;
pub use record_rule::{RecordEstimate, RecordRule, RecordRuleSpec};
