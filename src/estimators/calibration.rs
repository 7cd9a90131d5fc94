//! Calibrating an estimator's error bars on the scene itself
//! (docs/math.md §10.5).
//!
//! Each estimator has an error model: the sample variance of the mean (MC,
//! QMC) or the GP posterior variance (BMC). Neither is calibrated on real
//! scenes: QMC's i.i.d. formula is several times too wide, and every model
//! is blind to what falls between its samples (a thin occluder that no
//! direction hit), which gives rare, very large `z`. So the reported
//! variance is the model's, widened by a floor proportional to the estimate
//! and scaled, `σ² = κ² (σ_model² + τ² Ê²)` per channel, with `κ` and `τ`
//! fitted once per scene and estimator configuration on held-out training
//! points against a Monte Carlo reference: `κ` makes the rms `z` one, `τ`
//! brings the ±2σ coverage nearest 95 % (§10.3). The training points
//! ([`CALIBRATION_POINTS`] area-sampled surface points, [`CALIBRATION_SEEDS`]
//! request seeds) share nothing with the points of any request, so the
//! calibration is measured, not assumed, when a study checks it on others.
//! Where the light samples are stratified, their variance in `σ_model²` is
//! first moderated toward the scene's pooled ratio of it to the independent
//! samples' variance ([`StrataModeration`]), in the rule's estimates before
//! any prior is combined with them, at the training points as at a
//! request's.
//!
//! Plain MC adds one more term, fixed rather than fitted, where light may be
//! missing at the scene's scale ([`IrradianceEstimate::unseen_light`]): the
//! light its `N` independent directions may all have missed, `(μ_N Ē)²` with
//! `μ_N² = 3/(4(N + 1)(N + 2))` ([`unseen_light`]), so that an estimate that
//! saw nothing still reports an error bar of the scene's scale.

use std::sync::Arc;

use super::amortised::AmortisedRays;
use super::integral_prior::{PriorScales, share};
use super::sample_points::{camera_points, training_points};
use crate::render::Cancel;
use crate::render::MIN_STRATA_BLOCKS;
use crate::render::QueryPoint;
use crate::render::RenderError;
use crate::render::Transport;
use crate::render::{IrradianceEstimate, IrradianceMethod, IrradianceOptions, Rgb};
use crate::stats::standard_score;

/// Training points per calibration.
pub const CALIBRATION_POINTS: usize = 96;
/// Request seeds per training point.
pub const CALIBRATION_SEEDS: u64 = 4;
/// Samples of the training points' Monte Carlo reference: this many times
/// the estimator's, within [`CALIBRATION_REFERENCE_SAMPLES`] and
/// [`CALIBRATION_REFERENCE_MAX`].
pub const CALIBRATION_REFERENCE_FACTOR: u32 = 64;
pub const CALIBRATION_REFERENCE_SAMPLES: u32 = 4096;
pub const CALIBRATION_REFERENCE_MAX: u32 = 65_536;
/// Seed of the training points, their reference and their estimates.
pub const CALIBRATION_SEED: u64 = 0xCA11_B4A7;
/// See [`ErrorCalibration::level`].
pub const FLOOR_MIN_LEVEL: f64 = 0.05;
/// Most calibrations kept per scene (one per estimator configuration).
pub const MAX_CALIBRATIONS: u64 = 64;

/// The fitted widening of an estimator's error model (module docs).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ErrorCalibration {
    /// `κ`: scale of the standard deviation.
    pub scale: f64,
    /// `τ`: relative floor of the standard deviation, before scaling.
    pub floor: f64,
    /// Mean reference irradiance of the training points per channel, W/m²:
    /// the floor of an estimate is taken at no less than
    /// [`FLOOR_MIN_LEVEL`] times it, so an estimate of zero with a zero
    /// model variance (no sample found light) still gets an error bar.
    pub level: [f64; 3],
    /// Training `(point, seed, channel)` triples the fit used.
    pub pairs: usize,
    /// `μ_N`: standard deviation of light that no sample saw, relative to
    /// `level` and added after scaling where
    /// [`IrradianceEstimate::unseen_light`] says so ([`unseen_light`]); 0
    /// for BMC under the hemisphere decomposition (docs/math.md §10.5).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub unseen: f64,
    /// With the records prior: the multipliers of the priors' variances
    /// fitted on the same training points before the bars, which are then
    /// fitted on, and applied to, the estimates a prior moved
    /// (docs/math.md §10.9).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prior_scales: Option<PriorScales>,
    /// Where the light samples are stratified: how their variance is
    /// moderated before the fit and the scaling ([`StrataModeration`]);
    /// `None`: as the contrasts give it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub strata: Option<StrataModeration>,
}

