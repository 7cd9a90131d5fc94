//! Direct-light records: at the places of an irradiance cache's records,
//! the irradiance of the emission each place sees directly (the environment
//! where a ray escapes, an emitter's radiance where it hits one). Records
//! hold the indirect part (§10.7); these twins carry what the environment
//! and the emitters give once occluded by the scene, which a point
//! estimate's direct part integrates from its own few samples
//! (docs/math.md §10.8). A twin estimates the direct part as the query it
//! serves does: under the hemisphere decomposition by the record rule from
//! one-segment rays, with its gradients; in split mode by light samples.

use rand::{RngExt, SeedableRng};
use rayon::prelude::*;

use crate::cache::{RadiusLimits, Record, RecordRule, TwinCaches};
use crate::render::{
    AveragedPaths, Cancel, Decomposition, PathDepth, PathLengths, PathLimits, QueryPoint,
    RenderError, Rgb, TraceStats, Transport,
};
use crate::sphere::Frame;

/// Records estimated per batch ([`RecordRule::estimate_batch`] shares its
/// table reads among them).
const BATCH: usize = 32;

/// How twins estimate the direct light at their places: as the queries
/// they serve estimate their direct part.
#[derive(Clone, Copy)]
pub enum TwinRule<'a> {
    /// The record rule over one ray along each of its directions, with the
    /// rule's gradients (for the hemisphere decomposition).
    Directions(&'a RecordRule),
    /// This many light samples (multiple importance sampled with cosine
    /// directions where an environment shines), the estimate of a split
    /// query's direct part, with the rotation gradient from the same
    /// samples and no translation gradient (for the split decomposition).
    LightSamples(u32),
}

impl<'a> TwinRule<'a> {
    /// The twins that serve queries under `decomposition`, at the cost of
    /// `rule`'s: one light sample per direction of it in split mode.
    pub fn for_queries(decomposition: Decomposition, rule: &'a RecordRule) -> Self {
        match decomposition {
            Decomposition::Hemisphere => Self::Directions(rule),
            Decomposition::Split => Self::LightSamples(rule.directions().len() as u32),
        }
    }
}

/// The direct-light twins of `records`, inserted into `twins` (beside their
/// shadow probes when light-sampled): each at the record's place and with
/// its validity radius, estimated by `rule` (with the rule's directions
/// turned about the normal by a random angle); every random number is
/// drawn from `seed` and the record's place, so a record has the same twin
/// whenever and with whatever others it is computed. Returns the rays
/// traced.
pub fn direct_records(
    transport: &Transport,
    records: &[Record],
    rule: TwinRule,
    twins: &TwinCaches,
    seed: u64,
    cancel: &Cancel,
) -> Result<u64, RenderError> {
    type Batch = (Vec<Record>, Vec<Record>, u64);
    let batches: Vec<Result<Batch, RenderError>> = records
        .par_chunks(BATCH)
        .map(|batch| {
            cancel.check()?;
            let mut trace = TraceStats::default();
            let made = match rule {
                TwinRule::Directions(rule) => {
                    directions_twins(transport, batch, rule, seed, &mut trace)?
                }
                TwinRule::LightSamples(samples) => batch
                    .iter()
                    .map(|record| {
                        let mut rng =
                            rand_pcg::Pcg64::seed_from_u64(place_seed(seed, record.position));
                        let point = QueryPoint::new(record.position, record.normal)?;
                        let (direct, gradient) = transport.direct_irradiance_and_normal_gradient(
                            &point, samples, &mut rng, &mut trace,
                        );
                        Ok(Record {
                            irradiance: direct.mean,
                            variance: direct.variance_of_mean,
                            // E(n) ≈ E + (n_k × ∇)·(n_k × n) for ∇ = ∂E/∂n.
                            rotation_gradient: gradient.map(|g| record.normal.cross(g)),
                            translation_gradient: [glam::DVec3::ZERO; 3],
                            ..*record
                        })
                    })
                    .collect::<Result<Vec<_>, RenderError>>()?,
            };
            // Twins of the record rule turn and move with its gradients
            // under a smooth environment; light-sampled twins only turn, and
            // meet the edges of hard shadows (docs/math.md §10.8).
            let probed = match rule {
                TwinRule::Directions(_) => &made[..0],
                TwinRule::LightSamples(_) => &made[..],
            };
            let probes = probed
                .iter()
                .map(|twin| {
                    let point = QueryPoint::new(twin.position, twin.normal)?;
                    let (probe, gradient) = transport.shadow_probe(&point, &mut trace);
                    Ok(Record {
                        irradiance: probe,
                        variance: Rgb::BLACK,
                        rotation_gradient: gradient.map(|g| twin.normal.cross(g)),
                        translation_gradient: [glam::DVec3::ZERO; 3],
                        ..*twin
                    })
                })
                .collect::<Result<Vec<_>, RenderError>>()?;
            Ok((made, probes, trace.rays))
        })
        .collect();
    let mut rays = 0;
    for batch in batches {
        let (batch, probes, traced) = batch?;
        rays += traced;
        // In the same order into both: they evict alike.
        for twin in batch {
            twins.twins.insert(twin)?;
        }
        for probe in probes {
            twins.probes.insert(probe)?;
        }
    }
    Ok(rays)
}

