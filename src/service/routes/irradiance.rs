//! `POST /v1/scenes/{id}/irradiance`: irradiance `E(x, n)` in W/m² (RGB) at points.
//!
//! The estimator (`mc`, `qmc` or `bmc`, split or hemisphere decomposition)
//! is the library's [`EstimatorSpec`]; its behaviour and defaults are
//! documented in `estimators`. This route translates the request
//! into that spec and the scene's fitted kernels and the service's
//! quadrature cache, and records the cache's metrics.

use std::sync::Arc;

use axum::Json;
use axum::extract::State;
use glam::DVec3;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::bmc::KernelKind;
use crate::cache::RecordsPrior;
use crate::estimators::calibration::ErrorCalibration;
use crate::estimators::error_target::ErrorTarget;
use crate::estimators::{
    AmortisedRays, DEFAULT_METHOD, DEFAULT_SAMPLES, Estimates, EstimatorCaches, EstimatorMethod,
    EstimatorSpec, KernelSpec, Lengthscale, RecordsPriorMode,
};
use crate::integrator::cached::{DirectPrior, point_priors};
use crate::render::environment_prior::PriorChoice;
use crate::render::{
    Decomposition, IrradianceMethod, IrradianceOptions, PathDepth, QueryPoint, RenderError, Rgb,
};
use crate::service::error::{ApiError, AtField, ErrorBody};
use crate::service::extract::{ApiJson, SceneId};
use crate::service::metrics::{self, RAYS_TRACED};
use crate::service::state::AppState;
use crate::service::tile_priors::SceneRecords;
use crate::sphere::SampleSetKind;

/// A shading point: world position and the normal of the hemisphere of interest.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct PointDoc {
    pub position: [f64; 3],
    /// Need not be unit length; must be finite and non-zero.
    pub normal: [f64; 3],
}

/// The estimator of a point query; every field has a default, so `{}` (or
/// no `estimator` at all) is `bmc` with 64 samples, as on the command line
/// and in the Python client.
#[derive(Debug, Default, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct EstimatorDoc {
    /// `mc`, `qmc` or `bmc` (default).
    #[schema(value_type = Option<String>, example = "bmc")]
    pub method: Option<EstimatorMethod>,
    /// Hemisphere samples per point, 1..=`limits.max_samples`; default 64.
    pub samples: Option<u32>,
    /// Light samples per point for the direct part under the `split`
    /// decomposition, 1..=`limits.max_samples` (default: `samples`). Each is
    /// one shadow ray, where a hemisphere sample is a path, so where the
    /// error is in the direct light (penumbrae, a sun) many more of them than
    /// hemisphere samples are cheap. Refused with `"decomposition":
    /// "hemisphere"`, which takes none; ignored where `auto` resolves to it.
    pub light_samples: Option<u32>,
    /// `auto` (default: `hemisphere` for a scene lit only by a smooth
    /// environment, else `split`), `split` or `hemisphere`.
    #[serde(default)]
    #[schema(value_type = String, example = "auto")]
    pub decomposition: IrradianceMethod,
    /// Prior mean of the hemisphere values: `environment` (the unoccluded
    /// environment, used where the hemisphere part sees it directly) or
    /// `none`. Default: `environment` for `bmc`, `none` for `mc` and `qmc`.
    #[schema(value_type = Option<String>, example = "environment")]
    pub prior: Option<PriorChoice>,
    /// Calibrate the error bars on the scene (default true): the model's
    /// variance widened by a relative floor and scaled, both fitted once per
    /// scene and configuration against a reference at held-out points, and
    /// for `mc` a term for light that all its samples missed. With `false`,
    /// `std_dev` is the estimator's own error model (for `mc` its sample
    /// variance of the mean).
    pub calibrate: Option<bool>,
    /// `qmc` and `bmc` only: the fixed sample set.
    pub sample_set: Option<EstimatorSampleSetDoc>,
    /// `bmc` only: the GP kernel over incident radiance.
    pub kernel: Option<EstimatorKernelDoc>,
    /// `true`, `false` or `"auto"` (default: on for `bmc`, off for `mc` and
    /// `qmc`, which stay the plain rules). A query of 64 points or more
    /// first places records among its own points (docs/math.md §10.11; kept
    /// for later queries, their rays counted in `amortised_rays`). Where
    /// records of the scene cover a point (those placed among query points,
    /// those of every reproducible tile rendered, gathered per camera depth,
    /// and those of the shared cache), combine the point's
    /// indirect part with their interpolated irradiance by precision
    /// (docs/math.md §10.7), and under the hemisphere decomposition its
    /// direct part with the direct light seen from the records' places
    /// (their direct-light twins, made on first use: a thousand rays or so
    /// per record, §10.8). Records serve queries of a depth (from the point)
    /// no greater than theirs (their camera depth less one). The answer
    /// depends on the records held when it is asked, and on nothing else:
    /// the same records give the same numbers on any replica. `prior_used`
    /// says, per point, what moved its estimate. Calibrated error bars are
    /// fitted again each time the records double. Under a `target` the
    /// batches run without it and their mean is combined with it once
    /// (docs/math.md §10.6). `mc` refuses `true`.
    #[serde(default)]
    #[schema(value_type = Object, example = "auto")]
    pub records_prior: RecordsPriorMode,
}

