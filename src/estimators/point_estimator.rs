//! Point estimators of irradiance: MC, QMC and BMC over the Lambert density `cos θ/π`
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

mod resolve;

use std::sync::Arc;

use rayon::prelude::*;

use super::amortised::AmortisedRays;
use super::calibration::{Calibrations, ErrorCalibration, TrainingSet, calibrate, unseen_light};
use super::error::EstimatorError;
use super::hemisphere_estimate::HemisphereRule;
use super::integral_prior::{IntegralPrior, PriorAt, PriorScales, combine_direct, combine_part};
use super::lengthscale::{FitConfig, FittedKernels};
use super::spec::{DEFAULT_KERNEL, DEFAULT_NOISE, EstimatorSpec, RecordsPriorMode};
use crate::bmc::cache::{CachedQuadrature, QuadratureCache};
use crate::bmc::control_variate::BmcControlVariate;
use crate::bmc::estimator::{BayesianEstimator, BmcVariance, SampleMeanEstimator, SamplingPdf};
use crate::bmc::report::QuadratureSpec;
use crate::bmc::{Density, Kernel, KernelKind, KernelMeanMethod, PriorMean};
use crate::render::Cancel;
use crate::render::QueryPoint;
use crate::render::Transport;
use crate::render::environment_prior::PriorChoice;
use crate::render::{Decomposition, IrradianceEstimate, IrradianceOptions, Rgb};
use crate::sphere::SampleSetSpec;

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
    /// `bmc` in the batches of an error target: whether the rule adds the
    /// residual correction (`bmc::control_variate`, §10.6) from as many
    /// fresh directions per point as its set has; `false` everywhere else.
    corrected: bool,
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
    /// With the records prior, per estimate, which priors were combined
    /// with it (§10.7, §10.8); empty without it.
    pub priors_combined: Vec<PriorsCombined>,
}

/// Which priors were combined with one estimate.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PriorsCombined {
    /// The records' interpolated irradiance, on the indirect part (§10.7).
    pub records: bool,
    /// The direct-light twins, on the direct part (§10.8); not where the
    /// point's own estimate contradicts them.
    pub direct: bool,
}

impl PriorsCombined {
    /// Whether any prior moved the estimate.
    pub fn any(self) -> bool {
        self.records || self.direct
    }
}

