//! Irradiance at points, the whole query: a [`PointQuerySpec`] resolved
//! once into a [`PointQuery`] (points, estimator, options and error target
//! checked), then [`PointQuery::estimate`] with what the query reuses and
//! adds to ([`QueryState`]): the records prior's sources assembled (records
//! placed among the query's own points, the store's gatherings, the
//! caller's shared caches; docs/math.md §10.7–§10.11), the estimates plain
//! or to a target (§10.6), and per point which records moved it. The
//! service's route and the `irradiance` command only translate their input
//! into the spec and serialise the [`PointAnswer`], so the same query and
//! seed give the same numbers through either.

mod records;
mod spec;
#[cfg(test)]
mod tests;

use std::sync::Arc;

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

pub use records::{
    HeldRecords, Key, MIN_POINTS_FOR_RECORDS, PointRecords, RecordsStore, SceneRecords,
};
pub use spec::PointQuerySpec;

use crate::bmc::KernelKind;
use crate::bmc::cache::QuadratureCache;
use crate::estimators::calibration::{Calibrations, ErrorCalibration};
use crate::estimators::error_target::{ErrorTarget, TargetedEstimate};
use crate::estimators::lengthscale::FittedKernels;
use crate::estimators::{AmortisedRays, EstimatorCaches, EstimatorError, PointEstimator};
use crate::integrator::cached::{PriorSource, point_priors};
use crate::render::environment_prior::PriorChoice;
use crate::render::{
    Cancel, Decomposition, IrradianceEstimate, IrradianceOptions, QueryPoint, RenderError,
    Transport,
};

/// A point query checked against its scene, ready to run.
#[derive(Debug, Clone)]
pub struct PointQuery {
    pub points: Vec<QueryPoint>,
    pub estimator: PointEstimator,
    pub options: IrradianceOptions,
    pub target: Option<ErrorTarget>,
}

/// What a point query reuses from earlier ones and leaves for later ones.
pub struct QueryState<'a, S> {
    /// The scene's fitted lengthscales (docs/math.md §7.5).
    pub kernels: &'a FittedKernels,
    /// The scene's calibrated error bars (§10.5).
    pub calibrations: &'a Calibrations,
    pub quadratures: &'a Arc<QuadratureCache>,
    /// The records entries held for the scene, and their gatherings.
    pub store: &'a S,
    pub gatherings: &'a PointRecords,
    /// Further record sets the prior may draw on (the service's shared caches).
    pub shared: Vec<PriorSource>,
    /// Most points a query places records among.
    pub max_records: usize,
}

/// A point query's answer, as the service returns it.
#[derive(Debug, Serialize, Deserialize, ToSchema)]
pub struct PointAnswer {
    /// The unit of `irradiance` and `std_dev`: `W/m²`.
    pub unit: String,
    /// Irradiance per point, `[r, g, b]` in W/m².
    pub irradiance: Vec<[f64; 3]>,
    /// Standard error of each estimate, `[r, g, b]` in W/m².
    pub std_dev: Vec<[f64; 3]>,
    /// Rays traced for the whole query: its points' and those of the work
    /// it did first for this scene and configuration (below).
    pub rays: u64,
    /// Of `rays`, those spent on work kept for later queries of the scene,
    /// which the first query needing it does: fitting an `"auto"` kernel,
    /// calibrating the error bars (training points, their reference and the
    /// estimator's runs), placing records among the points, the records
    /// prior's direct-light twins. A query repeated once that work is kept
    /// reports 0 here.
    pub amortised_rays: u64,
    /// `bmc`: the kernel family used (selected by marginal likelihood when
    /// the query names none and the lengthscale is `"auto"`).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<String>, example = "matern52")]
    pub kernel: Option<KernelKind>,
    /// `bmc`: the lengthscale used (fitted for `"auto"`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lengthscale: Option<f64>,
    /// `bmc`: the kernel noise σ_n² used (with σ² it sets the weights' smoothing).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise: Option<f64>,
    /// With `records_prior`: the points whose indirect part was combined with
    /// the irradiance cache's records.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub records_prior_points: Option<usize>,
    /// With `records_prior`: the points whose direct part was combined with
    /// the direct-light twins of the records (docs/math.md §10.8).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub direct_records_points: Option<usize>,
    /// With the records prior: per point, which records were combined with
    /// each part of its estimate (`records_prior_points` and
    /// `direct_records_points` count them). A direct part whose own samples
    /// contradict the twins' prior keeps its estimate (docs/math.md §10.8)
    /// and names none; so does every point of an error target, whose
    /// batches do not use the prior.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub prior_used: Option<Vec<PriorUsed>>,
    /// The decomposition run: `split` or `hemisphere` (`auto` resolved).
    #[schema(value_type = String, example = "hemisphere")]
    pub decomposition: Decomposition,
    /// The prior mean used: `environment` or `none`.
    #[schema(value_type = String, example = "environment")]
    pub prior: PriorChoice,
    /// The calibration applied to `std_dev`, if any: `std_dev² =
    /// scale² (model² + (floor · irradiance)²) + (unseen · level)²` per
    /// channel (`unseen` for `mc`, `qmc` and the batches of `bmc` under a
    /// target).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Object>)]
    pub calibration: Option<ErrorCalibration>,
    /// With a `target`: per point, the hemisphere samples spent, …
    #[serde(skip_serializing_if = "Option::is_none")]
    pub samples: Option<Vec<u32>>,
    /// … the relative error `z σ / E` of the luminance reached, …
    #[serde(skip_serializing_if = "Option::is_none")]
    pub relative_error: Option<Vec<f64>>,
    /// … and whether it is within the target.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub target_met: Option<Vec<bool>>,
    /// `bmc`: whether the weights came from the quadrature cache (for the
    /// caller's metrics; not part of the answer).
    #[serde(skip)]
    pub quadrature_cached: Option<bool>,
}