/// The sample set of a `qmc`/`bmc` estimator; its size is `estimator.samples`.
#[derive(Debug, Clone, Copy, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct EstimatorSampleSetDoc {
    /// `fibonacci_cosine` (default), `fibonacci`; for `bmc` also `uniform`,
    /// `cosine`, `stratified`.
    #[schema(value_type = String, example = "fibonacci_cosine")]
    #[serde(default = "default_set_kind")]
    pub kind: SampleSetKind,
    /// Seed of the random kinds; default 0.
    #[serde(default)]
    pub seed: u64,
}

fn default_set_kind() -> SampleSetKind {
    crate::estimators::DEFAULT_SAMPLE_SET
}

/// The kernel of a `bmc` estimator.
#[derive(Debug, Clone, Copy, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct EstimatorKernelDoc {
    /// `squared_exponential`, `matern32` or `matern52`; default: with an
    /// `"auto"` lengthscale the family of largest marginal likelihood on the
    /// scene (the response's `kernel` says which), else `squared_exponential`.
    #[schema(value_type = String, example = "squared_exponential")]
    pub kind: Option<KernelKind>,
    /// ℓ in [0.01, 1000], or `"auto"` (default).
    #[serde(default)]
    #[schema(value_type = Object, example = "auto")]
    pub lengthscale: Lengthscale,
    /// σ², default 1 (the weights depend on `noise/variance` only).
    pub variance: Option<f64>,
    /// σ_n²; default: fitted with an `"auto"` lengthscale, else 1e-3 (Y is a
    /// path-traced estimate, and a tiny jitter makes SE weights oscillate).
    pub noise: Option<f64>,
}

#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct IrradianceRequest {
    /// 1..=`limits.max_points` points.
    pub points: Vec<PointDoc>,
    /// Default: `bmc` with 64 samples and every other option its default.
    #[serde(default)]
    pub estimator: EstimatorDoc,
    /// Longest path in segments from the point (1 = direct light only);
    /// default the scene's depth less the camera's segment (Mitsuba's
    /// integrator `max_depth` − 1), else 16.
    pub max_depth: Option<u32>,
    /// Seed of every random stream; same request and seed, same numbers. Default 1.
    #[serde(default = "default_seed")]
    pub seed: u64,
    /// Estimate each point in batches of `estimator.samples` (`bmc`: twice
    /// that, half of them fresh directions for an unbiased correction, and
    /// no records prior) until its calibrated error bar meets this target or
    /// `max_samples` is spent.
    /// For targets of a few per cent, batches of a few hundred samples keep
    /// the reported `target_met` honest (docs/math.md §10.6).
    pub target: Option<TargetDoc>,
}

/// An error target per point (docs/math.md §10.6).
#[derive(Debug, Clone, Copy, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct TargetDoc {
    /// Largest relative error of the luminance, in (0, 1].
    pub relative_error: f64,
    /// Probability that the error is within it, in [0.5, 0.9999]; default 0.95.
    #[serde(default = "default_confidence")]
    pub confidence: f64,
    /// Most hemisphere samples per point, `estimator.samples..=limits.max_samples`;
    /// default `limits.max_samples`.
    pub max_samples: Option<u32>,
}

fn default_confidence() -> f64 {
    0.95
}

fn default_seed() -> u64 {
    IrradianceOptions::default().seed
}

#[derive(Debug, Serialize, Deserialize, ToSchema)]
pub struct IrradianceResponse {
    /// The unit of `irradiance` and `std_dev`: `W/m²`.
    pub unit: String,
    /// Irradiance per point, `[r, g, b]` in W/m².
    pub irradiance: Vec<[f64; 3]>,
    /// Standard error of each estimate, `[r, g, b]` in W/m².
    pub std_dev: Vec<[f64; 3]>,
    /// Rays traced for the whole request: its points' and those of the work
    /// it did first for this scene and configuration (below).
    pub rays: u64,
    /// Of `rays`, those spent on work kept for later requests of the scene,
    /// which the first request needing it does: fitting an `"auto"` kernel,
    /// calibrating the error bars (training points, their reference and the
    /// estimator's runs), the records prior's direct-light twins. A request
    /// repeated once that work is kept reports 0 here.
    pub amortised_rays: u64,
    /// `bmc`: the kernel family used (selected by marginal likelihood when
    /// the request names none and the lengthscale is `"auto"`).
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
    pub prior_used: Option<Vec<PointPriors>>,
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
}

