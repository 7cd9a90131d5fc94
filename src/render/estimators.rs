//! Point estimators of irradiance as a request or the command line names
//! them: MC, QMC and BMC over the Lambert density `cos θ/π`
//! (docs/math.md §1.2, §3, §6), in split or hemisphere decomposition (§14).
//!
//! [`EstimatorSpec`] is the choice with every default in one place;
//! [`EstimatorSpec::resolve`] checks it once, before any work, and returns a
//! [`PointEstimator`] that cannot be invalid; [`PointEstimator::estimate`]
//! runs it. The HTTP route and the `irradiance` command both only translate
//! their input into a spec, so the same spec and seed give the same numbers
//! through either.
//!
//! - `mc`: cosine-weighted random directions, fresh per point;
//! - `qmc`: a spherical Fibonacci set (`fibonacci_cosine`, or `fibonacci` with
//!   uniform-pdf weights), equal weights, randomly rotated per point (§5.3);
//! - `bmc`: Bayesian quadrature on a fixed sample set with the constant GLS
//!   prior mean (§3.3), weights from a [`QuadratureCache`], randomly rotated
//!   per point. The lengthscale is a number or fitted once per scene and
//!   configuration by marginal likelihood ([`FittedKernels`], §7.5), with the
//!   noise ratio unless `noise` is given. The standard error is the posterior
//!   standard deviation with the amplitude fitted to each point's values
//!   (`BmcVariance::AmplitudeFit`, §7.3).
//!
//! Around any of the three rules: a prior mean (the unoccluded environment
//! under the hemisphere decomposition, §10.4; `bmc`'s default, a control
//! variate when `mc` or `qmc` ask for it); error bars calibrated on the scene
//! (§10.5; the default); and the decomposition `auto`
//! resolved per scene (§14).

use std::sync::Arc;

use super::calibration::{Calibrations, ErrorCalibration, calibrate, unseen_light};
use super::cancel::Cancel;
use super::environment_prior::PriorChoice;
use super::error::RenderError;
use super::hemisphere_estimate::HemisphereRule;
use super::integral_prior::{IntegralPrior, combine_direct, combine_part};
use super::irradiance::{Decomposition, IrradianceEstimate, IrradianceOptions};
use super::lengthscale::{FALLBACK_LENGTHSCALE, FitConfig, FittedKernels};
use super::query::QueryPoint;
use super::transport::Transport;
use crate::bmc::cache::{CachedQuadrature, QuadratureCache};
use crate::bmc::estimator::{BayesianEstimator, BmcVariance, SampleMeanEstimator, SamplingPdf};
use crate::bmc::report::QuadratureSpec;
use crate::bmc::{BmcError, Density, Kernel, KernelKind, KernelMeanMethod, PriorMean};
use crate::sphere::{SampleSetKind, SampleSetSpec};

/// Sample set of `qmc` and `bmc` when none is named.
pub const DEFAULT_SAMPLE_SET: SampleSetKind = SampleSetKind::FibonacciCosine;
/// Kernel family of `bmc` when none is named and the lengthscale is a
/// number; with `"auto"` the family is selected by marginal likelihood
/// too ([`FittedKernels::get_or_select`]).
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
            "expected a number or \"auto\", got {other:?}"
        ))),
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
    /// the irradiance cache's records where they cover the point
    /// (docs/math.md §10.7; [`EstimatorCaches::records`]).
    pub records_prior: bool,
}

/// Why a spec or an estimate failed; a variant about a field names its path
/// below the spec it belongs to (`sample_set.kind`, `kernel.variance`).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EstimatorError {
    /// An option of the [`EstimatorSpec`] outside its domain; `field` is
    /// below the spec (`samples`, `kernel.variance`).
    #[error("{message}")]
    Invalid { field: String, message: String },
    /// An error target (`render::error_target`) outside its
    /// domain; `field` is below the target (empty: the target as a whole).
    #[error("{message}")]
    InvalidTarget { field: String, message: String },
    /// The marginal-likelihood fit of an `"auto"` lengthscale failed.
    #[error("lengthscale fit failed: {0}")]
    Fit(String),
    #[error(transparent)]
    Render(#[from] RenderError),
}

impl EstimatorError {
    fn invalid(field: impl Into<String>, message: impl Into<String>) -> Self {
        EstimatorError::Invalid {
            field: field.into(),
            message: message.into(),
        }
    }

    /// A BMC error about the kernel (or its sample set).
    fn kernel(err: BmcError) -> Self {
        let field = match err.field() {
            Some("samples") => "samples".to_owned(),
            Some(field) => format!("kernel.{field}"),
            None => "kernel".to_owned(),
        };
        EstimatorError::invalid(field, err.to_string())
    }
}

