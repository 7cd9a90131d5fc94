//! `GET /v1/presets`: the quality presets of tiles and every knob each sets
//! (`integrator::preset`), so clients can show them and know their passes.

use axum::Json;
use serde::Serialize;
use utoipa::ToSchema;

use crate::integrator::Preset;

/// One preset as the API reports it.
#[derive(Debug, Serialize, ToSchema)]
pub struct PresetDoc {
    pub name: String,
    /// Whether tiles use it when none is named.
    pub default: bool,
    /// Camera rays per pixel in each pass.
    pub samples_per_pixel: u32,
    /// Passes of the progressive render.
    pub passes: u32,
    /// Longest path in segments.
    pub max_depth: u32,
    /// The cache integrator's knobs (`estimator` of a tile request).
    #[schema(value_type = Object)]
    pub estimator: serde_json::Value,
}

/// The presets, cheapest first.
#[utoipa::path(get, path = "/v1/presets", tag = "scenes",
    responses((status = 200, body = Vec<PresetDoc>)))]
pub async fn presets() -> Json<Vec<PresetDoc>> {
    Json(
        Preset::ALL
            .iter()
            .map(|&p| {
                let s = p.settings();
                let c = &s.cached;
                PresetDoc {
                    name: p.name().to_owned(),
                    default: p == Preset::default(),
                    samples_per_pixel: s.samples_per_pixel,
                    passes: s.passes,
                    max_depth: s.max_depth.get(),
                    estimator: serde_json::json!({
                        "method": s.integrator,
                        "samples": c.samples,
                        "glossy_samples": c.glossy_samples,
                        "paths_per_direction": c.paths_per_direction,
                        "secondary_cache": c.secondary_cache,
                        "accuracy": c.accuracy,
                        "min_pixels": c.min_pixels,
                        "light_samples": c.light_samples,
                        "reproducible": c.reproducible,
                    }),
                }
            })
            .collect(),
    )
}
