//! `POST /v1/scenes/{id}/irradiance`: irradiance `E(x, n)` in W/m² (RGB) at points.
//!
//! Hemisphere estimators (`estimator.method`), all over the Lambert density
//! `cos θ/π` (docs/math.md §1), in split mode (default: light-sampled direct
//! light plus the hemisphere estimate of the rest) or hemisphere mode:
//! - `mc`: cosine-weighted random directions (`render::irradiance`);
//! - `qmc`: spherical Fibonacci points (`fibonacci_cosine` by default, or
//!   `fibonacci`), equal weights, randomly rotated per point;
//! - `bmc`: Bayesian quadrature on a fixed sample set (default
//!   `fibonacci_cosine`) with the constant GLS prior mean, randomly rotated per
//!   point (`render::hemisphere_estimate`). Weights come from the service's
//!   factorisation cache, so repeated configurations never refactorise. The
//!   kernel's lengthscale is a number or `"auto"` (the default): fitted once per
//!   scene and configuration by marginal likelihood (`render::lengthscale`),
//!   together with the noise ratio unless `noise` is given. `std_dev` is the GP
//!   posterior standard deviation with the amplitude fitted to each point's
//!   radiance (`BmcVariance::AmplitudeFit`): the kernel's `σ²` carries no
//!   radiance units, while the per-point fit scales with the light level.

use std::sync::Arc;

use axum::Json;
use axum::extract::State;
use glam::DVec3;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::bmc::estimator::{BayesianEstimator, BmcVariance, SampleMeanEstimator, SamplingPdf};
use crate::bmc::report::QuadratureSpec;
use crate::bmc::{Density, Kernel, KernelKind, KernelMeanMethod, PriorMean};
use crate::render::lengthscale::{FALLBACK_LENGTHSCALE, FitConfig};
use crate::render::{
    Cancel, IrradianceEstimate, IrradianceMethod, IrradianceOptions, QueryPoint, RenderError, Rgb,
};
use crate::service::error::{ApiError, ErrorBody};
use crate::service::extract::{ApiJson, SceneId};
use crate::service::metrics::RAYS_TRACED;
use crate::service::routes::quadratures::{bmc_error, cached_quadrature, default_variance};
use crate::service::routes::scenes::scene_or_404;
use crate::service::scenes::LoadedScene;
use crate::service::state::AppState;
use crate::sphere::{SampleSetKind, SampleSetSpec};

/// A shading point: world position and the normal of the hemisphere of interest.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct PointDoc {
    pub position: [f64; 3],
    /// Need not be unit length; must be finite and non-zero.
    pub normal: [f64; 3],
}

/// The hemisphere estimator.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum EstimatorMethod {
    /// Monte Carlo with cosine-weighted directions.
    Mc,
    /// Quasi-Monte Carlo on spherical Fibonacci points.
    Qmc,
    /// Bayesian Monte Carlo (Bayesian quadrature) with cached weights.
    Bmc,
}

/// How the integral is split between estimators.
#[derive(Debug, Clone, Copy, Default, Deserialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum Decomposition {
    /// Direct light by light sampling + the rest through the hemisphere estimator.
    #[default]
    Split,
    /// Everything through the hemisphere estimator.
    Hemisphere,
}

#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct EstimatorDoc {
    pub method: EstimatorMethod,
    /// Hemisphere samples per point (and light samples in `split`), 1..=`limits.max_samples`.
    pub samples: u32,
    #[serde(default)]
    pub decomposition: Decomposition,
    /// `qmc` and `bmc` only: the fixed sample set.
    pub sample_set: Option<EstimatorSampleSetDoc>,
    /// `bmc` only: the GP kernel over incident radiance.
    pub kernel: Option<EstimatorKernelDoc>,
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
    SampleSetKind::FibonacciCosine
}

/// The kernel of a `bmc` estimator.
#[derive(Debug, Clone, Copy, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct EstimatorKernelDoc {
    /// `squared_exponential` (default), `matern32`, `matern52`.
    #[schema(value_type = String, example = "squared_exponential")]
    #[serde(default = "default_kernel_kind")]
    pub kind: KernelKind,
    /// ℓ in [0.01, 1000], or `"auto"` (default).
    #[serde(default)]
    #[schema(value_type = Object, example = "auto")]
    pub lengthscale: Lengthscale,
    /// σ², default 1 (the weights depend on `noise/variance` only).
    #[serde(default = "default_variance")]
    pub variance: f64,
    /// σ_n²; default: fitted with an `"auto"` lengthscale, else 1e-3 (Y is a
    /// path-traced estimate, and a tiny jitter makes SE weights oscillate).
    pub noise: Option<f64>,
}

fn default_kernel_kind() -> KernelKind {
    KernelKind::SquaredExponential
}

/// Noise of a numeric-lengthscale kernel when none is given.
const DEFAULT_NOISE: f64 = 1e-3;

/// A lengthscale: a number or `"auto"`.
#[derive(Debug, Clone, Copy, Default, Deserialize)]
#[serde(untagged)]
pub enum Lengthscale {
    Value(f64),
    #[default]
    #[serde(deserialize_with = "auto")]
    Auto,
}