/// A checked estimator, ready to run.
#[derive(Debug, Clone)]
pub struct PointEstimator {
    pub rule: PointRule,
    pub prior: PriorChoice,
    /// Whether error bars are calibrated (docs/math.md §10.5).
    pub calibrate: bool,
    /// The spec it was resolved from (names its calibration).
    spec: EstimatorSpec,
    /// Also estimate the indirect part under the hemisphere decomposition
    /// (the rule under a records prior, §10.7; it costs three more
    /// evaluations of the rule per point).
    indirect_part: bool,
}

/// The rule of a [`PointEstimator`].
#[derive(Debug, Clone)]
pub enum PointRule {
    /// Cosine-weighted random directions; with a prior, `count` of them.
    Mc {
        count: usize,
    },
    Qmc(SampleMeanEstimator),
    Bmc(BmcSetup),
}

/// A `bmc` estimator whose kernel may still need its lengthscale fitted.
#[derive(Debug, Clone, Copy)]
pub struct BmcSetup {
    sample_set: SampleSetSpec,
    /// `None`: [`DEFAULT_KERNEL`], or selected with an `"auto"` lengthscale.
    kind: Option<KernelKind>,
    /// `None`: `"auto"`.
    lengthscale: Option<f64>,
    variance: f64,
    noise: Option<f64>,
}

/// What [`PointEstimator::estimate`] returns.
#[derive(Debug, Clone)]
pub struct Estimates {
    pub estimates: Vec<IrradianceEstimate>,
    /// `bmc`: the kernel used (with a fitted lengthscale for `"auto"`).
    pub kernel: Option<Kernel>,
    /// `bmc`: whether the weights came from the quadrature cache.
    pub quadrature_cached: Option<bool>,
    /// The decomposition run (`auto` resolved for the scene).
    pub decomposition: Decomposition,
    /// The prior mean the hemisphere part used ([`Transport::hemisphere_prior`]).
    pub prior: PriorChoice,
    /// The calibration applied to the error bars, if any.
    pub calibration: Option<ErrorCalibration>,
}

impl EstimatorSpec {
    /// Checks the options against the method (module docs).
    pub fn resolve(&self) -> Result<PointEstimator, EstimatorError> {
        let samples = self.samples as usize;
        if samples == 0 {
            return Err(EstimatorError::invalid("samples", "must be at least 1"));
        }
        let (set_kind, set_seed) = self.sample_set.unwrap_or((DEFAULT_SAMPLE_SET, 0));
        if self.method != EstimatorMethod::Bmc && self.kernel.is_some() {
            return Err(EstimatorError::invalid(
                "kernel",
                "only `bmc` takes a kernel",
            ));
        }
        if self.records_prior && self.method == EstimatorMethod::Mc {
            return Err(EstimatorError::invalid(
                "records_prior",
                "`mc` stays plain Monte Carlo; `qmc` and `bmc` take the records prior",
            ));
        }
        let prior = self.prior.unwrap_or(match self.method {
            EstimatorMethod::Bmc => PriorChoice::Environment,
            EstimatorMethod::Mc | EstimatorMethod::Qmc => PriorChoice::None,
        });
        let rule = self.rule(samples, set_kind, set_seed)?;
        Ok(PointEstimator {
            rule,
            prior,
            // No error model is calibrated on real scenes as it is (§10.5):
            // QMC's is too wide, the GP's assumes a smooth integrand, and
            // MC's sample variance is blind to light that its few samples
            // all missed.
            calibrate: self.calibrate.unwrap_or(true),
            spec: *self,
            indirect_part: false,
        })
    }

