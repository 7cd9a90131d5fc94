//! Outgoing radiance at surface points towards given directions ("what does
//! a viewer at `x + t·ω` see at `x`"), by path tracing or through the
//! irradiance cache — the point-query form of the tile shading.
//!
//! A query names a point on a surface, its normal and the unit direction
//! `ω` towards the viewer (world frame). The surface is found by a short
//! ray from `x + δω` back to `x` (then, failing that, from `x + δn`), with
//! `δ` = [`PROBE_RELATIVE`] × the scene's bounding-box diagonal, so the
//! query's position need only be accurate to well within that.
//!
//! Each estimate averages `repeats` independent evaluations drawn from
//! `point_rng(seed, i)`; its standard error is their sample standard
//! deviation / √repeats (light-sampling and path noise), or, if larger, the
//! root of the mean variance the evaluations report themselves over
//! `repeats` (the glossy fallback's, docs/math.md §13.3), plus, through the
//! cache, the variance of the interpolated records (posterior variance plus
//! the noise of their paths, [`crate::cache::RecordEstimate::variance`])
//! scaled by `(k_d/π)²`: the records' own error, which repeats cannot reveal
//! because every repeat reads the same records.

use glam::DVec3;
use rayon::prelude::*;

use super::cached::{
    CachedIntegrator, OnMiss, PlacementReport, ShadePoint, ShadingStats, indirect_paths,
    secondary_cache_of,
};
use super::path::PathIntegrator;
use super::resolved::BoundIntegrator;
use crate::render::seed::point_rng;
use crate::render::{
    Cancel, Evaluation, MeanEstimate, PathDepth, QueryPoint, RenderError, Rgb, TraceStats,
    Transport,
};
use crate::scene::{Ray, SurfaceHit};

/// Probe distance relative to the scene's bounding-box diagonal.
pub const PROBE_RELATIVE: f64 = 1e-4;

/// A radiance query: a surface point and the direction towards the viewer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RadianceQuery {
    pub point: QueryPoint,
    /// Unit direction from the point towards the viewer, world frame.
    pub direction: DVec3,
}

impl RadianceQuery {
    /// Validates and normalises the direction (finite, non-zero).
    pub fn new(point: QueryPoint, direction: DVec3) -> Result<Self, RenderError> {
        let length = direction.length();
        if !direction.is_finite() || length == 0.0 || !length.is_finite() {
            return Err(RenderError::InvalidPoint {
                field: "direction",
                reason: format!("must be finite and non-zero, got {direction}"),
            });
        }
        Ok(Self {
            point,
            direction: direction / length,
        })
    }
}

/// Outgoing radiance with its standard error, W/(m²·sr).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RadianceEstimate {
    pub radiance: Rgb,
    pub std_error: Rgb,
    /// Rays traced for this query.
    pub rays: u64,
}

/// The surface hit a query names, or `None` if no surface lies within the
/// probe distance of its position (module docs).
pub fn surface_at(transport: &Transport, query: &RadianceQuery) -> Option<SurfaceHit> {
    let x = query.point.position();
    [query.direction, query.point.normal()]
        .into_iter()
        .find_map(|towards| transport.scene().intersect(&probe(transport, x, towards)))
}

/// The short ray from `x + δ·towards` back to `x` (module docs).
fn probe(transport: &Transport, x: DVec3, towards: DVec3) -> Ray {
    let (min, max) = transport.scene().bounds();
    let delta = PROBE_RELATIVE * (max - min).length().max(1e-9);
    Ray {
        origin: x + delta * towards,
        dir: -towards,
        t_max: 2.0 * delta,
    }
}

/// The work of a radiance query.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RadianceOptions {
    /// Path segments counted from the viewer, as a camera ray's from the
    /// camera (1 = emission only); records in a cache must have been made
    /// for the same `max_depth`.
    pub max_depth: PathDepth,
    /// Independent estimates averaged per point (≥ 1); their spread gives
    /// the standard error.
    pub repeats: u32,
    /// Seed of every random stream of the request.
    pub seed: u64,
}