/// `"auto"` as a unit variant of an untagged enum.
fn auto<'de, D: serde::Deserializer<'de>>(d: D) -> Result<(), D::Error> {
    use serde::de::Error;
    match String::deserialize(d)?.as_str() {
        "auto" => Ok(()),
        other => Err(D::Error::custom(format!(
            "expected a number or \"auto\", got {other:?}"
        ))),
    }
}
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct IrradianceRequest {
    /// 1..=`limits.max_points` points.
    pub points: Vec<PointDoc>,
    pub estimator: EstimatorDoc,
    /// Longest path in segments (1 = direct light only); default 16.
    #[serde(default = "default_max_depth")]
    pub max_depth: u32,
    /// Seed of every random stream; same request and seed, same numbers. Default 1.
    #[serde(default = "default_seed")]
    pub seed: u64,
}

fn default_max_depth() -> u32 {
    IrradianceOptions::default().max_depth
}

fn default_seed() -> u64 {
    IrradianceOptions::default().seed
}

#[derive(Debug, Serialize, Deserialize, ToSchema)]
pub struct IrradianceResponse {
    /// Irradiance per point, `[r, g, b]` in W/m².
    pub irradiance: Vec<[f64; 3]>,
    /// Standard error of each estimate, `[r, g, b]` in W/m².
    pub std_dev: Vec<[f64; 3]>,
    /// Rays traced for the whole request.
    pub rays: u64,
    /// `bmc`: the lengthscale used (fitted for `"auto"`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lengthscale: Option<f64>,
    /// `bmc`: the kernel noise σ_n² used (with σ² it sets the weights' smoothing).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise: Option<f64>,
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
    let scene = scene_or_404(&state, &id)?;
    let limits = &state.config.limits;
    ApiError::check_count(
        "points",
        request.points.len() as u64,
        limits.max_points as u64,
    )?;
    ApiError::check_limit(
        "estimator.samples",
        u64::from(request.estimator.samples),
        limits.max_samples as u64,
    )?;
    // One path per point and hemisphere sample (light samples are shadow rays).
    limits.check_work(request.points.len() as u64 * u64::from(request.estimator.samples))?;
    let points = request
        .points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            QueryPoint::new(DVec3::from(p.position), DVec3::from(p.normal))
                .map_err(|err| field_error(&format!("points[{i}]."), err))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let estimator = &request.estimator;
    let decomposition = match estimator.decomposition {
        Decomposition::Split => IrradianceMethod::Split,
        Decomposition::Hemisphere => IrradianceMethod::Hemisphere,
    };
    let options = IrradianceOptions {
        samples: estimator.samples,
        max_depth: request.max_depth,
        direct_only: false,
        method: decomposition,
        seed: request.seed,
    };
    options.validate().map_err(|err| field_error("", err))?;
    let plan = plan(estimator, decomposition)?;

    let worker = state.clone();
    let (estimates, kernel) = state
        .pool
        .run(move |cancel| plan.run(&worker, &scene, &points, &options, cancel))
        .await??;
    let rays = estimates.iter().map(|e| e.rays).sum();
    ::metrics::counter!(RAYS_TRACED).increment(rays);
    let rgb = |c: Rgb| [c.r, c.g, c.b];
    Ok(Json(IrradianceResponse {
        irradiance: estimates.iter().map(|e| rgb(e.irradiance)).collect(),
        std_dev: estimates.iter().map(|e| rgb(e.std_error)).collect(),
        rays,
        lengthscale: kernel.map(|k| k.lengthscale),
        noise: kernel.map(|k| k.noise),
    }))
}

/// A validated estimator, ready to run on the CPU pool.
enum Plan {
    Mc,
    Qmc(SampleMeanEstimator),
    Bmc(BmcPlan),
}

/// A `bmc` estimator before its kernel is resolved.
#[derive(Clone, Copy)]
struct BmcPlan {
    sample_set: SampleSetSpec,
    kind: KernelKind,
    /// `None`: `"auto"`.
    lengthscale: Option<f64>,
    variance: f64,
    noise: Option<f64>,
    decomposition: IrradianceMethod,
}