    fn rule(
        &self,
        samples: usize,
        set_kind: SampleSetKind,
        set_seed: u64,
    ) -> Result<PointRule, EstimatorError> {
        match self.method {
            EstimatorMethod::Mc if self.sample_set.is_some() => Err(EstimatorError::invalid(
                "sample_set",
                "`mc` draws fresh random directions; only `qmc` and `bmc` take a sample set",
            )),
            EstimatorMethod::Mc => Ok(PointRule::Mc { count: samples }),
            EstimatorMethod::Qmc => {
                let pdf = match set_kind {
                    SampleSetKind::FibonacciCosine => SamplingPdf::Cosine,
                    SampleSetKind::Fibonacci => SamplingPdf::Uniform,
                    _ => {
                        return Err(EstimatorError::invalid(
                            "sample_set.kind",
                            "`qmc` takes `fibonacci_cosine` or `fibonacci`",
                        ));
                    }
                };
                SampleMeanEstimator::quasi_monte_carlo(Density::Lambert, pdf, samples)
                    .map(PointRule::Qmc)
                    .map_err(|e| EstimatorError::invalid("samples", e.to_string()))
            }
            EstimatorMethod::Bmc => {
                let kernel = self.kernel.unwrap_or_default();
                let variance = kernel.variance.unwrap_or(DEFAULT_VARIANCE);
                // Check the numbers now (a stand-in ℓ for "auto"), so bad
                // input is refused before any work.
                Kernel::new(
                    kernel.kind.unwrap_or(DEFAULT_KERNEL),
                    kernel.lengthscale.value().unwrap_or(FALLBACK_LENGTHSCALE),
                    variance,
                    kernel.noise.unwrap_or(DEFAULT_NOISE),
                )
                .map_err(EstimatorError::kernel)?;
                let sample_set = SampleSetSpec {
                    kind: set_kind,
                    count: samples,
                    seed: set_seed,
                };
                Ok(PointRule::Bmc(BmcSetup {
                    sample_set,
                    kind: kernel.kind,
                    lengthscale: kernel.lengthscale.value(),
                    variance,
                    noise: kernel.noise,
                }))
            }
        }
    }
}

/// What `bmc` reuses between requests: the scene's fitted lengthscales and
/// the BMC weights, so repeated configurations neither refit nor refactorise.
#[derive(Clone, Copy)]
pub struct EstimatorCaches<'a> {
    pub kernels: &'a FittedKernels,
    pub quadratures: &'a QuadratureCache,
    pub calibrations: &'a Calibrations,
    /// The prior of specs with `records_prior` (the scene's irradiance-cache
    /// records); `None`: no records, the plain estimator.
    pub records: Option<&'a dyn IntegralPrior>,
    /// With `records_prior` under the hemisphere decomposition, the prior
    /// on the direct part: direct-light records at the records' places
    /// (docs/math.md §10.8); `None`: none.
    pub direct: Option<&'a dyn IntegralPrior>,
}

impl PointEstimator {
    /// Irradiance at every point on the current rayon pool; `on_done` is
    /// called once per finished point. Unless the spec turned it off, the
    /// error bars are calibrated for this scene and configuration
    /// ([`calibrate`], computed on first use and kept in `caches`).
    pub fn estimate(
        &self,
        transport: &Transport,
        caches: EstimatorCaches,
        points: &[QueryPoint],
        options: &IrradianceOptions,
        on_done: &(dyn Fn() + Sync),
        cancel: &Cancel,
    ) -> Result<Estimates, EstimatorError> {
        let calibration = if self.calibrate {
            // With the records prior, the bars are fitted again each time
            // the records it draws on double (§10.7), or the direct-light
            // records do (§10.8).
            let records = self.records(&caches).map(|r| r.state());
            let direct = self.direct(&caches).map(|r| r.state());
            let key = format!(
                "{:?} {:?} depth {} light samples {} records {records:?} direct {direct:?}",
                self.spec,
                options.method,
                options.effective_max_depth(),
                options.samples
            );
            Some(caches.calibrations.get_or_calibrate(key, || {
                // Light that independent directions all missed (§10.5).
                let unseen = match self.rule {
                    PointRule::Mc { .. } => unseen_light(self.spec.samples),
                    PointRule::Qmc(_) | PointRule::Bmc(_) => 0.0,
                };
                calibrate(transport, options, unseen, cancel, &|points, options| {
                    self.before_calibration(transport, caches, points, options, &|| {}, cancel)
                        .map(|e| e.estimates)
                })
            })?)
        } else {
            None
        };
        let mut estimates =
            self.before_calibration(transport, caches, points, options, on_done, cancel)?;
        if let Some(calibration) = calibration {
            estimates
                .estimates
                .iter_mut()
                .for_each(|e| calibration.apply(e));
        }
        estimates.calibration = calibration;
        Ok(estimates)
    }

    /// Hemisphere samples per point of one run.
    pub fn samples(&self) -> u32 {
        self.spec.samples
    }

    /// Whether the spec asked for the records prior (§10.7).
    pub fn records_prior(&self) -> bool {
        self.spec.records_prior
    }

