//! `POST /v1/quadratures`: the BMC weights of one configuration (docs/math.md §3),
//! from the service's factorisation cache.
//!
//! The response has the fields of the CLI's `quadrature --json`
//! ([`QuadratureReport`]): `id` (stable hash of the canonical configuration),
//! `directions`, `kernel_means`, `weights`, `prior_variance`,
//! `posterior_variance`, `jitter`, `condition_estimate`, `density_integral`
//! and `cached`.
//!
//! Metrics: every lookup of the cache — here and in BMC point requests, through
//! [`metrics::record_quadrature_lookup`] — counts one `bmc_factorisation_cache_hits_total` (the
//! weights, hence the factorisation, were reused) or one
//! `bmc_factorisation_cache_misses_total` (weights computed; the factorisation
//! itself may still have come from the cache for a new density), and a miss
//! refreshes the `bmc_factorisation_cache_bytes` gauge (bytes only change on
//! inserts and the evictions they trigger).

use std::sync::Arc;

use axum::Json;
use axum::extract::State;
use serde::Deserialize;
use utoipa::ToSchema;

use crate::bmc::report::{QuadratureReport, QuadratureSpec, quadrature_report};
use crate::bmc::{Density, Kernel, KernelKind, KernelMeanMethod, PriorMean};
use crate::service::error::{ApiError, ErrorBody};
use crate::service::extract::ApiJson;
use crate::service::metrics;
use crate::service::state::AppState;
use crate::sphere::{SampleSetKind, SampleSetSpec};

/// Sample directions on the hemisphere (local frame, z = normal).
#[derive(Debug, Clone, Copy, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct SampleSetDoc {
    /// `fibonacci`, `fibonacci_cosine`, `uniform`, `cosine` or `stratified`.
    #[schema(value_type = String, example = "fibonacci")]
    pub kind: SampleSetKind,
    /// Number of directions, 1..=`limits.max_samples`.
    pub count: u32,
    /// Seed of the random kinds (ignored by the Fibonacci kinds); default 0.
    #[serde(default)]
    pub seed: u64,
}

impl SampleSetDoc {
    /// The library spec, with the count checked against the service limit.
    pub fn spec(&self, field: &str, max_samples: usize) -> Result<SampleSetSpec, ApiError> {
        let count_field = format!("{field}.count");
        if self.count == 0 {
            return Err(ApiError::invalid(count_field, "must be at least 1"));
        }
        ApiError::check_limit(&count_field, self.count as u64, max_samples as u64)?;
        Ok(SampleSetSpec {
            kind: self.kind,
            count: self.count as usize,
            seed: self.seed,
        })
    }
}

/// The GP covariance over incident radiance.
#[derive(Debug, Clone, Copy, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct KernelDoc {
    /// `squared_exponential`, `matern32` or `matern52`.
    #[schema(value_type = String, example = "squared_exponential")]
    pub kind: KernelKind,
    /// ℓ in chordal-distance units, in [0.01, 1000].
    pub lengthscale: f64,
    /// σ², default 1.
    #[serde(default = "default_variance")]
    pub variance: f64,
    /// σ_n² added to the diagonal, default 1e-8.
    #[serde(default = "default_noise")]
    pub noise: f64,
}

/// Default kernel amplitude σ².
pub fn default_variance() -> f64 {
    1.0
}

/// Default diagonal noise σ_n²: a jitter for conditioning.
pub fn default_noise() -> f64 {
    1e-8
}

/// The density `p` of `∫ f p dω`.
#[derive(Debug, Clone, Copy, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct DensityDoc {
    /// `lambert` (cos θ/π), `uniform` (1/2π) or `phong`.
    pub kind: DensityKind,
    /// Phong exponent m ≥ 0 (required for `phong`).
    pub exponent: Option<f64>,
    /// Polar angle of the Phong mirror direction from the normal, radians in [0, π/2]; default 0.
    pub mirror_elevation: Option<f64>,
}

/// Names of the densities.
#[derive(Debug, Clone, Copy, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum DensityKind {
    Lambert,
    Uniform,
    Phong,
}

/// Body of `POST /v1/quadratures`.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct QuadratureRequest {
    pub sample_set: SampleSetDoc,
    pub kernel: KernelDoc,
    pub density: DensityDoc,
    /// `zero` (default) or `gls` (constant mean by generalised least squares).
    #[serde(default)]
    #[schema(value_type = String, example = "zero")]
    pub prior_mean: PriorMean,
    /// `exact` (default) or `spherical_gaussian` (SE kernel only, approximate).
    #[serde(default)]
    #[schema(value_type = String, example = "exact")]
    pub kernel_mean: KernelMeanMethod,
}

impl QuadratureRequest {
    fn spec(&self, max_samples: usize) -> Result<QuadratureSpec, ApiError> {
        let k = &self.kernel;
        let d = &self.density;
        let density = match d.kind {
            DensityKind::Lambert => Density::Lambert,
            DensityKind::Uniform => Density::Uniform,
            DensityKind::Phong => Density::Phong {
                exponent: d.exponent.ok_or_else(|| {
                    ApiError::invalid("density.exponent", "required with kind `phong`")
                })?,
                mirror_elevation: d.mirror_elevation.unwrap_or(0.0),
            },
        };
        density.validate()?;
        Ok(QuadratureSpec {
            sample_set: self.sample_set.spec("sample_set", max_samples)?,
            kernel: Kernel::new(k.kind, k.lengthscale, k.variance, k.noise)?,
            density,
            prior_mean: self.prior_mean,
            kernel_mean: self.kernel_mean,
        })
    }
}

/// BMC weights, kernel means and variances of one configuration, computed once
/// and then served from the cache (`cached: true`). Identical concurrent first
/// requests compute once.
#[utoipa::path(post, path = "/v1/quadratures", tag = "quadratures",
    request_body = QuadratureRequest,
    responses((status = 200, body = Object,
               description = "`id`, `cached`, `directions`, `kernel_means`, `weights`, `prior_variance`, \
                              `posterior_variance`, `jitter`, `condition_estimate`, `density_integral`"),
               (status = 422, description = "Invalid request", body = ErrorBody),
               (status = 503, description = "CPU queue full; see Retry-After", body = ErrorBody)))]
pub async fn post_quadrature(
    State(state): State<Arc<AppState>>,
    ApiJson(request): ApiJson<QuadratureRequest>,
) -> Result<Json<QuadratureReport>, ApiError> {
    let spec = request.spec(state.config.limits.max_samples)?;
    let worker = state.clone();
    let report = state
        .pool
        .run(move |_| {
            let report = quadrature_report(&spec, &worker.quadratures);
            metrics::record_quadrature_lookup(
                &worker.quadratures,
                report.as_ref().ok().map(|r| r.cached),
            );
            report
        })
        .await??;
    Ok(Json(report))
}