impl Estimates {
    /// Rays the estimates traced, all points together.
    pub fn rays(&self) -> u64 {
        self.estimates.iter().map(|e| e.rays).sum()
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
    /// Counts the rays of the kept work (fits, calibrations) this request
    /// does because no earlier one did.
    pub amortised: &'a AmortisedRays,
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
            // records do (§10.8); with no records to lean on, the key is the
            // plain estimator's, whose estimates these are.
            let records = self.records(&caches).map(|r| r.state());
            let direct = self.direct(&caches).map(|r| r.state());
            let spec = EstimatorSpec {
                records_prior: RecordsPriorMode::Set(self.has_priors(&caches)),
                ..self.spec
            };
            let key = format!(
                "{spec:?} corrected {} {:?} depth {} light samples {} records {records:?} \
                 direct {direct:?}",
                self.corrected,
                options.method,
                options.effective_max_depth(),
                options.light_samples()
            );
            Some(caches.calibrations.get_or_calibrate(key, || {
                // Light that every equally weighted direction missed (§10.5).
                let unseen = match self.rule {
                    PointRule::Mc { .. } | PointRule::Qmc(_) => unseen_light(self.spec.samples()),
                    // The corrected rule's bar is a sample variance too
                    // (§10.6), blind to light all its directions missed.
                    PointRule::Bmc(_) if self.corrected => unseen_light(self.samples()),
                    // Split direct light is the light samples' mean, the
                    // same independent draws for every rule (at depth 1
                    // the whole estimate, QMC's to the bit).
                    PointRule::Bmc(_)
                        if transport.decomposition(options.method) == Decomposition::Split =>
                    {
                        unseen_light(options.light_samples())
                    }
                    PointRule::Bmc(_) => 0.0,
                };
                let training = caches.calibrations.training_set(
                    transport,
                    options,
                    caches.amortised,
                    cancel,
                )?;
                if self.has_priors(&caches) {
                    return self.calibrate_with_priors(
                        transport, caches, &training, options, unseen, cancel,
                    );
                }
                calibrate(&training, options, unseen, &|points, options| {
                    let run = self.estimate_with_model_errors(
                        transport,
                        caches,
                        points,
                        options,
                        &|| {},
                        cancel,
                    )?;
                    caches.amortised.add(run.rays());
                    Ok(run.estimates)
                })
            })?)
        } else {
            None
        };
        // The stratified light samples' variance moderated as at the
        // training points, before any prior weighs the estimates (§10.5).
        let moderate = |mut estimates: Estimates| {
            if let Some(strata) = calibration.and_then(|c| c.strata) {
                estimates.estimates.iter_mut().for_each(|e| strata.apply(e));
            }
            estimates
        };
        let mut least = Vec::new();
        let (mut estimates, calibrated) = if self.has_priors(&caches) {
            let scales = calibration
                .and_then(|c| c.prior_scales)
                .unwrap_or(PriorScales::ONE);
            let estimates = moderate(
                self.rule()
                    .estimate(transport, caches, points, options, on_done, cancel)?,
            );
            let rule: Vec<Rgb> = estimates.estimates.iter().map(|e| e.std_error).collect();
            let combined = self.with_priors(estimates, caches, points, scales);
            // Under the hemisphere decomposition the bound made bars too
            // wide (docs/math.md §10.9): kept to split mode.
            if combined.0.decomposition == Decomposition::Split {
                least = rule
                    .into_iter()
                    .zip(&combined.0.estimates)
                    .map(|(rule, combined)| rule_noise_carried(rule, combined.std_error))
                    .collect();
            }
            combined
        } else {
            let estimates =
                moderate(self.estimate_with_model_errors(
                    transport, caches, points, options, on_done, cancel,
                )?);
            let all = vec![true; estimates.estimates.len()];
            (estimates, all)
        };
        if let Some(calibration) = calibration {
            for (i, estimate) in estimates
                .estimates
                .iter_mut()
                .zip(calibrated)
                .enumerate()
                .filter_map(|(i, (e, calibrated))| calibrated.then_some((i, e)))
            {
                calibration.apply(estimate);
                if let Some(least) = least.get(i) {
                    let (sd, least) = (estimate.std_error.to_array(), least.to_array());
                    estimate.std_error =
                        Rgb::from_array(std::array::from_fn(|c| sd[c].max(least[c])));
                }
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
        let mut runs = training
            .requests(options)
            .map(|request| {
                let run = rule.estimate(
                    transport,
                    caches,
                    &training.points,
                    &request,
                    &|| {},
                    cancel,
                )?;
                caches.amortised.add(run.rays());
                Ok::<_, EstimatorError>(run)
            })
            .collect::<Result<Vec<_>, _>>()?;
        let strata = training.moderate(
            &mut runs
                .iter_mut()
                .map(|run| run.estimates.as_mut_slice())
                .collect::<Vec<_>>(),
        );
        let known = self.priors_at(&caches, &training.points);
        caches
            .amortised
            .add(known.iter().map(KnownPriors::rays).sum());
        let combined = |scales| {
            runs.iter()
                .map(|run| {
                    let mut estimates = run.estimates.clone();
                    let combined = combine_priors(&mut estimates, &known, scales);
                    (
                        estimates,
                        combined.into_iter().map(PriorsCombined::any).collect(),
                    )
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
        calibration.strata = strata;
        Ok(calibration)
    }

    /// Hemisphere samples per point of one run: the spec's, doubled for
    /// the corrected `bmc` of error targets.
    pub fn samples(&self) -> u32 {
        if self.corrected {
            2 * self.spec.samples()
        } else {
            self.spec.samples()
        }
    }

    /// The estimator each batch of an error target runs (§10.6): the same
    /// rule without the records prior, which [`Self::estimate_to_target`]
    /// combines once with the batches' mean instead (a prior in every batch
    /// would be counted again with each), reporting its indirect part for
    /// that; `bmc` with the residual correction that makes its batches
    /// unbiased.
    pub fn batches(&self) -> PointEstimator {
        PointEstimator {
            corrected: matches!(self.rule, PointRule::Bmc(_)),
            ..self.rule()
        }
    }

    /// Whether the estimator leans on the records prior (§10.7): the spec
    /// asked, or left it to the method (`RecordsPriorMode::Auto`).
    pub fn records_prior(&self) -> bool {
        self.spec.uses_records()
    }

    /// The records prior this estimator uses: the caches', if it uses one.
    fn records<'a>(&self, caches: &EstimatorCaches<'a>) -> Option<&'a dyn IntegralPrior> {
        caches.records.filter(|_| self.records_prior())
    }

    /// The direct-light records this estimator uses (§10.8): the caches',
    /// if it uses the records prior.
    fn direct<'a>(&self, caches: &EstimatorCaches<'a>) -> Option<&'a dyn IntegralPrior> {
        caches.direct.filter(|_| self.records_prior())
    }

    /// Whether the estimator combines its rule with priors: it uses the
    /// records prior and the caches hold one (§10.7, §10.8).
    pub(super) fn has_priors(&self, caches: &EstimatorCaches) -> bool {
        self.records(caches).is_some() || self.direct(caches).is_some()
    }

