//! `POST /v1/scenes/{id}/irradiance`: irradiance `E(x, n)` in W/m² (RGB) at points.
//!
//! Estimators available: `mc` (cosine-weighted Monte Carlo through
//! `render::Transport`, split into light-sampled direct light plus the
//! hemisphere estimate of the rest by default). The BMC and QMC hemisphere
//! estimators are added to `method` when the library offers them.

use std::sync::Arc;

use axum::Json;
use axum::extract::{Path, State};
use glam::DVec3;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::render::{IrradianceMethod, IrradianceOptions, QueryPoint, RenderError, Rgb};
use crate::service::error::{ApiError, ErrorBody};
use crate::service::extract::ApiJson;
use crate::service::metrics::RAYS_TRACED;
use crate::service::routes::scenes::scene_or_404;
use crate::service::state::AppState;

/// A shading point: world position and the normal of the hemisphere of interest.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct PointDoc {
    pub position: [f64; 3],
    /// Need not be unit length; must be finite and non-zero.
    pub normal: [f64; 3],
}

/// The hemisphere estimator.
#[derive(Debug, Clone, Copy, Deserialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum EstimatorMethod {
    /// Monte Carlo with cosine-weighted directions.
    Mc,
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
    Path(id): Path<String>,
    ApiJson(request): ApiJson<IrradianceRequest>,
) -> Result<Json<IrradianceResponse>, ApiError> {
    let scene = scene_or_404(&state, &id)?;
    let limits = &state.config.limits;
    if request.points.is_empty() {
        return Err(ApiError::invalid("points", "must hold at least one point"));
    }
    ApiError::check_limit("points", request.points.len(), limits.max_points)?;
    ApiError::check_limit(
        "estimator.samples",
        request.estimator.samples as usize,
        limits.max_samples,
    )?;
    let points = request
        .points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            QueryPoint::new(DVec3::from(p.position), DVec3::from(p.normal))
                .map_err(|err| field_error(&format!("points[{i}]."), err))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let EstimatorMethod::Mc = request.estimator.method;
    let options = IrradianceOptions {
        samples: request.estimator.samples,
        max_depth: request.max_depth,
        direct_only: false,
        method: match request.estimator.decomposition {
            Decomposition::Split => IrradianceMethod::Split,
            Decomposition::Hemisphere => IrradianceMethod::Hemisphere,
        },
        seed: request.seed,
    };
    options.validate().map_err(|err| field_error("", err))?;

    let estimates = state
        .pool
        .run(move || {
            scene
                .transport
                .irradiance_at_points(&points, &options, &|| {})
        })
        .await?
        .map_err(|err| field_error("", err))?;
    let rays = estimates.iter().map(|e| e.rays).sum();
    ::metrics::counter!(RAYS_TRACED).increment(rays);
    let rgb = |c: Rgb| [c.r, c.g, c.b];
    Ok(Json(IrradianceResponse {
        irradiance: estimates.iter().map(|e| rgb(e.irradiance)).collect(),
        std_dev: estimates.iter().map(|e| rgb(e.std_error)).collect(),
        rays,
    }))
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
    };
    ApiError::invalid(field, err.to_string())
}