/// Radiance leaving each `hits[i]` towards `queries[i].direction`, in
/// parallel on the current rayon pool, and what building the scene's
/// secondary cache took if this call built it (records created here read
/// it when the options ask for `secondary_cache`, as a tile's do). Stops
/// between points once `cancel` is set.
pub fn radiance_at_points(
    integrator: &BoundIntegrator,
    queries: &[RadianceQuery],
    hits: &[SurfaceHit],
    options: RadianceOptions,
    cancel: &Cancel,
) -> Result<(Vec<RadianceEstimate>, PlacementReport), RenderError> {
    let RadianceOptions {
        max_depth,
        repeats,
        seed,
    } = options;
    if repeats == 0 {
        return Err(RenderError::InvalidOption {
            field: "repeats",
            reason: "must be at least 1".into(),
        });
    }
    let transport = integrator.transport();
    let path = PathIntegrator::new(transport);
    // The cached integrator, once for every point, with the scene's
    // secondary cache if the options ask for one; `None`: path tracing.
    let cached = match integrator {
        BoundIntegrator::Cache(cached) => Some(*cached),
        BoundIntegrator::Path(_) => None,
    };
    let (secondary, built) = match (&cached, max_depth.after_first_segment()) {
        (Some(integrator), Some(from_point)) => {
            secondary_cache_of(integrator, indirect_paths(from_point), cancel)?
        }
        _ => (None, PlacementReport::default()),
    };
    let cached = cached.map(|integrator| CachedIntegrator {
        secondary: secondary.as_ref().map(|s| &s.cache),
        ..integrator
    });
    let estimates = queries
        .par_iter()
        .zip(hits)
        .enumerate()
        .map(|(i, (query, hit))| {
            cancel.check()?;
            let mut rng = point_rng(seed, i as u64);
            let mut trace = TraceStats::default();
            let mut stats = ShadingStats::default();
            // The camera ray of this query, for path tracing.
            let camera_ray = probe(transport, hit.position, query.direction);
            let values = (0..repeats)
                .map(|_| match cached {
                    None => Ok(path.radiance(camera_ray, max_depth, &mut rng, &mut trace)),
                    Some(integrator) => {
                        let how = ShadePoint {
                            max_depth,
                            on_miss: OnMiss::Insert,
                            // Independent repeats, so their spread is the
                            // standard error (no pattern shared between them).
                            sample: None,
                            dense: false,
                        };
                        integrator.outgoing_radiance(
                            hit,
                            query.direction,
                            how,
                            &mut rng,
                            &mut stats,
                        )
                    }
                })
                .collect::<Result<Vec<Evaluation>, RenderError>>()?;
            // The records' error is every repeat's (`Evaluation::shared`),
            // so it stays in the variance however many repeats there are.
            let mean = MeanEstimate::of_evaluations(values);
            Ok(RadianceEstimate {
                radiance: mean.mean,
                std_error: mean.variance_of_mean.map(f64::sqrt),
                rays: trace.rays + stats.rays,
            })
        })
        .collect::<Result<_, RenderError>>()?;
    Ok((estimates, built))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bmc::cache::QuadratureCache;
    use crate::cache::IrradianceCache;
    use crate::integrator::cached::{CacheShadingOptions, CachedShading, default_rule_spec};
    use crate::testing::{agrees, cornell};
    use std::sync::Arc;

    fn floor_query() -> RadianceQuery {
        // The Cornell back wall (z = -1) above the boxes, seen from the front.
        let point = QueryPoint::new(DVec3::new(0.1, 0.6, -1.0), DVec3::Z).unwrap();
        RadianceQuery::new(point, DVec3::new(0.2, -0.1, 1.0)).unwrap()
    }

    fn shading(options: CacheShadingOptions) -> CachedShading {
        let mut spec = default_rule_spec();
        spec.samples.count = 128;
        CachedShading::new(spec, 4, Arc::new(QuadratureCache::new(1 << 24)), options).unwrap()
    }

    /// Radiance at the floor query through `cache` and `shading` (4
    /// repeats) agrees with path tracing (4096 repeats) at `max_depth`;
    /// returns what building a secondary cache took and the rays the
    /// query traced besides.
    fn assert_agrees_with_path_tracing(
        cache: &IrradianceCache,
        shading: &CachedShading,
        max_depth: u32,
    ) -> (PlacementReport, u64) {
        let transport = cornell(8);
        let query = floor_query();
        let hit = surface_at(&transport, &query).expect("on the wall");
        let radiance = |how: BoundIntegrator, repeats| {
            let options = RadianceOptions {
                max_depth: PathDepth::constant(max_depth),
                repeats,
                seed: 1,
            };
            radiance_at_points(&how, &[query], &[hit], options, &Cancel::never()).unwrap()
        };
        let path = radiance(BoundIntegrator::Path(PathIntegrator::new(&transport)), 4096).0[0];
        let cached = CachedIntegrator::new(&transport, cache, shading);
        let (bmc, built) = radiance(BoundIntegrator::Cache(cached), 4);
        let bmc = bmc[0];
        for (p, b, sp, sb) in [
            (
                path.radiance.r,
                bmc.radiance.r,
                path.std_error.r,
                bmc.std_error.r,
            ),
            (
                path.radiance.g,
                bmc.radiance.g,
                path.std_error.g,
                bmc.std_error.g,
            ),
        ] {
            assert!(b > 0.0 && sb > 0.0, "path {p} ± {sp}, bmc {b} ± {sb}");
            // Records are not free of bias from interpolation, but at their own
            // position they estimate the same integral; 4σ of the combined error
            // plus 3 % for the record's unmodelled path noise (and, through a
            // secondary cache, its interpolation).
            assert!(
                agrees(b, p, sp.hypot(sb), 4.0, 0.03),
                "path {p} ± {sp}, bmc {b} ± {sb}"
            );
        }
        (built, bmc.rays)
    }

    /// Points on the tutorials' mirror and glass spheres: the cache
    /// integrator follows the camera path through the deltas and shades the
    /// diffuse surface it reaches from the cache (depth 17: 16 segments from
    /// the sphere, so the chain is taken), agreeing with path tracing. The
    /// few records a point reaches carry most of its error (the glass sees a
    /// floor lit through it), so the cache's estimate is the mean over
    /// independent caches (seeds), with their spread as its error.
    #[test]
    fn cached_radiance_through_mirror_and_glass_agrees_with_path_tracing() {
        let dir =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mitsuba-tutorials");
        let options = crate::scene::MitsubaOptions {
            parameters: [("res".to_string(), "16".to_string())].into(),
            ..Default::default()
        };
        let (scene, _) =
            crate::scene::Scene::load_mitsuba_xml(&dir.join("cbox.xml"), &dir, &options).unwrap();
        let transport = Transport::new(Arc::new(scene));
        let shading = shading(CacheShadingOptions {
            light_samples: 16,
            ..CacheShadingOptions::default()
        });
        let camera = DVec3::new(0.0, 0.0, 4.0);
        for (centre, radius, normal) in [
            (DVec3::new(-0.3, -0.5, 0.2), 0.5, DVec3::new(-0.5, 0.5, 0.7)),
            (
                DVec3::new(0.5, -0.75, -0.2),
                0.25,
                DVec3::new(0.2, 0.3, 0.9),
            ),
        ] {
            let n = normal.normalize();
            let x = centre + radius * n;
            let query =
                RadianceQuery::new(QueryPoint::new(x, n).unwrap(), (camera - x).normalize())
                    .unwrap();
            let hit = surface_at(&transport, &query).expect("on the sphere");
            let radiance = |how: BoundIntegrator, repeats, seed| {
                let options = RadianceOptions {
                    max_depth: PathDepth::constant(17),
                    repeats,
                    seed,
                };
                let estimate =
                    radiance_at_points(&how, &[query], &[hit], options, &Cancel::never())
                        .unwrap()
                        .0[0];
                (
                    estimate.radiance.luminance(),
                    estimate.std_error.luminance(),
                )
            };
            let (path, path_se) = radiance(
                BoundIntegrator::Path(PathIntegrator::new(&transport)),
                8192,
                1,
            );
            let caches: Vec<f64> = (0..12)
                .map(|seed| {
                    let cache = IrradianceCache::new(Default::default()).unwrap();
                    let cached = CachedIntegrator::new(&transport, &cache, &shading);
                    let (value, _) = radiance(BoundIntegrator::Cache(cached), 64, seed);
                    assert!(cache.stats().records > 0, "the chain reached the cache");
                    value
                })
                .collect();
            let mean = caches.iter().sum::<f64>() / caches.len() as f64;
            let spread = (caches.iter().map(|v| (v - mean).powi(2)).sum::<f64>()
                / (caches.len() - 1) as f64)
                .sqrt();
            let se = (spread / (caches.len() as f64).sqrt()).hypot(path_se);
            assert!(
                agrees(mean, path, se, 4.0, 0.0),
                "{centre}: path {path}, cache {mean} ± {se} ({caches:?})"
            );
        }
    }

    /// On a checkerboard floor (`tests/data/mitsuba/textures.xml`), one
    /// point on each colour: the cache multiplies its records' irradiance by
    /// the texture at the point, not by the texture's mean (about 0.65× the
    /// light square's and 2.2× the dark square's), agreeing with path tracing.
    #[test]
    fn cached_radiance_takes_the_texture_at_the_point() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mitsuba");
        let (scene, _) = crate::scene::Scene::load_mitsuba_xml(
            &dir.join("textures.xml"),
            &dir,
            &Default::default(),
        )
        .unwrap();
        let transport = Transport::new(Arc::new(scene));
        let shading = shading(CacheShadingOptions {
            light_samples: 16,
            ..CacheShadingOptions::default()
        });
        let camera = DVec3::new(0.0, 1.2, 4.2);
        let mut values = Vec::new();
        // The floor is (3x, −1, −3y) for local (x, y): these two points lie
        // on squares of color0 (light) and color1 (dark).
        for x in [DVec3::new(0.9, -1.0, 1.5), DVec3::new(0.3, -1.0, 1.5)] {
            let query = RadianceQuery::new(
                QueryPoint::new(x, DVec3::Y).unwrap(),
                (camera - x).normalize(),
            )
            .unwrap();
            let hit = surface_at(&transport, &query).expect("on the floor");
            let options = RadianceOptions {
                max_depth: PathDepth::constant(3),
                repeats: 4096,
                seed: 3,
            };
            let estimate = |how: BoundIntegrator| {
                let e = radiance_at_points(&how, &[query], &[hit], options, &Cancel::never())
                    .unwrap()
                    .0[0];
                (e.radiance.luminance(), e.std_error.luminance())
            };
            let (path, path_se) = estimate(BoundIntegrator::Path(PathIntegrator::new(&transport)));
            let cache = IrradianceCache::new(Default::default()).unwrap();
            let (cached, cached_se) = estimate(BoundIntegrator::Cache(CachedIntegrator::new(
                &transport, &cache, &shading,
            )));
            assert!(
                agrees(cached, path, cached_se.hypot(path_se), 4.0, 0.02),
                "{x}: path {path} ± {path_se}, cache {cached} ± {cached_se}"
            );
            values.push(path);
        }
        // Luminances of color0 and color1 are 0.655 and 0.194: a ratio of 3.4.
        assert!(values[0] / values[1] > 2.5, "{values:?}");
    }

    #[test]
    fn cached_radiance_agrees_with_path_tracing_within_noise() {
        let shading = shading(CacheShadingOptions {
            light_samples: 64,
            paths_per_direction: 4,
            ..CacheShadingOptions::default()
        });
        let cache = IrradianceCache::new(Default::default()).unwrap();
        let (built, _) = assert_agrees_with_path_tracing(&cache, &shading, 8);
        assert_eq!(cache.stats().records, 1);
        assert_eq!(built.records_created, 0);
    }

    /// A record a query creates reads the scene's secondary cache when the
    /// options ask for it, for fewer rays than paths: the first query builds
    /// the cache, the next finds it (held by the rule set, so tiles read the
    /// same one).
    #[test]
    fn cached_radiance_through_the_secondary_cache_agrees_with_path_tracing() {
        let options = CacheShadingOptions {
            light_samples: 64,
            paths_per_direction: 4,
            ..CacheShadingOptions::default()
        };
        let by_paths = shading(options);
        let cache = IrradianceCache::new(Default::default()).unwrap();
        let (_, rays_by_paths) = assert_agrees_with_path_tracing(&cache, &by_paths, 20);

        let shading = shading(CacheShadingOptions {
            secondary_cache: true,
            ..options
        });
        let cache = IrradianceCache::new(Default::default()).unwrap();
        let (built, rays) = assert_agrees_with_path_tracing(&cache, &shading, 20);
        assert!(built.records_created > 0 && built.rays > 0, "{built:?}");
        assert_eq!(shading.secondary.records(), built.records_created);
        assert_eq!(cache.stats().records, 1);
        assert!(
            rays < rays_by_paths,
            "{rays} rays, {rays_by_paths} by paths"
        );
        let again = IrradianceCache::new(Default::default()).unwrap();
        let (found, _) = assert_agrees_with_path_tracing(&again, &shading, 20);
        assert_eq!(found.rays, 0);
    }

    #[test]
    fn points_off_every_surface_are_not_found() {
        let transport = cornell(8);
        let floating = RadianceQuery::new(
            QueryPoint::new(DVec3::new(0.0, 0.0, 0.0), DVec3::Y).unwrap(),
            DVec3::Z,
        )
        .unwrap();
        assert!(surface_at(&transport, &floating).is_none());
        assert!(surface_at(&transport, &floor_query()).is_some());
        assert!(matches!(
            RadianceQuery::new(floor_query().point, DVec3::ZERO),
            Err(RenderError::InvalidPoint {
                field: "direction",
                ..
            })
        ));
    }
}