/// The moderation of a stratified mean's variance ([`crate::render::StrataVariance`])
/// (docs/math.md §10.5): toward `ratio` times the independent samples'
/// variance, the prior worth [`STRATA_PRIOR_BLOCKS`] blocks.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StrataModeration {
    /// `c`: the training estimates' stratified variance over their
    /// independent one, each relative to its channel's level, pooled.
    pub ratio: f64,
}

/// `d₀`: the blocks the pooled prior of [`StrataModeration`] is worth, as
/// many as the fewest a stratified variance is estimated from
/// ([`MIN_STRATA_BLOCKS`]), so that at that count the point's own variance
/// and the prior weigh the same, and the point's own counts for more as its
/// blocks grow (docs/math.md §10.5).
pub const STRATA_PRIOR_BLOCKS: f64 = MIN_STRATA_BLOCKS as f64;

impl StrataModeration {
    /// The ratio pooled over `estimates` with channel levels `level`; none where
    /// no estimate had stratified light samples.
    fn pooled<'a>(
        estimates: impl Iterator<Item = &'a IrradianceEstimate>,
        level: [f64; 3],
    ) -> Option<Self> {
        let (mut stratified, mut independent) = (0.0, 0.0);
        for s in estimates.filter_map(|e| e.direct_strata) {
            let (a, b) = (s.stratified.to_array(), s.independent.to_array());
            for c in (0..3).filter(|&c| level[c] > 0.0) {
                stratified += a[c] / (level[c] * level[c]);
                independent += b[c] / (level[c] * level[c]);
            }
        }
        (independent > 0.0).then(|| Self {
            ratio: stratified / independent,
        })
    }

    /// Replaces the stratified variance in `estimate`'s by its moderation,
    /// once (it takes [`IrradianceEstimate::direct_strata`]); the indirect
    /// part keeps its own variance, now a share of another total.
    pub fn apply(&self, estimate: &mut IrradianceEstimate) {
        let Some(strata) = estimate.direct_strata.take() else {
            return;
        };
        let before = estimate.std_error * estimate.std_error;
        let moderated = strata.moderated(self.ratio, STRATA_PRIOR_BLOCKS);
        let after = (before - strata.stratified + moderated).map(|v| v.max(0.0));
        estimate.std_error = after.map(f64::sqrt);
        if let Some(part) = estimate.indirect.as_mut() {
            part.variance_share = share(part.variance_share * before, after);
        }
    }
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

/// The training points of every calibration on `transport`'s scene: where
/// the scene will be looked at, what its camera sees, or anywhere on its
/// surfaces if the camera sees nothing.
pub fn calibration_points(transport: &Transport) -> Vec<QueryPoint> {
    let points = camera_points(transport, CALIBRATION_POINTS, CALIBRATION_SEED);
    if points.len() < CALIBRATION_POINTS / 2 {
        return training_points(transport, CALIBRATION_POINTS, CALIBRATION_SEED);
    }
    points
}

/// `μ_N = sqrt(3/(4(N + 1)(N + 2)))` (docs/math.md §10.5): with a Jeffreys
/// prior `Beta(½, ½)` on the share `p` of the hemisphere (in the sampling
/// density's measure) that brings light, `N` independent directions that
/// all missed it leave `p ~ Beta(½, N + ½)`, whose second moment is
/// `3/(4(N + 1)(N + 2))`; light of the scene's mean level `Ē` over that share
/// is the missed irradiance `p Ē`.
pub fn unseen_light(samples: u32) -> f64 {
    let n = f64::from(samples);
    (0.75 / ((n + 1.0) * (n + 2.0))).sqrt()
}

/// One training comparison: the estimator's error against the reference,
/// its model standard deviation, the reference's standard error and the
/// estimate's magnitude.
#[derive(Clone, Copy, Debug)]
struct Training {
    error: f64,
    sigma: f64,
    reference_sigma: f64,
    magnitude: f64,
    /// `Ē` of the channel where [`ErrorCalibration::unseen`] applies
    /// ([`IrradianceEstimate::unseen_light`]), else 0.
    unseen_level: f64,
}

/// The scale of the light an estimate's samples may all have missed
/// ([`ErrorCalibration::unseen`]): `level` times the weight of those samples
/// in the estimate ([`IrradianceEstimate::unseen_light`]; docs/math.md
/// §10.5).
fn unseen_level(unseen_light: f64, level: f64) -> f64 {
    unseen_light * level
}