    /// The records prior this estimator uses: the caches' if the spec asked.
    fn records<'a>(&self, caches: &EstimatorCaches<'a>) -> Option<&'a dyn IntegralPrior> {
        caches.records.filter(|_| self.spec.records_prior)
    }

    /// The direct-light records this estimator uses (§10.8): the caches' if
    /// the spec asked for the records prior.
    fn direct<'a>(&self, caches: &EstimatorCaches<'a>) -> Option<&'a dyn IntegralPrior> {
        caches.direct.filter(|_| self.spec.records_prior)
    }

    /// The estimates whose error bars [`Self::estimate`] calibrates: the
    /// rule's with its own error model, or with the records prior, the
    /// rule's estimates (with the rule's calibrated error bars, if the spec
    /// calibrates) combined with the records where they cover a point
    /// (§10.7), then, under the hemisphere decomposition, their direct part
    /// with the direct-light records (§10.8).
    fn before_calibration(
        &self,
        transport: &Transport,
        caches: EstimatorCaches,
        points: &[QueryPoint],
        options: &IrradianceOptions,
        on_done: &(dyn Fn() + Sync),
        cancel: &Cancel,
    ) -> Result<Estimates, EstimatorError> {
        let (records, direct) = (self.records(&caches), self.direct(&caches));
        if records.is_none() && direct.is_none() {
            return self
                .estimate_with_model_errors(transport, caches, points, options, on_done, cancel);
        }
        let rule = PointEstimator {
            spec: EstimatorSpec {
                records_prior: false,
                ..self.spec
            },
            indirect_part: true,
            ..self.clone()
        };
        let mut estimates = rule.estimate(transport, caches, points, options, on_done, cancel)?;
        // In split mode the direct part is light-sampled, not the rule's.
        let direct = direct.filter(|_| estimates.decomposition == Decomposition::Hemisphere);
        for (estimate, point) in estimates.estimates.iter_mut().zip(points) {
            if let Some(known) = records.and_then(|r| r.at(point)) {
                combine_part(estimate, known);
            }
            if let Some(known) = direct.and_then(|d| d.at(point)) {
                combine_direct(estimate, known);
            }
        }
        estimates.calibration = None;
        Ok(estimates)
    }

    /// [`Self::estimate`] with the estimator's own error model.
    fn estimate_with_model_errors(
        &self,
        transport: &Transport,
        caches: EstimatorCaches,
        points: &[QueryPoint],
        options: &IrradianceOptions,
        on_done: &(dyn Fn() + Sync),
        cancel: &Cancel,
    ) -> Result<Estimates, EstimatorError> {
        let decomposition = transport.decomposition(options.method);
        let prior = match transport.hemisphere_prior(self.prior, decomposition) {
            Some(_) => self.prior,
            None => PriorChoice::None,
        };
        let run = |rule: &dyn crate::bmc::estimator::HemisphereEstimator| {
            let rule = HemisphereRule {
                estimator: rule,
                prior,
                indirect_part: self.indirect_part,
            };
            transport.irradiance_with_estimator(points, rule, options, on_done, cancel)
        };
        let (estimates, kernel, quadrature_cached) = match &self.rule {
            // Plain MC keeps its own path (the reference estimator).
            PointRule::Mc { .. } if prior == PriorChoice::None => (
                transport.irradiance_at_points(points, options, on_done, cancel)?,
                None,
                None,
            ),
            PointRule::Mc { count } => {
                let mc =
                    SampleMeanEstimator::monte_carlo(Density::Lambert, SamplingPdf::Cosine, *count)
                        .map_err(EstimatorError::kernel)?;
                (run(&mc)?, None, None)
            }
            PointRule::Qmc(qmc) => (run(qmc)?, None, None),
            PointRule::Bmc(bmc) => {
                let (quadrature, kernel, cached) =
                    bmc.quadrature(transport, caches, decomposition, prior)?;
                let estimator = BayesianEstimator::new(quadrature, BmcVariance::AmplitudeFit);
                (run(&estimator)?, Some(kernel), Some(cached))
            }
        };
        Ok(Estimates {
            estimates,
            kernel,
            quadrature_cached,
            decomposition,
            prior,
            calibration: None,
        })
    }
}

