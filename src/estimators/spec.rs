//! The point estimators as a caller names them: [`EstimatorSpec`] is at
//! once the `estimator` document of `POST /v1/scenes/{id}/irradiance`, the
//! `irradiance` command's arguments (clap flatten) and the OpenAPI schema,
//! each option's doc comment stating its meaning and default; every
//! default is written once here. `EstimatorSpec::resolve` (in
//! `point_estimator`) checks a spec once and returns a `PointEstimator`.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::bmc::KernelKind;
use crate::render::IrradianceMethod;
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
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
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
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Lengthscale {
    Value(f64),
    #[default]
    #[serde(deserialize_with = "auto", serialize_with = "write_auto")]
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

/// Writes a unit variant as `"auto"`.
fn write_auto<S: serde::Serializer>(s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str("auto")
}

/// Whether point estimates lean on the records the service holds
/// (docs/math.md §10.7, §10.8): `true`, `false`, or `"auto"`: yes for `bmc`,
/// whose Bayesian combination it is, while `mc` and `qmc` stay the plain
/// rules their names promise.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum RecordsPriorMode {
    Set(bool),
    #[default]
    #[serde(deserialize_with = "auto", serialize_with = "write_auto")]
    Auto,
}

impl std::str::FromStr for RecordsPriorMode {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, String> {
        match text {
            "auto" => Ok(RecordsPriorMode::Auto),
            _ => text
                .parse()
                .map(RecordsPriorMode::Set)
                .map_err(|_| format!("expected `true`, `false` or `auto`, got {text:?}")),
        }
    }
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

// The option groups below (`sample_set`, `kernel`) are `None` unless a
// caller names one of their fields, which on the command line means that
// none of their arguments may have a default (clap counts a default as
// named): their defaults are the accessors'.

/// The sample set of a `qmc`/`bmc` estimator; its size is the spec's `samples`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize, ToSchema, clap::Args)]
#[serde(deny_unknown_fields)]
pub struct SampleSetChoice {
    /// `fibonacci_cosine` (default), `fibonacci`; for `bmc` also `uniform`,
    /// `cosine`, `stratified`, `stratified_cosine`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<String>, example = "fibonacci_cosine")]
    #[arg(id = "sample_set", long = "sample-set", value_enum)]
    pub kind: Option<SampleSetKind>,
    /// Seed of the random kinds; default 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[arg(id = "set_seed", long = "set-seed")]
    pub seed: Option<u64>,
}

impl SampleSetChoice {
    /// The kind, or [`DEFAULT_SAMPLE_SET`].
    pub fn kind(&self) -> SampleSetKind {
        self.kind.unwrap_or(DEFAULT_SAMPLE_SET)
    }

