//! Error targets: estimate each point until its calibrated error bar says
//! the relative error is within a target at a confidence, or a sample cap is
//! reached (docs/math.md §10.6).
//!
//! A point is estimated in batches ([`PointEstimator::batches`]: `N`
//! samples, `2N` for `bmc`, whose batches add the unbiased residual
//! correction of `bmc::control_variate`); batch `k` is the same estimator
//! with an independent random stream (a new rotation of the sample set, new
//! paths and fresh directions), so batch errors are independent and the
//! mean of `B` batches has variance `Σ_b σ_b² / B²` per channel, `σ_b` the
//! batch's calibrated standard deviation (§10.5). After each batch a point
//! stops when `z · σ_Y ≤ relative_error · Y`, with `Y` the luminance of the
//! mean, `σ_Y = Σ_c w_c σ_c` its standard deviation (the sum, not the root
//! of the sum of squares, because the channels' errors are strongly
//! correlated) and `z` the two-sided normal quantile of `confidence`; or
//! when another batch would pass `max_samples`. Plain `bmc` batches would
//! share the bias of their fixed rings of directions, hence the correction.
//! With the records prior the batches run without it, and after each batch
//! their mean (with its indirect part) is combined with the priors at the
//! point once, the stopping rule then reading the posterior (§10.6).

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::error::EstimatorError;
use super::integral_prior::{PriorScales, share};
use super::point_estimator::{
    Estimates, EstimatorCaches, PointEstimator, PriorsCombined, combine_priors,
};
use crate::render::Cancel;
use crate::render::QueryPoint;
use crate::render::Rgb;
use crate::render::Transport;
use crate::render::{IndirectPart, IrradianceEstimate, IrradianceOptions};
use crate::stats::two_sided_normal_quantile;

/// Confidence of a target that names none.
pub const DEFAULT_CONFIDENCE: f64 = 0.95;

/// An error target as a request (`"target": {…}`) and the command line
/// (`--target 0.02 --confidence 0.95 --max-samples 4096`) name it;
/// [`TargetSpec::resolve`] fills the cap and checks every number.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, ToSchema, clap::Args)]
#[serde(deny_unknown_fields)]
pub struct TargetSpec {
    /// Largest relative error of each point's luminance, in (0, 1].
    // Not `required` on the command line, where it would be even with no
    // target (clap-rs/clap#5092); a target without it is still refused.
    #[arg(long = "target", value_name = "RELATIVE_ERROR", required = false)]
    pub relative_error: f64,
    /// Probability that the error is within it, in [0.5, 0.9999]; default 0.95.
    // No clap default: the target is `None` unless an argument of it is named.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub confidence: Option<f64>,
    /// Most hemisphere samples per point, from one batch's samples up to
    /// `limits.max_samples`; default `limits.max_samples`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub max_samples: Option<u32>,
}

impl TargetSpec {
    /// The target for `estimator`'s batches, capped at `max_samples` per
    /// point unless the spec names a cap (module docs).
    pub fn resolve(
        &self,
        estimator: &PointEstimator,
        max_samples: u32,
    ) -> Result<ErrorTarget, EstimatorError> {
        let target = ErrorTarget {
            relative_error: self.relative_error,
            confidence: self.confidence.unwrap_or(DEFAULT_CONFIDENCE),
            max_samples: self.max_samples.unwrap_or(max_samples),
        };
        target.validate(estimator)?;
        Ok(target)
    }
}

/// What a caller asks of every point's estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ErrorTarget {
    /// Largest accepted relative error of the luminance, in `(0, 1]`.
    pub relative_error: f64,
    /// Probability that the error is within the target, in `[0.5, 0.9999]`.
    pub confidence: f64,
    /// Most hemisphere samples per point, at least the estimator's `N`.
    pub max_samples: u32,
}

/// One point's estimate under a target.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TargetedEstimate {
    /// Mean of the batches, with the standard deviation of that mean.
    pub estimate: IrradianceEstimate,
    /// Hemisphere samples spent on the point.
    pub samples: u32,
    /// `z σ_Y / Y` when the point stopped (module docs).
    pub relative_error: f64,
    pub met: bool,
}

impl ErrorTarget {
    /// Checks the numbers against the batches `estimator` would run
    /// ([`PointEstimator::batches`]); errors name the field under `target`.
    pub fn validate(&self, estimator: &PointEstimator) -> Result<(), EstimatorError> {
        let invalid = |field: &str, message: String| EstimatorError::InvalidTarget {
            field: field.into(),
            message,
        };
        let batch = estimator.batches().samples();
        if !(self.relative_error > 0.0 && self.relative_error <= 1.0) {
            return Err(invalid(
                "relative_error",
                format!("must be in (0, 1], got {}", self.relative_error),
            ));
        }
        if !(0.5..=0.9999).contains(&self.confidence) {
            return Err(invalid(
                "confidence",
                format!("must be in [0.5, 0.9999], got {}", self.confidence),
            ));
        }
        if self.max_samples < batch {
            return Err(invalid(
                "max_samples",
                format!(
                    "must be at least one batch's samples ({batch}), got {}",
                    self.max_samples
                ),
            ));
        }
        Ok(())
    }
}

/// `z σ_Y / Y` of an estimate (module docs); infinite for `Y ≤ 0` with
/// a non-zero error bar.
fn relative_half_width(z: f64, estimate: &IrradianceEstimate) -> f64 {
    let y = estimate.irradiance.luminance();
    let sigma = estimate.std_error.luminance();
    if sigma == 0.0 {
        0.0
    } else if y > 0.0 {
        z * sigma / y
    } else {
        f64::INFINITY
    }
}

