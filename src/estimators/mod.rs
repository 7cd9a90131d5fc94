//! Point estimators of irradiance and their statistics, apart from light
//! transport: what `render` traces, these turn into estimates with
//! calibrated error bars (docs/math.md §1.2, §3, §6, §10, §14).
//!
//! - `spec`: the estimators as a caller names them, every default once;
//! - [`amortised`]: rays a request spends on work kept for later ones;
//! - `point_estimator`: a spec checked once and run over points;
//! - `error`: why a spec or an estimate failed;
//! - `hemisphere_estimate`: one rule over the hemisphere of a point;
//! - [`integral_prior`]: priors on the integral (records, direct-light
//!   records) and how an estimate is combined with one;
//! - [`lengthscale`]: kernel lengthscales fitted by marginal likelihood;
//! - [`calibration`]: error bars calibrated on the scene;
//! - [`error_target`]: estimates refined until an error target is met;
//! - `sample_points`: training and camera points of a scene;
//! - `points_csv`: points and estimates as CSV.

pub mod amortised;
pub mod calibration;
mod error;
pub mod error_target;
mod hemisphere_estimate;
pub mod integral_prior;
pub mod lengthscale;
mod point_estimator;
pub(crate) mod points_csv;
pub(crate) mod sample_points;
mod spec;

pub use amortised::AmortisedRays;
pub use error::EstimatorError;
pub use hemisphere_estimate::HemisphereRule;
pub use integral_prior::{IntegralPrior, PriorAt};
pub use point_estimator::{
    BmcSetup, Estimates, EstimatorCaches, PointEstimator, PointRule, PriorsCombined,
};
pub use spec::{
    DEFAULT_KERNEL, DEFAULT_METHOD, DEFAULT_NOISE, DEFAULT_SAMPLE_SET, DEFAULT_SAMPLES,
    DEFAULT_VARIANCE, EstimatorMethod, EstimatorSpec, KernelSpec, Lengthscale, RecordsPriorMode,
};
