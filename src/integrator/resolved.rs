//! An integrator resolved and checked ([`Integrator`]), and bound to a
//! scene and, for the cache integrator, a cache and its rules
//! ([`BoundIntegrator`]): what every front end renders tiles and answers
//! radiance queries with, matching on the method in this file only.

use super::cached::{CachedConfig, CachedIntegrator, CachedShading, CachedTileReport};
use super::method::Method;
use super::path::PathIntegrator;
use crate::cache::IrradianceCache;
use crate::render::{Cancel, RenderError, RenderedTile, SamplePlan, TileRequest, Transport};

/// A checked integrator: [`super::IntegratorSpec::resolve`]'s result.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Integrator {
    Path,
    Cache(CachedConfig),
}

impl Integrator {
    pub fn method(&self) -> Method {
        match self {
            Integrator::Path => Method::Path,
            Integrator::Cache(_) => Method::Cache,
        }
    }

    /// The cache integrator's configuration, if this is it: what a front
    /// end needs to find (or make) the cache to bind it to.
    pub fn cached(&self) -> Option<&CachedConfig> {
        match self {
            Integrator::Cache(config) => Some(config),
            Integrator::Path => None,
        }
    }

    /// Paths an estimate may trace: `camera_paths` plus, through the
    /// cache, one record at each of `shading_points` (the bound a work
    /// budget checks before any work).
    pub fn estimated_paths(&self, camera_paths: u64, shading_points: u64) -> u64 {
        let per_point = self.cached().map_or(0, CachedConfig::paths_per_record);
        camera_paths.saturating_add(shading_points.saturating_mul(per_point))
    }

    /// Whether a tile's output depends only on the scene's content and the
    /// request (path tracing always; the cache integrator when asked for).
    pub fn reproducible(&self) -> bool {
        self.cached().is_none_or(CachedConfig::reproducible)
    }

    /// Text naming everything the integrator's output depends on, for
    /// content keys of memoised work: its canonical JSON (every field, in
    /// declaration order; a field added changes the keys, as it should).
    pub fn content_key(&self) -> String {
        serde_json::to_string(self).expect("an integrator serialises")
    }

    /// The integrator on `transport`'s scene; the cache integrator reads
    /// and extends `cache` with `shading`'s rules (which the caller built
    /// for this integrator's configuration and the requests' `max_depth`).
    pub fn bind<'a>(
        &self,
        transport: &'a Transport,
        cache: Option<(&'a IrradianceCache, &'a CachedShading)>,
    ) -> Result<BoundIntegrator<'a>, RenderError> {
        Ok(match (self, cache) {
            (Integrator::Path, _) => BoundIntegrator::Path(PathIntegrator::new(transport)),
            (Integrator::Cache(_), Some((cache, shading))) => {
                BoundIntegrator::Cache(CachedIntegrator::new(transport, cache, shading))
            }
            (Integrator::Cache(_), None) => {
                return Err(RenderError::InvalidOption {
                    field: "estimator",
                    reason: "the cache integrator needs a cache to read and extend".into(),
                });
            }
        })
    }
}

/// An integrator ready to shade: the path tracer, or the cache integrator
/// with its cache.
#[derive(Clone, Copy)]
pub enum BoundIntegrator<'a> {
    Path(PathIntegrator<'a>),
    Cache(CachedIntegrator<'a>),
}

impl BoundIntegrator<'_> {
    /// One tile of the scene camera's image, with what the cache did (all
    /// zero for path tracing). Stops between pixels once `cancel` is set.
    /// `plan`: the rays per pixel of an adaptive pass
    /// (`render::render_tile_with`).
    pub fn render_tile(
        &self,
        request: &TileRequest,
        plan: Option<&SamplePlan>,
        cancel: &Cancel,
    ) -> Result<(RenderedTile, CachedTileReport), RenderError> {
        match self {
            BoundIntegrator::Path(path) => Ok((
                path.render_tile(request, plan, cancel)?,
                CachedTileReport::default(),
            )),
            BoundIntegrator::Cache(cached) => cached.render_tile(request, plan, cancel),
        }
    }

    /// The scene's light transport.
    pub fn transport(&self) -> &Transport {
        match self {
            BoundIntegrator::Path(path) => path.transport(),
            BoundIntegrator::Cache(cached) => cached.transport,
        }
    }

    /// The cache integrator, if this is it.
    pub fn cached(&self) -> Option<&CachedIntegrator<'_>> {
        match self {
            BoundIntegrator::Cache(cached) => Some(cached),
            BoundIntegrator::Path(_) => None,
        }
    }
}