/// `|value|`, but no less than [`FLOOR_MIN_LEVEL`] times `level`.
fn floor_magnitude(value: f64, level: f64) -> f64 {
    value.abs().max(FLOOR_MIN_LEVEL * level)
}

impl ErrorCalibration {
    /// The model's error bars as they are.
    pub const IDENTITY: Self = Self {
        scale: 1.0,
        floor: 0.0,
        level: [0.0; 3],
        pairs: 0,
        unseen: 0.0,
        prior_scales: None,
        strata: None,
    };

    /// Widens `estimate.std_error` (module docs).
    pub fn apply(&self, estimate: &mut IrradianceEstimate) {
        let (floor, scale) = (self.floor, self.scale);
        let value = estimate.irradiance;
        let sigma = estimate.std_error.to_array();
        let value = value.to_array();
        let unseen_light = estimate.unseen_light;
        estimate.std_error = Rgb::from_array(std::array::from_fn(|c| {
            let magnitude = floor_magnitude(value[c], self.level[c]);
            // The unseen term, only where light may be missing, is not
            // scaled by κ; written inside the root so that without it the
            // result is `κ sqrt(…)` bit for bit.
            let unseen = unseen_level(unseen_light[c], self.level[c]) * self.unseen / scale;
            scale * (sigma[c] * sigma[c] + (floor * magnitude).powi(2) + unseen * unseen).sqrt()
        }));
    }

    /// Fits `τ` on a grid and `κ` for each by bisection (module docs), with
    /// the fixed term `unseen` ([`Self::unseen`]) where it applies; of the
    /// fits whose coverage is within a binomial standard error of 95 %, the
    /// sharpest (narrowest mean bar), else the one nearest 95 %
    /// (docs/math.md §10.5).
    fn fit(training: &[Training], level: [f64; 3], unseen: f64) -> Self {
        if training.is_empty() {
            return Self {
                unseen,
                level,
                ..Self::IDENTITY
            };
        }
        let bar = |scale: f64, floor: f64, t: &Training| {
            let model = t.sigma * t.sigma + (floor * t.magnitude).powi(2);
            scale * scale * model + (unseen * t.unseen_level).powi(2)
        };
        let z = |scale: f64, floor: f64, t: &Training| {
            standard_score(t.error, bar(scale, floor, t), t.reference_sigma.powi(2))
        };
        let width = |scale, floor| {
            training
                .iter()
                .map(|t| bar(scale, floor, t).sqrt())
                .sum::<f64>()
                / training.len() as f64
        };
        let rms = |scale, floor| {
            (training
                .iter()
                .map(|t| z(scale, floor, t).powi(2))
                .sum::<f64>()
                / training.len() as f64)
                .sqrt()
        };
        let coverage = |scale, floor| {
            training
                .iter()
                .filter(|t| z(scale, floor, t).abs() <= 2.0)
                .count() as f64
                / training.len() as f64
        };
        let floors =
            std::iter::once(0.0).chain((0..=16).map(|k| 10f64.powf(-4.0 + 0.25 * k as f64)));
        let tolerance = (0.95 * 0.05 / training.len() as f64).sqrt();
        // (miss of 95 %, mean width, the fit) of each floor that reaches rms z 1.
        let mut fits: Vec<(f64, f64, Self)> = Vec::new();
        for floor in floors {
            // rms z falls as κ grows; bisect log κ for rms z = 1.
            let (mut lo, mut hi) = (1e-3f64.ln(), 1e3f64.ln());
            if !(rms(hi.exp(), floor) <= 1.0 && rms(lo.exp(), floor) >= 1.0) {
                continue;
            }
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if rms(mid.exp(), floor) > 1.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let scale = hi.exp();
            fits.push((
                (coverage(scale, floor) - 0.95).abs(),
                width(scale, floor),
                Self {
                    scale,
                    floor,
                    level,
                    pairs: training.len(),
                    unseen,
                    prior_scales: None,
                    strata: None,
                },
            ));
        }
        choose(&fits, tolerance).map_or(
            Self {
                unseen,
                level,
                ..Self::IDENTITY
            },
            |c| *c,
        )
    }
}

