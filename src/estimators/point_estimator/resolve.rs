//! [`EstimatorSpec::resolve`]: a spec checked once against its method, its
//! defaults filled in and its rule built (the `bmc` kernel's numbers
//! checked with a stand-in lengthscale for `"auto"`), before any work.

use super::{BmcSetup, PointEstimator, PointRule};
use crate::bmc::estimator::{SampleMeanEstimator, SamplingPdf};
use crate::bmc::{Density, Kernel};
use crate::estimators::error::EstimatorError;
use crate::estimators::lengthscale::FALLBACK_LENGTHSCALE;
use crate::estimators::spec::{
    DEFAULT_KERNEL, DEFAULT_NOISE, DEFAULT_VARIANCE, EstimatorMethod, EstimatorSpec,
    RecordsPriorMode, SampleSetChoice,
};
use crate::render::environment_prior::PriorChoice;
use crate::sphere::{SampleSetKind, SampleSetSpec};

impl EstimatorSpec {
    /// Checks the options against the method (module docs).
    pub fn resolve(&self) -> Result<PointEstimator, EstimatorError> {
        let method = self.method();
        let samples = self.samples() as usize;
        if samples == 0 {
            return Err(EstimatorError::invalid("samples", "must be at least 1"));
        }
        let chosen = self.sample_set.unwrap_or_default();
        let set = SampleSetChoice {
            kind: Some(chosen.kind()),
            seed: Some(chosen.seed()),
        };
        if method != EstimatorMethod::Bmc && self.kernel.is_some() {
            return Err(EstimatorError::invalid(
                "kernel",
                "only `bmc` takes a kernel",
            ));
        }
        if self.records_prior == RecordsPriorMode::Set(true) && method == EstimatorMethod::Mc {
            return Err(EstimatorError::invalid(
                "records_prior",
                "`mc` stays plain Monte Carlo; `qmc` and `bmc` take the records prior",
            ));
        }
        let prior = self.prior.unwrap_or(match method {
            EstimatorMethod::Bmc => PriorChoice::Environment,
            EstimatorMethod::Mc | EstimatorMethod::Qmc => PriorChoice::None,
        });
        let rule = self.rule(method, samples, set)?;
        Ok(PointEstimator {
            rule,
            prior,
            // No error model is calibrated on real scenes as it is (§10.5):
            // QMC's is too wide, the GP's assumes a smooth integrand, and
            // MC's sample variance is blind to light that its few samples
            // all missed.
            calibrate: self.calibrate.unwrap_or(true),
            // Defaults filled in: a spec that names them and one that
            // leaves them are one estimator, with one calibration.
            spec: EstimatorSpec {
                method: Some(method),
                samples: Some(samples as u32),
                sample_set: Some(set),
                prior: Some(prior),
                ..*self
            },
            indirect_part: false,
            corrected: false,
        })
    }

    fn rule(
        &self,
        method: EstimatorMethod,
        samples: usize,
        set: SampleSetChoice,
    ) -> Result<PointRule, EstimatorError> {
        match method {
            EstimatorMethod::Mc if self.sample_set.is_some() => Err(EstimatorError::invalid(
                "sample_set",
                "`mc` draws fresh random directions; only `qmc` and `bmc` take a sample set",
            )),
            EstimatorMethod::Mc => Ok(PointRule::Mc { count: samples }),
            EstimatorMethod::Qmc => {
                let pdf = match set.kind() {
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
                    kernel.lengthscale().value().unwrap_or(FALLBACK_LENGTHSCALE),
                    variance,
                    kernel.noise.unwrap_or(DEFAULT_NOISE),
                )
                .map_err(EstimatorError::kernel)?;
                let sample_set = SampleSetSpec {
                    kind: set.kind(),
                    count: samples,
                    seed: set.seed(),
                };
                Ok(PointRule::Bmc(BmcSetup {
                    sample_set,
                    kind: kernel.kind,
                    lengthscale: kernel.lengthscale().value(),
                    variance,
                    noise: kernel.noise,
                }))
            }
        }
    }
}