    /// With the records prior: `estimates`, the [`Self::rule`]'s (with the
    /// rule's calibrated error bars, if the spec calibrates), combined with the
    /// records where they cover a point (§10.7), then their direct part with
    /// the direct-light records (§10.8), the priors' variances scaled by `scales` (§10.9); and for
    /// each estimate whether a prior moved it (the others keep the rule's
    /// error bars, the moved ones are calibrated again).
    fn with_priors(
        &self,
        mut estimates: Estimates,
        caches: EstimatorCaches,
        points: &[QueryPoint],
        scales: PriorScales,
    ) -> (Estimates, Vec<bool>) {
        let known = self.priors_at(&caches, points);
        let combined = combine_priors(&mut estimates.estimates, &known, scales);
        estimates.calibration = None;
        let moved = combined.iter().map(|c| c.any()).collect();
        estimates.priors_combined = combined;
        (estimates, moved)
    }

    /// The rule under the records prior: the same spec without it, which
    /// also reports the indirect part of its estimates.
    fn rule(&self) -> PointEstimator {
        PointEstimator {
            spec: EstimatorSpec {
                records_prior: RecordsPriorMode::Set(false),
                ..self.spec
            },
            indirect_part: true,
            ..self.clone()
        }
    }

    /// The priors at each point (the caches' direct-light records are made
    /// for the queries' decomposition, §10.8).
    pub(super) fn priors_at(
        &self,
        caches: &EstimatorCaches,
        points: &[QueryPoint],
    ) -> Vec<KnownPriors> {
        let records = self.records(caches);
        let direct = self.direct(caches);
        points
            .par_iter()
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
            rule.estimate(transport, points, options, on_done, cancel)
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
                let estimates = if self.corrected {
                    let count = quadrature.quadrature.weights.len();
                    run(&BmcControlVariate::new(quadrature, kernel, count))?
                } else {
                    run(&BayesianEstimator::new(
                        quadrature,
                        BmcVariance::AmplitudeFit,
                    ))?
                };
                (estimates, Some(kernel), Some(cached))
            }
        };
        Ok(Estimates {
            estimates,
            kernel,
            quadrature_cached,
            decomposition,
            prior,
            calibration: None,
            priors_combined: Vec::new(),
        })
    }
}

/// The priors' means and variances at a point, where they cover it.
pub(super) struct KnownPriors {
    records: Option<PriorAt>,
    direct: Option<PriorAt>,
}

impl KnownPriors {
    /// The rays traced at the point to state the priors.
    fn rays(&self) -> u64 {
        [self.records, self.direct]
            .iter()
            .flatten()
            .map(|p| p.rays)
            .sum()
    }
}

/// The least standard error, per channel, of an estimate combined with
/// priors (docs/math.md §10.9): the rule's own noise it still carries. A
/// combination keeps the share `w = v / (s² + v)` of the rule's part, whose
/// calibrated variance `s²` is independent of the prior's error, so its
/// variance is at least `w² s²`; with the combination's model variance
/// `t² = w s²` that is `t⁴ / s²`, and over two parts (Cauchy–Schwarz) the
/// same expression stays below what both carry. `rule` is the rule's
/// calibrated standard error, `combined` the combination's before its own
/// calibration.
fn rule_noise_carried(rule: Rgb, combined: Rgb) -> Rgb {
    Rgb::from_array(std::array::from_fn(|c| {
        let (s, t) = (rule.to_array()[c], combined.to_array()[c]);
        if s > 0.0 { t * t / s } else { 0.0 }
    }))
}

/// Combines each estimate with the priors at its point (§10.7, §10.8),
/// their variances scaled by `scales`; which priors were combined with each.
/// Each estimate counts the rays its priors traced at its point, combined
/// or not.
pub(super) fn combine_priors(
    estimates: &mut [IrradianceEstimate],
    known: &[KnownPriors],
    scales: PriorScales,
) -> Vec<PriorsCombined> {
    estimates
        .iter_mut()
        .zip(known)
        .map(|(estimate, known)| {
            estimate.rays += known.rays();
            PriorsCombined {
                records: known
                    .records
                    .is_some_and(|prior| combine_part(estimate, prior.scaled(scales.records))),
                direct: known
                    .direct
                    .is_some_and(|prior| combine_direct(estimate, prior.scaled(scales.direct))),
            }
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
                    Some(_) => caches
                        .kernels
                        .get_or_fit(transport, config, caches.amortised),
                    None => caches
                        .kernels
                        .get_or_select(transport, config, caches.amortised),
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
mod tests;