/// The twins of `batch` by the record rule from one-segment rays.
fn directions_twins(
    transport: &Transport,
    batch: &[Record],
    rule: &RecordRule,
    seed: u64,
    trace: &mut TraceStats,
) -> Result<Vec<Record>, RenderError> {
    let paths = AveragedPaths {
        limits: PathLimits {
            max_depth: PathDepth::new(1)?,
            lengths: PathLengths::All,
        },
        per_direction: 1,
    };
    let mut gathered = Vec::with_capacity(batch.len());
    for record in batch {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(place_seed(seed, record.position));
        let point = QueryPoint::new(record.position, record.normal)?;
        let frame = Frame::from_normal(record.normal)
            .rotated_about_normal(std::f64::consts::TAU * rng.random::<f64>());
        let samples = transport.hemisphere_samples_averaged(
            &point,
            &frame,
            rule.directions(),
            paths,
            &mut rng,
            trace,
        );
        gathered.push((point, frame, samples));
    }
    let values: Vec<&[_]> = gathered.iter().map(|(_, _, s)| s.as_slice()).collect();
    let estimates = rule.estimate_batch(&values);
    gathered
        .iter()
        .zip(estimates)
        .zip(batch)
        .map(|(((point, frame, samples), estimate), record)| {
            let distances: Vec<f64> = samples.iter().map(|s| s.distance).collect();
            // The twin keeps the record's radius (and clamps its
            // gradients to it), so both cover the same points.
            let limits = RadiusLimits {
                min: record.radius,
                max: record.radius,
            };
            Ok(Record::from_estimate(
                point, frame, &estimate?, &distances, limits,
            ))
        })
        .collect()
}

