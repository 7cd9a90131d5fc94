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

use super::calibration::{Calibrations, ErrorCalibration, TrainingSet, calibrate, unseen_light};
use super::cancel::Cancel;
use super::environment_prior::PriorChoice;
use super::error::RenderError;
use super::hemisphere_estimate::HemisphereRule;
use super::integral_prior::{IntegralPrior, PriorScales, combine_direct, combine_part, scaled};
use super::irradiance::{Decomposition, IrradianceEstimate, IrradianceOptions};
use super::lengthscale::{FALLBACK_LENGTHSCALE, FitConfig, FittedKernels};
use super::query::QueryPoint;
use super::rgb::Rgb;
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
                let training = caches
                    .calibrations
                    .training_set(transport, options, cancel)?;
                if self.has_priors(&caches) {
                    return self.calibrate_with_priors(
                        transport, caches, &training, options, unseen, cancel,
                    );
                }
                calibrate(&training, options, unseen, &|points, options| {
                    self.estimate_with_model_errors(
                        transport,
                        caches,
                        points,
                        options,
                        &|| {},
                        cancel,
                    )
                    .map(|e| e.estimates)
                })
            })?)
        } else {
            None
        };
        let (mut estimates, calibrated) = if self.has_priors(&caches) {
            let scales = calibration
                .and_then(|c| c.prior_scales)
                .unwrap_or(PriorScales::ONE);
            self.with_priors(transport, caches, points, options, scales, on_done, cancel)?
        } else {
            let estimates = self
                .estimate_with_model_errors(transport, caches, points, options, on_done, cancel)?;
            let all = vec![true; estimates.estimates.len()];
            (estimates, all)
        };
        if let Some(calibration) = calibration {
            for (estimate, _) in estimates
                .estimates
                .iter_mut()
                .zip(calibrated)
                .filter(|(_, calibrated)| *calibrated)
            {
                calibration.apply(estimate);
            }
        }
        estimates.calibration = calibration;
        Ok(estimates)
    }

    /// The calibration of an estimator with the records prior (§10.9): the
    /// rule's estimates at the training points are combined with the priors
    /// under each pair of [`PriorScales::CANDIDATES`], the pair with the
    /// smallest squared error against the reference is kept, and the bars
    /// of that combination are fitted as any estimator's.
    fn calibrate_with_priors(
        &self,
        transport: &Transport,
        caches: EstimatorCaches,
        training: &TrainingSet,
        options: &IrradianceOptions,
        unseen: f64,
        cancel: &Cancel,
    ) -> Result<ErrorCalibration, EstimatorError> {
        let rule = self.rule();
        let runs = training
            .requests(options)
            .map(|request| {
                rule.estimate(
                    transport,
                    caches,
                    &training.points,
                    &request,
                    &|| {},
                    cancel,
                )
            })
            .collect::<Result<Vec<_>, _>>()?;
        let decomposition = transport.decomposition(options.method);
        let known = self.priors_at(&caches, &training.points, decomposition);
        let combined = |scales| {
            runs.iter()
                .map(|run| {
                    let mut estimates = run.estimates.clone();
                    let moved = combine_priors(&mut estimates, &known, scales);
                    (estimates, moved)
                })
                .unzip::<_, _, Vec<_>, Vec<_>>()
        };
        // A prior that covers no training point keeps its stated variance.
        let candidates = |used: bool| {
            if used {
                &PriorScales::CANDIDATES[..]
            } else {
                &PriorScales::CANDIDATES[..1]
            }
        };
        let mut best = (
            PriorScales::ONE,
            training.squared_error(&combined(PriorScales::ONE).0),
        );
        for &records in candidates(known.iter().any(|k| k.records.is_some())) {
            for &direct in candidates(known.iter().any(|k| k.direct.is_some())) {
                let scales = PriorScales { records, direct };
                let error = training.squared_error(&combined(scales).0);
                if error < best.1 {
                    best = (scales, error);
                }
            }
        }
        // Estimates no prior moved keep the rule's calibrated bars; the
        // combination's are fitted on those the priors moved.
        let (runs, moved) = combined(best.0);
        let mut calibration = training.fit(&runs, Some(&moved), unseen);
        calibration.prior_scales = Some(best.0);
        Ok(calibration)
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

    /// Whether the estimator combines its rule with priors: the spec asked
    /// for the records prior and the caches hold one (§10.7, §10.8).
    fn has_priors(&self, caches: &EstimatorCaches) -> bool {
        self.records(caches).is_some() || self.direct(caches).is_some()
    }

    /// With the records prior: the rule's estimates (with the rule's
    /// calibrated error bars, if the spec calibrates) combined with the
    /// records where they cover a point (§10.7), then, under the hemisphere
    /// decomposition, their direct part with the direct-light records
    /// (§10.8), the priors' variances scaled by `scales` (§10.9); and for
    /// each estimate whether a prior moved it (the others keep the rule's
    /// error bars, the moved ones are calibrated again).
    #[allow(clippy::too_many_arguments)]
    fn with_priors(
        &self,
        transport: &Transport,
        caches: EstimatorCaches,
        points: &[QueryPoint],
        options: &IrradianceOptions,
        scales: PriorScales,
        on_done: &(dyn Fn() + Sync),
        cancel: &Cancel,
    ) -> Result<(Estimates, Vec<bool>), EstimatorError> {
        let mut estimates = self
            .rule()
            .estimate(transport, caches, points, options, on_done, cancel)?;
        let known = self.priors_at(&caches, points, estimates.decomposition);
        let moved = combine_priors(&mut estimates.estimates, &known, scales);
        estimates.calibration = None;
        Ok((estimates, moved))
    }

    /// The rule under the records prior: the same spec without it, which
    /// also reports the indirect part of its estimates.
    fn rule(&self) -> PointEstimator {
        PointEstimator {
            spec: EstimatorSpec {
                records_prior: false,
                ..self.spec
            },
            indirect_part: true,
            ..self.clone()
        }
    }

    /// The priors at each point, for estimates run under `decomposition`
    /// (in split mode the direct part is light-sampled, not the rule's, so
    /// it takes no direct prior).
    fn priors_at(
        &self,
        caches: &EstimatorCaches,
        points: &[QueryPoint],
        decomposition: Decomposition,
    ) -> Vec<KnownPriors> {
        let records = self.records(caches);
        let direct = self
            .direct(caches)
            .filter(|_| decomposition == Decomposition::Hemisphere);
        points
            .iter()
            .map(|point| KnownPriors {
                records: records.and_then(|r| r.at(point)),
                direct: direct.and_then(|d| d.at(point)),
            })
            .collect()
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

/// The priors' means and variances at a point, where they cover it.
struct KnownPriors {
    records: Option<(Rgb, Rgb)>,
    direct: Option<(Rgb, Rgb)>,
}

/// Combines each estimate with the priors at its point (§10.7, §10.8),
/// their variances scaled by `scales`; whether a prior moved each.
fn combine_priors(
    estimates: &mut [IrradianceEstimate],
    known: &[KnownPriors],
    scales: PriorScales,
) -> Vec<bool> {
    estimates
        .iter_mut()
        .zip(known)
        .map(|(estimate, known)| {
            let mut moved = false;
            if let Some(prior) = known.records {
                moved |= combine_part(estimate, scaled(prior, scales.records));
            }
            if let Some(prior) = known.direct {
                combine_direct(estimate, scaled(prior, scales.direct));
                moved = true;
            }
            moved
        })
        .collect()
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

    /// A prior on the direct part that knows each point's irradiance (a
    /// Monte Carlo reference of many samples), scaled by `bias`, and states
    /// a relative standard deviation `stated`; on the half `x > 0` of the
    /// scene only, if `half`.
    struct ReferencePrior<'a> {
        transport: &'a Transport,
        bias: f64,
        stated: f64,
        half: bool,
    }

    impl IntegralPrior for ReferencePrior<'_> {
        fn at(&self, point: &QueryPoint) -> Option<(Rgb, Rgb)> {
            if self.half && point.position().x <= 0.0 {
                return None;
            }
            let options = IrradianceOptions {
                samples: 4096,
                max_depth: super::super::PathDepth::new(1).unwrap(),
                method: super::super::IrradianceMethod::Split,
                seed: 99,
                ..IrradianceOptions::default()
            };
            let reference = self
                .transport
                .irradiance_at_points(&[*point], &options, &|| {}, &Cancel::never())
                .unwrap();
            let e = reference[0].irradiance;
            Some((e * self.bias, e * e * (self.stated * self.stated)))
        }

        fn state(&self) -> u64 {
            0
        }
    }

    /// A ground under a constant sky, partly shaded by a square above it:
    /// 16 directions see the square's edges badly, a prior that knows the
    /// answer and says it knows it poorly is trusted more than it says, and
    /// a wrong prior that says it is sure is trusted less (docs/math.md
    /// §10.9); where the prior says nothing, the estimate and its error bar
    /// are the rule's.
    #[test]
    fn the_priors_variance_is_scaled_by_what_the_training_points_show() {
        let doc = r#"{
            "materials": [{"id": "grey", "type": "diffuse", "reflectance": [0.5, 0.5, 0.5]}],
            "shapes": [
                {"type": "rectangle", "material": "grey",
                 "to_world": [{"scale": [3, 3, 1]}]},
                {"type": "rectangle", "material": "grey",
                 "to_world": [{"scale": [0.6, 0.6, 1]}, {"translate": [0, 0, 0.4]}]}
            ],
            "environment": {"type": "constant", "radiance": [1, 1, 1]},
            "camera": {"type": "perspective", "fov": 50, "origin": [0.3, -0.2, 4],
                       "target": [0, 0, 0], "up": [0, 1, 0], "width": 16, "height": 16}
        }"#;
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let scene = crate::scene::Scene::from_json_str(doc, dir, dir).unwrap();
        let transport = Transport::new(Arc::new(scene));
        let (kernels, quadratures) = (FittedKernels::default(), QuadratureCache::new(16 << 20));
        let options = IrradianceOptions {
            samples: 16,
            max_depth: super::super::PathDepth::new(1).unwrap(),
            method: super::super::IrradianceMethod::Hemisphere,
            seed: 5,
            ..IrradianceOptions::default()
        };
        let points = crate::render::sample_points::camera_points(&transport, 12, 3);
        let run = |records_prior: bool, prior: Option<&ReferencePrior>| {
            // Each prior is fitted apart (its state says nothing of it).
            let calibrations = Calibrations::default();
            let caches = EstimatorCaches {
                kernels: &kernels,
                quadratures: &quadratures,
                calibrations: &calibrations,
                records: None,
                direct: prior.map(|p| p as &dyn IntegralPrior),
            };
            EstimatorSpec {
                records_prior,
                ..spec(EstimatorMethod::Qmc)
            }
            .resolve()
            .unwrap()
            .estimate(
                &transport,
                caches,
                &points,
                &options,
                &|| {},
                &Cancel::never(),
            )
            .unwrap()
        };
        let prior = |bias, stated, half| ReferencePrior {
            transport: &transport,
            bias,
            stated,
            half,
        };
        let scales = |estimates: &Estimates| estimates.calibration.unwrap().prior_scales.unwrap();
        let trusted = scales(&run(true, Some(&prior(1.0, 0.5, false))));
        assert!(trusted.direct <= 1.0 / 16.0, "{trusted:?}");
        assert_eq!(trusted.records, 1.0, "no records prior");
        let wrong = scales(&run(true, Some(&prior(0.7, 0.01, false))));
        assert!(wrong.direct >= 1.0, "{wrong:?}");
        let rule = run(false, None);
        let half = run(true, Some(&prior(1.0, 0.5, true)));
        let (mut moved, mut kept) = (0, 0);
        for ((with, without), point) in half.estimates.iter().zip(&rule.estimates).zip(&points) {
            if point.position().x <= 0.0 {
                kept += 1;
                assert_eq!(
                    (with.irradiance, with.std_error),
                    (without.irradiance, without.std_error)
                );
            } else {
                moved += usize::from(with.irradiance != without.irradiance);
            }
        }
        assert!(moved > 0 && kept > 0, "{moved} moved, {kept} kept");
    }
}