/// Of `fits` (miss of 95 % coverage, mean bar width, fit), each calibrated
/// to rms z 1: the narrowest of those whose miss is within `tolerance`,
/// calibration first and then sharpness (Gneiting, Balabdaoui & Raftery,
/// "Probabilistic forecasts, calibration and sharpness", 2007); else the
/// nearest 95 %, the first of equals.
fn choose<T>(fits: &[(f64, f64, T)], tolerance: f64) -> Option<&T> {
    let sharpest = fits
        .iter()
        .filter(|(miss, _, _)| *miss <= tolerance)
        .min_by(|a, b| a.1.total_cmp(&b.1));
    let nearest = || {
        fits.iter()
            .reduce(|best, f| if f.0 < best.0 - 1e-9 { f } else { best })
    };
    sharpest.or_else(nearest).map(|(_, _, fit)| fit)
}

/// Uncalibrated estimates at points for options (see [`calibrate`]).
pub type EstimateFn<'a, E> =
    dyn Fn(&[QueryPoint], &IrradianceOptions) -> Result<Vec<IrradianceEstimate>, E> + 'a;

/// Calibrates the estimator `estimate` runs (module docs) on `training`:
/// `estimate(points, options)` must return the uncalibrated estimates of the
/// configuration for `options` (whose seed it must honour). `unseen` is the
/// estimator's [`ErrorCalibration::unseen`] (0, or [`unseen_light`] where §10.5 adds it).
pub fn calibrate<E>(
    training: &TrainingSet,
    options: &IrradianceOptions,
    unseen: f64,
    estimate: &EstimateFn<'_, E>,
) -> Result<ErrorCalibration, E> {
    let mut runs = training
        .requests(options)
        .map(|request| estimate(&training.points, &request))
        .collect::<Result<Vec<_>, E>>()?;
    let strata = training.moderate(&mut runs.iter_mut().map(Vec::as_mut_slice).collect::<Vec<_>>());
    Ok(ErrorCalibration {
        strata,
        ..training.fit(&runs, None, unseen)
    })
}

/// Samples of the training reference for estimators run with `options`
/// ([`CALIBRATION_REFERENCE_FACTOR`]).
fn reference_samples(options: &IrradianceOptions) -> u32 {
    options
        .samples
        .saturating_mul(CALIBRATION_REFERENCE_FACTOR)
        .clamp(CALIBRATION_REFERENCE_SAMPLES, CALIBRATION_REFERENCE_MAX)
}

/// The training points of a calibration and their reference (module docs).
pub struct TrainingSet {
    /// [`CALIBRATION_POINTS`] points where the scene will be looked at.
    pub points: Vec<QueryPoint>,
    reference: Vec<IrradianceEstimate>,
    /// Mean reference irradiance per channel (see [`ErrorCalibration::level`]).
    level: [f64; 3],
}

/// Seed of the part a reference of `samples` adds to the one of half as
/// many ([`Calibrations::training_set`]); the smallest references are drawn
/// with [`CALIBRATION_SEED`].
fn reference_seed(samples: u32) -> u64 {
    CALIBRATION_SEED ^ u64::from(samples).wrapping_mul(0x9E37_79B9_7F4A_7C15)
}

/// Plain MC with light sampling of `samples` paths per point, seeded with
/// `seed`: unbiased for every decomposition, and with enough samples that
/// its own noise does not hide the estimator's.
fn reference_at(
    transport: &Transport,
    points: &[QueryPoint],
    options: &IrradianceOptions,
    samples: u32,
    seed: u64,
    cancel: &Cancel,
) -> Result<Vec<IrradianceEstimate>, RenderError> {
    transport.irradiance_at_points(
        points,
        &IrradianceOptions {
            samples,
            method: IrradianceMethod::Split,
            seed,
            ..*options
        },
        &|| {},
        cancel,
    )
}

impl TrainingSet {
    /// The training points and a reference at them.
    fn with_reference(points: Vec<QueryPoint>, reference: Vec<IrradianceEstimate>) -> Self {
        let level: [f64; 3] = std::array::from_fn(|c| {
            reference
                .iter()
                .map(|r| r.irradiance.to_array()[c])
                .sum::<f64>()
                / reference.len().max(1) as f64
        });
        Self {
            points,
            reference,
            level,
        }
    }