    /// The seed, or 0.
    pub fn seed(&self) -> u64 {
        self.seed.unwrap_or(0)
    }
}

/// The GP kernel of a `bmc` estimator; `None` fields take the defaults above
/// (the lengthscale `"auto"`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize, ToSchema, clap::Args)]
#[serde(deny_unknown_fields)]
pub struct KernelSpec {
    /// `squared_exponential` (`se` on the command line), `matern32` or
    /// `matern52`; default: with an `"auto"` lengthscale the family of
    /// largest marginal likelihood on the scene (the response's `kernel`
    /// says which), else `squared_exponential`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<String>, example = "squared_exponential")]
    #[arg(id = "kernel", long = "kernel", value_enum)]
    pub kind: Option<KernelKind>,
    /// ℓ in [0.01, 1000] (chordal units), or `"auto"` (default): fitted by
    /// marginal likelihood once per scene and configuration (docs/math.md §7.5).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Object, example = "auto")]
    #[arg(long)]
    pub lengthscale: Option<Lengthscale>,
    /// σ², default 1 (the weights depend on `noise/variance` only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub variance: Option<f64>,
    /// σ_n²; default: fitted with an `"auto"` lengthscale, else 1e-3 (Y is a
    /// path-traced estimate, and a tiny jitter makes SE weights oscillate).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub noise: Option<f64>,
}

/// The estimator of a point query (module docs); every field has a
/// default, so `{}` (or no `estimator` at all) is `bmc` with 64 samples, as
/// on the command line and in the Python client.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize, ToSchema, clap::Args)]
#[serde(deny_unknown_fields)]
pub struct EstimatorSpec {
    /// `mc` (cosine-weighted random directions), `qmc` (spherical
    /// Fibonacci, equal weights) or `bmc` (Bayesian quadrature; default).
    /// On the command line `--estimator`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<String>, example = "bmc")]
    #[arg(long = "estimator", value_enum)]
    pub method: Option<EstimatorMethod>,
    /// Hemisphere samples per point, 1..=`limits.max_samples`; default 64.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub samples: Option<u32>,
    /// Light samples per point for the direct part under the `split`
    /// decomposition, 1..=`limits.max_samples` (default: `samples`). Each is
    /// one shadow ray, where a hemisphere sample is a path, so where the
    /// error is in the direct light (penumbrae, a sun) many more of them than
    /// hemisphere samples are cheap. Refused with `"decomposition":
    /// "hemisphere"`, which takes none; ignored where `auto` resolves to it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub light_samples: Option<u32>,
    /// `auto` (default: `hemisphere` for a scene lit only by a smooth
    /// environment, else `split`), `split` (direct light by light sampling,
    /// the rest through the hemisphere) or `hemisphere` (everything through
    /// the hemisphere).
    #[serde(default)]
    #[schema(value_type = String, example = "auto")]
    #[arg(long, alias = "method", value_enum, default_value_t = IrradianceMethod::Auto)]
    pub decomposition: IrradianceMethod,
    /// Prior mean of the hemisphere values: `environment` (the unoccluded
    /// environment, used where the hemisphere part sees it directly) or
    /// `none`. Default: `environment` for `bmc`, `none` for `mc` and `qmc`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<String>, example = "environment")]
    #[arg(long, value_enum)]
    pub prior: Option<PriorChoice>,
    /// Calibrate the error bars on the scene (default true): the model's
    /// variance widened by a relative floor and scaled, both fitted once per
    /// scene and configuration against a reference at held-out points
    /// (docs/math.md §10.5), and for `mc` a term for light that all its
    /// samples missed. With `false`, `std_dev` is the estimator's own error
    /// model (for `mc` its sample variance of the mean).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub calibrate: Option<bool>,
    /// `qmc` and `bmc` only: the fixed sample set.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[command(flatten)]
    pub sample_set: Option<SampleSetChoice>,
    /// `bmc` only: the GP kernel over incident radiance.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[command(flatten)]
    pub kernel: Option<KernelSpec>,
    /// `true`, `false` or `"auto"` (default: on for `bmc`, off for `mc` and
    /// `qmc`, which stay the plain rules; `mc` refuses `true`). A query of
    /// 64 points or more first places records among its own points
    /// (docs/math.md §10.11; kept for later queries, their rays counted in
    /// `amortised_rays`). Where records of the scene cover a point (those
    /// placed among query points, those of every reproducible tile
    /// rendered, gathered per camera depth, and those of the shared cache),
    /// the point's indirect part is combined with their interpolated
    /// irradiance by precision (§10.7), and under the hemisphere
    /// decomposition its direct part with the direct light seen from the
    /// records' places (their direct-light twins, made on first use: a
    /// thousand rays or so per record, §10.8). Records serve queries of a
    /// depth (from the point) no greater than theirs (their camera depth
    /// less one). The answer depends on the records held when it is asked,
    /// and on nothing else: the same records give the same numbers on any
    /// replica, and on the command line, which holds the records of its own
    /// run only. `prior_used` says, per point, what moved its estimate.
    /// Calibrated error bars are fitted again each time the records double.
    /// Under a `target` the batches run without it and their mean is
    /// combined with it once (§10.6).
    #[serde(default)]
    #[schema(value_type = Object, example = "auto")]
    #[arg(long, default_value = "auto")]
    pub records_prior: RecordsPriorMode,
}

impl KernelSpec {
    /// The lengthscale, or `"auto"`.
    pub fn lengthscale(&self) -> Lengthscale {
        self.lengthscale.unwrap_or_default()
    }
}

impl EstimatorSpec {
    /// The method, or [`DEFAULT_METHOD`].
    pub fn method(&self) -> EstimatorMethod {
        self.method.unwrap_or(DEFAULT_METHOD)
    }

    /// Hemisphere samples per point, or [`DEFAULT_SAMPLES`].
    pub fn samples(&self) -> u32 {
        self.samples.unwrap_or(DEFAULT_SAMPLES)
    }

    /// Whether the estimator combines its estimates with the records.
    pub fn uses_records(&self) -> bool {
        self.records_prior.applies_to(self.method())
    }
}