/// Checks the estimator options against the method (module docs).
fn plan(estimator: &EstimatorDoc, decomposition: IrradianceMethod) -> Result<Plan, ApiError> {
    let samples = estimator.samples as usize;
    let set = estimator.sample_set.unwrap_or(EstimatorSampleSetDoc {
        kind: default_set_kind(),
        seed: 0,
    });
    if estimator.method != EstimatorMethod::Bmc && estimator.kernel.is_some() {
        return Err(ApiError::invalid(
            "estimator.kernel",
            "only `bmc` takes a kernel",
        ));
    }
    match estimator.method {
        EstimatorMethod::Mc if estimator.sample_set.is_some() => Err(ApiError::invalid(
            "estimator.sample_set",
            "`mc` draws fresh random directions; only `qmc` and `bmc` take a sample set",
        )),
        EstimatorMethod::Mc => Ok(Plan::Mc),
        EstimatorMethod::Qmc => {
            let pdf = match set.kind {
                SampleSetKind::FibonacciCosine => SamplingPdf::Cosine,
                SampleSetKind::Fibonacci => SamplingPdf::Uniform,
                _ => {
                    return Err(ApiError::invalid(
                        "estimator.sample_set.kind",
                        "`qmc` takes `fibonacci_cosine` or `fibonacci`",
                    ));
                }
            };
            SampleMeanEstimator::quasi_monte_carlo(Density::Lambert, pdf, samples)
                .map(Plan::Qmc)
                .map_err(|e| ApiError::invalid("estimator.samples", e.to_string()))
        }
        EstimatorMethod::Bmc => {
            let kernel = estimator.kernel.unwrap_or(EstimatorKernelDoc {
                kind: default_kernel_kind(),
                lengthscale: Lengthscale::Auto,
                variance: default_variance(),
                noise: None,
            });
            let lengthscale = match kernel.lengthscale {
                Lengthscale::Value(value) => Some(value),
                Lengthscale::Auto => None,
            };
            // Check the numbers now (a stand-in ℓ for "auto") so bad input is a 422.
            Kernel::new(
                kernel.kind,
                lengthscale.unwrap_or(FALLBACK_LENGTHSCALE),
                kernel.variance,
                kernel.noise.unwrap_or(DEFAULT_NOISE),
            )
            .map_err(|e| bmc_error("estimator.kernel", e))?;
            Ok(Plan::Bmc(BmcPlan {
                sample_set: SampleSetSpec {
                    kind: set.kind,
                    count: samples,
                    seed: set.seed,
                },
                kind: kernel.kind,
                lengthscale,
                variance: kernel.variance,
                noise: kernel.noise,
                decomposition,
            }))
        }
    }
}

impl Plan {
    /// Estimates on the calling (pool) thread; BMC also returns its kernel.
    fn run(
        self,
        state: &AppState,
        scene: &LoadedScene,
        points: &[QueryPoint],
        options: &IrradianceOptions,
        cancel: &Cancel,
    ) -> Result<(Vec<IrradianceEstimate>, Option<Kernel>), ApiError> {
        let transport = &scene.transport;
        let (estimates, kernel) = match self {
            Plan::Mc => (
                transport.irradiance_at_points(points, options, &|| {}, cancel),
                None,
            ),
            Plan::Qmc(qmc) => (
                transport.irradiance_with_estimator(points, &qmc, options, cancel),
                None,
            ),
            Plan::Bmc(bmc) => {
                let (estimator, kernel) = bmc.estimator(state, scene)?;
                (
                    transport.irradiance_with_estimator(points, &estimator, options, cancel),
                    Some(kernel),
                )
            }
        };
        Ok((estimates.map_err(|err| field_error("", err))?, kernel))
    }
}

impl BmcPlan {
    /// The kernel (fitting `"auto"` on first use for this scene and
    /// configuration) and the estimator over its cached weights.
    fn estimator(
        self,
        state: &AppState,
        scene: &LoadedScene,
    ) -> Result<(BayesianEstimator, Kernel), ApiError> {
        let (lengthscale, default_noise) = match self.lengthscale {
            Some(value) => (value, DEFAULT_NOISE),
            None => {
                let config = FitConfig {
                    kernel: self.kind,
                    sample_set: self.sample_set,
                    decomposition: self.decomposition,
                };
                let fit =
                    scene
                        .kernels
                        .get_or_fit(&scene.transport, config)
                        .map_err(|message| ApiError::Internal {
                            message: format!("lengthscale fit failed: {message}"),
                        })?;
                (fit.lengthscale, fit.noise_ratio * self.variance)
            }
        };
        let noise = self.noise.unwrap_or(default_noise);
        let kernel = Kernel::new(self.kind, lengthscale, self.variance, noise)
            .map_err(|e| bmc_error("estimator.kernel", e))?;
        let spec = QuadratureSpec {
            sample_set: self.sample_set,
            kernel,
            density: Density::Lambert,
            prior_mean: PriorMean::Gls,
            kernel_mean: KernelMeanMethod::Exact,
        };
        let (quadrature, _) =
            cached_quadrature(state, &spec).map_err(|e| bmc_error("estimator.kernel", e))?;
        Ok((
            BayesianEstimator::new(quadrature, BmcVariance::AmplitudeFit),
            kernel,
        ))
    }
}

/// A render error as a 422 naming the request field: point fields under
/// `prefix`, option fields by their request path.
fn field_error(prefix: &str, err: RenderError) -> ApiError {
    let field = match &err {
        RenderError::InvalidPoint { field, .. } => format!("{prefix}{field}"),
        RenderError::InvalidOption {
            field: "samples", ..
        } => "estimator.samples".into(),
        RenderError::InvalidOption { field, .. } => (*field).into(),
        RenderError::PointsRow { .. } => prefix.trim_end_matches('.').into(),
        RenderError::Cancelled => return ApiError::Cancelled,
    };
    ApiError::invalid(field, err.to_string())
}