/// What a point's batches add up to so far.
#[derive(Clone, Copy, Debug, Default)]
struct BatchSums {
    batches: u32,
    samples: u32,
    rays: u64,
    irradiance: Rgb,
    variance: Rgb,
    /// The indirect parts, and their variances (share × variance).
    indirect: Option<(Rgb, Rgb)>,
    /// Per channel, the least weight of samples that may all have missed
    /// light at the scene's scale over the batches
    /// ([`IrradianceEstimate::unseen_light`]): a batch whose light samples
    /// saw light shows the light is there.
    unseen_light: Option<[f64; 3]>,
}

impl BatchSums {
    fn add(&mut self, e: &IrradianceEstimate, batch: u32) {
        let variance = e.std_error * e.std_error;
        self.batches += 1;
        self.samples += batch;
        self.rays += e.rays;
        self.irradiance += e.irradiance;
        self.variance += variance;
        // A part every batch reports, or none.
        self.indirect = match (self.batches, self.indirect, e.indirect) {
            (1, _, Some(part)) => Some((part.irradiance, part.variance_share * variance)),
            (_, Some((sum, part_variance)), Some(part)) => Some((
                sum + part.irradiance,
                part_variance + part.variance_share * variance,
            )),
            _ => None,
        };
        let least = self.unseen_light.unwrap_or([1.0; 3]);
        self.unseen_light = Some(std::array::from_fn(|c| least[c].min(e.unseen_light[c])));
    }

    /// The mean of the batches with the standard deviation of that mean
    /// (their variances add, the batches being independent), and its
    /// indirect part with that part's share of the variance.
    fn mean(&self) -> IrradianceEstimate {
        let inverse = 1.0 / f64::from(self.batches.max(1));
        IrradianceEstimate {
            irradiance: self.irradiance * inverse,
            std_error: self.variance.map(f64::sqrt) * inverse,
            rays: self.rays,
            indirect: self.indirect.map(|(sum, variance)| IndirectPart {
                irradiance: sum * inverse,
                variance_share: share(variance, self.variance),
            }),
            unseen_light: self.unseen_light.unwrap_or([0.0; 3]),
            // The batches' bars are calibrated (moderated) already.
            direct_strata: None,
        }
    }
}

/// Seed of batch `k` of a request with seed `seed`: the request's own for
/// the first batch, so a target that one batch meets changes nothing.
fn batch_seed(seed: u64, k: u64) -> u64 {
    if k == 0 {
        seed
    } else {
        seed ^ k.wrapping_mul(0x9E37_79B9_7F4A_7C15)
    }
}

impl PointEstimator {
    /// Irradiance at every point to `target` (module docs), in batches of
    /// the estimator's samples. Returns the metadata of the first batch
    /// (kernel, decomposition, prior, calibration) and one
    /// [`TargetedEstimate`] per point, in order.
    pub fn estimate_to_target(
        &self,
        transport: &Transport,
        caches: EstimatorCaches,
        points: &[QueryPoint],
        options: &IrradianceOptions,
        target: &ErrorTarget,
        cancel: &Cancel,
    ) -> Result<(Estimates, Vec<TargetedEstimate>), EstimatorError> {
        target.validate(self)?;
        let estimator = self.batches();
        let batch = estimator.samples();
        if points.is_empty() {
            return Err(EstimatorError::Invalid {
                field: "points".into(),
                message: "at least one point is needed".into(),
            });
        }
        let z = two_sided_normal_quantile(target.confidence);
        // The priors, stated once for every point, are combined with the
        // mean of its batches, never with a batch (docs/math.md §10.6).
        let known = if self.has_priors(&caches) {
            self.priors_at(&caches, points)
        } else {
            Vec::new()
        };
        let mut sums = vec![BatchSums::default(); points.len()];
        let mut results: Vec<Option<TargetedEstimate>> = vec![None; points.len()];
        let mut combined = vec![PriorsCombined::default(); points.len()];
        let mut active: Vec<usize> = (0..points.len()).collect();
        let mut first = None;
        for k in 0.. {
            if active.is_empty() {
                break;
            }
            let subset: Vec<QueryPoint> = active.iter().map(|&i| points[i]).collect();
            let request = IrradianceOptions {
                seed: batch_seed(options.seed, k),
                ..*options
            };
            let estimates =
                estimator.estimate(transport, caches, &subset, &request, &|| {}, cancel)?;
            let mut still_active = Vec::new();
            for (&i, e) in active.iter().zip(&estimates.estimates) {
                sums[i].add(e, batch);
                let mut mean = sums[i].mean();
                if let Some(known) = known.get(i) {
                    combined[i] = combine_priors(
                        std::slice::from_mut(&mut mean),
                        std::slice::from_ref(known),
                        PriorScales::ONE,
                    )[0];
                }
                let relative_error = relative_half_width(z, &mean);
                let met = relative_error <= target.relative_error;
                let samples = sums[i].samples;
                results[i] = Some(TargetedEstimate {
                    estimate: mean,
                    samples,
                    relative_error,
                    met,
                });
                if !met && samples.saturating_add(batch) <= target.max_samples {
                    still_active.push(i);
                }
            }
            first.get_or_insert(estimates);
            active = still_active;
        }
        let mut first = first.expect("at least one point and one batch");
        if !known.is_empty() {
            first.priors_combined = combined;
        }
        let results = results
            .into_iter()
            .map(|r| r.expect("every point estimated at least once"))
            .collect();
        Ok((first, results))
    }
}