impl BmcSetup {
    /// The kernel (fitting `"auto"` on first use for this scene and
    /// configuration, and selecting the family unless one is named) and its
    /// cached weights; the flag says whether the weights came from the cache.
    fn quadrature(
        &self,
        transport: &Transport,
        caches: EstimatorCaches,
        decomposition: Decomposition,
        prior: PriorChoice,
    ) -> Result<(Arc<CachedQuadrature>, Kernel, bool), EstimatorError> {
        let (kind, lengthscale, fitted_noise) = match self.lengthscale {
            Some(value) => (self.kind.unwrap_or(DEFAULT_KERNEL), value, DEFAULT_NOISE),
            None => {
                let config = FitConfig {
                    kernel: self.kind.unwrap_or(DEFAULT_KERNEL),
                    sample_set: self.sample_set,
                    decomposition,
                    prior,
                };
                let fit = match self.kind {
                    Some(_) => caches.kernels.get_or_fit(transport, config),
                    None => caches.kernels.get_or_select(transport, config),
                }
                .map_err(EstimatorError::Fit)?;
                let noise = fit.noise_ratio * self.variance;
                (fit.config.kernel, fit.lengthscale, noise)
            }
        };
        let noise = self.noise.unwrap_or(fitted_noise);
        let kernel =
            Kernel::new(kind, lengthscale, self.variance, noise).map_err(EstimatorError::kernel)?;
        let spec = QuadratureSpec {
            sample_set: self.sample_set,
            kernel,
            density: Density::Lambert,
            prior_mean: PriorMean::Gls,
            kernel_mean: KernelMeanMethod::Exact,
        };
        let (quadrature, cached) = spec
            .quadrature(caches.quadratures)
            .map_err(EstimatorError::kernel)?;
        Ok((quadrature, kernel, cached))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(method: EstimatorMethod) -> EstimatorSpec {
        EstimatorSpec {
            method,
            samples: 16,
            sample_set: None,
            kernel: None,
            prior: None,
            calibrate: None,
            records_prior: false,
        }
    }

    fn field(result: Result<PointEstimator, EstimatorError>) -> String {
        match result {
            Err(EstimatorError::Invalid { field, .. }) => field,
            other => panic!("expected an invalid field, got {other:?}"),
        }
    }

    #[test]
    fn options_are_checked_against_the_method() {
        assert!(matches!(
            spec(EstimatorMethod::Mc).resolve(),
            Ok(PointEstimator {
                rule: PointRule::Mc { count: 16 },
                prior: PriorChoice::None,
                calibrate: true,
                ..
            })
        ));
        let mc_with_set = EstimatorSpec {
            sample_set: Some((SampleSetKind::Fibonacci, 0)),
            ..spec(EstimatorMethod::Mc)
        };
        assert_eq!(field(mc_with_set.resolve()), "sample_set");
        let qmc_random = EstimatorSpec {
            sample_set: Some((SampleSetKind::Uniform, 3)),
            ..spec(EstimatorMethod::Qmc)
        };
        assert_eq!(field(qmc_random.resolve()), "sample_set.kind");
        let qmc_kernel = EstimatorSpec {
            kernel: Some(KernelSpec::default()),
            ..spec(EstimatorMethod::Qmc)
        };
        assert_eq!(field(qmc_kernel.resolve()), "kernel");
        let zero = EstimatorSpec {
            samples: 0,
            ..spec(EstimatorMethod::Bmc)
        };
        assert_eq!(field(zero.resolve()), "samples");
    }

    #[test]
    fn lengthscales_parse_from_text_and_json() {
        assert_eq!("auto".parse(), Ok(Lengthscale::Auto));
        assert_eq!("0.5".parse(), Ok(Lengthscale::Value(0.5)));
        assert!("short".parse::<Lengthscale>().is_err());
        let json: Lengthscale = serde_json::from_str("0.25").unwrap();
        assert_eq!(json, Lengthscale::Value(0.25));
        let json: Lengthscale = serde_json::from_str("\"auto\"").unwrap();
        assert_eq!(json, Lengthscale::Auto);
        assert!(serde_json::from_str::<Lengthscale>("\"long\"").is_err());
    }

    #[test]
    fn bmc_kernel_numbers_are_checked_before_any_work() {
        let overflow = EstimatorSpec {
            kernel: Some(KernelSpec {
                variance: Some(1e308),
                noise: Some(1e308),
                ..KernelSpec::default()
            }),
            ..spec(EstimatorMethod::Bmc)
        };
        assert_eq!(field(overflow.resolve()), "kernel.variance");
        let Ok(PointEstimator {
            rule: PointRule::Bmc(setup),
            prior: PriorChoice::Environment,
            ..
        }) = spec(EstimatorMethod::Bmc).resolve()
        else {
            panic!("bmc resolves, with the environment prior by default");
        };
        // Defaults: Fibonacci-cosine set, the kernel family selected with
        // the "auto" lengthscale.
        assert_eq!(setup.sample_set.kind, DEFAULT_SAMPLE_SET);
        assert_eq!(setup.kind, None);
        assert_eq!(setup.lengthscale, None);
        assert_eq!(setup.variance, DEFAULT_VARIANCE);
    }
}