    /// This set, whose reference has `kept` samples per point, with a
    /// reference of `more` samples more per point, `added`, drawn
    /// independently: the sample-weighted mean of the two and the variance
    /// of that mean. Only the irradiance and its standard error are kept.
    fn extended(&self, kept: u32, added: &[IrradianceEstimate], more: u32) -> Self {
        let total = f64::from(kept) + f64::from(more);
        let (a, b) = (f64::from(kept) / total, f64::from(more) / total);
        let reference = self
            .reference
            .iter()
            .zip(added)
            .map(|(old, new)| IrradianceEstimate {
                irradiance: old.irradiance * a + new.irradiance * b,
                std_error: (old.std_error * old.std_error * (a * a)
                    + new.std_error * new.std_error * (b * b))
                    .map(f64::sqrt),
                rays: old.rays + new.rays,
                indirect: None,
                unseen_light: std::array::from_fn(|c| old.unseen_light[c].min(new.unseen_light[c])),
                direct_strata: None,
            })
            .collect();
        Self::with_reference(self.points.clone(), reference)
    }

    /// The [`CALIBRATION_SEEDS`] requests the estimator is run with at the
    /// points: `options` with the training seeds.
    pub fn requests(
        &self,
        options: &IrradianceOptions,
    ) -> impl Iterator<Item = IrradianceOptions> + use<> {
        let options = *options;
        (0..CALIBRATION_SEEDS).map(move |s| IrradianceOptions {
            seed: CALIBRATION_SEED.wrapping_add(1 + s),
            ..options
        })
    }

    /// The moderation of the stratified light samples' variance pooled
    /// over the estimates of `runs` at the training points
    /// ([`StrataModeration`]), applied to them.
    pub fn moderate(&self, runs: &mut [&mut [IrradianceEstimate]]) -> Option<StrataModeration> {
        let moderation = StrataModeration::pooled(runs.iter().flat_map(|r| r.iter()), self.level)?;
        runs.iter_mut()
            .flat_map(|r| r.iter_mut())
            .for_each(|e| moderation.apply(e));
        Some(moderation)
    }

    /// Sum over runs, points and channels of the squared error against the
    /// reference, each channel relative to its level: the mean of its
    /// expectation over the reference's noise is the estimator's own mean
    /// squared error plus a constant, so the run with the smallest is the
    /// most accurate whatever the reference's noise.
    pub fn squared_error(&self, runs: &[Vec<IrradianceEstimate>]) -> f64 {
        runs.iter()
            .flat_map(|run| run.iter().zip(&self.reference))
            .map(|(e, r)| {
                let (value, truth) = (e.irradiance.to_array(), r.irradiance.to_array());
                (0..3)
                    .filter(|&c| self.level[c] > 0.0)
                    .map(|c| ((value[c] - truth[c]) / self.level[c]).powi(2))
                    .sum::<f64>()
            })
            .sum()
    }

    /// The calibration of the estimator whose uncalibrated estimates at the
    /// points are `runs`, one per request of [`Self::requests`]; with
    /// `only`, fitted on the estimates it marks (per run, per point).
    pub fn fit(
        &self,
        runs: &[Vec<IrradianceEstimate>],
        only: Option<&[Vec<bool>]>,
        unseen: f64,
    ) -> ErrorCalibration {
        let level = self.level;
        let mut training = Vec::new();
        for (k, run) in runs.iter().enumerate() {
            let marked = |i: usize| only.is_none_or(|only| only[k][i]);
            let pairs = run.iter().zip(&self.reference).enumerate();
            for (_, (e, r)) in pairs.filter(|(i, _)| marked(*i)) {
                let (value, sigma) = (e.irradiance.to_array(), e.std_error.to_array());
                let (truth, reference_sigma) = (r.irradiance.to_array(), r.std_error.to_array());
                for c in 0..3 {
                    training.push(Training {
                        error: value[c] - truth[c],
                        sigma: sigma[c],
                        reference_sigma: reference_sigma[c],
                        magnitude: floor_magnitude(value[c], level[c]),
                        unseen_level: unseen_level(e.unseen_light[c], level[c]),
                    });
                }
            }
        }
        ErrorCalibration::fit(&training, level, unseen)
    }
}

/// Calibrations of one scene by estimator configuration; each computed at
/// most once while kept, at most [`MAX_CALIBRATIONS`] kept (least used go
/// first). A cancelled calibration is not kept. The training sets are kept
/// beside them: their reference depends only on the samples and depth of
/// the request, so the estimators of a configuration (a rule and the rule
/// with the records prior, at each count of records) share one.
pub struct Calibrations {
    kept: moka::sync::Cache<String, ErrorCalibration>,
    training: moka::sync::Cache<String, Arc<TrainingSet>>,
}

impl Default for Calibrations {
    fn default() -> Self {
        Self {
            kept: moka::sync::Cache::new(MAX_CALIBRATIONS),
            training: moka::sync::Cache::new(MAX_CALIBRATIONS),
        }
    }
}

