//! `GET /v1/presets`: the quality presets of tiles and every knob each sets
//! (`integrator::preset`), so clients can show them and know their passes.

use axum::Json;
use serde::Serialize;
use utoipa::ToSchema;

use crate::integrator::{IntegratorSpec, Preset};

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
    /// Longest path in segments from the camera, on scenes that set none
    /// (a scene's own `max_depth` replaces it).
    pub max_depth: u32,
    /// The integrator and every knob the preset sets, as a tile request's
    /// `estimator` names them (posting it back changes nothing).
    pub estimator: IntegratorSpec,
    /// What the preset is on a scene with surfaces that make caustics
    /// (mirrors, glass, sharp microfacet lobes), where records do not pay:
    /// path tracing, denoised unless a tile asks otherwise.
    pub on_caustic_scenes: PathTracedDoc,
}

/// A preset as path tracing.
#[derive(Debug, Serialize, ToSchema)]
pub struct PathTracedDoc {
    /// Camera rays per pixel in each of the preset's `passes`.
    pub samples_per_pixel: u32,
    /// Whether tiles are denoised when they do not say.
    pub denoise: bool,
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
                let path = p.path_settings();
                PresetDoc {
                    name: p.name().to_owned(),
                    default: p == Preset::default(),
                    samples_per_pixel: s.samples_per_pixel,
                    passes: s.passes,
                    max_depth: s.max_depth.get(),
                    estimator: s.integrator,
                    on_caustic_scenes: PathTracedDoc {
                        samples_per_pixel: path.samples_per_pixel,
                        denoise: path.denoise,
                    },
                }
            })
            .collect(),
    )
}
