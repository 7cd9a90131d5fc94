//! Records from gathered rays, with no shading in between: where records
//! may be placed, the point a record is wanted at, its rays once gathered
//! (`shade::gather_record`), their BMC estimates and radii, and the cache
//! lookup (with the occlusion test) that decides whether one is needed.

use glam::DVec3;

use super::config::PlacementOptions;
use crate::cache::{
    CacheError, Interpolated, IrradianceCache, PixelFootprint, RadiusLimits, Record, RecordRule,
};
use crate::render::{QueryPoint, RadianceSample, Transport};
use crate::scene::SurfaceHit;
use crate::sphere::Frame;

/// A point where irradiance is wanted, with the optional pixel footprint
/// that bounds a record's radius there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlacementPoint {
    pub point: QueryPoint,
    pub footprint: Option<PixelFootprint>,
}

/// A record's rays, gathered but not yet estimated (`shade::gather_record`).
pub struct GatheredRecord {
    /// The record's local frame, turned about the normal.
    pub(super) frame: Frame,
    /// One radiance sample per direction of the rule, in its order.
    pub(super) samples: Vec<RadianceSample>,
}

impl GatheredRecord {
    /// Distance to the first hit along each direction (∞ where none).
    fn distances(&self) -> Vec<f64> {
        self.samples.iter().map(|s| s.distance).collect()
    }
}

/// The records of `shade::compute_record` from gathered rays, in order, estimated
/// together ([`RecordRule::estimate_batch`]).
pub fn finish_records(
    rule: &RecordRule,
    gathered: &[(&PlacementPoint, GatheredRecord)],
    limits: RadiusLimits,
) -> Vec<Result<Record, CacheError>> {
    let samples: Vec<&[RadianceSample]> =
        gathered.iter().map(|(_, g)| g.samples.as_slice()).collect();
    let estimates = rule.estimate_batch(&samples);
    gathered
        .iter()
        .zip(estimates)
        .map(|((target, g), estimate)| {
            Ok(Record::from_estimate(
                &target.point,
                &g.frame,
                &estimate?,
                &g.distances(),
                record_limits(target, limits),
            ))
        })
        .collect()
}

/// The record [`finish_records`] will make at `target` from rays with
/// these first-hit `distances`, its values still zero
/// (`Record::awaiting_values`).
pub fn awaiting_record(target: &PlacementPoint, distances: &[f64], limits: RadiusLimits) -> Record {
    Record::awaiting_values(&target.point, distances, record_limits(target, limits))
}

/// The radius limits of a record at `target`: `limits` narrowed by the
/// pixel footprint where there is one.
fn record_limits(target: &PlacementPoint, limits: RadiusLimits) -> RadiusLimits {
    match &target.footprint {
        Some(fp) => limits.with_footprint(fp),
        None => limits,
    }
}

/// Whether `hit`, reached along `dir`, is a front face with a diffuse lobe:
/// where records may be placed.
pub fn diffuse_front(transport: &Transport, hit: &SurfaceHit, dir: DVec3) -> bool {
    hit.shading_normal.dot(dir) < 0.0
        && transport
            .bsdf(hit.material)
            .is_some_and(|b| b.flags().diffuse)
}

/// Relative lift of the occlusion-test ray ends off their surfaces.
const OCCLUSION_LIFT: f64 = 1e-3;

/// Cache lookup with the options' accuracy and optional occlusion test.
pub fn lookup(
    cache: &IrradianceCache,
    transport: &Transport,
    point: &QueryPoint,
    options: &PlacementOptions,
) -> Option<Interpolated> {
    if !options.occlusion_check {
        return cache.lookup(point, options.accuracy);
    }
    let scene = transport.scene();
    let (x, n) = (point.position(), point.normal());
    cache.lookup_filtered(point, options.accuracy, |r| {
        let lift = OCCLUSION_LIFT * r.radius;
        let from = x + n * lift;
        let ray = scene.spawn_ray_to(from, n, r.position + r.normal * lift, None);
        !scene.occluded(&ray)
    })
}