/// Irradiance at each point of the request.
#[utoipa::path(post, path = "/v1/scenes/{id}/irradiance", tag = "scenes",
    params(("id" = String, Path, description = "Scene id")),
    request_body = IrradianceRequest,
    responses((status = 200, body = IrradianceResponse),
               (status = 404, description = "Unknown scene", body = ErrorBody),
               (status = 422, description = "Invalid request", body = ErrorBody),
               (status = 503, description = "CPU queue full; see Retry-After", body = ErrorBody)))]
pub async fn irradiance(
    State(state): State<Arc<AppState>>,
    SceneId(id): SceneId,
    ApiJson(request): ApiJson<IrradianceRequest>,
) -> Result<Json<IrradianceResponse>, ApiError> {
    let scene = state.scene(&id).await?;
    let limits = &state.config.limits;
    ApiError::check_count(
        "points",
        request.points.len() as u64,
        limits.max_points as u64,
    )?;
    ApiError::check_limit(
        "estimator.samples",
        u64::from(request.estimator.samples()),
        limits.max_samples as u64,
    )?;
    if let Some(light_samples) = request.estimator.light_samples {
        ApiError::check_count(
            "estimator.light_samples",
            u64::from(light_samples),
            limits.max_samples as u64,
        )?;
    }
    let point_estimator = request.estimator.spec().resolve()?;
    let target = request
        .target
        .map(|t| ErrorTarget {
            relative_error: t.relative_error,
            confidence: t.confidence,
            max_samples: t
                .max_samples
                .unwrap_or(u32::try_from(limits.max_samples).unwrap_or(u32::MAX)),
        })
        .map(|target| {
            ApiError::check_limit(
                "target.max_samples",
                u64::from(target.max_samples),
                limits.max_samples as u64,
            )?;
            target.validate(&point_estimator)?;
            Ok::<_, ApiError>(target)
        })
        .transpose()?;
    let records_prior = point_estimator.records_prior();
    // One path per point and hemisphere sample, at most `max_samples` of
    // them per point under a target; a light sample is a shadow ray, no
    // more than a path, and every batch of a target draws them again.
    let samples = u64::from(request.estimator.samples());
    let paths = target.map_or(samples, |t| u64::from(t.max_samples));
    let light = request
        .estimator
        .light_samples
        .map_or(0, |l| u64::from(l) * paths.div_ceil(samples.max(1)));
    limits.check_work(request.points.len() as u64 * paths.max(light))?;
    let points = request
        .points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            QueryPoint::new(DVec3::from(p.position), DVec3::from(p.normal))
                .at(&format!("points[{i}]"))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let estimator = &request.estimator;
    // The sample count was checked with the estimator.
    let options = IrradianceOptions {
        samples: estimator.samples(),
        light_samples: estimator.light_samples,
        max_depth: request.max_depth.map_or_else(
            || Ok(PathDepth::for_points(scene.transport.scene())),
            PathDepth::new,
        )?,
        direct_only: false,
        method: estimator.decomposition,
        seed: request.seed,
    };
    options.validate().at("estimator")?;

    let worker = state.clone();
    let amortised = Arc::new(AmortisedRays::default());
    let spent = amortised.clone();
    let estimates = state
        .pool
        .run(move |cancel| {
            let transport = &scene.transport;
            // The scene's records serve as priors only when the spec uses
            // them: those placed among the points first (a query of many
            // points), then its reproducible tiles' and its shared caches'.
            let mut sources = Vec::new();
            if records_prior {
                let at = SceneRecords {
                    scene: &scene,
                    tiles: &worker.tiles,
                    quadratures: &worker.quadratures,
                };
                spent.add(worker.tile_priors.place_among(
                    at,
                    &points,
                    options.max_depth,
                    worker.config.limits.max_tile_area,
                    cancel,
                )?);
                sources = worker.tile_priors.sources(at).map_err(RenderError::from)?;
                sources.extend(worker.irradiance_caches.prior_sources(&scene));
            }
            let priors = point_priors(
                &sources,
                transport,
                options.max_depth,
                options.method,
                cancel,
            )?;
            spent.add(priors.rays);
            let (records, direct): (&RecordsPrior, &DirectPrior) =
                (&priors.records, &priors.direct);
            let caches = EstimatorCaches {
                kernels: &scene.kernels,
                quadratures: &worker.quadratures,
                calibrations: &scene.calibrations,
                records: (!records.is_empty()).then_some(records),
                direct: (!direct.is_empty()).then_some(direct),
                amortised: &spent,
            };
            let estimates = match &target {
                None => point_estimator
                    .estimate(transport, caches, &points, &options, &|| {}, cancel)
                    .map(|e| (e, None)),
                Some(target) => point_estimator
                    .estimate_to_target(transport, caches, &points, &options, target, cancel)
                    .map(|(first, targeted)| (first, Some(targeted))),
            };
            if let Ok(Some(cached)) = estimates.as_ref().map(|(e, _)| e.quadrature_cached) {
                metrics::record_quadrature_lookup(&worker.quadratures, Some(cached));
            }
            // Per point, the records combined with its indirect part and
            // those whose twins were combined with its direct part.
            let covered = |e: &Estimates| {
                points
                    .iter()
                    .enumerate()
                    .map(|(i, p)| {
                        let combined = e.priors_combined.get(i).copied().unwrap_or_default();
                        PointPriors {
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
            };
            estimates.map(|(e, targeted)| {
                let covered = records_prior.then(|| covered(&e));
                ((e, targeted), covered)
            })
        })
        .await??;
    let (estimates, covered) = estimates;
    let count = |part: fn(&PointPriors) -> bool| {
        covered
            .as_ref()
            .map(|c| c.iter().filter(|p| part(p)).count())
    };
    let records_prior_points = count(|p| p.indirect.is_some());
    let direct_records_points = count(|p| p.direct.is_some());
    let prior_used = covered;
    let (estimates, targeted) = estimates;
    let (kernel, decomposition, prior, calibration) = (
        estimates.kernel,
        estimates.decomposition,
        estimates.prior,
        estimates.calibration,
    );
    let estimates = match &targeted {
        Some(targeted) => targeted.iter().map(|t| t.estimate).collect(),
        None => estimates.estimates,
    };
    let amortised_rays = amortised.get();
    let rays = estimates.iter().map(|e| e.rays).sum::<u64>() + amortised_rays;
    ::metrics::counter!(RAYS_TRACED).increment(rays);
    let rgb = |c: Rgb| [c.r, c.g, c.b];
    Ok(Json(IrradianceResponse {
        unit: "W/m²".into(),
        irradiance: estimates.iter().map(|e| rgb(e.irradiance)).collect(),
        std_dev: estimates.iter().map(|e| rgb(e.std_error)).collect(),
        rays,
        amortised_rays,
        records_prior_points,
        direct_records_points,
        prior_used,
        kernel: kernel.map(|k| k.kind),
        lengthscale: kernel.map(|k| k.lengthscale),
        noise: kernel.map(|k| k.noise),
        decomposition,
        prior,
        calibration,
        samples: targeted
            .as_ref()
            .map(|t| t.iter().map(|t| t.samples).collect()),
        relative_error: targeted
            .as_ref()
            .map(|t| t.iter().map(|t| t.relative_error).collect()),
        target_met: targeted.map(|t| t.iter().map(|t| t.met).collect()),
    }))
}

/// The records one point's estimate was combined with (docs/math.md
/// §10.7, §10.8): `"records"` for the content-keyed ones (of reproducible
/// tiles, and placed among queries' points, §10.10–§10.11), `"cache"` for
/// the shared cache's; absent where none covered the point.
#[derive(Debug, Serialize, Deserialize, ToSchema)]
pub struct PointPriors {
    /// The records its indirect part met.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub indirect: Option<String>,
    /// The records whose direct-light twins its direct part met
    /// (hemisphere decomposition only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub direct: Option<String>,
}

impl EstimatorDoc {
    /// `samples`, or the library's default.
    fn samples(&self) -> u32 {
        self.samples.unwrap_or(DEFAULT_SAMPLES)
    }

    /// The library spec this document names.
    fn spec(&self) -> EstimatorSpec {
        EstimatorSpec {
            method: self.method.unwrap_or(DEFAULT_METHOD),
            samples: self.samples(),
            sample_set: self.sample_set.map(|set| (set.kind, set.seed)),
            kernel: self.kernel.map(|k| KernelSpec {
                kind: k.kind,
                lengthscale: k.lengthscale,
                variance: k.variance,
                noise: k.noise,
            }),
            prior: self.prior,
            calibrate: self.calibrate,
            records_prior: self.records_prior,
        }
    }
}