impl Calibrations {
    /// The calibration for `key`, computing it with `compute` on first use.
    pub fn get_or_calibrate<E: Clone + Send + Sync + 'static>(
        &self,
        key: String,
        compute: impl FnOnce() -> Result<ErrorCalibration, E> + Send,
    ) -> Result<ErrorCalibration, E> {
        crate::isolated::try_get_with(&self.kept, key, compute)
            .map_err(|err: Arc<E>| (*err).clone())
    }

    /// The training set for estimators run with `options`, computed on
    /// first use, its reference's new rays counted in `amortised` then. A
    /// reference of at least twice [`CALIBRATION_REFERENCE_SAMPLES`] is the
    /// one of half its samples (computed first if not kept) extended by as
    /// many more, so a request at `2N` pays for half of its reference
    /// when one at `N` came before; which request built it changes nothing.
    pub fn training_set(
        &self,
        transport: &Transport,
        options: &IrradianceOptions,
        amortised: &AmortisedRays,
        cancel: &Cancel,
    ) -> Result<Arc<TrainingSet>, RenderError> {
        self.training_set_of(
            transport,
            options,
            reference_samples(options),
            amortised,
            cancel,
        )
    }

    /// [`Self::training_set`] with a reference of `samples` per point.
    fn training_set_of(
        &self,
        transport: &Transport,
        options: &IrradianceOptions,
        samples: u32,
        amortised: &AmortisedRays,
        cancel: &Cancel,
    ) -> Result<Arc<TrainingSet>, RenderError> {
        let key = format!(
            "reference samples {samples} depth {:?}",
            options.effective_max_depth()
        );
        let rays = |reference: &[IrradianceEstimate]| reference.iter().map(|r| r.rays).sum();
        crate::isolated::try_get_with(&self.training, key, || {
            if samples >= 2 * CALIBRATION_REFERENCE_SAMPLES {
                let kept = samples / 2;
                let half = self.training_set_of(transport, options, kept, amortised, cancel)?;
                let more = samples - kept;
                let added = reference_at(
                    transport,
                    &half.points,
                    options,
                    more,
                    reference_seed(samples),
                    cancel,
                )?;
                amortised.add(rays(&added));
                return Ok(Arc::new(half.extended(kept, &added, more)));
            }
            let points = calibration_points(transport);
            let reference = reference_at(
                transport,
                &points,
                options,
                samples,
                CALIBRATION_SEED,
                cancel,
            )?;
            amortised.add(rays(&reference));
            Ok(Arc::new(TrainingSet::with_reference(points, reference)))
        })
        .map_err(|err: Arc<RenderError>| (*err).clone())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn training(errors: &[(f64, f64)]) -> Vec<Training> {
        errors
            .iter()
            .map(|&(error, sigma)| Training {
                error,
                sigma,
                reference_sigma: 0.0,
                magnitude: 1.0,
                unseen_level: 0.0,
            })
            .collect()
    }

    /// Calibration first, then sharpness: of the fits within the tolerance
    /// the narrowest, not the one nearest 95 %; none within it, the
    /// nearest.
    #[test]
    fn the_sharpest_calibrated_fit_is_chosen() {
        let fits = [(0.004, 2.0, 'a'), (0.001, 3.0, 'b'), (0.02, 1.0, 'c')];
        assert_eq!(choose(&fits, 0.005), Some(&'a'));
        assert_eq!(choose(&fits, 0.0005), Some(&'b'));
        assert_eq!(choose::<char>(&[], 0.005), None);
    }

    /// Stratified variances with the expectation of the true ones but only
    /// two degrees of freedom (a few blocks on a small sun) are calibrated
    /// only by bars that all but ignore them; moderated toward the pooled
    /// ratio times the independent variance, by sharper ones.
    #[test]
    fn heavy_tailed_stratified_variances_are_moderated() {
        use crate::render::StrataVariance;
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        let mut normal = || {
            let (u, v): (f64, f64) = (rng.random(), rng.random());
            (-2.0 * (1.0 - u).ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        };
        let truth = Rgb::splat(10.0);
        let estimates: Vec<IrradianceEstimate> = (0..1000)
            .map(|i| {
                let sd = 0.5 + f64::from(i % 10) * 0.1;
                // χ²₂/2 is exponential with mean 1.
                let chi2 = 0.5 * (normal().powi(2) + normal().powi(2));
                let stratified = Rgb::splat(sd * sd * chi2);
                IrradianceEstimate {
                    irradiance: truth + Rgb::new(normal(), normal(), normal()) * sd,
                    std_error: stratified.map(f64::sqrt),
                    rays: 0,
                    indirect: None,
                    unseen_light: [0.0; 3],
                    direct_strata: Some(StrataVariance {
                        stratified,
                        independent: Rgb::splat(sd * sd / 0.4),
                        blocks: 16,
                    }),
                }
            })
            .collect();
        let point = QueryPoint::new(glam::DVec3::ZERO, glam::DVec3::Z).unwrap();
        let reference = IrradianceEstimate {
            irradiance: truth,
            std_error: Rgb::BLACK,
            direct_strata: None,
            ..estimates[0]
        };
        let set = TrainingSet::with_reference(vec![point; 1000], vec![reference; 1000]);
        // (coverage, mean bar) of a fit on `runs`, which it then takes.
        let measure = |runs: &[Vec<IrradianceEstimate>]| {
            let fit = set.fit(runs, None, 0.0);
            let (mut covered, mut width) = (0, 0.0);
            for e in &runs[0] {
                let mut e = *e;
                fit.apply(&mut e);
                let (error, bar) = ((e.irradiance - truth).r.abs(), e.std_error.r);
                covered += usize::from(error <= 2.0 * bar);
                width += bar;
            }
            (covered as f64 / 1000.0, width / 1000.0)
        };
        let (_, plain_width) = measure(std::slice::from_ref(&estimates));
        let mut moderated = estimates.clone();
        let strata = set.moderate(&mut [moderated.as_mut_slice()]).unwrap();
        assert!((strata.ratio - 0.4).abs() < 0.03, "{strata:?}");
        assert!(moderated.iter().all(|e| e.direct_strata.is_none()));
        let (coverage, width) = measure(&[moderated]);
        assert!((coverage - 0.95).abs() < 0.015, "coverage {coverage}");
        assert!(width < 0.95 * plain_width, "{width} against {plain_width}");
    }

    /// The moderation replaces the stratified variance in the total, keeps
    /// the indirect part's own variance, and applies once.
    #[test]
    fn moderation_keeps_the_indirect_variance() {
        use crate::render::StrataVariance;
        let mut e = IrradianceEstimate {
            irradiance: Rgb::splat(5.0),
            // Indirect 3 + stratified 1.
            std_error: Rgb::splat(4.0f64.sqrt()),
            rays: 0,
            indirect: Some(crate::render::IndirectPart {
                irradiance: Rgb::splat(2.0),
                variance_share: Rgb::splat(0.75),
            }),
            unseen_light: [0.0; 3],
            direct_strata: Some(StrataVariance {
                stratified: Rgb::splat(1.0),
                independent: Rgb::splat(4.0),
                blocks: 16,
            }),
        };
        let m = StrataModeration { ratio: 0.75 };
        m.apply(&mut e);
        // (16 · 1 + 16 · 0.75 · 4)/32 = 2, beside the indirect 3.
        assert!((e.std_error.g - 5.0f64.sqrt()).abs() < 1e-12);
        assert!((e.indirect.unwrap().variance_share.b - 0.6).abs() < 1e-12);
        let once = e;
        m.apply(&mut e);
        assert_eq!(e, once);
    }

    #[test]
    fn too_wide_bars_are_narrowed_to_unit_rms_z() {
        // Errors of size 1 with model σ = 4: κ ≈ 1/4.
        let t = training(&[(1.0, 4.0), (-1.0, 4.0), (0.5, 4.0), (-1.3, 4.0)]);
        let fit = ErrorCalibration::fit(&t, [1.0; 3], 0.0);
        let rms = (t
            .iter()
            .map(|t| (t.error / (fit.scale * (t.sigma.powi(2) + fit.floor.powi(2)).sqrt())).powi(2))
            .sum::<f64>()
            / 4.0)
            .sqrt();
        assert!((rms - 1.0).abs() < 1e-6, "rms z {rms} with {fit:?}");
    }

    #[test]
    fn errors_the_model_cannot_see_get_a_floor() {
        // Most errors well modelled; a few with σ_model = 0 (nothing seen).
        let mut errors: Vec<(f64, f64)> = (0..95)
            .map(|i| (((i * 37) % 19) as f64 / 10.0 - 0.9, 1.0))
            .collect();
        errors.extend([
            (0.3, 0.0),
            (-0.2, 0.0),
            (0.25, 0.0),
            (-0.3, 0.0),
            (0.2, 0.0),
        ]);
        let fit = ErrorCalibration::fit(&training(&errors), [1.0, 1.0, 0.0], 0.0);
        assert!(fit.floor > 0.0, "{fit:?}");
        let mut estimate = IrradianceEstimate {
            irradiance: Rgb::from_array([1.0, 2.0, 0.0]),
            std_error: Rgb::BLACK,
            rays: 0,
            indirect: None,
            unseen_light: [0.0; 3],
            direct_strata: None,
        };
        fit.apply(&mut estimate);
        assert!(estimate.std_error.r > 0.0 && estimate.std_error.g > estimate.std_error.r);
        assert_eq!(estimate.std_error.b, 0.0);
    }

    #[test]
    fn unseen_light_is_the_jeffreys_second_moment_of_a_missed_share() {
        // p ~ Beta(½, N + ½): E p² = (½ · 3/2) / ((N + 1)(N + 2)).
        for n in [1u32, 16, 64, 256] {
            let (a, b) = (0.5, f64::from(n) + 0.5);
            let second_moment = a * (a + 1.0) / ((a + b) * (a + b + 1.0));
            assert!((unseen_light(n).powi(2) - second_moment).abs() < 1e-15);
        }
        assert!((unseen_light(16) - 0.0495).abs() < 1e-4);
    }

    #[test]
    fn an_estimate_that_saw_nothing_keeps_the_unseen_light_bar() {
        // Errors the model explains exactly, and one zero estimate with a
        // zero model σ: only the fixed unseen-light term gives it a bar.
        let errors: Vec<(f64, f64)> = (0..100)
            .map(|i| (if i % 2 == 0 { 1.0 } else { -1.0 }, 1.0))
            .collect();
        let unseen = unseen_light(16);
        let fit = ErrorCalibration::fit(&training(&errors), [1.0; 3], unseen);
        assert_eq!(fit.unseen, unseen);
        let mut nothing = IrradianceEstimate {
            irradiance: Rgb::BLACK,
            std_error: Rgb::BLACK,
            rays: 0,
            indirect: None,
            unseen_light: [1.0; 3],
            direct_strata: None,
        };
        fit.apply(&mut nothing);
        let floor = fit.scale * fit.floor * FLOOR_MIN_LEVEL;
        let expected = (floor * floor + unseen * unseen).sqrt();
        assert!((nothing.std_error.r - expected).abs() < 1e-12, "{fit:?}");
        assert!(nothing.std_error.r >= unseen);
        // An estimate that saw light does not take it, even with a zero
        // model σ: its bar is the floor's.
        let mut some = IrradianceEstimate {
            irradiance: Rgb::WHITE,
            unseen_light: [0.0; 3],
            direct_strata: None,
            ..nothing
        };
        some.std_error = Rgb::BLACK;
        fit.apply(&mut some);
        assert_eq!(some.std_error.r, fit.scale * fit.floor);
        // Without the term (QMC, BMC) the same fit leaves only the floor.
        let plain = ErrorCalibration::fit(&training(&errors), [1.0; 3], 0.0);
        assert_eq!(plain.unseen, 0.0);
    }

    /// A reference of twice the samples extends the one of half as many,
    /// paying only for the half it adds, and is the same whether or not
    /// the smaller one was asked for first.
    #[test]
    fn a_larger_reference_extends_the_smaller_one() {
        let transport = crate::testing::cornell(16);
        let options = |samples| IrradianceOptions {
            samples,
            max_depth: crate::render::PathDepth::new(1).unwrap(),
            ..IrradianceOptions::default()
        };
        let build = |calibrations: &Calibrations, samples| {
            let amortised = AmortisedRays::default();
            let set = calibrations
                .training_set(&transport, &options(samples), &amortised, &Cancel::never())
                .unwrap();
            (set, amortised.get())
        };
        let climbing = Calibrations::default();
        let (small, small_rays) = build(&climbing, 64);
        let (large, large_rays) = build(&climbing, 128);
        let (direct, direct_rays) = build(&Calibrations::default(), 128);
        assert!(small_rays > 0);
        assert_eq!(direct_rays, small_rays + large_rays);
        assert_eq!(large.reference, direct.reference);
        assert_eq!(large.level, direct.level);
        for (s, l) in small.reference.iter().zip(&large.reference) {
            let (s, l) = (s.std_error.to_array(), l.std_error.to_array());
            assert!((0..3).all(|c| l[c] < s[c] || s[c] == 0.0), "{s:?} {l:?}");
        }
    }
}
