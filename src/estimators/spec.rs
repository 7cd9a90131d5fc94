//! The point estimators as a caller names them ([`EstimatorSpec`]), every
//! default written once here; `EstimatorSpec::resolve` (in
//! `point_estimator`) checks a spec once and returns a `PointEstimator`.

use crate::bmc::KernelKind;
use crate::render::environment_prior::PriorChoice;
use crate::sphere::SampleSetKind;

/// The estimator a point query uses when it names none: the Bayesian one,
/// which the service, the command line and the Python client all default to.
pub const DEFAULT_METHOD: EstimatorMethod = EstimatorMethod::Bmc;
/// Hemisphere samples per point when a query gives no number.
pub const DEFAULT_SAMPLES: u32 = 64;

/// Sample set of `qmc` and `bmc` when none is named.
pub const DEFAULT_SAMPLE_SET: SampleSetKind = SampleSetKind::FibonacciCosine;
/// Kernel family of `bmc` when none is named and the lengthscale is a
/// number; with `"auto"` the family is selected by marginal likelihood
/// too (`FittedKernels::get_or_select`).
pub const DEFAULT_KERNEL: KernelKind = KernelKind::SquaredExponential;
/// Kernel amplitude `σ²` of `bmc` when none is given (the weights depend on
/// `noise/variance` only).
pub const DEFAULT_VARIANCE: f64 = 1.0;
/// Noise `σ_n²` of a numeric-lengthscale kernel when none is given: the
/// values are path-traced estimates, and a tiny jitter makes SE weights
/// oscillate (docs/math.md §10.2).
pub const DEFAULT_NOISE: f64 = 1e-3;

/// Which hemisphere estimator.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum EstimatorMethod {
    /// Monte Carlo with cosine-weighted directions.
    Mc,
    /// Quasi-Monte Carlo on spherical Fibonacci points.
    Qmc,
    /// Bayesian Monte Carlo (Bayesian quadrature) with cached weights.
    Bmc,
}

/// A kernel lengthscale: a number (chordal units) or `"auto"`, fitted by
/// marginal likelihood (docs/math.md §7.5).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Deserialize)]
#[serde(untagged)]
pub enum Lengthscale {
    Value(f64),
    #[default]
    #[serde(deserialize_with = "auto")]
    Auto,
}

/// `"auto"` as a unit variant of an untagged enum.
fn auto<'de, D: serde::Deserializer<'de>>(d: D) -> Result<(), D::Error> {
    use serde::Deserialize;
    use serde::de::Error;
    match String::deserialize(d)?.as_str() {
        "auto" => Ok(()),
        other => Err(D::Error::custom(format!(
            "expected \"auto\", got {other:?}"
        ))),
    }
}

/// Whether point estimates lean on the records the service holds
/// (docs/math.md §10.7, §10.8): `true`, `false`, or `"auto"`: yes for `bmc`,
/// whose Bayesian combination it is, while `mc` and `qmc` stay the plain
/// rules their names promise.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Deserialize)]
#[serde(untagged)]
pub enum RecordsPriorMode {
    Set(bool),
    #[default]
    #[serde(deserialize_with = "auto")]
    Auto,
}

impl RecordsPriorMode {
    /// Whether `method` combines its estimates with the records.
    pub fn applies_to(self, method: EstimatorMethod) -> bool {
        match self {
            RecordsPriorMode::Set(on) => on,
            RecordsPriorMode::Auto => method == EstimatorMethod::Bmc,
        }
    }
}

impl std::str::FromStr for Lengthscale {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, String> {
        match text {
            "auto" => Ok(Lengthscale::Auto),
            _ => text
                .parse()
                .map(Lengthscale::Value)
                .map_err(|_| format!("expected a number or `auto`, got {text:?}")),
        }
    }
}

impl Lengthscale {
    /// The number, or `None` for `"auto"`.
    pub fn value(self) -> Option<f64> {
        match self {
            Lengthscale::Value(value) => Some(value),
            Lengthscale::Auto => None,
        }
    }
}

/// The GP kernel of a `bmc` estimator; `None` fields take the defaults above.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct KernelSpec {
    /// `None`: selected with an `"auto"` lengthscale, else [`DEFAULT_KERNEL`].
    pub kind: Option<KernelKind>,
    pub lengthscale: Lengthscale,
    pub variance: Option<f64>,
    /// `σ_n²`; `None` = fitted with `"auto"`, else [`DEFAULT_NOISE`].
    pub noise: Option<f64>,
}

/// An irradiance point estimator as named by a caller (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EstimatorSpec {
    pub method: EstimatorMethod,
    /// Hemisphere samples per point, `1..=MAX_SAMPLES`.
    pub samples: u32,
    /// `qmc` and `bmc`: the sample set's kind and seed (random kinds only).
    pub sample_set: Option<(SampleSetKind, u64)>,
    /// `bmc` only.
    pub kernel: Option<KernelSpec>,
    /// The prior mean of the hemisphere values; `None`: the environment for
    /// `bmc`, none for `mc` and `qmc` (which then stay the plain rules; with
    /// `environment` they become control-variate estimators).
    pub prior: Option<PriorChoice>,
    /// Calibrate the error bars on the scene (docs/math.md §10.5); default
    /// true.
    pub calibrate: Option<bool>,
    /// `qmc` and `bmc`, either decomposition: combine the indirect part with
    /// the irradiance cache's records where they cover the point, and the
    /// direct part with their twins (docs/math.md §10.7, §10.8;
    /// `EstimatorCaches::records`).
    pub records_prior: RecordsPriorMode,
}
