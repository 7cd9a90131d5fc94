//! `POST /v1/scenes/{id}/radiance`: outgoing radiance in W/(m²·sr) (RGB) at
//! surface points towards a viewer direction per point — what a camera ray
//! arriving at the point from that direction would return. Shaded as tiles
//! are (`estimator.method`: `bmc` through the scene's irradiance cache,
//! sharing records with tiles of the same `max_depth`; `path` by path
//! tracing); see `integrator::radiance`.

use std::sync::Arc;

use axum::Json;
use axum::extract::State;
use glam::DVec3;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::integrator::{
    IntegratorSpec, RadianceOptions, RadianceQuery, radiance_at_points, surface_at,
};
use crate::render::{PathDepth, QueryPoint, Rgb};
use crate::service::error::{ApiError, AtField, ErrorBody};
use crate::service::extract::{ApiJson, SceneId};
use crate::service::integrator::{CachedSetup, cached_setup, resolve_integrator};
use crate::service::metrics::RAYS_TRACED;
use crate::service::state::AppState;

/// A surface point, its normal and the direction towards the viewer.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct RadiancePointDoc {
    /// On a surface (within 1e-4 of the scene's diagonal).
    pub position: [f64; 3],
    /// Finite and non-zero; need not be unit length.
    pub normal: [f64; 3],
    /// From the point towards the viewer, world frame; finite and non-zero.
    pub direction: [f64; 3],
}

#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct RadianceRequest {
    /// 1..=`limits.max_points` points.
    pub points: Vec<RadiancePointDoc>,
    /// As for tiles: `{"method": "cache" | "path", …}`; default `cache`
    /// with its default knobs.
    #[serde(default)]
    pub estimator: IntegratorSpec,
    /// Independent evaluations averaged per point (their spread gives
    /// `std_dev`), 1..=`limits.max_samples`; default 16.
    #[serde(default = "default_repeats")]
    pub repeats: u32,
    /// Longest path in segments, the viewer's segment included; default the
    /// scene's (its Mitsuba integrator's `max_depth`), else 16.
    pub max_depth: Option<u32>,
    /// Seed of every random stream; default 1.
    #[serde(default = "default_seed")]
    pub seed: u64,
}

fn default_repeats() -> u32 {
    16
}

fn default_seed() -> u64 {
    1
}

#[derive(Debug, Serialize, Deserialize, ToSchema)]
pub struct RadianceResponse {
    /// The unit of `radiance` and `std_dev`: `W/(m²·sr)`.
    pub unit: String,
    /// Outgoing radiance per point, `[r, g, b]` in W/(m²·sr).
    pub radiance: Vec<[f64; 3]>,
    /// Standard error per point: the repeats' spread plus, through the
    /// cache, the records' posterior variance.
    pub std_dev: Vec<[f64; 3]>,
    /// Rays traced for the whole request.
    pub rays: u64,
}

/// Outgoing radiance at each point of the request.
#[utoipa::path(post, path = "/v1/scenes/{id}/radiance", tag = "scenes",
    params(("id" = String, Path, description = "Scene id")),
    request_body = RadianceRequest,
    responses((status = 200, body = RadianceResponse),
               (status = 404, description = "Unknown scene", body = ErrorBody),
               (status = 422, description = "Invalid request", body = ErrorBody),
               (status = 503, description = "CPU queue full; see Retry-After", body = ErrorBody)))]
pub async fn radiance(
    State(state): State<Arc<AppState>>,
    SceneId(id): SceneId,
    ApiJson(request): ApiJson<RadianceRequest>,
) -> Result<Json<RadianceResponse>, ApiError> {
    let scene = state.scene(&id).await?;
    let limits = &state.config.limits;
    ApiError::check_count(
        "points",
        request.points.len() as u64,
        limits.max_points as u64,
    )?;
    ApiError::check_count(
        "repeats",
        u64::from(request.repeats),
        limits.max_samples as u64,
    )?;
    let max_depth = request.max_depth.map_or(
        Ok(PathDepth::for_camera(
            scene.transport.scene(),
            PathDepth::default(),
        )),
        PathDepth::new,
    )?;
    let queries = request
        .points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            QueryPoint::new(DVec3::from(p.position), DVec3::from(p.normal))
                .and_then(|point| RadianceQuery::new(point, DVec3::from(p.direction)))
                .at(&format!("points[{i}]"))
        })
        .collect::<Result<Vec<_>, _>>()?;
    // The work, bounded before it starts: the repeats' paths, plus for `bmc`
    // at most one record per point.
    let integrator = resolve_integrator(request.estimator, limits)?;
    let points = request.points.len() as u64;
    limits.check_work(integrator.estimated_paths(points * u64::from(request.repeats), points))?;
    let (repeats, seed) = (request.repeats, request.seed);
    let shared = state.clone();
    let (estimates, secondary) = state
        .pool
        .run(move |cancel| {
            // On the pool: a new configuration factorises its record rule.
            let setup = cached_setup(&shared, &scene, &integrator, max_depth)?;
            let transport = &scene.transport;
            let hits = queries
                .iter()
                .enumerate()
                .map(|(i, q)| {
                    surface_at(transport, q).ok_or_else(|| {
                        ApiError::invalid(
                            format!("points[{i}].position"),
                            "no surface at this position (probed along the direction and the normal)",
                        )
                    })
                })
                .collect::<Result<Vec<_>, _>>()?;
            let bound = integrator.bind(transport, setup.as_ref().map(CachedSetup::binding))?;
            let options = RadianceOptions {
                max_depth,
                repeats,
                seed,
            };
            // The points and options were checked above, so what fails here
            // is the shading the estimator asked for.
            radiance_at_points(&bound, &queries, &hits, options, cancel)
                .at("estimator")
        })
        .await??;
    let rays = estimates.iter().map(|e| e.rays).sum::<u64>() + secondary.rays;
    ::metrics::counter!(RAYS_TRACED).increment(rays);
    let rgb = |c: Rgb| [c.r, c.g, c.b];
    Ok(Json(RadianceResponse {
        unit: "W/(m²·sr)".into(),
        radiance: estimates.iter().map(|e| rgb(e.radiance)).collect(),
        std_dev: estimates.iter().map(|e| rgb(e.std_error)).collect(),
        rays,
    }))
}