/// The seed of a record's twin: `seed` mixed with the bits of its place.
fn place_seed(seed: u64, position: glam::DVec3) -> u64 {
    // An odd multiplier and a rotation spread each coordinate's bits.
    position.to_array().iter().fold(seed, |h, c| {
        (h ^ c.to_bits())
            .wrapping_mul(0x9E37_79B9_7F4A_7C15)
            .rotate_left(29)
    })
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use glam::DVec3;

    use super::*;
    use crate::bmc::cache::QuadratureCache;
    use crate::cache::CacheConfig;
    use crate::integrator::cached::CachedSpec;

    /// A unit disk at the origin facing +z under a constant sky of radiance
    /// 2: above it the whole sky is seen, `E = 2π`; one unit below it,
    /// facing up, the disk hides the cone of half-angle 45°, which holds
    /// `sin² 45° = ½` of the cosine-weighted sky, `E = π`. Returns the
    /// scene and the records' places at those two heights, with `gradient`
    /// in every gradient (a twin must not keep it).
    fn disk_under_sky(gradient: DVec3) -> (Transport, [Record; 2]) {
        let doc = r#"{
            "materials": [{"id": "grey", "type": "diffuse", "reflectance": [0.5, 0.5, 0.5]}],
            "shapes": [{"type": "disk", "material": "grey"}],
            "environment": {"type": "constant", "radiance": [2, 2, 2]},
            "camera": {"type": "perspective", "fov": 30, "origin": [0, 0, 4],
                       "target": [0, 0, 0], "up": [0, 1, 0], "width": 4, "height": 4}
        }"#;
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let scene = crate::scene::Scene::from_json_str(doc, dir, dir).unwrap();
        let place = |z: f64| Record {
            position: DVec3::new(0.0, 0.0, z),
            normal: DVec3::Z,
            irradiance: Rgb::BLACK,
            variance: Rgb::BLACK,
            radius: 0.3,
            rotation_gradient: [gradient; 3],
            translation_gradient: [gradient; 3],
        };
        (Transport::new(Arc::new(scene)), [place(0.0), place(-1.0)])
    }

    #[test]
    fn twins_hold_the_sky_the_places_see_past_the_occluders() {
        let (transport, places) = disk_under_sky(DVec3::ZERO);
        let spec = CachedSpec {
            samples: Some(256),
            ..CachedSpec::default()
        };
        let shading = spec
            .resolve()
            .unwrap()
            .shading(Arc::new(QuadratureCache::new(64 << 20)))
            .unwrap();
        let twins_of = |places: &[Record]| {
            let cache = TwinCaches::new(CacheConfig::default()).unwrap();
            let rays = direct_records(
                &transport,
                places,
                TwinRule::Directions(&shading.rule),
                &cache,
                7,
                &Cancel::never(),
            )
            .unwrap();
            (cache, rays)
        };
        let (cache, rays) = twins_of(&places);
        // One ray per direction, and no probe: these twins have gradients.
        assert_eq!(rays, 2 * 256);
        assert!(cache.probes.records().is_empty());
        let twins = cache.twins.records();
        assert_eq!(twins.len(), 2);
        let at = |z: f64| *twins.iter().find(|t| t.position.z == z).unwrap();
        let (open, under) = (at(0.0), at(-1.0));
        let pi = std::f64::consts::PI;
        assert!((open.irradiance.g - 2.0 * pi).abs() < 1e-9 * pi, "{open:?}");
        assert!((under.irradiance.g - pi).abs() < 0.05 * pi, "{under:?}");
        assert!(under.variance.g > 0.0);
        assert_eq!((open.radius, under.radius), (0.3, 0.3));
        // A place has the same twin whatever it is computed with.
        let (alone, _) = twins_of(&places[1..]);
        assert_eq!(alone.twins.records()[0], under);
    }

    /// Light-sampled twins (split mode) hold the same sky: above the disk
    /// `2π`, under it `π`, with the light samples' variance, the record's
    /// radius and no gradients; a place has the same twin however it is
    /// computed.
    #[test]
    fn light_sampled_twins_hold_the_same_sky() {
        let (transport, places) = disk_under_sky(DVec3::ONE);
        let twins_of = |places: &[Record]| {
            let cache = TwinCaches::new(CacheConfig::default()).unwrap();
            let rays = direct_records(
                &transport,
                places,
                TwinRule::LightSamples(4096),
                &cache,
                7,
                &Cancel::never(),
            )
            .unwrap();
            (cache, rays)
        };
        let (cache, rays) = twins_of(&places);
        assert!(rays >= 2 * 4096, "{rays}");
        let twins = cache.twins.records();
        let at = |z: f64| *twins.iter().find(|t| t.position.z == z).unwrap();
        let (open, under) = (at(0.0), at(-1.0));
        let pi = std::f64::consts::PI;
        for (twin, truth) in [(open, 2.0 * pi), (under, pi)] {
            let sigma = twin.variance.g.sqrt();
            assert!(sigma > 0.0 && sigma < 0.02 * truth, "{twin:?}");
            assert!((twin.irradiance.g - truth).abs() < 4.0 * sigma, "{twin:?}");
            assert_eq!(twin.radius, 0.3);
            // The sky is symmetric about the normal at both places: turning
            // the normal changes E only at second order, and the gradient
            // holds the samples' noise alone (a few times the value's).
            assert!(twin.rotation_gradient[1].length() < 0.1 * truth, "{twin:?}");
            assert_eq!(twin.translation_gradient, [DVec3::ZERO; 3]);
        }
        let (alone, _) = twins_of(&places[1..]);
        assert_eq!(alone.twins.records()[0], under);
        // Each twin has its probe at its place, with its radius: the sky is
        // half hidden under the disk, so the probe there sees less.
        let probes = cache.probes.records();
        for (twin, probe) in twins.iter().zip(&probes) {
            assert_eq!((probe.position, probe.radius), (twin.position, twin.radius));
        }
        assert!(
            probes[1].irradiance.g < probes[0].irradiance.g,
            "{probes:?}"
        );
    }

    /// A light-sampled twin turns with the normal: lit by a point light,
    /// its rotation gradient predicts `I cos θ' / r²` at a normal turned by
    /// 0.1 rad up to the second-order term.
    #[test]
    fn light_sampled_twins_turn_with_the_normal() {
        let transport = crate::testing::occluded_ground(0.0);
        let place =
            crate::testing::flat_record(DVec3::new(1.0, 0.0, 0.0), DVec3::Z, Rgb::BLACK, 0.5);
        let caches = TwinCaches::new(CacheConfig::default()).unwrap();
        let never = Cancel::never();
        direct_records(
            &transport,
            &[place],
            TwinRule::LightSamples(8),
            &caches,
            1,
            &never,
        )
        .unwrap();
        let twin = caches.twins.records()[0];
        let to_light = DVec3::new(-1.0, 0.0, 2.0);
        let exact = |n: DVec3| 4.0 * n.dot(to_light.normalize()) / to_light.length_squared();
        assert!((twin.irradiance.r - exact(DVec3::Z)).abs() < 1e-12);
        for angle in [0.1f64, -0.1] {
            let turned = DVec3::new(-angle.sin(), 0.0, angle.cos());
            let predicted = twin.extrapolate(place.position, turned).r;
            let (e, flat) = (exact(turned), twin.irradiance.r);
            assert!((predicted - e).abs() < angle * angle * e, "{predicted} {e}");
            assert!((flat - e).abs() > 4.0 * (predicted - e).abs());
        }
    }
}