/// The records one point's estimate was combined with (docs/math.md
/// §10.7, §10.8): `"records"` for the content-keyed ones (of reproducible
/// tiles, and placed among queries' points, §10.10–§10.11), `"cache"` for
/// the shared cache's; absent where none covered the point.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct PriorUsed {
    /// The records its indirect part met.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub indirect: Option<String>,
    /// The records whose direct-light twins its direct part met
    /// (hemisphere decomposition only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub direct: Option<String>,
}

impl PointQuery {
    /// Paths the query may trace at most: one per point and hemisphere
    /// sample, up to the target's cap under a target; a light sample is a
    /// shadow ray, no more than a path, and every batch draws them again.
    pub fn estimated_paths(&self) -> u64 {
        let samples = u64::from(self.options.samples);
        let paths = self.target.map_or(samples, |t| u64::from(t.max_samples));
        let light = self
            .options
            .light_samples
            .map_or(0, |l| u64::from(l) * paths.div_ceil(samples.max(1)));
        self.points.len() as u64 * paths.max(light)
    }

    /// Irradiance at every point on the current rayon pool (module docs);
    /// `on_done` is called once per finished point of a plain query.
    pub fn estimate<S: RecordsStore>(
        &self,
        transport: &Transport,
        state: QueryState<S>,
        on_done: &(dyn Fn() + Sync),
        cancel: &Cancel,
    ) -> Result<PointAnswer, EstimatorError> {
        let amortised = AmortisedRays::default();
        let options = &self.options;
        // The scene's records serve as priors only when the estimator uses
        // them: those placed among the points first (a query of many
        // points), then the store's gatherings and the shared caches.
        let mut sources = Vec::new();
        let uses_records = self.estimator.records_prior();
        if uses_records {
            let at = SceneRecords {
                transport,
                store: state.store,
                quadratures: state.quadratures,
            };
            amortised.add(state.gatherings.place_among(
                at,
                &self.points,
                options.max_depth,
                state.max_records,
                cancel,
            )?);
            sources = state.gatherings.sources(at).map_err(RenderError::from)?;
            sources.extend(state.shared);
        }
        let priors = point_priors(
            &sources,
            transport,
            options.max_depth,
            options.method,
            cancel,
        )?;
        amortised.add(priors.rays);
        let (records, direct) = (&priors.records, &priors.direct);
        let caches = EstimatorCaches {
            kernels: state.kernels,
            quadratures: state.quadratures,
            calibrations: state.calibrations,
            records: (!records.is_empty()).then_some(records),
            direct: (!direct.is_empty()).then_some(direct),
            amortised: &amortised,
        };
        let (mut estimates, targeted) = match &self.target {
            None => (
                self.estimator.estimate(
                    transport,
                    caches,
                    &self.points,
                    options,
                    on_done,
                    cancel,
                )?,
                None,
            ),
            Some(target) => {
                let (first, targeted) = self.estimator.estimate_to_target(
                    transport,
                    caches,
                    &self.points,
                    options,
                    target,
                    cancel,
                )?;
                (first, Some(targeted))
            }
        };
        // Per point, the records combined with its indirect part and those
        // whose twins were combined with its direct part.
        let prior_used = uses_records.then(|| {
            self.points
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    let combined = estimates
                        .priors_combined
                        .get(i)
                        .copied()
                        .unwrap_or_default();
                    PriorUsed {
                        indirect: records
                            .origin_at(p)
                            .filter(|_| combined.records)
                            .map(Into::into),
                        direct: direct
                            .origin_at(p)
                            .filter(|_| combined.direct)
                            .map(Into::into),
                    }
                })
                .collect::<Vec<_>>()
        });
        let count = |part: fn(&PriorUsed) -> bool| {
            prior_used
                .as_ref()
                .map(|used| used.iter().filter(|p| part(p)).count())
        };
        let final_estimates: Vec<IrradianceEstimate> = match &targeted {
            Some(targeted) => targeted
                .iter()
                .map(|t: &TargetedEstimate| t.estimate)
                .collect(),
            None => std::mem::take(&mut estimates.estimates),
        };
        let amortised_rays = amortised.get();
        let rgb = |c: crate::color::Rgb| [c.r, c.g, c.b];
        let kernel = estimates.kernel;
        Ok(PointAnswer {
            unit: "W/m²".into(),
            irradiance: final_estimates.iter().map(|e| rgb(e.irradiance)).collect(),
            std_dev: final_estimates.iter().map(|e| rgb(e.std_error)).collect(),
            rays: final_estimates.iter().map(|e| e.rays).sum::<u64>() + amortised_rays,
            amortised_rays,
            kernel: kernel.map(|k| k.kind),
            lengthscale: kernel.map(|k| k.lengthscale),
            noise: kernel.map(|k| k.noise),
            records_prior_points: count(|p| p.indirect.is_some()),
            direct_records_points: count(|p| p.direct.is_some()),
            prior_used,
            decomposition: estimates.decomposition,
            prior: estimates.prior,
            calibration: estimates.calibration,
            samples: targeted
                .as_ref()
                .map(|t| t.iter().map(|t| t.samples).collect()),
            relative_error: targeted
                .as_ref()
                .map(|t| t.iter().map(|t| t.relative_error).collect()),
            target_met: targeted.map(|t| t.iter().map(|t| t.met).collect()),
            quadrature_cached: estimates.quadrature_cached,
        })
    }
}
